//! Live-update figures: the quarantine cycle against a single-program cycle, the setup of the U.2
//! package away from the scan thread, the in-cycle state transformation and install, the cycle
//! of a revert against a probation cycle, and the derivation of U.1's generated bases.

use std::collections::BTreeMap;
use std::hint::black_box;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use cetratus_node::clock::MonotonicStopwatch;
use cetratus_program::{
    build_package, KeyPair, Program, Projection, StateTransform, TrustStore, Value,
};
use cetratus_runtime::{
    Command, Container, Dispatcher, Plc, Provider, SubstituteMode, SubstituteRequest,
};
use serde::Serialize;

use crate::program::{examples_dir, recorded_inputs};

/// Replays recorded input images; outputs go nowhere. Keeps the twin out of the figures.
pub struct Replay {
    images: Vec<Vec<Value>>,
    k: usize,
}

impl Replay {
    /// Replays `images` in a loop.
    pub fn new(images: Vec<Vec<Value>>) -> Self {
        Replay { images, k: 0 }
    }
}

impl Provider for Replay {
    fn read_inputs(&mut self, _now_us: u64, inputs: &mut [Value]) {
        inputs.copy_from_slice(&self.images[self.k % self.images.len()]);
        self.k += 1;
    }
}

impl Dispatcher for Replay {
    fn write_outputs(&mut self, _now_us: u64, outputs: &[Value]) {
        black_box(outputs);
    }
}

/// Signed U.1 and U.2 packages and the key that trusts them, built in a temporary directory.
pub struct Packages {
    /// U.1.
    pub u1: Vec<u8>,
    /// U.2 (built against U.1).
    pub u2: Vec<u8>,
    /// Trusts the signing key.
    pub trust: TrustStore,
}

impl Packages {
    /// `package` prepared against `ctx`, as a PLC that takes signed packages only prepares it.
    pub fn prepare(
        &self,
        ctx: &cetratus_runtime::UpdateContext,
        package: &[u8],
    ) -> cetratus_runtime::PreparedUpdate {
        ctx.prepare_package(
            package,
            &self.trust,
            cetratus_program::Unsigned::Refused,
            cetratus_program::OtherBase::Refused,
        )
        .expect("the package prepares")
    }
}

/// Builds and signs U.1 and U.2 from the examples.
pub fn packages() -> Packages {
    let dir = std::env::temp_dir().join(format!("cetratus-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    for entry in std::fs::read_dir(examples_dir().join("vernadat")).expect("examples") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "toml" || e == "pnml") {
            std::fs::copy(&path, dir.join(path.file_name().expect("name"))).expect("copy");
        }
    }
    let key = KeyPair::generate();
    let key_path = dir.join("bench.key");
    key.save(&key_path).expect("save key");
    let trusted = dir.join("trusted");
    std::fs::create_dir_all(&trusted).expect("trusted");
    std::fs::copy(KeyPair::public_path(&key_path), trusted.join("bench.pub")).expect("pub");
    let build = |m: &str| {
        build_package(&dir.join(m), Some(&key), 1_700_000_000)
            .expect("builds")
            .0
    };
    let p = Packages {
        u1: build("u1.package.toml"),
        u2: build("u2.package.toml"),
        trust: TrustStore::load_dir(&trusted).expect("trust"),
    };
    let _ = std::fs::remove_dir_all(&dir);
    p
}

/// Update figures.
#[derive(Debug, Serialize)]
pub struct UpdateFigures {
    /// Mean ns of a full single-program cycle (routing, one container, Monitor).
    pub single_cycle_ns: f64,
    /// Mean ns of a full cycle in quarantine (routing, two containers, Monitor).
    pub quarantine_cycle_ns: f64,
    /// quarantine_cycle_ns / single_cycle_ns.
    pub quarantine_ratio: f64,
    /// Mean ns of a full single-program cycle with the twin as the I/O driver.
    pub single_cycle_twin_ns: f64,
    /// Mean ns of a full quarantine cycle with the twin as the I/O driver.
    pub quarantine_cycle_twin_ns: f64,
    /// quarantine_cycle_twin_ns / single_cycle_twin_ns.
    pub quarantine_ratio_twin: f64,
    /// Verify, parse and build the U.2 package away from the scan thread, µs (median).
    pub setup_us: f64,
    /// The in-cycle part of U.2's install (transform + install), µs (median).
    pub state_transform_us: f64,
    /// The same for a net of 10⁵ places, µs (median).
    pub state_transform_100k_places_us: f64,
    /// A cycle of U.2 on probation with U.1 as its shadow, µs (median): the baseline of the
    /// next figure.
    pub probation_cycle_us: f64,
    /// The cycle in which U.2 on probation reverts to U.1: both markings of U.1 rehearsed
    /// against the outputs being dispatched, the shadow takes over and scans, µs (median).
    pub revert_cycle_us: f64,
    /// U.1's generated transformation and projection, their bases derived from the invariants
    /// of both nets (away from the scan thread), µs (median).
    pub derive_u1_us: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn mean_cycle_ns<IO: Provider + Dispatcher>(
    plc: &mut Plc,
    replay: &mut IO,
    cycles: usize,
    start_us: u64,
) -> f64 {
    let t0 = Instant::now();
    for k in 0..cycles {
        plc.cycle(start_us + k as u64 * 10_000, replay);
        black_box(plc.dispatched());
    }
    t0.elapsed().as_nanos() as f64 / cycles as f64
}

/// Measures the update figures.
pub fn update_figures(quick: bool) -> UpdateFigures {
    let pk = packages();
    let vernadat = crate::program::vernadat_program();
    let cycles = if quick { 30_000 } else { 200_000 };
    let images = recorded_inputs(&vernadat, cycles);
    let rounds = if quick { 5 } else { 9 };

    // Single-program and quarantine cycles on the same replayed inputs.
    let mut single = Vec::new();
    let mut quarantine = Vec::new();
    for _ in 0..rounds {
        let mut replay = Replay::new(images.clone());
        let mut plc = Plc::new(vernadat.clone(), 0, MonotonicStopwatch::boxed());
        single.push(mean_cycle_ns(&mut plc, &mut replay, cycles, 0));

        let mut replay = Replay::new(images.clone());
        let mut plc = Plc::new(vernadat.clone(), 0, MonotonicStopwatch::boxed());
        let prepared = pk.prepare(&plc.update_context(), &pk.u1);
        plc.command(Command::Load(Box::new(prepared)))
            .expect("accepted");
        plc.cycle(0, &mut replay);
        assert_eq!(plc.status(), cetratus_runtime::Status::Quarantine);
        quarantine.push(mean_cycle_ns(&mut plc, &mut replay, cycles, 10_000));
        drop(plc.drain_events());
    }
    let single_cycle_ns = median(single);
    let quarantine_cycle_ns = median(quarantine);

    // The same with the twin as Provider and Dispatcher: the cycle the cell actually runs.
    let mut single_t = Vec::new();
    let mut quarantine_t = Vec::new();
    for _ in 0..rounds {
        let twin = |p: &Arc<Program>| {
            cetratus_io::TwinDriver::new(
                cetratus_twin::TwinKind::Vernadat.build(1),
                p.inputs(),
                p.outputs(),
            )
            .expect("signals match")
        };
        let mut io = twin(&vernadat);
        let mut plc = Plc::new(vernadat.clone(), 0, MonotonicStopwatch::boxed());
        single_t.push(mean_cycle_ns(&mut plc, &mut io, cycles, 0));

        let mut io = twin(&vernadat);
        let mut plc = Plc::new(vernadat.clone(), 0, MonotonicStopwatch::boxed());
        let prepared = pk.prepare(&plc.update_context(), &pk.u1);
        plc.command(Command::Load(Box::new(prepared)))
            .expect("accepted");
        plc.cycle(0, &mut io);
        quarantine_t.push(mean_cycle_ns(&mut plc, &mut io, cycles, 10_000));
        drop(plc.drain_events());
    }
    let single_cycle_twin_ns = median(single_t);
    let quarantine_cycle_twin_ns = median(quarantine_t);

    // Setup of U.2 against a PLC running U.1.
    let u1_program =
        Arc::new(Program::load(&examples_dir().join("vernadat/u1.toml")).expect("U.1 loads"));
    let plc = Plc::new(u1_program.clone(), 0, MonotonicStopwatch::boxed());
    let ctx = plc.update_context();
    let setup: Vec<f64> = (0..if quick { 50 } else { 300 })
        .map(|_| {
            let t0 = Instant::now();
            black_box(pk.prepare(&ctx, &pk.u2));
            t0.elapsed().as_secs_f64() * 1e6
        })
        .collect();

    // The in-cycle part of U.2: transform + install into a prebuilt container.
    let u2_program =
        Arc::new(Program::load(&examples_dir().join("vernadat/u2.toml")).expect("U.2 loads"));
    let st =
        StateTransform::generated(&u1_program, &u2_program, &BTreeMap::new()).expect("generated");
    let state_transform_us = transform_install_us(
        &st,
        &u1_program,
        &u2_program,
        if quick { 2_000 } else { 20_000 },
    );

    let (old, new) = big_programs(100_000);
    let st = StateTransform::generated(&old, &new, &BTreeMap::new()).expect("generated");
    let state_transform_100k_places_us =
        transform_install_us(&st, &old, &new, if quick { 10 } else { 50 });

    let (probation_cycle_us, revert_cycle_us) = revert_cycles_us(&pk, if quick { 30 } else { 200 });
    let derive: Vec<f64> = (0..if quick { 200 } else { 2_000 })
        .map(|_| {
            let t0 = Instant::now();
            black_box(StateTransform::generated(&vernadat, &u1_program, &BTreeMap::new()).ok());
            black_box(Projection::generated(vernadat.net(), u1_program.net()).ok());
            t0.elapsed().as_secs_f64() * 1e6
        })
        .collect();

    UpdateFigures {
        single_cycle_ns,
        quarantine_cycle_ns,
        quarantine_ratio: quarantine_cycle_ns / single_cycle_ns,
        single_cycle_twin_ns,
        quarantine_cycle_twin_ns,
        quarantine_ratio_twin: quarantine_cycle_twin_ns / single_cycle_twin_ns,
        setup_us: median(setup),
        state_transform_us,
        state_transform_100k_places_us,
        probation_cycle_us,
        revert_cycle_us,
        derive_u1_us: median(derive),
    }
}

/// Median µs of a probation cycle of U.2 over U.1, and of the cycle in which an operator's
/// revert takes U.1 back, on replayed inputs: `n` reverts, each from a fresh substitution (a
/// revert that waits for the plant to agree is not counted).
fn revert_cycles_us(pk: &Packages, n: usize) -> (f64, f64) {
    let u1 = Arc::new(Program::load(&examples_dir().join("vernadat/u1.toml")).expect("U.1 loads"));
    let images = recorded_inputs(&u1, 2_000);
    let (mut probation, mut revert) = (Vec::new(), Vec::new());
    let timed = |plc: &mut Plc, now: u64, replay: &mut Replay| {
        let t0 = Instant::now();
        plc.cycle(now, replay);
        t0.elapsed().as_secs_f64() * 1e6
    };
    for _ in 0..n * 3 {
        if revert.len() == n {
            break;
        }
        let mut replay = Replay::new(images.clone());
        let mut plc = Plc::new(u1.clone(), 0, MonotonicStopwatch::boxed());
        let mut limits = plc.limits();
        limits.probation_us = 600_000_000;
        plc.set_limits(limits);
        let prepared = pk.prepare(&plc.update_context(), &pk.u2);
        plc.command(Command::Load(Box::new(prepared)))
            .expect("accepted");
        plc.cycle(0, &mut replay);
        plc.command(Command::Substitute(SubstituteRequest::now(
            SubstituteMode::Retransform,
        )))
        .expect("accepted");
        let mut now = 10_000;
        for _ in 0..200 {
            plc.cycle(now, &mut replay);
            now += 10_000;
        }
        assert_eq!(plc.status(), cetratus_runtime::Status::Probation);
        probation.push(timed(&mut plc, now, &mut replay));
        plc.command(Command::Revert).expect("accepted");
        let took = timed(&mut plc, now + 10_000, &mut replay);
        if plc.status() == cetratus_runtime::Status::Idle {
            revert.push(took);
        }
        drop(plc.drain_events());
        drop(plc.take_retired());
    }
    (median(probation), median(revert))
}

/// Median µs of `M_new = ST·M_old + ST_base`, the timers, and the install into a container built
/// beforehand: exactly what the Updater does at the cycle boundary.
fn transform_install_us(
    st: &StateTransform,
    old: &Arc<Program>,
    new: &Arc<Program>,
    n: usize,
) -> f64 {
    let old_c = Container::new(old.clone(), 0);
    let mut new_c = Container::new(new.clone(), 0);
    let np = new.net().num_places();
    let mut m = vec![0; np];
    let mut since = vec![None; np];
    let samples: Vec<f64> = (0..n)
        .map(|_| {
            let t0 = Instant::now();
            st.apply(old_c.marking(), new, &mut m)
                .expect("transform applies");
            st.apply_timers(old_c.place_since_us(), &m, 0, &mut since);
            new_c.set_state(&m, &since).expect("install");
            t0.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    median(samples)
}

/// A program of `n` places (the ring nets) and its update with one more ring place.
fn big_programs(n: usize) -> (Arc<Program>, Arc<Program>) {
    let toml = |name: &str, version: &str| {
        format!("[program]\nname = \"{name}\"\nversion = \"{version}\"\nnet = \"x.pnml\"\n")
    };
    let old_net = crate::workloads::rings(n);
    let old = Program::from_sources(&toml("rings", "1"), "rings.toml", old_net.clone())
        .expect("old program");
    // The new net: the same places plus one more, so the transform has a new row.
    let text = cetratus_net::pnml::write_string(&old_net).replace(
        "<place id=\"p0_0\">",
        "<place id=\"extra\"><initialMarking><text>0</text></initialMarking></place>\n<place id=\"p0_0\">",
    );
    let new_net = cetratus_net::pnml::read_str(&text, "rings-new.pnml").expect("new net");
    let new =
        Program::from_sources(&toml("rings", "2"), "rings.toml", new_net).expect("new program");
    let _ = Path::new("");
    (Arc::new(old), Arc::new(new))
}
