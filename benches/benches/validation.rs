//! Criterion benches of validated updates: twin validation of a 10-minute horizon (both programs)
//! for the Vernadat cell (U.1) and the Festo station (F.1), forked from a running PLC; the
//! analysis gate at load for U.1 and U.2; and the revert, whose latency in cycles is printed.

use std::path::Path;
use std::sync::Arc;

use cetratus_io::TwinDriver;
use cetratus_node::gate::{self, GatePolicy};
use cetratus_node::validate::{self, Job, Start, ValidationMode, ValidationPolicy};
use cetratus_program::{build_package, Program, TrustStore};
use cetratus_runtime::{
    Command, EventDetail, EventKind, ManualStopwatch, Plc, SubstituteMode, SubstituteRequest,
};
use cetratus_twin::{Plant, Twin, TwinKind};
use criterion::{criterion_group, criterion_main, BatchSize, Criterion};

const PERIOD: u64 = 10_000;

fn example(dir: &str, file: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(dir)
        .join(file)
}

struct Cell {
    plc: Plc,
    io: TwinDriver<Twin>,
    now: u64,
}

impl Cell {
    fn new(program: &Path, mut twin: Twin) -> Self {
        let program = Arc::new(Program::load(program).expect("the program"));
        if twin.kind() == TwinKind::Festo {
            twin.press("RESET", 100_000).expect("RESET");
            twin.press("START", 500_000).expect("START");
        }
        let io = TwinDriver::new(twin, program.inputs(), program.outputs()).expect("signals");
        let mut plc = Plc::new(program, 0, Box::new(ManualStopwatch::new()));
        plc.use_virtual_time(PERIOD);
        Cell { plc, io, now: 0 }
    }
    fn run_for(&mut self, us: u64) {
        let end = self.now + us;
        while self.now < end {
            self.plc.cycle(self.now, &mut self.io);
            drop(self.plc.take_retired());
            let _ = self.plc.drain_events();
            self.now += PERIOD;
        }
    }
    fn load(&mut self, manifest: &Path) {
        let (bytes, _) = build_package(manifest, None, 1_700_000_000).expect("the package builds");
        let p = self
            .plc
            .update_context()
            .prepare_package(
                &bytes,
                &TrustStore::empty(),
                cetratus_program::Unsigned::Allowed,
                cetratus_program::OtherBase::Refused,
            )
            .expect("prepared");
        self.plc
            .command(Command::Load(Box::new(p)))
            .expect("accepted");
        self.run_for(PERIOD);
    }
    fn fork_job(&self) -> Job {
        let start = Start::fork(&self.plc, self.io.plant().clone());
        let policy = ValidationPolicy {
            mode: ValidationMode::Fork,
            ..ValidationPolicy::default()
        };
        validate::job_for(&self.plc, start, policy, PERIOD).expect("an update under way")
    }
}

fn validation(c: &mut Criterion) {
    let mut g = c.benchmark_group("validation_10min");
    g.sample_size(10);
    for (name, dir, program, manifest, twin) in [
        (
            "vernadat-u1",
            "vernadat",
            "vernadat.toml",
            "u1.package.toml",
            TwinKind::Vernadat,
        ),
        (
            "festo-f1",
            "festo",
            "festo.toml",
            "f1.package.toml",
            TwinKind::Festo,
        ),
    ] {
        let mut cell = Cell::new(&example(dir, program), twin.build(1));
        cell.run_for(20_000_000);
        cell.load(&example(dir, manifest));
        let job = cell.fork_job();
        let v = validate::validate(&job);
        eprintln!("{name}: {:?} {:?}", v.result, v.figures);
        g.bench_function(name, |b| b.iter(|| validate::validate(&job)));
    }
    g.finish();
}

fn gate_at_load(c: &mut Criterion) {
    let mut g = c.benchmark_group("gate");
    for (name, base, manifest) in [
        ("u1", "vernadat.toml", "u1.package.toml"),
        ("u2", "u1.toml", "u2.package.toml"),
    ] {
        let program = Arc::new(Program::load(&example("vernadat", base)).expect("program"));
        let plc = Plc::new(program, 0, Box::new(ManualStopwatch::new()));
        let ctx = plc.update_context();
        let (bytes, _) =
            build_package(&example("vernadat", manifest), None, 1_700_000_000).expect("package");
        let up = ctx
            .prepare_package(
                &bytes,
                &TrustStore::empty(),
                cetratus_program::Unsigned::Allowed,
                cetratus_program::OtherBase::Refused,
            )
            .expect("prepared");
        let policy = GatePolicy::default();
        let out = gate::run(&ctx, &up, &policy);
        eprintln!(
            "gate {name}: {:?} {:?}",
            out.verdict.result, out.verdict.figures
        );
        g.bench_function(name, |b| b.iter(|| gate::run(&ctx, &up, &policy)));
    }
    g.finish();
}

/// U.1 on probation, substituted after `warmup_us`, with a revert asked for.
fn on_probation(warmup_us: u64) -> Cell {
    let mut cell = Cell::new(
        &example("vernadat", "vernadat.toml"),
        TwinKind::Vernadat.build(1),
    );
    let mut limits = cell.plc.limits();
    limits.probation_us = 60_000_000;
    cell.plc.set_limits(limits);
    cell.run_for(warmup_us);
    cell.load(&example("vernadat", "u1.package.toml"));
    cell.plc
        .command(Command::Substitute(SubstituteRequest::now(
            SubstituteMode::Retransform,
        )))
        .expect("substitute");
    cell.run_for(PERIOD);
    cell
}

fn revert(c: &mut Criterion) {
    // Latency in cycles, from the cycle that saw the cause to the one in which the old program
    // drives the outputs, over a sweep of substitution instants: operator reverts.
    let mut worst = 0;
    let mut n = 0;
    for k in 0..100u64 {
        let mut cell = on_probation(2_000_000 + k * 130_000);
        cell.plc.command(Command::Revert).expect("revert");
        cell.plc.cycle(cell.now, &mut cell.io);
        for e in cell.plc.drain_events() {
            if let (EventKind::Reverted, Some(EventDetail::Revert { detected_cycle, .. })) =
                (e.kind, e.detail)
            {
                worst = worst.max(e.cycle - detected_cycle);
                n += 1;
            }
        }
    }
    eprintln!("revert latency (operator): at most {worst} cycle(s) over {n} reverts");
    let mut g = c.benchmark_group("revert");
    g.bench_function("revert_cycle", |b| {
        b.iter_batched(
            || {
                let mut cell = on_probation(5_000_000);
                cell.plc.command(Command::Revert).expect("revert");
                cell
            },
            |mut cell| {
                cell.plc.cycle(cell.now, &mut cell.io);
                cell
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

criterion_group!(benches, validation, gate_at_load, revert);
criterion_main!(benches);
