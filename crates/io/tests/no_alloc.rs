//! A running scan cycle never touches the heap (ARCHITECTURE: "a scan never allocates"): reading
//! the twin's inputs, scanning the program and writing the outputs back.

mod common;

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
