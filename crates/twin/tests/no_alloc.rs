//! `Plant::step` and `Plant::inputs` must not touch the heap (DESIGN §2: no allocation inside a scan).
//!
//! Proving it needs a counting global allocator, and a `GlobalAlloc` impl is `unsafe` by definition;
//! the workspace denies unsafe code, so this test file alone allows it, for this allocator only.
#![allow(unsafe_code)]

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use cetratus_twin::{FestoParams, FestoStation, Plant, Twin, VernadatCell, VernadatParams};
use common::{Controller, FestoProgram, VernadatNet, HOUR_US, INITIAL, SCAN_US};

thread_local! {
    // Const-initialised and without a destructor, so touching it never allocates.
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

struct Counting;

// SAFETY: delegates to the system allocator unchanged; only counts calls on the current thread.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

/// Runs an hour and counts allocations made inside `step` and `inputs` only.
fn allocations_in_step<C: Controller>(mut twin: Twin, mut ctl: C) -> u64 {
    let mut outs = vec![false; twin.output_names().len()];
    let mut ins = vec![false; twin.input_names().len()];
    let mut inside = 0;
    let mut now = 0;
    while now < HOUR_US {
        let before = allocations();
        twin.step(now, &outs);
        twin.inputs(&mut ins);
        inside += allocations() - before;
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
    let before = allocations();
    for k in 0..10_000u64 {
        let on = k % 2 == 0;
        cell.step(k * SCAN_US, &[on, false, on, on, false, false, false]);
    }
    assert_eq!(allocations() - before, 0);
    assert!(cell.faults().len() > 100);
}
