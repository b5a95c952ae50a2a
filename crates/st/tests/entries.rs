//! Entries: an SFC chart's action bodies and conditions compiled on the state of its POU, as a
//! CODESYS export writes them (a TON called in an action, a VAR_INPUT assigned, a body that
//! ends in `END_IF` without its `;`).

use cetratus_st::parse::{parse_expression, parse_library, parse_statements};
use cetratus_st::{compile_with_entries, EntryText, State, Unit, Work};

const MS: i64 = 1_000_000;

const POU: &str = "
TYPE STEP_FLAGS : STRUCT X : BOOL; T : TIME; END_STRUCT; END_TYPE
FUNCTION_BLOCK Chart
VAR_INPUT start : BOOL; preset : TIME := T#30ms; END_VAR
VAR_OUTPUT lamp : BOOL; END_VAR
VAR t : TON; n : INT := 32767; Wait : STEP_FLAGS; END_VAR
END_FUNCTION_BLOCK
";

fn unit(bodies: &[(&str, &str)], conditions: &[(&str, &str)]) -> Unit {
    let lib = parse_library(POU).expect("the POU parses");
    let stmts: Vec<_> = (bodies.iter())
        .map(|(n, t)| (*n, parse_statements(t).expect("a body parses")))
        .collect();
    let exprs: Vec<_> = (conditions.iter())
        .map(|(n, t)| (*n, parse_expression(t).expect("a condition parses")))
        .collect();
    let mut entries: Vec<(String, EntryText<'_>)> = Vec::new();
    for (n, s) in &stmts {
        entries.push((n.to_string(), EntryText::Body(s)));
    }
    for (n, e) in &exprs {
        entries.push((n.to_string(), EntryText::Condition(e)));
    }
    compile_with_entries(&lib, Some("Chart"), &entries).expect("the entries compile")
}

fn slot(u: &Unit, s: &State, name: &str) -> u64 {
    s.slots[u.var(name).expect("declared").at.slots as usize]
}

#[test]
fn a_ton_called_in_an_action_is_seen_by_a_condition_and_a_var_input_may_be_assigned() {
    let u = unit(
        &[(
            "Act",
            "t(IN := start, PT := preset); n := n + 1; IF t.Q THEN lamp := TRUE; start := FALSE; END_IF",
        )],
        &[("T1", "t.Q AND Wait.X"), ("T2", "n < 0")],
    );
    let (act, t1, t2) = (u.entry("act"), u.entry("T1"), u.entry("t2"));
    let (act, t1, t2) = (act.unwrap(), t1.unwrap(), t2.unwrap());
    let mut s = u.new_state();
    let start = u.var("start").unwrap().at.slots as usize;
    let wait_x = u.var("Wait").unwrap().at.slots as usize;
    s.slots[start] = 1;
    s.slots[wait_x] = 1;
    let mut work = Work::unlimited();
    for k in 0..3 {
        u.run_entry(act, &mut s, k * 10 * MS, &mut work).unwrap();
        assert!(!u.run_entry(t1, &mut s, k * 10 * MS, &mut work).unwrap());
    }
    // The INT wrapped at its width, as IEC and MATIEC make it.
    assert!(u.run_entry(t2, &mut s, 0, &mut work).unwrap());
    u.run_entry(act, &mut s, 30 * MS, &mut work).unwrap();
    assert!(u.run_entry(t1, &mut s, 30 * MS, &mut work).unwrap());
    assert_eq!(slot(&u, &s, "lamp"), 1);
    assert_eq!(
        slot(&u, &s, "start"),
        0,
        "the action assigned its VAR_INPUT"
    );
    s.slots[wait_x] = 0;
    assert!(!u.run_entry(t1, &mut s, 30 * MS, &mut work).unwrap());
}

#[test]
fn an_entry_that_is_not_bool_or_not_well_typed_is_refused_naming_the_entry() {
    let lib = parse_library(POU).unwrap();
    let e = parse_expression("n + 1").unwrap();
    let body = parse_statements("lamp := n;").unwrap();
    let entries = [
        ("ok".to_string(), EntryText::Condition(&e)),
        ("bad".to_string(), EntryText::Body(&body)),
    ];
    let err = compile_with_entries(&lib, Some("Chart"), &entries[..1]).unwrap_err();
    assert_eq!(err.entry, Some(0));
    assert!(
        err.diagnostic.message.contains("condition is BOOL"),
        "{err:?}"
    );
    let err = compile_with_entries(&lib, Some("Chart"), &entries[1..]).unwrap_err();
    assert_eq!(err.entry, Some(0));
    let err = compile_with_entries(
        &parse_library("FUNCTION_BLOCK Chart VAR x : NOPE; END_VAR END_FUNCTION_BLOCK").unwrap(),
        Some("Chart"),
        &[],
    )
    .unwrap_err();
    assert_eq!(err.entry, None);
}

#[test]
fn a_runaway_loop_in_an_entry_stops_at_the_work_budget() {
    let u = unit(&[("Spin", "WHILE TRUE DO n := n + 1; END_WHILE")], &[]);
    let mut s = u.new_state();
    let mut work = Work::within(10_000);
    assert!(u.run_entry(0, &mut s, 0, &mut work).is_err());
}

#[test]
fn entries_share_one_bound_on_code_so_many_small_texts_cannot_expand_without_end() {
    // A function block whose body expands to thousands of instructions, called by each of many
    // one-line entries: each alone is small, together they pass the unit's bound.
    let big = "a := a + 1; ".repeat(20_000);
    let text = format!(
        "FUNCTION_BLOCK Big VAR_INPUT go : BOOL; END_VAR VAR a : DINT; END_VAR {big} END_FUNCTION_BLOCK
         FUNCTION_BLOCK Chart VAR b : Big; END_VAR END_FUNCTION_BLOCK"
    );
    let lib = parse_library(&text).expect("parses");
    let call = parse_statements("b(go := TRUE);").expect("a call");
    let entries: Vec<(String, EntryText<'_>)> = (0..200)
        .map(|k| (format!("A{k}"), EntryText::Body(&call)))
        .collect();
    let err = compile_with_entries(&lib, Some("Chart"), &entries).expect_err("too large");
    assert!(err.entry.is_some(), "{err:?}");
    assert!(err.diagnostic.message.contains("too large"), "{err:?}");
}

/// A condition may be statements that assign its value to its own name, as IEC writes a named
/// transition's body and as an FBD network drawn for a condition lowers: here a TON that runs
/// only when the condition is evaluated. The name is the condition's alone (FALSE until the
/// statements assign it), and a POU variable of that name is refused.
#[test]
fn a_condition_written_as_statements_assigns_its_own_name() {
    let lib = parse_library(POU).expect("the POU parses");
    let texts = [(
        "T9",
        "t(IN := start, PT := T#20ms);\nIF t.Q THEN T9 := TRUE; END_IF;",
        false,
    )];
    let u = cetratus_st::compile_entry_texts(&lib, Some("Chart"), &texts)
        .unwrap_or_else(|e| panic!("{:?}", e.diagnostic));
    let t9 = u.entry("T9").expect("the condition");
    assert!(u.entries[t9].result.is_some());
    let mut s = u.new_state();
    s.slots[u.var("start").unwrap().at.slots as usize] = 1;
    let mut work = Work::unlimited();
    let at = |ms: i64| ms * MS;
    assert!(!u.run_entry(t9, &mut s, at(0), &mut work).unwrap());
    assert!(!u.run_entry(t9, &mut s, at(10), &mut work).unwrap());
    assert!(u.run_entry(t9, &mut s, at(20), &mut work).unwrap());
    let clash = [("lamp", "lamp := start;", false)];
    let err = cetratus_st::compile_entry_texts(&lib, Some("Chart"), &clash).expect_err("a clash");
    assert!(
        err.diagnostic.message.contains("is a variable of the POU"),
        "{:?}",
        err.diagnostic
    );
}
