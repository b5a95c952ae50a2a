//! Edges across a substitution, on the Vernadat twin: with T11 guarded by `rise(FCM1)` in both
//! programs, an edge that falls in the switch cycle must reach the new primary, or CM1 stays on
//! for good and the cell stops.

mod updates;

use cetratus_runtime::{EventKind, Slot, Status, SubstituteMode};
use cetratus_twin::Plant;
use updates::{Cell, Workshop, PERIOD};

/// The Vernadat workshop with T11 = `rise(FCM1)` in the initial program and in U.1.
fn rising_workshop() -> Workshop {
    let w = Workshop::new();
    for name in ["vernadat.toml", "u1.toml"] {
        let path = w.path(name);
        let text = std::fs::read_to_string(&path).expect("example program");
        assert!(text.contains("T11 = \"FCM1\""), "{name} guards T11 by FCM1");
        std::fs::write(
            &path,
            text.replace("T11 = \"FCM1\"", "T11 = \"rise(FCM1)\""),
        )
        .expect("write program");
    }
    w
}

/// Runs the rising-edge cell for `end_us`, loading U.1 at 10 s and substituting it so that the
/// switch happens in the cycle at `switch_us`; returns the parts finished.
fn parts_with_switch_at(w: &Workshop, u1: &[u8], switch_us: u64, end_us: u64) -> u64 {
    let mut cell = Cell::new(w.program("vernadat.toml"));
    cell.run_for(10_000_000);
    cell.load(u1, &w.trust).expect("U.1 accepted");
    // The substitution happens at the boundary of the next cycle.
    cell.run_for(switch_us - cell.now);
    cell.substitute(SubstituteMode::Retransform, false)
        .expect("substitute accepted");
    cell.step();
    assert_eq!(
        (cell.plc.primary(), cell.plc.status()),
        (Slot::B, Status::Idle),
        "U.1 drives the cell from {switch_us} µs"
    );
    assert!(cell.has_event(EventKind::Substituted));
    cell.run_for(end_us - cell.now);
    assert!(
        cell.io.plant().faults().is_empty(),
        "{:?}",
        cell.io.plant().faults()
    );
    cell.parts()
}

fn parts_without_switch(w: &Workshop, end_us: u64) -> u64 {
    let mut cell = Cell::new(w.program("vernadat.toml"));
    cell.run_for(end_us);
    cell.parts()
}

#[test]
fn a_rising_edge_in_the_switch_cycle_reaches_the_new_primary_and_the_cell_keeps_producing() {
    let w = rising_workshop();
    let u1 = w.package("u1.package.toml");
    let reference = parts_without_switch(&w, 120_000_000);
    assert!(reference >= 12, "the cell makes {reference} parts in 120 s");
    // 21.08 s: FCM1 rises in the switch cycle.
    let with_switch = parts_with_switch_at(&w, &u1, 21_080_000, 120_000_000);
    eprintln!("120 s: {with_switch} parts with U.1 substituted at 21.08 s, {reference} without");
    assert!(
        with_switch + 1 >= reference,
        "{with_switch} parts in 120 s with U.1 substituted at 21.08 s, {reference} without"
    );
}

#[test]
fn no_switch_instant_in_a_cell_cycle_stops_a_rising_edge_cell() {
    let w = rising_workshop();
    let u1 = w.package("u1.package.toml");
    let reference = parts_without_switch(&w, 60_000_000);
    // Every cycle of two seconds of the cell's work, around the 21.08 s of the paper's figure.
    for k in 0..200 {
        let switch_us = 20_000_000 + k * PERIOD;
        let with_switch = parts_with_switch_at(&w, &u1, switch_us, 60_000_000);
        assert!(
            with_switch + 1 >= reference,
            "switch at {switch_us} µs: {with_switch} parts in 60 s, {reference} without a switch"
        );
    }
}
