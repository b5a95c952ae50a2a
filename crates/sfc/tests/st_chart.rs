//! A chart as a CODESYS export writes it, which the guard subset refuses: an action body that
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
    let note = imported.notes.iter().find(|n| n.contains("ST compiler"));
    assert!(note.is_some(), "{:?}", imported.notes);
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

#[test]
fn a_named_fbd_transition_and_an_ld_action_import_on_the_st_compiler_and_run() {
    // Two of the chart's conditions are networks drawn in the chart itself, a form that stays
    // refused (the next test); written inline, the rest of the file imports as it is.
    let xml = cetratus_testkit::paths::traffic_light_inline();
    let imported = cetratus_sfc::import_str(&xml, "light.xml", None, "Light.pnml")
        .unwrap_or_else(|e| panic!("{e}"));
    let toml = &imported.toml;
    assert!(
        toml.contains("\"T16\" = '''\n(NOT SWITCH_BUTTON)'''"),
        "{toml}"
    );
    assert!(
        toml.contains("TON1(IN := (NOT ORANGE_LIGHT), PT := T#500ms);"),
        "{toml}"
    );
    assert!(
        toml.contains("IF R_TRIG0.Q THEN ORANGE_LIGHT := FALSE; END_IF;"),
        "{toml}"
    );
    let p = Arc::new(imported.program);
    let output = |c: &Container, name: &str| {
        let i = (p.outputs().iter().position(|o| o.name == name)).expect("an output");
        c.outputs()[i]
    };
    let mut c = Container::new(p.clone(), 0);
    let mut ms = 0u64;
    let mut run = |c: &mut Container, switch: bool, for_ms: u64| {
        for _ in 0..for_ms / 10 {
            ms += 10;
            let inputs = [Value::Bool(switch), Value::Bool(false)];
            c.scan(ms * 1000, &inputs)
                .unwrap_or_else(|e| panic!("at {ms} ms: {e}"));
        }
    };
    run(&mut c, true, 100);
    assert_eq!(
        output(&c, "ORANGE_LIGHT"),
        Value::Bool(true),
        "switched on: orange"
    );
    run(&mut c, true, 2_100);
    assert_eq!(output(&c, "RED_LIGHT"), Value::Bool(true), "2 s later: red");
    assert_eq!(output(&c, "ORANGE_LIGHT"), Value::Bool(false));
    // Switched off: the FBD transition STOP (NOT SWITCH_BUTTON) takes the chart back.
    run(&mut c, false, 100);
    assert!(c.marking()[0] > 0, "back in Standstill: {:?}", c.marking());
}

#[test]
fn a_network_drawn_in_the_chart_as_a_condition_is_refused_by_name_and_place() {
    let err = cetratus_sfc::import_str(&traffic_light(), "light.xml", None, "Light.pnml")
        .expect_err("refused");
    let text = err.to_string();
    assert!(text.starts_with("light.xml:1191:13:"), "{text}");
    assert!(
        text.contains("an LD network drawn in the chart as a condition"),
        "{text}"
    );
}
