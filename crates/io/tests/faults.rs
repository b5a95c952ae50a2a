//! Faults on purpose (feature `fault-injection`) on the real scan path: a candidate that panics or
//! errors is aborted, a primary that faults drives its safe values. Injected faults are global to
//! the process, so these tests take turns.

mod updates;

use std::sync::Mutex;

use cetratus_program::Value;
use cetratus_runtime::{Command, EventKind, Slot, Status};
use updates::{reference_marking, Cell, Workshop};

static TURN: Mutex<()> = Mutex::new(());

#[test]
fn a_candidate_that_panics_or_errors_is_aborted_and_the_primary_goes_on() {
    use cetratus_runtime::inject::{arm, disarm, Fault};
    let _turn = TURN.lock().unwrap_or_else(|e| e.into_inner());
    let w = Workshop::new();
    let u1 = w.package("u1.package.toml");
    for fault in [Fault::Panic, Fault::Error] {
        let reference = reference_marking(&w, 1_000);
        let mut cell = Cell::new(w.program("vernadat.toml"));
        cell.run_for(2_000_000);
        cell.load(&u1, &w.trust).expect("accepted");
        cell.run_for(1_000_000);
        assert_eq!(cell.plc.status(), Status::Quarantine);
        arm("vernadat-cell", "1.1.0", fault.clone());
        cell.run_for(2_000_000);
        disarm();
        assert_eq!(cell.plc.status(), Status::Idle, "{fault:?}");
        assert!(cell.has_event(EventKind::CandidateFault), "{fault:?}");
        assert!(cell.plc.container(Slot::B).is_none());
        cell.run_for(5_000_000);
        assert_eq!(
            cell.plc.primary_container().marking(),
            &reference[..],
            "{fault:?}"
        );
    }
}

#[test]
fn a_primary_that_faults_drives_its_safe_values_until_reset() {
    use cetratus_runtime::inject::{arm, disarm, Fault};
    let _turn = TURN.lock().unwrap_or_else(|e| e.into_inner());
    let w = Workshop::new();
    let mut cell = Cell::new(w.program("u1.toml"));
    cell.run_for(3_000_000);
    arm("vernadat-cell", "1.1.0", Fault::Error);
    cell.step();
    disarm();
    assert_eq!(cell.plc.status(), Status::Fault);
    assert!(cell.has_event(EventKind::PrimaryFault));
    let mut safe = vec![Value::Bool(true); cell.plc.io_outputs().len()];
    cell.plc.primary_program().safe_outputs(&mut safe);
    cell.run_for(500_000);
    assert_eq!(cell.plc.dispatched(), &safe[..]);
    cell.plc.command(Command::Reset).expect("reset in fault");
    cell.run_for(5_000_000);
    assert_eq!(cell.plc.status(), Status::Idle);
    assert!(
        cell.plc.dispatched().contains(&Value::Bool(true)),
        "the cell works again"
    );
}

#[test]
fn a_primary_scan_past_the_watchdog_is_a_primary_fault() {
    use cetratus_runtime::inject::{arm, disarm, Fault};
    let _turn = TURN.lock().unwrap_or_else(|e| e.into_inner());
    let w = Workshop::new();
    let mut cell = Cell::new(w.program("u1.toml"));
    let mut limits = cell.plc.limits();
    limits.watchdog_ns = 20_000_000;
    cell.plc.set_limits(limits);
    cell.run_for(1_000_000);
    arm("vernadat-cell", "1.1.0", Fault::Slow(50_000));
    cell.step();
    disarm();
    assert_eq!(cell.plc.status(), Status::Fault);
    let e = cell
        .events
        .iter()
        .find(|e| e.kind == EventKind::PrimaryFault)
        .expect("primary_fault");
    assert!(e.message.contains("watchdog"), "{}", e.message);
}
