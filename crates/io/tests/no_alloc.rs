//! A running scan cycle never touches the heap (ARCHITECTURE: "a scan never allocates"): reading
//! the twin's inputs, scanning the program and writing the outputs back.

mod common;
mod updates;

use cetratus_testkit::CountingAlloc;
use cetratus_twin::{FestoStation, Plant, VernadatCell};
use common::{connect, load, start_festo, FESTO, VERNADAT};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc::new();

/// Warm-up cycles, so that anything built lazily on first use is built before counting.
const WARM_UP: u64 = 500;
/// Cycles counted: 100 s of program time, a dozen machine cycles of either plant.
const COUNTED: u64 = 10_000;

/// Runs `program` against `plant` and returns the allocations made by the counted cycles.
fn allocations_while_scanning<P: Plant>(path: &str, plant: P) -> u64 {
    let program = load(path);
    let (mut cycle, mut io) = connect(&program, plant);
    let period = cycle.period_us();
    let mut now = 0;
    for _ in 0..WARM_UP {
        cycle.cycle(now, &mut io).expect("no scan error");
        now += period;
    }
    let fired_before: u64 = cycle.container().firings().iter().sum();
    let before = ALLOC.allocations();
    for _ in 0..COUNTED {
        cycle.cycle(now, &mut io).expect("no scan error");
        now += period;
    }
    let counted = ALLOC.allocations() - before;
    let fired: u64 = cycle.container().firings().iter().sum::<u64>() - fired_before;
    // A plant standing still would prove nothing about firing, timers and actions.
    assert!(fired > 100, "only {fired} firings in the counted cycles");
    assert!(io.plant().faults().is_empty(), "the twin saw a fault");
    counted
}

#[test]
fn scanning_the_vernadat_program_against_its_twin_never_allocates() {
    assert_eq!(
        allocations_while_scanning(VERNADAT, VernadatCell::with_defaults(1)),
        0
    );
}

#[test]
fn scanning_the_festo_program_against_its_twin_never_allocates() {
    let mut station = FestoStation::with_defaults(1);
    start_festo(&mut station);
    assert_eq!(allocations_while_scanning(FESTO, station), 0);
}

/// The install of a candidate at the cycle boundary (the state transformation into the prebuilt
/// container, and connecting it to the Router and the Monitor) allocates nothing but the event
/// list that its `quarantine_started` event starts. The candidate's input image, its figures,
/// the quarantine it enters and the event's message are built when the update is prepared, off
/// the scan thread.
#[test]
fn the_install_of_a_candidate_allocates_only_the_list_of_its_event() {
    use cetratus_runtime::{Command, EventKind, ManualStopwatch, Plc, Status};
    let w = updates::Workshop::new();
    let program = w.program("vernadat.toml");
    let mut io = cetratus_io::TwinDriver::new(
        VernadatCell::with_defaults(1),
        program.inputs(),
        program.outputs(),
    )
    .expect("the signals match");
    let mut plc = Plc::new(program, 0, Box::new(ManualStopwatch::new()));
    plc.use_virtual_time(updates::PERIOD);
    let mut now = 0;
    for _ in 0..WARM_UP {
        plc.cycle(now, &mut io);
        now += updates::PERIOD;
    }
    let prepared = plc
        .update_context()
        .prepare_package(
            &w.package("u1.package.toml"),
            &w.trust,
            cetratus_program::Unsigned::Refused,
            cetratus_program::OtherBase::Refused,
        )
        .expect("U.1 prepares");
    plc.command(Command::Load(Box::new(prepared)))
        .expect("accepted");
    let _ = plc.drain_events();
    let counted = ALLOC.during(|| plc.cycle(now, &mut io));
    let events = plc.drain_events();
    assert_eq!(plc.status(), Status::Quarantine, "{events:?}");
    assert_eq!(
        events.iter().map(|e| e.kind).collect::<Vec<_>>(),
        [EventKind::QuarantineStarted]
    );
    assert!(
        counted <= 1,
        "the install cycle made {counted} allocations; the event list needs 1"
    );
}

/// Inputs that change every cycle: signal `i` is on in cycles where `(cycle + i) % 7 == 0`.
struct Moving {
    cycle: u64,
}

impl cetratus_runtime::Provider for Moving {
    fn read_inputs(&mut self, _now_us: u64, inputs: &mut [cetratus_program::Value]) {
        for (i, v) in inputs.iter_mut().enumerate() {
            *v = cetratus_program::Value::Bool((self.cycle + i as u64).is_multiple_of(7));
        }
        self.cycle += 1;
    }
}

impl cetratus_runtime::Dispatcher for Moving {
    fn write_outputs(&mut self, _now_us: u64, _outputs: &[cetratus_program::Value]) {}
}

/// A program of 100 inputs and 100 outputs: `y_i` follows `x_i` one cycle later.
fn wide_program(dir: &std::path::Path) -> std::path::PathBuf {
    let n = 100;
    let mut pnml = String::from("<?xml version=\"1.0\"?>\n<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\"><net id=\"w\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\"><page id=\"g\">\n");
    let mut toml = String::from("[program]\nname = \"wide\"\nversion = \"1.0.0\"\nnet = \"wide.pnml\"\npolicy = \"step\"\nscan_period = \"10ms\"\n");
    let (mut outs, mut guards, mut actions) = (String::new(), String::new(), String::new());
    for i in 0..n {
        pnml.push_str(&format!("<place id=\"p{i}\"><initialMarking><text>1</text></initialMarking></place><place id=\"q{i}\"/><transition id=\"on{i}\"/><transition id=\"off{i}\"/><arc id=\"a{i}\" source=\"p{i}\" target=\"on{i}\"/><arc id=\"b{i}\" source=\"on{i}\" target=\"q{i}\"/><arc id=\"c{i}\" source=\"q{i}\" target=\"off{i}\"/><arc id=\"d{i}\" source=\"off{i}\" target=\"p{i}\"/>\n"));
        toml.push_str(&format!("[[input]]\nname = \"x{i}\"\ntype = \"bool\"\n"));
        outs.push_str(&format!("[[output]]\nname = \"y{i}\"\ntype = \"bool\"\n"));
        guards.push_str(&format!("on{i} = \"x{i}\"\noff{i} = \"!x{i}\"\n"));
        actions.push_str(&format!(
            "[[action]]\nplace = \"q{i}\"\nqualifier = \"N\"\ntarget = \"y{i}\"\n"
        ));
    }
    pnml.push_str("</page></net></pnml>\n");
    toml.push_str(&outs);
    toml.push_str("[guards]\n");
    toml.push_str(&guards);
    toml.push_str(&actions);
    std::fs::write(dir.join("wide.pnml"), pnml).expect("write the net");
    let path = dir.join("wide.toml");
    std::fs::write(&path, toml).expect("write the program");
    path
}

#[test]
fn a_plc_of_200_signals_records_every_cycle_for_the_timing_diagram_without_allocating() {
    let dir = tempfile::tempdir().expect("temp dir");
    let program = std::sync::Arc::new(cetratus_testkit::programs::load(&wide_program(dir.path())));
    let mut plc = cetratus_runtime::Plc::new(program, 0, cetratus_testkit::stopwatch());
    let _ = plc.drain_events();
    let mut io = Moving { cycle: 0 };
    let mut now = 0;
    for _ in 0..WARM_UP {
        plc.cycle(now, &mut io);
        now += 10_000;
    }
    let before = ALLOC.allocations();
    // Past the Monitor's 8192 recent cycles, so that the ring wraps while counted.
    for _ in 0..COUNTED {
        plc.cycle(now, &mut io);
        now += 10_000;
    }
    let counted = ALLOC.allocations() - before;
    let last = plc.monitor().recent.last().expect("a recorded cycle");
    // Signal 150 is output y50; both signals past the 64th have their bits in the record.
    let bit = |words: &[u64], i: usize| words[i / 64] & (1 << (i % 64)) != 0;
    let c = io.cycle - 1;
    assert_eq!(bit(last.inputs, 99), (c + 99).is_multiple_of(7));
    assert_eq!(bit(last.inputs, 70), (c + 70).is_multiple_of(7));
    assert_eq!(bit(last.dispatched, 90), (c - 1 + 90).is_multiple_of(7));
    assert_eq!(plc.monitor().recent.len(), 8192);
    assert_eq!(counted, 0);
}
