//! A chart whose action bodies and conditions are Structured Text on its POU's state
//! (`[st.bodies]`, `[st.conditions]`, `[st.steps]`), run scan by scan in a container: the forms
//! a CODESYS export writes (a TON called in an action, a VAR_INPUT assigned in its own POU, a
//! body ending in `END_IF` without its `;`), step flags read by the conditions, IEC integer
//! wrapping, and a failing condition that rolls the scan back.

use std::sync::Arc;

use cetratus_program::{Program, Value};
use cetratus_runtime::{Container, RuntimeError};

/// Idle → Run (`start`) → Done (`t.Q`) → Idle (after 50 ms in Done).
fn chart() -> Arc<Program> {
    let net = cetratus_testkit::nets::sequence(
        &[("Idle", 1), ("Run", 0), ("Done", 0)],
        &[
            ("T1", "Idle", "Run"),
            ("T2", "Run", "Done"),
            ("T3", "Done", "Idle"),
        ],
    );
    let toml = r#"[program]
name = "chart"
version = "1"
chart = "sfc"
[[input]]
name = "start"
type = "bool"
[[output]]
name = "lamp"
type = "bool"
[[output]]
name = "count"
type = "int"
[[output]]
name = "busy"
type = "bool"
[[action]]
place = "Run"
qualifier = "N"
target = "busy"
[[action]]
place = "Run"
qualifier = "N"
body = "RunAct"
[[action]]
place = "Done"
qualifier = "N"
body = "DoneAct"
[st]
pou = "Chart"
source = '''
TYPE STEP_FLAGS : STRUCT X : BOOL; T : TIME; END_STRUCT; END_TYPE
FUNCTION_BLOCK Chart
VAR_INPUT start : BOOL; END_VAR
VAR_OUTPUT lamp : BOOL; count : SINT := 126; busy : BOOL; END_VAR
VAR t : TON; Idle, Run, Done : STEP_FLAGS; END_VAR
END_FUNCTION_BLOCK
'''
[st.bodies]
RunAct = '''
t(IN := Run.X, PT := T#30ms);
count := count + 1;
IF t.Q THEN
  start := FALSE;
END_IF'''
DoneAct = "lamp := Done.X;"
[st.conditions]
T1 = "start"
T2 = "t.Q AND busy"
T3 = "Done.T >= T#50ms"
[st.steps]
Idle = "Idle"
Run = "Run"
Done = "Done"
"#;
    Arc::new(Program::from_sources(toml, "chart.toml", net).unwrap_or_else(|e| panic!("{e}")))
}

fn scan(c: &mut Container, ms: u64, start: bool) -> Vec<Value> {
    c.scan(ms * 1000, &[Value::Bool(start)])
        .unwrap_or_else(|e| panic!("at {ms} ms: {e}"));
    c.outputs().to_vec()
}

fn marked(c: &Container, p: &Program) -> Vec<String> {
    let places = p.net().places();
    (c.marking().iter().zip(places))
        .filter(|(m, _)| **m > 0)
        .map(|(_, pl)| pl.id.clone())
        .collect()
}

#[test]
fn a_chart_in_st_runs_its_timer_its_step_flags_and_its_vendor_forms() {
    let p = chart();
    let mut c = Container::new(p.clone(), 0);
    scan(&mut c, 0, false);
    assert_eq!(marked(&c, &p), ["Idle"]);
    let out = scan(&mut c, 10, true);
    assert_eq!(marked(&c, &p), ["Run"]);
    assert_eq!(
        out[2],
        Value::Bool(true),
        "N busy: Q of Run's action, a VAR_OUTPUT of the ST"
    );
    // The TON runs in Run's body; its Q is read by T2's condition in the scan after.
    let mut at = 10;
    while marked(&c, &p) == ["Run"] {
        at += 10;
        assert!(at < 200, "the timer never ended Run");
        scan(&mut c, at, true);
    }
    assert_eq!(marked(&c, &p), ["Done"]);
    assert!((40..=60).contains(&at), "Run lasted until {at} ms");
    // The body's count is a SINT from 126: it wrapped, as IEC and MATIEC make it.
    let out = scan(&mut c, at + 10, true);
    assert_eq!(out[0], Value::Bool(true), "Done's body sees Done.X");
    assert_eq!(out[2], Value::Bool(false), "busy fell with Run's Q");
    assert!(matches!(out[1], Value::Int(n) if n < 0), "{:?}", out[1]);
    // Done.T reaches 50 ms, and the chart is back in Idle.
    let mut t = at + 10;
    while marked(&c, &p) == ["Done"] {
        t += 10;
        assert!(t < at + 200, "Done.T never passed 50 ms");
        scan(&mut c, t, true);
    }
    assert_eq!(marked(&c, &p), ["Idle"]);
    assert!(t - at >= 50, "left Done after {} ms", t - at);
}

#[test]
fn a_condition_that_fails_rolls_the_scan_back_naming_the_transition() {
    let p = chart();
    let broken = {
        let text = p.source().replace(
            r#"T1 = "start""#,
            r#"T1 = "10 / BOOL_TO_INT(NOT start) < 0""#,
        );
        let net = p.net().as_ref().clone();
        Arc::new(Program::from_sources(&text, "chart.toml", net).expect("loads"))
    };
    let mut c = Container::new(broken.clone(), 0);
    scan(&mut c, 0, false);
    let err = c.scan(10_000, &[Value::Bool(true)]).unwrap_err();
    assert!(
        matches!(&err, RuntimeError::Guard { transition, .. } if transition == "T1"),
        "{err}"
    );
    assert_eq!(marked(&c, &broken), ["Idle"], "nothing was half-applied");
}

#[test]
fn st_tables_that_do_not_fit_the_net_or_the_pou_are_refused_clearly() {
    let p = chart();
    let load = |from: &str, to: &str| {
        let text = p.source().replace(from, to);
        assert_ne!(text, p.source(), "{from}");
        Program::from_sources(&text, "chart.toml", p.net().as_ref().clone())
            .expect_err("refused")
            .to_string()
    };
    let e = load(r#"T3 = "Done.T >= T#50ms""#, r#"T9 = "TRUE""#);
    assert!(e.contains("`T9`") && e.contains("does not have"), "{e}");
    let e = load(r#"T2 = "t.Q AND busy""#, r#"T2 = "t.ET""#);
    assert!(e.contains("condition of `T2`") && e.contains("BOOL"), "{e}");
    let e = load(r#"Done = "Done""#, r#"Done = "lamp""#);
    assert!(e.contains("X : BOOL and T : TIME"), "{e}");
    let e = load("count := count + 1;", "count := count + ;");
    assert!(
        e.contains("chart.toml:") && e.contains("ST body `RunAct`"),
        "{e}"
    );
    let e = load(r#"target = "busy""#, r#"target = "count""#);
    assert!(e.contains("not a BOOL variable of the chart's POU"), "{e}");
    let e = load("END_FUNCTION_BLOCK", "lamp := TRUE;\nEND_FUNCTION_BLOCK");
    assert!(e.contains("does not run in a chart"), "{e}");
}
