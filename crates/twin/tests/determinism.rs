//! Seeds, forks and names: the properties that let a twin validate an update candidate.

mod common;

use cetratus_twin::{
    FestoParams, FestoStation, Plant, Twin, TwinKind, VernadatCell, VernadatParams, SECOND_US,
};
use common::{run, Controller, FestoProgram, VernadatNet, INITIAL};

const MINUTE: u64 = 60 * SECOND_US;

fn jittery_cell(seed: u64) -> Twin {
    let params = VernadatParams {
        jitter_us: 200_000,
        ..VernadatParams::default()
    };
    Twin::Vernadat(VernadatCell::new(params, seed).expect("valid parameters"))
}

fn jittery_station(seed: u64) -> Twin {
    let params = FestoParams {
        jitter_us: 100_000,
        ..FestoParams::default()
    };
    let mut st = FestoStation::new(params, seed).expect("valid parameters");
    st.press("START", 0).expect("start button");
    Twin::Festo(st)
}

fn fork_and_compare<C: Controller>(mut twin: Twin, mut ctl: C) {
    let mut outs = vec![false; twin.output_names().len()];
    run(&mut twin, &mut ctl, &mut outs, 0, 10 * MINUTE);

    let mut fork = twin.clone();
    let mut fork_ctl = ctl.clone();
    let mut fork_outs = outs.clone();
    let mut boxed = twin.fork();
    let mut boxed_ctl = ctl.clone();
    let mut boxed_outs = outs.clone();

    let a = run(&mut twin, &mut ctl, &mut outs, 10 * MINUTE, 20 * MINUTE);
    let b = run(
        &mut fork,
        &mut fork_ctl,
        &mut fork_outs,
        10 * MINUTE,
        20 * MINUTE,
    );
    let c = run(
        &mut *boxed,
        &mut boxed_ctl,
        &mut boxed_outs,
        10 * MINUTE,
        20 * MINUTE,
    );
    assert_eq!(a, b, "input traces differ");
    assert_eq!(a, c, "the boxed fork's input trace differs");
    assert_eq!(twin, fork);
    assert_eq!(twin.counters(), boxed.counters());
    assert_eq!(twin.faults(), boxed.faults());
}

#[test]
fn a_vernadat_fork_driven_like_the_original_stays_identical() {
    fork_and_compare(jittery_cell(7), VernadatNet::new(&INITIAL));
}

#[test]
fn a_festo_fork_driven_like_the_original_stays_identical() {
    fork_and_compare(jittery_station(7), FestoProgram::default());
}

fn trace<C: Controller>(mut twin: Twin, mut ctl: C) -> (u64, Twin) {
    let mut outs = vec![false; twin.output_names().len()];
    let digest = run(&mut twin, &mut ctl, &mut outs, 0, 20 * MINUTE);
    (digest, twin)
}

#[test]
fn the_same_seed_gives_the_same_run_and_another_seed_another() {
    let (a, ta) = trace(jittery_cell(1), VernadatNet::new(&INITIAL));
    let (b, tb) = trace(jittery_cell(1), VernadatNet::new(&INITIAL));
    let (c, _) = trace(jittery_cell(2), VernadatNet::new(&INITIAL));
    assert_eq!(a, b);
    assert_eq!(ta, tb);
    assert_ne!(a, c, "jitter should make seeds 1 and 2 differ");
    assert!(
        ta.faults().is_empty(),
        "jitter alone causes no fault: {:?}",
        ta.faults()
    );

    let (a, ta) = trace(jittery_station(1), FestoProgram::default());
    let (b, tb) = trace(jittery_station(1), FestoProgram::default());
    let (c, _) = trace(jittery_station(2), FestoProgram::default());
    assert_eq!(a, b);
    assert_eq!(ta, tb);
    assert_ne!(a, c, "jitter should make seeds 1 and 2 differ");
    assert!(
        ta.faults().is_empty(),
        "jitter alone causes no fault: {:?}",
        ta.faults()
    );
}

#[test]
fn with_default_parameters_the_seed_does_not_matter() {
    let (a, _) = trace(TwinKind::Vernadat.build(1), VernadatNet::new(&INITIAL));
    let (b, _) = trace(TwinKind::Vernadat.build(99), VernadatNet::new(&INITIAL));
    assert_eq!(a, b);
}

#[test]
fn twins_are_built_by_name() {
    for kind in TwinKind::ALL {
        let twin = Twin::by_name(kind.name(), 0).expect("every kind has a name");
        assert_eq!(twin.kind(), kind);
        assert_eq!(twin.name(), kind.name());
        let boxed = kind.boxed(0);
        assert_eq!(boxed.output_names(), twin.output_names());
    }
    assert!(Twin::by_name("lathe", 0).is_err());
}
