//! The stall watchdog on the twins in virtual time: the examples' watchdogs stay quiet for an hour
//! of normal production; a program that waits for a signal that never comes raises one
//! `stall_alarm` per episode, by dwell or by no firing; on probation a stall reverts.

mod updates;

use cetratus_runtime::{EventDetail, EventKind, RevertReason, Slot, Status, SubstituteMode};
use cetratus_twin::{FestoParams, FestoStation, Plant, Twin};
use updates::{Cell, Workshop, FESTO_EXAMPLES};

const HOUR_US: u64 = 3_600_000_000;

fn stalls(cell: &Cell) -> Vec<&cetratus_runtime::Event> {
    cell.events
        .iter()
        .filter(|e| e.kind == EventKind::StallAlarm)
        .collect()
}

/// `program` of the workshop with T11's guard replaced by one that holds only after an hour in
/// P11: the robot's acknowledgement of loading M1 is never taken, and P11 stays marked.
fn t11_waits_forever(w: &Workshop, program: &str) -> String {
    let text = std::fs::read_to_string(w.path(program)).expect("program");
    let name = format!("stuck-{program}");
    std::fs::write(
        w.path(&name),
        text.replace("T11 = \"FCM1\"", "T11 = \"FCM1 && P11.t >= 3600s\""),
    )
    .expect("write");
    name
}

#[test]
fn the_vernadat_watchdogs_stay_quiet_for_an_hour_of_production() {
    let w = Workshop::new();
    let mut cell = Cell::new(w.program("vernadat.toml"));
    assert!(!cell.plc.primary_program().watchdogs().is_empty());
    cell.run_for(HOUR_US);
    assert_eq!(stalls(&cell), Vec::<&cetratus_runtime::Event>::new());
    let made = cell.io.plant().counters().get("parts_finished");
    assert!(
        made.is_some_and(|n| n >= 300),
        "the cell produced: {made:?}"
    );
}

#[test]
fn the_festo_watchdogs_stay_quiet_for_an_hour_with_five_percent_defective_parts() {
    let w = Workshop::of(FESTO_EXAMPLES);
    let params = FestoParams {
        defect_ppm: 50_000,
        ..FestoParams::default()
    };
    let mut station = FestoStation::new(params, 7).expect("valid parameters");
    station.press("RESET", 100_000).expect("RESET is a button");
    station.press("START", 500_000).expect("START is a button");
    let mut cell = Cell::with_twin(w.program("festo.toml"), Twin::Festo(station));
    assert!(!cell.plc.primary_program().watchdogs().is_empty());
    cell.run_for(HOUR_US);
    assert_eq!(stalls(&cell), Vec::<&cetratus_runtime::Event>::new());
    let counters = cell.io.plant().counters();
    let ejected = counters.get("parts_ejected").unwrap_or(0);
    let rejected = counters.get("parts_rejected").unwrap_or(0);
    assert!(ejected >= 600, "the station produced: {ejected} ejected");
    assert!(rejected > 0, "defective parts took the reject branch");
}

#[test]
fn a_place_held_past_its_maximum_raises_one_stall_alarm_per_episode() {
    let w = Workshop::new();
    let stuck = t11_waits_forever(&w, "vernadat.toml");
    let mut cell = Cell::new(w.program(&stuck));
    cell.run_for(60_000_000);
    let s = stalls(&cell);
    assert_eq!(s.len(), 1, "one alarm for the episode: {s:#?}");
    assert!(s[0].message.contains("place P11"), "{}", s[0].message);
    // P11 was marked at about 1 s (PE at start); its watchdog is 5 s.
    let Some(EventDetail::Stall { waited_us }) = s[0].detail else {
        panic!("{:?}", s[0])
    };
    assert!((5_000_000..5_100_000).contains(&waited_us), "{waited_us}");
    let info = cell.plc.exec_info();
    assert_eq!(
        info[0].as_ref().map(|e| e.stall),
        Some(true),
        "exec_info shows it"
    );
    assert_eq!(cell.plc.status(), Status::Idle, "an alarm, not a fault");
}

#[test]
fn nothing_firing_while_a_watched_place_is_marked_is_a_stall_too() {
    let w = Workshop::new();
    let stuck = t11_waits_forever(&w, "vernadat.toml");
    // P11's own maximum far away: only `[stall] no_firing` can see it.
    let text = std::fs::read_to_string(w.path(&stuck)).expect("program");
    std::fs::write(
        w.path(&stuck),
        text.replacen(
            "place = \"P11\"   # CM1: the robot loads M1\nmax = \"5s\"",
            "place = \"P11\"   # CM1: the robot loads M1\nmax = \"1h\"",
            1,
        ),
    )
    .expect("write");
    let mut cell = Cell::new(w.program(&stuck));
    cell.run_for(120_000_000);
    let s = stalls(&cell);
    assert_eq!(s.len(), 1, "{s:#?}");
    assert!(
        s[0].message.contains("nothing has fired"),
        "{}",
        s[0].message
    );
    assert!(s[0].message.contains("P11"), "{}", s[0].message);
}

#[test]
fn a_new_primary_that_stalls_on_probation_is_reverted_and_the_cell_goes_on() {
    let w = Workshop::new();
    let stuck = t11_waits_forever(&w, "u1.toml");
    let manifest = std::fs::read_to_string(w.path("u1.package.toml")).expect("manifest");
    std::fs::write(
        w.path("u1-stuck.package.toml"),
        manifest.replace("program = \"u1.toml\"", &format!("program = \"{stuck}\"")),
    )
    .expect("write");
    let mut cell = Cell::new(w.program("vernadat.toml"));
    let mut limits = cell.plc.limits();
    limits.probation_us = 60_000_000;
    cell.plc.set_limits(limits);
    cell.run_for(2_000_000);
    cell.load(&w.package("u1-stuck.package.toml"), &w.trust)
        .expect("accepted");
    cell.step();
    cell.substitute(SubstituteMode::Retransform, false)
        .expect("substitute accepted");
    cell.step();
    assert_eq!(cell.plc.status(), Status::Probation);
    cell.run_for(30_000_000);
    let e = cell
        .events
        .iter()
        .find(|e| e.kind == EventKind::Reverted)
        .unwrap_or_else(|| panic!("reverted: {:#?}", cell.events));
    let Some(EventDetail::Revert {
        reason,
        detected_cycle,
        ..
    }) = e.detail
    else {
        panic!("{e:?}")
    };
    assert_eq!(reason, RevertReason::Stall);
    assert_eq!(e.cycle - detected_cycle, 1, "one cycle after the alarm");
    assert_eq!(cell.plc.primary(), Slot::A);
    let before = cell.plc.primary_container().firings().iter().sum::<u64>();
    cell.run_for(20_000_000);
    assert!(
        cell.plc.primary_container().firings().iter().sum::<u64>() > before + 10,
        "the old program drives the cell again"
    );
}

/// A warm start against a plant that was started afresh: the saved marking has a part where the
/// new twin has none, the cell waits on places no watchdog covers, and `[stall] no_firing`
/// counts whatever is marked until the first firing: the alarm says the state may not match.
#[test]
fn after_a_warm_start_against_a_fresh_plant_no_firing_is_a_stall_whatever_is_marked() {
    let w = Workshop::new();
    let program = w.program("vernadat.toml");
    let limit = program
        .no_firing_us()
        .expect("the example declares [stall] no_firing");
    // Every saved state of the first minute, warm-started against a fresh twin: the cell either
    // fires within `no_firing`, or is told why it does not.
    let mut warm = Cell::new(program.clone());
    let mut told = 0;
    for _ in 0..12 {
        warm.run_for(5_000_000);
        let mut snap = cetratus_runtime::PlcSnapshot::default();
        warm.plc.snapshot_into(&mut snap);
        let plc = cetratus_runtime::Plc::warm_start(
            &snap,
            |_| Some(program.clone()),
            program.clone(),
            cetratus_testkit::stopwatch(),
        )
        .expect("warm start");
        let mut cell = Cell::new(program.clone());
        cell.plc = plc;
        cell.plc.use_virtual_time(updates::PERIOD);
        cell.now = snap.time_us;
        cell.run_for(limit + 2_000_000);
        let fired: u64 = cell.plc.primary_container().firings().iter().sum();
        let alarms = stalls(&cell);
        if fired == 0 {
            assert_eq!(alarms.len(), 1, "{:#?}", cell.events);
            assert!(
                alarms[0].message.contains("since the warm start")
                    && alarms[0].message.contains("may not match the plant")
                    && alarms[0].message.contains("--cold"),
                "{}",
                alarms[0].message
            );
            told += 1;
        } else {
            // A cell that moved is watched as always: a watched place may still stall.
            assert!(
                alarms.iter().all(|a| !a.message.contains("warm start")),
                "{alarms:#?}"
            );
        }
    }
    assert!(
        told > 0,
        "some saved state leaves the cell waiting on a fresh plant"
    );
}
