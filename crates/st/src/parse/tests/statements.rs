//! Statements, the vendors' forms, and the two CODESYS failures this crate was written for.

#![allow(unused_imports)]
use super::*;

// ---- Statements ----

#[test]
fn an_assignment_to_a_member_of_an_element_is_read() {
    let s = stmts("a.b[i + 1, 2].c := 5;");
    let StmtKind::Assign { target, value } = &s[0].kind else {
        panic!("not an assignment")
    };
    assert_eq!(show(target), "a.b[(i + 1), 2].c");
    assert_eq!(show(value), "5");
}

#[test]
fn calls_with_formal_positional_and_no_arguments_are_read() {
    let s =
        stmts("inst(IN := a, PT := T#1s, Q => b, NOT Q => c); F(x, y); inst(); s.t(IN := TRUE);");
    let calls: Vec<String> = s
        .iter()
        .map(|s| match &s.kind {
            StmtKind::Call(c) => format!(
                "{}({})",
                show(&c.callee),
                c.args.iter().map(show_arg).collect::<Vec<_>>().join(", ")
            ),
            other => panic!("not a call: {other:?}"),
        })
        .collect();
    assert_eq!(
        calls,
        [
            "inst(IN := a, PT := 1000000000ns, Q => b, NOT Q => c)",
            "F(x, y)",
            "inst()",
            "s.t(IN := TRUE)"
        ]
    );
}

#[test]
fn mixing_positional_and_formal_arguments_is_refused() {
    let d = stmts_err("F(x, IN := y);");
    assert_eq!(d.pos, 5);
    assert!(d
        .message
        .starts_with("a call takes either positional arguments"));
}

#[test]
fn if_elsif_else_is_read() {
    let s =
        stmts("IF a THEN x := 1; ELSIF b THEN x := 2; ELSIF c THEN ; ELSE x := 3; y := 4; END_IF;");
    let StmtKind::If { arms, otherwise } = &s[0].kind else {
        panic!("not an IF")
    };
    assert_eq!(arms.len(), 3);
    assert_eq!(otherwise.len(), 2);
}

#[test]
fn case_with_values_ranges_enumerations_and_typed_labels_is_read() {
    let s = stmts(
        "CASE x OF 1, 2, 5..7: y := 1; Red: y := 2; INT#-3: y := 3; Color#Blue, -1: ; ELSE y := 0; END_CASE",
    );
    let StmtKind::Case {
        arms, otherwise, ..
    } = &s[0].kind
    else {
        panic!("not a CASE")
    };
    let labels: Vec<String> = arms
        .iter()
        .flat_map(|(ls, _)| ls)
        .map(|l| match l {
            CaseLabel::Value(v) => show(v),
            CaseLabel::Range(a, b) => format!("{}..{}", show(a), show(b)),
        })
        .collect();
    assert_eq!(
        labels,
        ["1", "2", "5..7", "Red", "INT#-3", "Color#Blue", "(-1)"]
    );
    assert!(arms[3].1[0].kind.is_empty());
    assert_eq!(otherwise.len(), 1);
}

impl StmtKind {
    fn is_empty(&self) -> bool {
        matches!(self, StmtKind::Empty)
    }
}

#[test]
fn for_while_and_repeat_are_read() {
    let s = stmts(
        "FOR i := 1 TO n BY -1 DO x := x + i; END_FOR; FOR j := 0 TO 3 DO END_FOR; WHILE x > 0 DO x := x - 1; END_WHILE; REPEAT x := x + 1; UNTIL x >= 10 END_REPEAT;",
    );
    assert!(matches!(&s[0].kind, StmtKind::For { by: Some(_), body, .. } if body.len() == 1));
    assert!(matches!(&s[1].kind, StmtKind::For { by: None, body, .. } if body.is_empty()));
    assert!(matches!(&s[2].kind, StmtKind::While { .. }));
    assert!(matches!(&s[3].kind, StmtKind::Repeat { body, .. } if body.len() == 1));
}

#[test]
fn exit_return_and_empty_statements_are_read() {
    let s = stmts("WHILE TRUE DO EXIT; END_WHILE; ; RETURN;");
    assert!(
        matches!(&s[0].kind, StmtKind::While { body, .. } if matches!(body[0].kind, StmtKind::Exit))
    );
    assert!(matches!(s[1].kind, StmtKind::Empty));
    assert!(matches!(s[2].kind, StmtKind::Return));
}

#[test]
fn an_assignment_without_its_semicolon_is_refused_naming_what_was_found() {
    let d = stmts_err("y := 1\nx := 2;");
    assert_eq!(d.message, "expected ';' after the assignment, found 'x'");
    assert_eq!(d.pos, 7);
}

#[test]
fn a_name_alone_is_not_a_statement() {
    let d = stmts_err("x;");
    assert_eq!(
        d.message,
        "expected ':=' (an assignment) or '(' (a call) after 'x', found ';'"
    );
    let d = stmts_err("a.b = 1;");
    assert_eq!(
        d.message,
        "expected ':=' (an assignment) or '(' (a call) after 'a.b', found '='"
    );
}

#[test]
fn a_call_cannot_be_assigned_to_nor_its_result_read_in_place() {
    let d = stmts_err("inst(IN := x) := 5;");
    assert!(d.message.starts_with("a call cannot be assigned to"));
    let d = stmts_err("y := inst(IN := x).Q;");
    assert!(d
        .message
        .starts_with("a call's result cannot be followed by"));
}

#[test]
fn a_missing_end_names_the_statement_it_closes() {
    let d = stmts_err("FOR i := 1 TO 3 DO IF a THEN x := 1; END_FOR");
    assert_eq!(
        d.message,
        "expected END_IF to close the IF, found 'END_FOR'"
    );
    let d = stmts_err("WHILE a DO x := 1;");
    assert_eq!(
        d.message,
        "expected END_WHILE to close the WHILE, found the end of the text"
    );
}

// ---- The vendors' forms ----

#[test]
fn a_body_that_ends_in_end_if_without_a_semicolon_is_accepted() {
    let s = stmts("x := 1;\nIF a THEN\n  x := 2;\nEND_IF");
    assert_eq!(s.len(), 2);
    assert!(matches!(s[1].kind, StmtKind::If { .. }));
}

#[test]
fn each_compound_statement_may_end_its_body_without_a_semicolon() {
    let bodies = [
        "IF a THEN CASE x OF 1: y := 1; END_CASE END_IF;",
        "IF a THEN FOR i := 1 TO 2 DO END_FOR ELSE y := 1; END_IF;",
        "IF a THEN WHILE b DO END_WHILE ELSIF c THEN y := 1; END_IF;",
        "REPEAT IF a THEN y := 1; END_IF UNTIL b END_REPEAT;",
        "WHILE b DO REPEAT y := 1; UNTIL c END_REPEAT END_WHILE",
        "FOR i := 1 TO 2 DO IF a THEN EXIT; END_IF END_FOR",
    ];
    for body in bodies {
        stmts(body);
    }
    let l = lib("PROGRAM P IF a THEN x := 1; END_IF END_PROGRAM FUNCTION_BLOCK F WHILE a DO END_WHILE END_FUNCTION_BLOCK");
    assert_eq!(l.pous.len(), 2);
}

#[test]
fn a_compound_statement_may_end_a_case_arm_without_a_semicolon() {
    let s = stmts("CASE x OF 1: IF a THEN y := 1; END_IF 2, 3: y := 2; Red: FOR i := 1 TO 2 DO END_FOR ELSE y := 0; END_CASE");
    let StmtKind::Case { arms, .. } = &s[0].kind else {
        panic!("not a CASE")
    };
    assert_eq!(arms.len(), 3);
}

#[test]
fn a_compound_statement_followed_by_another_statement_needs_its_semicolon() {
    let d = stmts_err("IF a THEN x := 1; END_IF\ny := 2;");
    assert_eq!(d.message, "expected ';' after END_IF, found 'y'");
    let d = stmts_err("WHILE a DO END_WHILE IF b THEN END_IF");
    assert_eq!(d.message, "expected ';' after END_WHILE, found 'IF'");
}

#[test]
fn a_simple_statement_at_the_end_of_a_body_still_needs_its_semicolon() {
    let d = stmts_err("IF a THEN x := 1 END_IF;");
    assert_eq!(
        d.message,
        "expected ';' after the assignment, found 'END_IF'"
    );
    let d = stmts_err("inst(IN := TRUE)");
    assert_eq!(
        d.message,
        "expected ';' after the call, found the end of the text"
    );
}

// ---- The two CODESYS failures this crate was written for ----

#[test]
fn an_action_body_ending_in_end_if_without_a_semicolon_parses() {
    // As CODESYS exports an SFC action body.
    let body = "counter := counter + 1;\r\nIF counter >= limit THEN\r\n\tcounter := 0;\r\n\tdone := TRUE;\r\nEND_IF";
    let s = stmts(body);
    assert_eq!(s.len(), 2);
    let StmtKind::If { arms, .. } = &s[1].kind else {
        panic!("not an IF")
    };
    assert_eq!(arms[0].1.len(), 2);
}

#[test]
fn a_body_that_calls_a_ton_instance_and_then_reads_its_output_parses() {
    let s = stmts(
        "t(IN := x, PT := T#2s);\nIF t.Q THEN\n  lamp := NOT lamp;\nEND_IF;\ny := t.ET > T#1s;",
    );
    let StmtKind::Call(call) = &s[0].kind else {
        panic!("not a call")
    };
    assert_eq!(show(&call.callee), "t");
    assert_eq!(
        call.args.iter().map(show_arg).collect::<Vec<_>>(),
        ["IN := x", "PT := 2000000000ns"]
    );
    let StmtKind::If { arms, .. } = &s[1].kind else {
        panic!("not an IF")
    };
    assert_eq!(show(&arms[0].0), "t.Q");
    let StmtKind::Assign { value, .. } = &s[2].kind else {
        panic!("not an assignment")
    };
    assert_eq!(show(value), "(t.ET > 1000000000ns)");
}

#[test]
fn the_vendors_missing_semicolon_is_written_in_for_an_export() {
    let body = "IF a THEN\n  b := 1;\nEND_IF  (* done *)\n";
    let done = crate::parse::terminated(body).expect("lexes");
    assert_eq!(done, "IF a THEN\n  b := 1;\nEND_IF;  (* done *)\n");
    assert!(crate::parse::parse_statements(&done).is_ok());
    assert_eq!(
        crate::parse::terminated("x := 1; // end").expect("lexes"),
        "x := 1; // end"
    );
}
