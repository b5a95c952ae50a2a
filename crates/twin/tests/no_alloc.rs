//! `Plant::step` and `Plant::inputs` must not touch the heap (docs/design.md §2: no allocation inside a scan).

mod common;

use cetratus_testkit::CountingAlloc;
use cetratus_twin::{FestoParams, FestoStation, Plant, Twin, VernadatCell, VernadatParams};
use common::{Controller, FestoProgram, VernadatNet, HOUR_US, INITIAL, SCAN_US};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc::new();

/// Runs an hour and counts allocations made inside `step` and `inputs` only.
fn allocations_in_step<C: Controller>(mut twin: Twin, mut ctl: C) -> u64 {
    let mut outs = vec![false; twin.output_names().len()];
    let mut ins = vec![false; twin.input_names().len()];
    let mut inside = 0;
    let mut now = 0;
    while now < HOUR_US {
        let before = ALLOC.allocations();
        twin.step(now, &outs);
        twin.inputs(&mut ins);
        inside += ALLOC.allocations() - before;
        ctl.scan(now, &ins, &mut outs);
        now += SCAN_US;
    }
    inside
}

#[test]
fn stepping_either_twin_for_an_hour_never_allocates_even_after_a_fork_and_with_faults() {
    let cell = VernadatCell::new(
        VernadatParams {
            jitter_us: 50_000,
            ..VernadatParams::default()
        },
        3,
    )
    .expect("valid parameters");
    let fork = Twin::Vernadat(cell).clone();
    assert_eq!(allocations_in_step(fork, VernadatNet::new(&INITIAL)), 0);

    let mut st = FestoStation::new(
        FestoParams {
            jitter_us: 50_000,
            ..FestoParams::default()
        },
        3,
    )
    .expect("valid parameters");
    st.press("START", 0).expect("start button");
    assert_eq!(
        allocations_in_step(Twin::Festo(st).clone(), FestoProgram::default()),
        0
    );

    // Faults are recorded without allocating too: a wrong-sized image and a collision every scan.
    let mut cell = Twin::Vernadat(VernadatCell::with_defaults(0)).clone();
    let before = ALLOC.allocations();
    for k in 0..10_000u64 {
        let on = k % 2 == 0;
        cell.step(k * SCAN_US, &[on, false, on, on, false, false, false]);
    }
    assert_eq!(ALLOC.allocations() - before, 0);
    assert!(cell.faults().len() > 100);
}
