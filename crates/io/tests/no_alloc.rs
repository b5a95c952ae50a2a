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
        .prepare_package(&w.package("u1.package.toml"), &w.trust, false, false)
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
