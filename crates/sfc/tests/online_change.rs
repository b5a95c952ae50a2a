//! Online change between two versions of a chart: the state transform generated from place ids
//! carries the active steps over by name, new steps start inactive, step times are kept, and a
//! removed step that is active refuses the change.

use std::collections::BTreeMap;

use cetratus_program::{Program, StateTransform};
use cetratus_testkit::paths::fixture;

fn program(file: &str) -> Program {
    let path = fixture(&format!("plcopen/{file}"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "cannot read {}: {e}; the fixtures live in ../shared/fixtures",
            path.display()
        )
    });
    cetratus_sfc::import_str(&text, file, None, "Main.pnml")
        .expect("imports")
        .program
}

/// The marking of `p` with one token on each named step.
fn marking(p: &Program, active: &[&str]) -> Vec<u32> {
    p.net()
        .places()
        .iter()
        .map(|s| u32::from(active.contains(&s.id.as_str())))
        .collect()
}

#[test]
fn the_active_step_of_version_1_stays_active_in_version_6_and_new_steps_start_inactive() {
    let (v1, v6) = (
        program("twincat-sfc-evolution-1.xml"),
        program("twincat-sfc-evolution-6.xml"),
    );
    let st = StateTransform::generated(&v1, &v6, &BTreeMap::new()).expect("a transform");
    let mut out = vec![0; v6.net().num_places()];
    for active in ["Start", "Step1"] {
        st.apply(&marking(&v1, &[active]), &v6, &mut out)
            .expect("applies");
        assert_eq!(
            out,
            marking(&v6, &[active]),
            "{active} carries over by name"
        );
    }
    // Step1 active since 2 s: its time is kept, so `Step1.T` goes on counting.
    let since = [None, Some(2_000_000)];
    let mut timers = vec![None; v6.net().num_places()];
    st.apply(&marking(&v1, &["Step1"]), &v6, &mut out)
        .expect("applies");
    st.apply_timers(&since, &out, 5_000_000, &mut timers);
    let step1 = v6.net().place_by_id("Step1").expect("Step1").index();
    assert_eq!(timers[step1], Some(2_000_000));
}

#[test]
fn going_back_to_version_1_while_a_removed_parallel_step_is_active_is_refused() {
    let (v1, v6) = (
        program("twincat-sfc-evolution-1.xml"),
        program("twincat-sfc-evolution-6.xml"),
    );
    let st = StateTransform::generated(&v6, &v1, &BTreeMap::new()).expect("a transform");
    let mut out = vec![0; v1.net().num_places()];
    st.apply(&marking(&v6, &["Step1"]), &v1, &mut out)
        .expect("Step1 is kept");
    assert_eq!(out, marking(&v1, &["Step1"]));
    let err = st
        .apply(&marking(&v6, &["Step2", "Step3"]), &v1, &mut out)
        .expect_err("Step2 and Step3 are removed while active");
    assert!(err.to_string().contains("Step2"), "{err}");
    // With a mapping for the removed step (a package's `removed` table), its token goes there.
    let map = BTreeMap::from([("Step2".to_string(), "Step1".to_string())]);
    let st = StateTransform::generated(&v6, &v1, &map).expect("a transform");
    assert!(st.apply(&marking(&v6, &["Step2"]), &v1, &mut out).is_ok());
    assert_eq!(out, marking(&v1, &["Step1"]));
}

fn program_from(text: &str) -> Program {
    cetratus_sfc::import_str(text, "v.xml", None, "Main.pnml")
        .expect("imports")
        .program
}

#[test]
fn a_new_initial_step_starts_inactive_unless_the_whole_chart_is_new() {
    let read = |f: &str| {
        std::fs::read_to_string(fixture(&format!("plcopen/{f}"))).expect("reads the fixture")
    };
    let v1 = program("twincat-sfc-evolution-1.xml");
    // Version 6 with its initial step renamed: a step the new version adds, in a chart whose
    // other steps carry over. Step1 active in v1 stays the one active step.
    let renamed = program_from(&read("twincat-sfc-evolution-6.xml").replace("Start", "Begin"));
    assert!(renamed.is_sfc());
    let st = StateTransform::generated(&v1, &renamed, &BTreeMap::new()).expect("a transform");
    let mut out = vec![0; renamed.net().num_places()];
    st.apply(&marking(&v1, &["Step1"]), &renamed, &mut out)
        .expect("applies");
    assert_eq!(out, marking(&renamed, &["Step1"]), "Begin starts inactive");
    // Every step renamed: the whole chart is new, and it starts at its initial step.
    let all_new = read("twincat-sfc-evolution-6.xml")
        .replace("Start", "A0")
        .replace("Step1", "A1")
        .replace("Step2", "A2")
        .replace("Step3", "A3");
    let fresh = program_from(&all_new);
    let st = StateTransform::generated(&v1, &fresh, &BTreeMap::new()).expect("a transform");
    let mut out = vec![0; fresh.net().num_places()];
    // (An old step still active would be refused: its step is removed and nothing maps it.)
    st.apply(&marking(&v1, &[]), &fresh, &mut out)
        .expect("applies");
    assert_eq!(out, fresh.net().initial_marking().0);
}

/// A POU whose step `Run` starts the action `Sub` (S) when `with_sub`; `Sub`'s body is a chart
/// A → B → A.
fn with_nested(with_sub: bool) -> Program {
    let block = if with_sub {
        r#"<actionBlock localId="4"><connectionPointIn><connection refLocalId="3"/></connectionPointIn><action localId="0" qualifier="S"><reference name="Sub"/></action></actionBlock>"#
    } else {
        ""
    };
    let text = format!(
        r#"<?xml version="1.0"?>
<project xmlns="http://www.plcopen.org/xml/tc6_0201"><types><pous>
<pou name="P" pouType="program"><interface><localVars>
<variable name="go"><type><BOOL/></type></variable>
</localVars></interface>
<actions><action name="Sub"><body><SFC>
<step localId="1" name="A" initialStep="true"/>
<transition localId="2"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<condition><inline name=""><ST><p>go</p></ST></inline></condition></transition>
<step localId="3" name="B"><connectionPointIn><connection refLocalId="2"/></connectionPointIn></step>
<transition localId="4"><connectionPointIn><connection refLocalId="3"/></connectionPointIn>
<condition><inline name=""><ST><p>go</p></ST></inline></condition></transition>
<jumpStep localId="5" targetName="A"><connectionPointIn><connection refLocalId="4"/></connectionPointIn></jumpStep>
</SFC></body></action></actions>
<body><SFC>
<step localId="1" name="Idle" initialStep="true"/>
<transition localId="2"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<condition><inline name=""><ST><p>go</p></ST></inline></condition></transition>
<step localId="3" name="Run"><connectionPointIn><connection refLocalId="2"/></connectionPointIn></step>{block}
<transition localId="5"><connectionPointIn><connection refLocalId="3"/></connectionPointIn>
<condition><inline name=""><ST><p>NOT go</p></ST></inline></condition></transition>
<jumpStep localId="6" targetName="Idle"><connectionPointIn><connection refLocalId="5"/></connectionPointIn></jumpStep>
</SFC></body></pou></pous></types></project>"#
    );
    cetratus_sfc::import_str(&text, "p.xml", None, "P.pnml")
        .expect("imports")
        .program
}

#[test]
fn a_nested_chart_that_an_update_adds_starts_at_its_initial_step_held() {
    let (old, new) = (with_nested(false), with_nested(true));
    assert!(
        old.net().place_by_id("Sub__A").is_none(),
        "not associated: not imported"
    );
    let st = StateTransform::generated(&old, &new, &BTreeMap::new()).expect("a transform");
    let mut out = vec![0; new.net().num_places()];
    st.apply(&marking(&old, &["Run"]), &new, &mut out)
        .expect("applies");
    // The running chart keeps its step; the nested chart is new as a whole, so it starts at
    // its initial step, held until `Sub` is on.
    assert_eq!(out, marking(&new, &["Run", "Sub__A__held"]));
}
