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
