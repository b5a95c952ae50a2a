//! A chart as a CODESYS export writes it: an action body that
//! calls a TON, assigns a VAR_INPUT of its own POU and ends in `END_IF` without its `;`, a
//! condition that reads the timer's output and a step's time, a STRING and a typed integer
//! that wraps. It imports on the one Structured Text compiler and runs as IEC 61131-3 says.

use std::sync::Arc;

use cetratus_program::Value;
use cetratus_runtime::Container;

/// The chart of `examples/press-sfc`.
fn chart() -> String {
    std::fs::read_to_string(cetratus_testkit::paths::example("press-sfc/press.xml"))
        .expect("the example chart")
}

fn import(text: &str) -> Result<cetratus_sfc::Imported, cetratus_sfc::SfcError> {
    cetratus_sfc::import_str(text, "press.xml", None, "Press.pnml")
}

#[test]
fn a_codesys_chart_with_a_ton_call_and_an_assigned_var_input_imports_and_runs() {
    let imported = import(&chart()).unwrap_or_else(|e| panic!("{e}"));
    let p = Arc::new(imported.program);
    assert!(p.is_sfc());
    let names: Vec<&str> = p.outputs().iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["lamp", "strokes"]);
    let mut c = Container::new(p.clone(), 0);
    let idle = |c: &Container| c.marking()[0] > 0;
    let mut ms = 0u64;
    let mut scan = |c: &mut Container, start: bool| {
        ms += 10;
        c.scan(ms * 1000, &[Value::Bool(start)])
            .unwrap_or_else(|e| panic!("at {ms} ms: {e}"));
        c.outputs().to_vec()
    };
    scan(&mut c, false);
    assert!(idle(&c));
    let out = scan(&mut c, true);
    assert!(!idle(&c));
    assert_eq!(out[0], Value::Bool(true), "lamp is Run's Q");
    // The stroke counter is a SINT from 126: it wraps at its width, as IEC makes it.
    let out = scan(&mut c, true);
    assert_eq!(out[1], Value::Int(-128), "{out:?}");
    let mut runs = 0;
    while !idle(&c) {
        runs += 1;
        assert!(runs < 20, "the TON never ended Run");
        scan(&mut c, true);
    }
    let out = scan(&mut c, false);
    assert_eq!(out[0], Value::Bool(false), "lamp fell with Run's Q");
}

#[test]
fn an_error_in_the_charts_st_names_the_file_line_and_column() {
    let broken = chart().replace("strokes := strokes + 1;", "strokes := strokes + ;");
    let err = import(&broken).expect_err("broken");
    let text = err.to_string();
    assert!(text.starts_with("press.xml:19:22:"), "{text}");
    assert!(text.contains("the action `Stroke`"), "{text}");
    let wrong = chart().replace("t.Q AND Run.T", "t.ET AND Run.T");
    let err = import(&wrong).expect_err("not BOOL");
    assert!(err.to_string().contains("press.xml:"), "{err}");
}

/// The text of Beremiz's SVGHMI traffic light.
fn traffic_light() -> String {
    std::fs::read_to_string(cetratus_testkit::paths::fixture(
        "plcopen/beremiz-svghmi-traffic-light.xml",
    ))
    .expect("the fixture")
}

/// The whole of Beremiz's SVGHMI traffic light, as the editor wrote it: its named transition
/// `STOP` is an FBD network, its action `BLINK_ORANGE_LIGHT` an LD network (two TONs, two
/// R_TRIGs, set and reset coils), and two conditions are networks drawn in the chart itself, a
/// negated contact and, for the pedestrian's request, a latch (SR) and a 2 s timer (TON) behind
/// an OR, which become statements that assign the condition's value.
#[test]
fn beremizs_traffic_light_with_ld_and_fbd_in_its_chart_imports_and_runs() {
    let imported = cetratus_sfc::import_str(&traffic_light(), "light.xml", None, "Light.pnml")
        .unwrap_or_else(|e| panic!("{e}"));
    let toml = &imported.toml;
    for part in [
        "\"T16\" = '''\n(NOT SWITCH_BUTTON)'''",
        "\"T26\" = '''\n(NOT SWITCH_BUTTON)'''",
        "TON1(IN := (NOT ORANGE_LIGHT), PT := T#500ms);",
        "IF R_TRIG0.Q THEN ORANGE_LIGHT := FALSE; END_IF;",
        "SR0(S1 := PEDESTRIAN_BUTTON, R := TON3.Q);",
        "T37 := (TON3.Q OR WARN_CARS);",
    ] {
        assert!(toml.contains(part), "{part} in {toml}");
    }
    let p = Arc::new(imported.program);
    let output = |c: &Container, name: &str| {
        let i = (p.outputs().iter().position(|o| o.name == name)).expect("an output");
        c.outputs()[i]
    };
    let mut c = Container::new(p.clone(), 0);
    let mut ms = 0u64;
    let mut run = |c: &mut Container, switch: bool, pedestrian: bool, for_ms: u64| {
        for _ in 0..for_ms / 10 {
            ms += 10;
            let inputs = [Value::Bool(switch), Value::Bool(pedestrian)];
            c.scan(ms * 1000, &inputs)
                .unwrap_or_else(|e| panic!("at {ms} ms: {e}"));
        }
    };
    // Switched off, the orange lamp blinks: the LD action sets and resets it every 500 ms,
    // and the S association of the step ORANGE, whose Q is off, leaves it to the action.
    let mut changes = 0;
    let mut last = Value::Bool(false);
    for _ in 0..30 {
        run(&mut c, false, false, 100);
        let now = output(&c, "ORANGE_LIGHT");
        changes += usize::from(now != last);
        last = now;
    }
    assert!((5..=7).contains(&changes), "{changes} changes in 3 s");
    run(&mut c, true, false, 100);
    assert_eq!(
        output(&c, "ORANGE_LIGHT"),
        Value::Bool(true),
        "switched on: orange"
    );
    run(&mut c, true, false, 2_100);
    assert_eq!(output(&c, "RED_LIGHT"), Value::Bool(true), "2 s later: red");
    run(&mut c, true, false, 14_100);
    assert_eq!(
        output(&c, "GREEN_LIGHT"),
        Value::Bool(true),
        "then green for the cars"
    );
    // A pedestrian's request latches (SR0), and 2 s later (TON3) the cars get orange.
    run(&mut c, true, true, 100);
    run(&mut c, true, false, 1_500);
    assert_eq!(output(&c, "GREEN_LIGHT"), Value::Bool(true), "not yet");
    run(&mut c, true, false, 600);
    assert_eq!(
        output(&c, "ORANGE_LIGHT"),
        Value::Bool(true),
        "the request is served"
    );
    // Switched off: the FBD transition STOP (NOT SWITCH_BUTTON) takes the chart back.
    run(&mut c, false, false, 100);
    assert!(c.marking()[0] > 0, "back in Standstill: {:?}", c.marking());
}

#[test]
fn an_il_condition_is_refused_by_name_and_place() {
    let xml = cetratus_testkit::paths::traffic_light_il();
    let err = cetratus_sfc::import_str(&xml, "light.xml", None, "Light.pnml").expect_err("refused");
    let text = err.to_string();
    assert!(text.starts_with("light.xml:"), "{text}");
    assert!(text.contains("an inline IL condition"), "{text}");
    assert!(text.contains("in POU `traffic_light_sequence`"), "{text}");
}

/// A named transition whose network needs more than one statement (here the traffic light's
/// `STOP` drawn with an R_TRIG instead of its NOT) is a condition written as statements: each
/// transition that refers to it assigns its own id.
#[test]
fn a_named_transition_of_several_statements_assigns_each_referring_transitions_id() {
    let xml = traffic_light();
    let (from, to) = (
        xml.find("<transition name=\"STOP\">").expect("STOP"),
        xml.find("</transitions>").expect("its end"),
    );
    let stop = xml[from..to]
        .replace(
            "typeName=\"NOT\"",
            "typeName=\"R_TRIG\" instanceName=\"EDGE0\"",
        )
        .replace("formalParameter=\"IN\"", "formalParameter=\"CLK\"")
        .replace("formalParameter=\"OUT\"", "formalParameter=\"Q\"");
    let xml = format!("{}{stop}{}", &xml[..from], &xml[to..]);
    let imported = cetratus_sfc::import_str(&xml, "light.xml", None, "Light.pnml")
        .unwrap_or_else(|e| panic!("{e}"));
    let toml = &imported.toml;
    for part in [
        "EDGE0(CLK := SWITCH_BUTTON);\nT16 := EDGE0.Q;",
        "T4 := EDGE0.Q;",
        "EDGE0 : R_TRIG",
    ] {
        assert!(toml.contains(part), "{part} in {toml}");
    }
    let mut c = Container::new(Arc::new(imported.program), 0);
    for k in 1..=10u64 {
        c.scan(k * 10_000, &[Value::Bool(k > 5), Value::Bool(false)])
            .unwrap_or_else(|e| panic!("scan {k}: {e}"));
    }
}

/// In a nested chart a network of statements as a condition assigns its value to the
/// transition's name in its chart (`T5`: its id, `sub_sfc1__T5`, is no IEC name), and holds
/// only while the chart's action is on. (CODESYS's nested chart, with an R_TRIG drawn between
/// its condition and the box that feeds it.)
#[test]
fn a_network_of_statements_in_a_nested_chart_holds_while_its_action_is_on() {
    let xml = cetratus_testkit::paths::codesys_nested_edge();
    let imported = cetratus_sfc::import_str(&xml, "nested.xml", None, "Nested.pnml")
        .unwrap_or_else(|e| panic!("{e}"));
    let gated = "EDGE9(CLK := ((i MOD 3) = 0));\nT5 := EDGE9.Q;\nT5 := sub_sfc1 AND T5;";
    assert!(imported.toml.contains(gated), "{}", imported.toml);
    let mut c = Container::new(Arc::new(imported.program), 0);
    for k in 1..=200u64 {
        c.scan(k * 100_000, &[])
            .unwrap_or_else(|e| panic!("scan {k}: {e}"));
    }
}
