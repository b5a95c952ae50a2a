//! Live updates seen from outside: the paper's U.1/U.2 experiment on the Vernadat twin, refusals,
//! stateTransTimeout, faults in either container, and conditional substitution.

mod updates;

use cetratus_program::Value;
use cetratus_runtime::{
    Command, EventDetail, EventKind, InstallTiming, Slot, Status, SubstituteMode, SubstituteRequest,
};
use cetratus_twin::Plant;
use updates::{reference_marking, Cell, Workshop};

fn buffer(cell: &Cell) -> u32 {
    cell.tokens(cell.plc.primary(), &["H", "B", "P14"])
}

#[test]
fn the_paper_experiment_keeps_dispatch_on_the_primary_and_conserves_parts() {
    let w = Workshop::new();
    let (u1, u2) = (w.package("u1.package.toml"), w.package("u2.package.toml"));
    let mut cell = Cell::new(w.program("vernadat.toml"));
    cell.run_for(10_000_000);
    assert_eq!(buffer(&cell), 7);

    cell.load(&u1, &w.trust).expect("U.1 accepted");
    cell.step();
    assert_eq!(cell.plc.status(), Status::Quarantine);
    assert_eq!(
        cell.tokens(Slot::B, &["H", "B", "P14"]),
        9,
        "ST_base adds two free slots"
    );
    for _ in 0..12_000 {
        cell.step();
        assert_eq!(buffer(&cell), 7, "A keeps its seven slots in quarantine");
    }
    let info = cell.plc.exec_info();
    let b = info[1].as_ref().expect("B in quarantine");
    assert!(!b.divergence.is_empty(), "A blocks at T13 while B goes on");
    assert_eq!(
        b.first_cause.as_deref(),
        Some("T13 fired in B only; in A it was blocked by H")
    );

    cell.substitute(SubstituteMode::Retransform, false)
        .expect("substitute accepted");
    cell.step();
    assert_eq!(
        (cell.plc.primary(), cell.plc.status()),
        (Slot::B, Status::Idle)
    );
    assert!(
        cell.plc.container(Slot::A).is_none(),
        "the old program stops"
    );
    cell.run_for(20_000_000);
    assert_eq!(buffer(&cell), 9);

    cell.load(&u2, &w.trust).expect("U.2 accepted");
    cell.step();
    assert_eq!(cell.plc.status(), Status::Quarantine);
    let lm1 = cell
        .plc
        .io_outputs()
        .iter()
        .position(|n| n == "LM1")
        .expect("LM1");
    let mut lubricated = false;
    for _ in 0..3_000 {
        cell.step();
        lubricated |= cell.plc.outputs_of(Slot::A).expect("A")[lm1] == Value::Bool(true);
        assert_eq!(
            cell.plc.dispatched()[lm1],
            Value::Bool(false),
            "a candidate's LM1 is withheld"
        );
    }
    assert!(lubricated, "the candidate lubricates in quarantine");
    assert!(cell.plc.monitor().stats[0].max_drift > 0, "the drift shows");
    cell.substitute(SubstituteMode::Retransform, false)
        .expect("substitute accepted");
    cell.step();
    assert_eq!(cell.plc.primary(), Slot::A);
    cell.run_for(60_000_000);
    assert_eq!(buffer(&cell), 9);
    assert!(
        cell.io.plant().faults().is_empty(),
        "{:?}",
        cell.io.plant().faults()
    );
    assert!(
        cell.io
            .plant()
            .counters()
            .get("lubrications_m1")
            .unwrap_or(0)
            > 0
    );
}

#[test]
fn refused_packages_leave_the_running_program_exactly_as_it_would_have_been() {
    let w = Workshop::new();
    let u1 = w.package("u1.package.toml");
    let u2 = w.package("u2.package.toml");
    let mut tampered = u1.clone();
    let mid = tampered.len() / 2;
    tampered[mid] ^= 0x20;
    let truncated = u1[..u1.len() * 2 / 3].to_vec();
    let negative = w.u1_with_base("base = [-5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]");
    let broken_invariant = w.u1_with_base("base = [1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]");

    let cycles = 3_000;
    let reference = reference_marking(&w, cycles);
    let mut cell = Cell::new(w.program("vernadat.toml"));
    for k in 0..cycles {
        match k {
            100 => assert!(cell.load(&tampered, &w.trust).is_err(), "tampered"),
            200 => assert!(cell.load(&truncated, &w.trust).is_err(), "truncated"),
            300 => {
                let e = cell.load(&u2, &w.trust).expect_err("wrong base program");
                assert!(e.contains("built against"), "{e}");
            }
            400 => {
                cell.load(&negative, &w.trust)
                    .expect("accepted until the install");
            }
            700 => {
                cell.load(&broken_invariant, &w.trust)
                    .expect("accepted until the install");
            }
            _ => {}
        }
        cell.step();
        if k == 400 || k == 700 {
            assert_eq!(cell.plc.status(), Status::Idle, "refused at the install");
            assert!(cell.plc.container(Slot::B).is_none());
        }
    }
    let refusals: Vec<&str> = cell
        .events
        .iter()
        .filter(|e| e.kind == EventKind::TransformRefused)
        .map(|e| e.message.as_str())
        .collect();
    assert_eq!(refusals.len(), 2, "{refusals:?}");
    assert!(
        refusals[0].contains("negative") || refusals[0].contains("H"),
        "{}",
        refusals[0]
    );
    assert!(
        refusals[1].contains("H + B + P14"),
        "the error names the invariant: {}",
        refusals[1]
    );
    assert_eq!(cell.plc.primary_container().marking(), &reference[..]);
    assert_eq!(cell.plc.primary(), Slot::A);
}

#[test]
fn packages_whose_transform_does_not_fit_the_running_net_are_refused_even_when_forced() {
    let w = Workshop::new();
    let u1 = w.package("u1.package.toml");
    // A PLC running U.2 (15 places): U.1's 13×13 dense matrix has the wrong dimensions.
    let mut cell = Cell::new(w.program("u2.toml"));
    cell.run_for(1_000_000);
    let p = cell.plc.update_context().prepare_package(
        &u1,
        &w.trust,
        cetratus_program::Unsigned::Refused,
        cetratus_program::OtherBase::Forced,
    );
    let e = p.err().expect("refused").to_string();
    assert!(
        e.contains("P30") || e.contains("15") || e.contains("13"),
        "names the mismatch: {e}"
    );
    assert_eq!(cell.plc.status(), Status::Idle);
}

#[test]
fn state_trans_timeout_fires_just_below_the_install_cost_and_not_just_above() {
    let w = Workshop::new();
    let u1 = w.package("u1.package.toml");
    let install_cost = |budget: u64| -> (Vec<cetratus_runtime::Event>, Status, Vec<u32>) {
        let mut cell = Cell::new(w.program("vernadat.toml"));
        cell.plc
            .set_install_timing(InstallTiming::Model { ns_per_entry: 10 });
        let mut l = cell.plc.limits();
        l.state_trans_timeout_ns = budget;
        cell.plc.set_limits(l);
        cell.run_for(5_000_000);
        cell.load(&u1, &w.trust).expect("accepted");
        cell.run_for(1_000_000);
        let status = cell.plc.status();
        (
            cell.events,
            status,
            cell.plc.primary_container().marking().to_vec(),
        )
    };
    let (events, status, _) = install_cost(u64::MAX);
    assert_eq!(status, Status::Quarantine);
    let cost = events
        .iter()
        .find(|e| e.kind == EventKind::QuarantineStarted)
        .and_then(|e| match e.detail {
            Some(EventDetail::Install { install_ns, .. }) => Some(install_ns),
            _ => None,
        })
        .expect("the install reports its cost");
    let reference = reference_marking(&w, 600);

    let (events, status, marking) = install_cost(cost - 1);
    assert_eq!(status, Status::Idle);
    assert!(
        events
            .iter()
            .any(|e| e.kind == EventKind::StateTransTimeout),
        "{events:?}"
    );
    assert_eq!(marking, reference, "the primary never noticed");

    let (events, status, marking) = install_cost(cost + 1);
    assert_eq!(status, Status::Quarantine);
    assert!(!events
        .iter()
        .any(|e| e.kind == EventKind::StateTransTimeout));
    assert_eq!(marking, reference, "the primary never noticed");
}

#[test]
fn one_update_at_a_time_and_every_refusal_is_an_event() {
    let w = Workshop::new();
    let u1 = w.package("u1.package.toml");
    let mut cell = Cell::new(w.program("vernadat.toml"));
    cell.step();
    assert!(cell.plc.command(Command::Remove).is_err());
    assert!(cell.substitute(SubstituteMode::Retransform, false).is_err());
    cell.load(&u1, &w.trust).expect("first load");
    let second = cell
        .plc
        .update_context()
        .prepare_package(
            &u1,
            &w.trust,
            cetratus_program::Unsigned::Refused,
            cetratus_program::OtherBase::Refused,
        )
        .expect("prepared");
    assert!(cell.plc.command(Command::Load(Box::new(second))).is_err());
    cell.step();
    assert_eq!(
        cell.events
            .iter()
            .filter(|e| e.kind == EventKind::Refused)
            .count(),
        3
    );
    cell.plc
        .command(Command::Remove)
        .expect("remove in quarantine");
    cell.step();
    assert_eq!(cell.plc.status(), Status::Idle);
    assert!(cell.plc.container(Slot::B).is_none());
}

#[test]
fn keep_mode_is_refused_while_the_candidate_has_drifted_unless_forced() {
    let w = Workshop::new();
    let u1 = w.package("u1.package.toml");
    let mut cell = Cell::new(w.program("vernadat.toml"));
    cell.run_for(1_000_000);
    cell.load(&u1, &w.trust).expect("accepted");
    cell.run_for(70_000_000);
    assert!(cell.plc.drift().unwrap_or(0) > 0);
    cell.substitute(SubstituteMode::Keep, false)
        .expect("accepted, checked at the boundary");
    cell.step();
    assert_eq!(cell.plc.primary(), Slot::A, "refused with drift");
    assert!(cell
        .events
        .iter()
        .any(|e| e.kind == EventKind::Refused && e.message.contains("drift")));
    cell.substitute(SubstituteMode::Keep, true).expect("forced");
    cell.step();
    assert_eq!(cell.plc.primary(), Slot::B);
}

#[test]
fn substitute_when_waits_for_its_condition_and_gives_up_after_within() {
    let w = Workshop::new();
    let u1 = w.package("u1.package.toml");
    let mut cell = Cell::new(w.program("vernadat.toml"));
    cell.run_for(1_000_000);
    cell.load(&u1, &w.trust).expect("accepted");
    cell.step();
    // Both machines idle never happens while the cell works flat out: give up after 2 s.
    let never = cell
        .plc
        .primary_program()
        .compile_condition("P10 == 1 && P20 == 1 && P13 == 1")
        .expect("compiles");
    cell.plc
        .command(Command::Substitute(SubstituteRequest {
            mode: SubstituteMode::Retransform,
            when: Some(("P10 == 1 && P20 == 1 && P13 == 1".into(), never)),
            within_us: Some(2_000_000),
            force: false,
        }))
        .expect("accepted");
    cell.run_for(3_000_000);
    assert!(cell.has_event(EventKind::SubstituteTimeout));
    assert_eq!(
        (cell.plc.primary(), cell.plc.status()),
        (Slot::A, Status::Quarantine)
    );

    // The robot free is a safe moment that comes often.
    let robot_free = cell
        .plc
        .primary_program()
        .compile_condition("R == 1 && P14 == 0")
        .expect("compiles");
    cell.plc
        .command(Command::Substitute(SubstituteRequest {
            mode: SubstituteMode::Retransform,
            when: Some(("R == 1 && P14 == 0".into(), robot_free)),
            within_us: Some(30_000_000),
            force: false,
        }))
        .expect("accepted");
    let mut waited = 0;
    while cell.plc.primary() == Slot::A && waited < 3_000 {
        cell.step();
        waited += 1;
    }
    assert_eq!(cell.plc.primary(), Slot::B);
    assert!(cell.has_event(EventKind::Substituted));
}
