//! Update F.1 of the Festo processing station (examples/festo/f1.*), validated on the twin as U.1
//! and U.2 are: loaded into quarantine beside the running program on a station that makes
//! defective parts, watched there with its new output withheld, then substituted, after which the
//! new output reaches the plant.

mod updates;

use cetratus_program::Value;
use cetratus_runtime::{Slot, Status, SubstituteMode};
use cetratus_twin::{FestoParams, FestoStation, Plant, Twin};
use updates::{Cell, Workshop, FESTO_EXAMPLES};

const SECOND: u64 = 1_000_000;

/// The station at one defective part in five, reset and started, after a minute of festo.toml.
fn running_station(w: &Workshop) -> Cell {
    let params = FestoParams {
        defect_ppm: 200_000,
        ..FestoParams::default()
    };
    let mut station = FestoStation::new(params, 4).expect("valid parameters");
    station.press("RESET", 100_000).expect("RESET is a button");
    station.press("START", 500_000).expect("START is a button");
    let mut cell = Cell::with_twin(w.program("festo.toml"), Twin::Festo(station));
    cell.run_for(60 * SECOND);
    cell
}

fn lamp(cell: &Cell) -> usize {
    cell.plc
        .io_outputs()
        .iter()
        .position(|n| n == "REJECT_BIN_FULL")
        .expect("festo.toml declares REJECT_BIN_FULL")
}

fn on(values: &[Value], i: usize) -> bool {
    values[i] == Value::Bool(true)
}

fn counter(cell: &Cell, name: &str) -> u64 {
    cell.io
        .plant()
        .counters()
        .get(name)
        .unwrap_or_else(|| panic!("the station counts {name}"))
}

/// Steps until `cond` holds, at most `max_us`; panics with `what` if it never does.
fn step_until(cell: &mut Cell, max_us: u64, what: &str, mut cond: impl FnMut(&Cell) -> bool) {
    let end = cell.now + max_us;
    while !cond(cell) {
        assert!(cell.now < end, "{what} within {} s", max_us / SECOND);
        cell.step();
    }
}

fn assert_every_part_went_its_way(cell: &Cell) {
    let plant = cell.io.plant();
    assert!(plant.faults().is_empty(), "faults: {:?}", plant.faults());
    assert_eq!(counter(cell, "parts_rejected_good"), 0);
    assert_eq!(counter(cell, "parts_ejected_defective"), 0);
    assert_eq!(counter(cell, "parts_ejected_incomplete"), 0);
    assert_eq!(counter(cell, "parts_good"), counter(cell, "parts_ejected"));
}

#[test]
fn reject_counting_runs_in_quarantine_with_its_lamp_withheld_then_substitutes_and_lights_it() {
    let w = Workshop::of(FESTO_EXAMPLES);
    let f1 = w.package("f1.package.toml");
    let mut cell = running_station(&w);
    let lamp = lamp(&cell);
    assert!(
        counter(&cell, "parts_rejected") > 0,
        "the first minute rejected a part"
    );

    cell.load(&f1, &w.trust).expect("F.1 accepted");
    cell.step();
    assert_eq!(cell.plc.status(), Status::Quarantine);
    assert_eq!(
        cell.tokens(Slot::B, &["BinFree"]),
        5,
        "the bin starts empty"
    );
    let rejected_at_load = counter(&cell, "parts_rejected");

    // The candidate counts the rejects it sees; when the fifth fills its bin it lights its lamp,
    // which the Message Router withholds from the plant.
    step_until(&mut cell, 600 * SECOND, "the candidate's bin fills", |c| {
        assert!(
            !on(c.plc.dispatched(), lamp),
            "a candidate's lamp is withheld"
        );
        on(c.plc.outputs_of(Slot::B).expect("B in quarantine"), lamp)
    });
    assert_eq!(counter(&cell, "parts_rejected") - rejected_at_load, 5);
    cell.run_for(10 * SECOND);
    let info = cell.plc.exec_info();
    let b = info[1].as_ref().expect("B in quarantine");
    let diverged: Vec<&str> = b
        .divergence
        .iter()
        .filter(|(_, &n)| n > 0)
        .map(|(s, _)| s.as_str())
        .collect();
    assert_eq!(
        diverged,
        ["REJECT_BIN_FULL"],
        "the lamp is the only difference"
    );
    assert_eq!(b.max_drift, 0, "no drift: {b:?}");

    // Retransform recomputes the candidate's marking from the primary's: the bin starts again.
    cell.substitute(SubstituteMode::Retransform, false)
        .expect("substitute accepted");
    cell.step();
    assert_eq!(cell.plc.primary(), Slot::B);
    assert_eq!(cell.tokens(Slot::B, &["BinFree"]), 5);
    let rejected_at_switch = counter(&cell, "parts_rejected");
    step_until(&mut cell, 600 * SECOND, "the lamp lights", |c| {
        on(c.plc.dispatched(), lamp)
    });
    assert_eq!(counter(&cell, "parts_rejected") - rejected_at_switch, 5);

    // The operator empties the bin and presses RESET: the lamp goes out, the count starts again.
    let now = cell.now;
    cell.io
        .plant_mut()
        .press("RESET", now)
        .expect("RESET is a button");
    cell.run_for(SECOND);
    assert!(!on(cell.plc.dispatched(), lamp), "RESET puts the lamp out");
    assert_eq!(cell.tokens(Slot::B, &["BinFree"]), 5);
    cell.run_for(300 * SECOND);
    assert_every_part_went_its_way(&cell);
    assert!(cell.io.plant().faults().is_empty());
}

#[test]
fn substituting_in_keep_mode_keeps_the_count_the_candidate_made_in_quarantine() {
    let w = Workshop::of(FESTO_EXAMPLES);
    let f1 = w.package("f1.package.toml");
    let mut cell = running_station(&w);
    cell.load(&f1, &w.trust).expect("F.1 accepted");
    cell.step();
    let counted = |c: &Cell| c.tokens(Slot::B, &["BinUsed"]);
    step_until(&mut cell, 600 * SECOND, "a reject is counted", |c| {
        counted(c) > 0
    });
    let before = counted(&cell);
    cell.substitute(SubstituteMode::Keep, false)
        .expect("keep accepted: the drift is 0");
    cell.step();
    assert_eq!(
        (cell.plc.primary(), counted(&cell)),
        (Slot::B, before),
        "the count survives the switch"
    );
    cell.run_for(120 * SECOND);
    assert_every_part_went_its_way(&cell);
}
