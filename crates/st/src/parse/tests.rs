use proptest::prelude::*;

use super::{
    parse_expression, parse_library, parse_statements, MAX_DEPTH, MAX_NESTING, MAX_TEXT, MAX_TOKENS,
};
use crate::ast::{
    Arg, BinOp, CaseLabel, Expr, ExprKind, Init, Library, Literal, PouKind, Section, Stmt,
    StmtKind, TypeDeclKind, TypeRef, UnOp,
};
use crate::error::{Diagnostic, Source};

fn located(text: &str, d: Diagnostic) -> String {
    Source {
        origin: "test.st",
        text,
    }
    .error(d)
    .to_string()
}

fn lib(text: &str) -> Library {
    parse_library(text).unwrap_or_else(|d| panic!("{}", located(text, d)))
}

fn stmts(text: &str) -> Vec<Stmt> {
    parse_statements(text).unwrap_or_else(|d| panic!("{}", located(text, d)))
}

fn expr(text: &str) -> Expr {
    parse_expression(text).unwrap_or_else(|d| panic!("{}", located(text, d)))
}

fn lib_err(text: &str) -> Diagnostic {
    parse_library(text).expect_err("the text should be refused")
}

fn stmts_err(text: &str) -> Diagnostic {
    parse_statements(text).expect_err("the body should be refused")
}

fn expr_err(text: &str) -> Diagnostic {
    parse_expression(text).expect_err("the expression should be refused")
}

/// The expression fully parenthesised, to compare trees.
fn show(e: &Expr) -> String {
    let list = |items: Vec<String>| items.join(", ");
    match &e.kind {
        ExprKind::Lit(l) => show_lit(l),
        ExprKind::Name(n) => n.text.clone(),
        ExprKind::Member(base, m) => format!("{}.{}", show(base), m.text),
        ExprKind::Index(base, ix) => {
            format!("{}[{}]", show(base), list(ix.iter().map(show).collect()))
        }
        ExprKind::Call(c) => format!(
            "{}({})",
            show(&c.callee),
            list(c.args.iter().map(show_arg).collect())
        ),
        ExprKind::Unary(UnOp::Neg, x) => format!("(-{})", show(x)),
        ExprKind::Unary(UnOp::Not, x) => format!("(NOT {})", show(x)),
        ExprKind::Binary(op, l, r) => format!("({} {} {})", show(l), op.symbol(), show(r)),
    }
}

fn show_lit(l: &Literal) -> String {
    match l {
        Literal::Int { value, ty: None } => value.to_string(),
        Literal::Int { value, ty: Some(t) } => format!("{}#{value}", t.text),
        Literal::Real { value, ty: None } => format!("{value:?}"),
        Literal::Real { value, ty: Some(t) } => format!("{}#{value:?}", t.text),
        Literal::Bool(b) => b.to_string().to_uppercase(),
        Literal::Time(ns) => format!("{ns}ns"),
        Literal::String(s) => format!("'{}'", String::from_utf8_lossy(s)),
        Literal::Enum { ty, value } => format!("{}#{}", ty.text, value.text),
    }
}

fn show_arg(a: &Arg) -> String {
    match a {
        Arg::Positional(e) => show(e),
        Arg::Input(n, e) => format!("{} := {}", n.text, show(e)),
        Arg::Output {
            name,
            target,
            negated,
        } => format!(
            "{}{} => {}",
            if *negated { "NOT " } else { "" },
            name.text,
            show(target)
        ),
    }
}

fn lit(text: &str) -> Literal {
    match expr(text).kind {
        ExprKind::Lit(l) => l,
        other => panic!("{text} is not a literal: {other:?}"),
    }
}

/// One program using most of the syntax: the seed of the corruption test, and the unit of the
/// large file.
const SAMPLE: &str = r#"
TYPE
    Color : (Red, Green := 5, Blue) := Green;
    Level : INT (0..100) := 10;
    Pair : STRUCT
        a : INT := 1;
        b : ARRAY [1..3] OF REAL := [1.0, 2(0.5)];
    END_STRUCT;
END_TYPE

FUNCTION Clamp : INT
VAR_INPUT x, lo, hi : INT; END_VAR
IF x < lo THEN Clamp := lo; ELSIF x > hi THEN Clamp := hi; ELSE Clamp := x; END_IF
END_FUNCTION

FUNCTION_BLOCK Blink
VAR_INPUT enable : BOOL; END_VAR
VAR_OUTPUT q : BOOL; END_VAR
VAR t : TON := (PT := T#500ms); n : DINT; s : STRING[20] := 'a$'b$N'; END_VAR
t(IN := enable AND NOT t.Q, PT := T#1s500ms, Q => q);
CASE n MOD 4 OF
    0, 1: n := n + 1;
    2..3: n := -(n ** 2) + 16#FF;
ELSE
    n := 0;
END_CASE;
END_FUNCTION_BLOCK

PROGRAM Main
VAR RETAIN
    count AT %MW10 : INT := -5;
    grid : ARRAY [0..1, 0..2] OF INT := [6(0)];
    c : Color := Color#Blue;
    b : Blink;
    x : LREAL := LREAL#-2.0E3;
END_VAR
FOR count := 1 TO 10 BY 2 DO
    WHILE grid[0, count MOD 3] < 5 DO grid[0, count MOD 3] := grid[0, count MOD 3] + 1; END_WHILE;
    REPEAT x := x / 2.0; UNTIL x < 1.0 END_REPEAT;
    IF count = 7 THEN EXIT; END_IF
END_FOR;
b(enable := TRUE);
count := Clamp(count, 0, 100);
END_PROGRAM

CONFIGURATION Plant
    RESOURCE Cpu ON PLC
        TASK Fast (INTERVAL := T#20ms, PRIORITY := 1);
        PROGRAM Inst WITH Fast : Main;
    END_RESOURCE
END_CONFIGURATION
"#;

#[test]
fn the_sample_program_is_read_whole() {
    let l = lib(SAMPLE);
    assert_eq!(l.types.len(), 3);
    assert_eq!(l.pous.len(), 3);
    assert_eq!(l.configs.len(), 1);
}

// ---- Types ----

#[test]
fn a_struct_type_with_initial_values_is_read() {
    let l = lib("TYPE P : STRUCT a, b : INT := 1; s : STRING(8); END_STRUCT; END_TYPE");
    let TypeDeclKind::Struct(members) = &l.types[0].kind else {
        panic!("not a struct")
    };
    assert_eq!(members.len(), 2);
    assert_eq!(members[0].names.len(), 2);
    assert!(matches!(members[0].init, Some(Init::Expr(_))));
    assert!(matches!(
        &members[1].ty,
        TypeRef::String { len: Some(_), .. }
    ));
}

#[test]
fn an_enum_with_explicit_values_and_an_initial_value_is_read() {
    let l = lib("TYPE Color : (Red := 1, Green, Blue := -3) := Green; END_TYPE");
    let TypeDeclKind::Enum { values, init } = &l.types[0].kind else {
        panic!("not an enum")
    };
    assert_eq!(values.len(), 3);
    assert!(values[0].1.is_some() && values[1].1.is_none());
    assert_eq!(init.as_ref().map(|i| i.text.as_str()), Some("Green"));
}

#[test]
fn an_enum_with_a_base_type_is_read_in_both_vendors_spellings() {
    for text in [
        "TYPE E : (A, B) INT; END_TYPE",
        "TYPE E : INT (A := 1, B := 2) := B; END_TYPE",
        "TYPE E : DINT (A); END_TYPE",
    ] {
        assert!(
            matches!(lib(text).types[0].kind, TypeDeclKind::Enum { .. }),
            "{text}"
        );
    }
}

#[test]
fn an_alias_a_subrange_and_an_array_type_are_read() {
    let l = lib(
        "TYPE Speed : INT := 10; Level : INT (0..100) := 5; Grid : ARRAY [1..3, 0..1] OF INT := [1, 2, 3(0)]; END_TYPE",
    );
    assert!(matches!(
        &l.types[0].kind,
        TypeDeclKind::Alias {
            range: None,
            init: Some(_),
            ..
        }
    ));
    assert!(matches!(
        &l.types[1].kind,
        TypeDeclKind::Alias {
            range: Some(_),
            init: Some(_),
            ..
        }
    ));
    let TypeDeclKind::Alias {
        ty: TypeRef::Array { dims, .. },
        init: Some(Init::Array(elems, _)),
        ..
    } = &l.types[2].kind
    else {
        panic!("not an array alias")
    };
    assert_eq!(dims.len(), 2);
    assert_eq!(elems.len(), 3);
    assert!(elems[2].0.is_some());
}

#[test]
fn the_semicolon_before_end_type_may_be_left_out() {
    let l = lib("TYPE P :\nSTRUCT\n  a : INT;\nEND_STRUCT\nEND_TYPE\nTYPE A : INT END_TYPE");
    assert_eq!(l.types.len(), 2);
}

#[test]
fn two_type_declarations_need_a_semicolon_between_them() {
    let d = lib_err("TYPE A : INT B : INT; END_TYPE");
    assert_eq!(
        d.message,
        "expected ';' after the type declaration, found 'B'"
    );
}

// ---- POUs and variables ----

#[test]
fn a_function_a_function_block_and_a_program_are_read() {
    let l = lib(
        "FUNCTION F : STRING[10] F := 'x'; END_FUNCTION FUNCTION_BLOCK B END_FUNCTION_BLOCK PROGRAM P ; END_PROGRAM",
    );
    assert!(matches!(
        &l.pous[0].kind,
        PouKind::Function(TypeRef::String { len: Some(_), .. })
    ));
    assert!(matches!(l.pous[1].kind, PouKind::FunctionBlock));
    assert!(l.pous[1].body.is_empty());
    assert!(matches!(l.pous[2].kind, PouKind::Program));
    assert!(matches!(l.pous[2].body[0].kind, StmtKind::Empty));
}

#[test]
fn var_blocks_of_every_section_with_their_qualifiers_are_read() {
    let l = lib("PROGRAM P
         VAR a : INT; END_VAR
         VAR_INPUT b : INT; END_VAR
         VAR_OUTPUT c : INT; END_VAR
         VAR_IN_OUT d : INT; END_VAR
         VAR_TEMP e : INT; END_VAR
         VAR_EXTERNAL f : INT; END_VAR
         VAR_GLOBAL g : INT; END_VAR
         VAR CONSTANT k : INT := 1; END_VAR
         VAR RETAIN r : INT; END_VAR
         VAR PERSISTENT pr : INT; END_VAR
         VAR NON_RETAIN nr : INT; END_VAR
         END_PROGRAM");
    let blocks = &l.pous[0].vars;
    let sections: Vec<Section> = blocks.iter().map(|b| b.section).collect();
    assert_eq!(
        &sections[..7],
        &[
            Section::Var,
            Section::Input,
            Section::Output,
            Section::InOut,
            Section::Temp,
            Section::External,
            Section::Global
        ]
    );
    assert!(blocks[7].constant && !blocks[7].retain);
    assert!(blocks[8].retain && blocks[9].retain && !blocks[10].retain);
}

#[test]
fn retain_and_non_retain_together_are_refused() {
    let d = lib_err("PROGRAM P VAR RETAIN NON_RETAIN a : INT; END_VAR END_PROGRAM");
    assert!(
        d.message.contains("RETAIN or NON_RETAIN, not both"),
        "{}",
        d.message
    );
}

#[test]
fn declarations_with_addresses_strings_arrays_and_initial_values_are_read() {
    let l = lib("PROGRAM P VAR
           a, b AT %IX0.0 : BOOL := TRUE;
           x AT %QW1 : INT;
           s : STRING[20] := 'abc';
           s2 : STRING(20);
           s3 : STRING;
           m : ARRAY [1..3, 0..1] OF INT := [1, 2, 3(0)];
           n : ARRAY [1..2] OF ARRAY [1..2] OF INT := [[1, 2], [3, 4]];
           p : Pair := (a := 1, b := [1.0, 2.0, 3.0]);
         END_VAR END_PROGRAM");
    let decls = &l.pous[0].vars[0].decls;
    assert_eq!(decls[0].names.len(), 2);
    assert_eq!(
        decls[0].at.as_ref().map(|a| a.text.as_str()),
        Some("%IX0.0")
    );
    assert_eq!(decls[1].at.as_ref().map(|a| a.text.as_str()), Some("%QW1"));
    assert!(matches!(decls[4].ty, TypeRef::String { len: None, .. }));
    let Some(Init::Array(elems, _)) = &decls[5].init else {
        panic!("not an array init")
    };
    let (Some(count), Init::Expr(zero)) = &elems[2] else {
        panic!("not a repeated element")
    };
    assert_eq!(
        (show(count), show(zero)),
        ("3".to_string(), "0".to_string())
    );
    assert!(
        matches!(&decls[6].ty, TypeRef::Array { elem, .. } if matches!(**elem, TypeRef::Array { .. }))
    );
    let Some(Init::Struct(members, _)) = &decls[7].init else {
        panic!("not a struct init")
    };
    assert!(matches!(members[1].1, Init::Array(..)));
}

#[test]
fn a_function_block_instance_with_input_values_is_read() {
    let l = lib("PROGRAM P VAR t : TON := (PT := T#1s); END_VAR END_PROGRAM");
    let Some(Init::Struct(members, _)) = &l.pous[0].vars[0].decls[0].init else {
        panic!("not an instance init")
    };
    assert_eq!(members[0].0.text, "PT");
}

#[test]
fn a_function_without_a_return_type_is_refused() {
    let d = lib_err("FUNCTION F VAR_INPUT x : INT; END_VAR END_FUNCTION");
    assert_eq!(
        d.message,
        "expected ':' and the return type after the FUNCTION's name, found 'VAR_INPUT'"
    );
}

#[test]
fn the_end_keyword_must_match_the_pou() {
    let d = lib_err("PROGRAM Main x := 1; END_FUNCTION_BLOCK");
    assert_eq!(
        d.message,
        "expected END_PROGRAM to close PROGRAM Main, found 'END_FUNCTION_BLOCK'"
    );
}

#[test]
fn a_subrange_in_a_variable_declaration_is_refused_with_the_way_to_declare_it() {
    let d = lib_err("PROGRAM P VAR x : INT (0..10); END_VAR END_PROGRAM");
    assert!(
        d.message.contains("TYPE Level : INT (0..100)"),
        "{}",
        d.message
    );
}

#[test]
fn an_anonymous_enumeration_in_a_declaration_is_refused() {
    let d = lib_err("PROGRAM P VAR x : (A, B); END_VAR END_PROGRAM");
    assert!(d
        .message
        .starts_with("an enumeration must be declared as a type"));
}

// ---- Configurations ----

#[test]
fn a_configuration_with_a_resource_tasks_and_programs_is_read() {
    let l = lib("CONFIGURATION C
           VAR_GLOBAL g : INT := 3; END_VAR
           RESOURCE R ON PLC
             VAR_GLOBAL h AT %QX0.0 : BOOL; END_VAR
             TASK Fast (INTERVAL := T#20ms, PRIORITY := 1);
             TASK Slow (PRIORITY := 2);
             PROGRAM A WITH Fast : Main;
             PROGRAM B : Other;
           END_RESOURCE
         END_CONFIGURATION");
    let c = &l.configs[0];
    assert_eq!(c.tasks.len(), 2);
    assert_eq!(
        c.tasks[0].interval.as_ref().map(show),
        Some("20000000ns".into())
    );
    assert!(c.tasks[1].interval.is_none());
    assert_eq!(
        c.programs[0].task.as_ref().map(|t| t.text.as_str()),
        Some("Fast")
    );
    assert_eq!(c.programs[1].program.text, "Other");
    assert!(c.programs[1].task.is_none());
    assert_eq!(c.globals.len(), 2);
}

#[test]
fn a_configuration_without_a_resource_is_read() {
    let l =
        lib("CONFIGURATION C TASK T (INTERVAL := T#1s); PROGRAM I WITH T : P; END_CONFIGURATION");
    assert_eq!(l.configs[0].tasks.len(), 1);
    assert_eq!(l.configs[0].programs.len(), 1);
}

#[test]
fn an_event_task_is_refused() {
    let d = lib_err("CONFIGURATION C TASK T (SINGLE := trig); END_CONFIGURATION");
    assert!(d
        .message
        .starts_with("event tasks (SINGLE) are not supported"));
}

#[test]
fn var_global_outside_a_configuration_is_refused() {
    let d = lib_err("VAR_GLOBAL g : INT; END_VAR");
    assert!(d
        .message
        .starts_with("VAR_GLOBAL outside a CONFIGURATION is not supported"));
}

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

// ---- Expressions ----

#[test]
fn the_precedence_table_of_iec_61131_3_is_followed() {
    let cases = [
        ("a OR b XOR c", "(a OR (b XOR c))"),
        ("a XOR b AND c", "(a XOR (b AND c))"),
        ("a AND b = c", "(a AND (b = c))"),
        ("a & b <> c", "(a AND (b <> c))"),
        ("a = b < c", "(a = (b < c))"),
        ("a <> b >= c", "(a <> (b >= c))"),
        ("a < b + c", "(a < (b + c))"),
        ("a <= b - c", "(a <= (b - c))"),
        ("a + b * c", "(a + (b * c))"),
        ("a - b / c", "(a - (b / c))"),
        ("a + b MOD c", "(a + (b MOD c))"),
        ("a * b ** c", "(a * (b ** c))"),
        ("a ** b * c", "((a ** b) * c)"),
        ("-a * b", "((-a) * b)"),
        ("NOT a AND b", "((NOT a) AND b)"),
        ("NOT a = b", "((NOT a) = b)"),
        ("(a OR b) AND c", "((a OR b) AND c)"),
        ("F(a + b) * 2", "(F((a + b)) * 2)"),
        ("a > b OR c < d AND e", "((a > b) OR ((c < d) AND e))"),
    ];
    for (text, tree) in cases {
        assert_eq!(show(&expr(text)), tree, "{text}");
    }
}

#[test]
fn binary_operators_are_left_associative_power_included() {
    let cases = [
        ("a - b - c", "((a - b) - c)"),
        ("a / b * c", "((a / b) * c)"),
        ("a OR b OR c", "((a OR b) OR c)"),
        ("a < b < c", "((a < b) < c)"),
        ("2 ** 3 ** 2", "((2 ** 3) ** 2)"),
    ];
    for (text, tree) in cases {
        assert_eq!(show(&expr(text)), tree, "{text}");
    }
}

#[test]
fn a_unary_operator_before_an_operand_of_power_is_refused_as_ambiguous() {
    for text in ["-a ** 2", "NOT a ** b", "a ** -b ** c", "+a ** 2"] {
        let d = expr_err(text);
        assert!(
            d.message
                .starts_with("a unary operator before an operand of '**' is ambiguous"),
            "{text}: {}",
            d.message
        );
    }
    assert_eq!(expr_err("x + -a ** 2").pos, 4);
}

#[test]
fn power_with_a_parenthesised_or_a_last_negative_operand_is_accepted() {
    assert_eq!(show(&expr("(-a) ** 2")), "((-a) ** 2)");
    assert_eq!(show(&expr("-(a ** 2)")), "(-(a ** 2))");
    assert_eq!(show(&expr("a ** -b")), "(a ** (-b))");
}

#[test]
fn repeated_unary_operators_and_unary_plus_are_accepted() {
    assert_eq!(show(&expr("NOT NOT a")), "(NOT (NOT a))");
    assert_eq!(show(&expr("- -a")), "(-(-a))");
    assert_eq!(show(&expr("+a - +b")), "(a - b)");
    assert_eq!(show(&expr("a - -1")), "(a - (-1))");
}

#[test]
fn member_index_and_call_chains_are_read() {
    assert_eq!(show(&expr("a.b[1][2].c")), "a.b[1][2].c");
    assert_eq!(show(&expr("F(G(x), y[i])")), "F(G(x), y[i])");
    assert_eq!(
        show(&expr("LIMIT(MN := 0, IN := x, MX := 10)")),
        "LIMIT(MN := 0, IN := x, MX := 10)"
    );
}

#[test]
fn the_expression_position_of_a_binary_operation_is_its_operator() {
    let e = expr("a + b");
    assert_eq!(e.pos, 2);
    let ExprKind::Binary(BinOp::Add, l, r) = &e.kind else {
        panic!("not an addition")
    };
    assert_eq!((l.pos, r.pos), (0, 4));
}

#[test]
fn an_expression_alone_must_be_whole() {
    assert_eq!(
        expr_err("a b").message,
        "expected an operator or the end of the text, found 'b'"
    );
    assert!(expr_err("").message.starts_with("the expression is empty"));
    assert_eq!(
        expr_err("(a + b").message,
        "expected ')' to close the parenthesis, found the end of the text"
    );
    assert_eq!(
        expr_err("a +").message,
        "expected an expression, found the end of the text"
    );
}

// ---- Literals ----

#[test]
fn integers_with_underscores_and_bases_are_read() {
    for (text, value) in [
        ("1_000", 1000),
        ("2#1010_1010", 0xaa),
        ("8#17", 15),
        ("16#FF", 255),
        ("16#ff", 255),
        ("0", 0),
    ] {
        assert!(
            matches!(lit(text), Literal::Int { value: v, ty: None } if v == value),
            "{text}"
        );
    }
    for text in ["1__0", "1_", "16#", "2#102", "10#5", "12ab"] {
        assert!(parse_expression(text).is_err(), "{text}");
    }
}

#[test]
fn typed_literals_are_read() {
    let cases = [
        ("INT#-5", "INT#-5"),
        ("WORD#16#8001", "WORD#32769"),
        ("DINT#100", "DINT#100"),
        ("UINT#5", "UINT#5"),
        ("BOOL#1", "TRUE"),
        ("BOOL#0", "FALSE"),
        ("BOOL#TRUE", "TRUE"),
        ("bool#false", "FALSE"),
        ("REAL#1.5", "REAL#1.5"),
        ("REAL#5", "REAL#5.0"),
        ("LREAL#-2.0E3", "LREAL#-2000.0"),
        ("Color#Red", "Color#Red"),
        ("STRING#'a$Nb'", "'a\nb'"),
    ];
    for (text, shown) in cases {
        assert_eq!(show(&expr(text)), shown, "{text}");
    }
    for text in ["BOOL#2", "INT#TRUE", "INT#-16#FF", "INT# 5", "INT#'a'"] {
        assert!(parse_expression(text).is_err(), "{text}");
    }
}

#[test]
fn reals_need_a_point_and_a_fraction() {
    assert!(matches!(lit("1.5"), Literal::Real { value, .. } if value == 1.5));
    assert!(matches!(lit("1.0E-3"), Literal::Real { value, .. } if value == 1.0E-3));
    assert!(matches!(lit("2.5e2"), Literal::Real { value, .. } if value == 250.0));
    assert!(matches!(lit("1_000.5"), Literal::Real { value, .. } if value == 1000.5));
    let d = expr_err("2e5");
    assert_eq!(
        d.message,
        "a REAL literal needs a '.' and a fraction: write 2.0E…"
    );
    assert!(parse_expression("1.").is_err());
    assert!(parse_expression("1.0E999").is_err());
}

#[test]
fn durations_are_read_in_nanoseconds() {
    const MS: i64 = 1_000_000;
    let cases = [
        ("T#1s500ms", 1500 * MS),
        ("TIME#20ms", 20 * MS),
        ("t#-5s", -5000 * MS),
        ("T#1.5s", 1500 * MS),
        ("T#1h2m3s4ms", (3600 + 120 + 3) * 1000 * MS + 4 * MS),
        ("T#100us", 100_000),
        ("T#7ns", 7),
        ("T#1d_2h", 26 * 3600 * 1000 * MS),
        ("T#90m", 90 * 60 * 1000 * MS),
        ("T#1H30M", 90 * 60 * 1000 * MS),
        ("LT#1.25ms", 1_250_000),
        ("LTIME#+2s", 2000 * MS),
        ("T#0.000000001s", 1),
    ];
    for (text, ns) in cases {
        assert!(matches!(lit(text), Literal::Time(v) if v == ns), "{text}");
    }
}

#[test]
fn malformed_durations_are_refused() {
    let cases = [
        ("T#1m1h", "must go from the largest to the smallest"),
        ("T#1s1s", "must go from the largest to the smallest"),
        ("T#1h70m", "must be less than 60"),
        ("T#1.5h30m", "only the last unit"),
        ("T#5x", "is not a unit of duration"),
        ("T#5", "is not a unit of duration"),
        ("T#0.0000000001s", "finer than a nanosecond"),
        ("T#", "expected a duration after 'T#'"),
        ("T#300000d", "too long"),
    ];
    for (text, part) in cases {
        let d = expr_err(text);
        assert!(d.message.contains(part), "{text}: {}", d.message);
    }
}

#[test]
fn strings_with_escapes_are_read() {
    let Literal::String(bytes) = lit("'a$$b$'c$L$N$P$R$T$0A$41\"'") else {
        panic!("not a string")
    };
    assert_eq!(bytes, b"a$b'c\n\n\x0c\r\t\nA\"");
    assert!(matches!(lit("''"), Literal::String(b) if b.is_empty()));
    assert!(matches!(lit("'Grüße'"), Literal::String(b) if b == "Grüße".as_bytes()));
    assert!(expr_err("'a$Qb'").message.contains("is not an escape"));
    assert!(expr_err("'abc")
        .message
        .starts_with("the string that starts here is never closed"));
    assert!(expr_err("'ab\ncd'")
        .message
        .contains("not closed on its line"));
}

#[test]
fn true_and_false_in_any_case_are_bools() {
    assert!(matches!(lit("TRUE"), Literal::Bool(true)));
    assert!(matches!(lit("false"), Literal::Bool(false)));
    assert!(matches!(lit("True"), Literal::Bool(true)));
}

// ---- Lexical ----

#[test]
fn comments_of_three_kinds_and_pragmas_are_skipped() {
    let s = stmts(
        "(* a comment *) x := 1; // to the end of the line\n/* another\n one */ {attribute 'hide'} y := (* inside *) 2;(**)",
    );
    assert_eq!(s.len(), 2);
}

#[test]
fn comments_do_not_nest() {
    let d = stmts_err("(* outer (* inner *) still outer? *) x := 1;");
    assert_eq!(
        d.message,
        "expected ':=' (an assignment) or '(' (a call) after 'still', found 'outer'"
    );
}

#[test]
fn an_unclosed_comment_or_pragma_is_reported_where_it_starts() {
    let d = stmts_err("x := 1; (* forever");
    assert_eq!(d.pos, 8);
    assert_eq!(
        d.message,
        "the comment that starts here is never closed: add '*)'"
    );
    let d = stmts_err("x := 1; {pragma");
    assert_eq!(
        d.message,
        "the pragma that starts here is never closed: add '}'"
    );
}

#[test]
fn keywords_and_names_are_case_insensitive() {
    let l = lib("program p var X : int; end_var if x > 0 Then x := 0; End_If; END_program");
    assert_eq!(l.pous[0].body.len(), 1);
}

#[test]
fn names_with_double_or_trailing_underscores_are_refused_as_matiec_refuses_them() {
    for text in ["a__b := 1;", "a_ := 1;", "__a := 1;", "_ := 1;"] {
        let d = stmts_err(text);
        assert!(d.message.contains("is not a name"), "{text}: {}", d.message);
    }
    assert_eq!(stmts("_a1 := 1; b_2_c := 2;").len(), 2);
}

#[test]
fn a_byte_order_mark_and_crlf_line_ends_are_accepted() {
    assert_eq!(stmts("\u{feff}x := 1;\r\ny := 2;\r\n").len(), 2);
}

#[test]
fn an_unexpected_character_is_named() {
    let d = stmts_err("x := 1 ! 2;");
    assert_eq!(d.message, "unexpected character '!'");
    assert_eq!(d.pos, 7);
}

// ---- Refused by name ----

#[test]
fn an_instruction_list_body_is_refused_by_name() {
    let il = "PROGRAM P\nVAR a, b : BOOL; END_VAR\n  LD a\n  ANDN b\n  ST c\nEND_PROGRAM";
    let d = lib_err(il);
    assert!(d
        .message
        .starts_with("Instruction List (IL) is not supported"));
    assert_eq!(
        Source {
            origin: "t",
            text: il
        }
        .locate(d.pos),
        (3, 3)
    );
    let d = stmts_err("start: LD %IX0.0\nST q");
    assert!(d
        .message
        .starts_with("Instruction List (IL) is not supported"));
    let d = stmts_err("x := 1;\nRET\n");
    assert!(d
        .message
        .starts_with("Instruction List (IL) is not supported"));
    // A variable that shares a mnemonic's name is still a variable.
    assert_eq!(stmts("LD := 1; ST := LD; S(1);").len(), 3);
}

#[test]
fn sfc_in_text_form_is_refused_by_name() {
    for body in [
        "INITIAL_STEP s0: END_STEP",
        "STEP s1: a(N); END_STEP",
        "TRANSITION FROM s0 TO s1 := x; END_TRANSITION",
        "ACTION a: x := 1; END_ACTION",
    ] {
        let d = stmts_err(body);
        assert!(
            d.message
                .starts_with("Sequential Function Chart (SFC) in text form"),
            "{body}: {}",
            d.message
        );
    }
    // As names, the words are free.
    assert_eq!(stmts("step := step + 1; action := transition;").len(), 2);
}

#[test]
fn pointers_and_references_are_refused_by_name() {
    let cases = [
        "PROGRAM P VAR p : REF_TO INT; END_VAR END_PROGRAM",
        "PROGRAM P VAR p : POINTER TO INT; END_VAR END_PROGRAM",
        "PROGRAM P p^ := 1; END_PROGRAM",
        "PROGRAM P p := ADR(x); END_PROGRAM",
        "PROGRAM P p := REF(x); END_PROGRAM",
    ];
    for text in cases {
        let d = lib_err(text);
        assert!(
            d.message.starts_with("pointers and references"),
            "{text}: {}",
            d.message
        );
    }
}

#[test]
fn methods_and_interfaces_are_refused_by_name() {
    let cases = [
        "FUNCTION_BLOCK F METHOD M : INT END_METHOD END_FUNCTION_BLOCK",
        "FUNCTION_BLOCK F EXTENDS G END_FUNCTION_BLOCK",
        "FUNCTION_BLOCK F IMPLEMENTS I END_FUNCTION_BLOCK",
        "INTERFACE I END_INTERFACE",
        "FUNCTION_BLOCK F x := 1; PROPERTY P : INT END_PROPERTY END_FUNCTION_BLOCK",
        "CLASS C END_CLASS",
        "TYPE S EXTENDS T : STRUCT END_STRUCT END_TYPE",
    ];
    for text in cases {
        let d = lib_err(text);
        assert!(
            d.message.starts_with("object-oriented extensions"),
            "{text}: {}",
            d.message
        );
    }
}

#[test]
fn wstring_and_the_date_types_are_refused_by_name() {
    for text in [
        "PROGRAM P VAR s : WSTRING; END_VAR END_PROGRAM",
        "PROGRAM P s := \"wide\"; END_PROGRAM",
        "PROGRAM P s := WSTRING#'x'; END_PROGRAM",
    ] {
        assert!(lib_err(text).message.starts_with("WSTRING"), "{text}");
    }
    for ty in ["DATE", "TOD", "TIME_OF_DAY", "DT", "DATE_AND_TIME", "ldt"] {
        let text = format!("PROGRAM P VAR d : {ty}; END_VAR END_PROGRAM");
        assert!(
            lib_err(&text).message.starts_with("DATE, TIME_OF_DAY"),
            "{ty}"
        );
    }
    for literal in [
        "D#2024-01-01",
        "DATE#2024-01-01",
        "TOD#12:00:00",
        "DT#2024-01-01-12:00",
        "TIME_OF_DAY#1:2:3",
    ] {
        let d = expr_err(literal);
        assert!(
            d.message.starts_with("DATE, TIME_OF_DAY"),
            "{literal}: {}",
            d.message
        );
        assert_eq!(d.pos, 0);
    }
}

#[test]
fn a_variable_named_dt_or_date_is_a_variable() {
    let l = lib(
        "PROGRAM P VAR dt : TIME; date : INT; END_VAR dt := dt + T#1ms; date := 1; END_PROGRAM",
    );
    assert_eq!(l.pous[0].body.len(), 2);
}

#[test]
fn jumps_labels_and_continue_are_refused_by_name() {
    assert!(stmts_err("JMP done;")
        .message
        .starts_with("JMP and labels are not supported"));
    assert!(stmts_err("x := 1; done: x := 2;")
        .message
        .starts_with("JMP and labels are not supported"));
    assert!(stmts_err("WHILE a DO CONTINUE; END_WHILE")
        .message
        .starts_with("CONTINUE is not supported"));
}

#[test]
fn other_refusals_name_the_construct() {
    let cases = [
        (
            "PROGRAM P VAR_ACCESS a : x : INT; END_VAR END_PROGRAM",
            "VAR_ACCESS and VAR_CONFIG",
        ),
        (
            "FUNCTION_BLOCK F VAR_INPUT x : BOOL R_EDGE; END_VAR END_FUNCTION_BLOCK",
            "R_EDGE and F_EDGE",
        ),
        (
            "PROGRAM P VAR a : ARRAY [*] OF INT; END_VAR END_PROGRAM",
            "ARRAY [*]",
        ),
        (
            "PROGRAM P x := %IX0.0; END_PROGRAM",
            "a direct address cannot be used",
        ),
        ("PROGRAM P x := y.3; END_PROGRAM", "bit access (x.3)"),
        (
            "PROGRAM P VAR AT %IX0.0 : BOOL; END_VAR END_PROGRAM",
            "a located variable needs a name",
        ),
        (
            "PROGRAM P VAR x AT %I* : BOOL; END_VAR END_PROGRAM",
            "an address left open",
        ),
        (
            "PROGRAM P x ?= y; END_PROGRAM",
            "the assignment attempt '?='",
        ),
        (
            "CONFIGURATION C PROGRAM I : P (a := b); END_CONFIGURATION",
            "connecting a program instance's variables",
        ),
    ];
    for (text, part) in cases {
        let d = lib_err(text);
        assert!(d.message.contains(part), "{text}: {}", d.message);
    }
}

// ---- Errors ----

#[test]
fn an_error_in_the_middle_of_a_file_is_located_at_its_line_and_column() {
    let text = "PROGRAM Main\nVAR\n  x : INT;\nEND_VAR\nx := 1;\nIF x > 0 THEN\n  x := x +* 2;\nEND_IF;\nEND_PROGRAM\n";
    let d = lib_err(text);
    assert_eq!(d.message, "expected an expression, found '*'");
    let e = Source {
        origin: "main.st",
        text,
    }
    .error(d);
    assert_eq!((e.line, e.column), (7, 11));
    assert_eq!(
        e.to_string(),
        "main.st:7:11: expected an expression, found '*'"
    );
}

#[test]
fn a_column_counts_characters_not_bytes() {
    let text = "x := 'äöü'; y := ;";
    let d = stmts_err(text);
    assert_eq!(Source { origin: "t", text }.locate(d.pos), (1, 18));
}

#[test]
fn errors_come_in_the_order_of_the_text() {
    // A syntax error before a lexical one is the one reported.
    let d = stmts_err("x := ;\ny := 'unclosed");
    assert_eq!(d.message, "expected an expression, found ';'");
    let d = stmts_err("x := 1;\ny := 'unclosed");
    assert!(d
        .message
        .starts_with("the string that starts here is never closed"));
    assert_eq!(d.pos, 13);
}

#[test]
fn a_long_token_is_shortened_in_a_message() {
    let long = "a".repeat(100);
    let d = stmts_err(&format!("x := 1 {long} := 2;"));
    assert_eq!(
        d.message,
        format!(
            "expected ';' after the assignment, found '{}…'",
            "a".repeat(32)
        )
    );
}

// ---- Bounds ----

fn nested_ifs(n: usize) -> String {
    "IF a THEN ".repeat(n) + "x := 1;" + &" END_IF;".repeat(n)
}

#[test]
fn nesting_at_the_limit_is_accepted_and_past_it_refused_naming_the_limit() {
    stmts(&nested_ifs(MAX_NESTING));
    let d = stmts_err(&nested_ifs(MAX_NESTING + 1));
    assert!(
        d.message
            .contains(&format!("more than {MAX_NESTING} levels")),
        "{}",
        d.message
    );
    let parens = |n: usize| "(".repeat(n) + "a" + &")".repeat(n);
    expr(&parens(MAX_NESTING));
    assert!(expr_err(&parens(MAX_NESTING + 1))
        .message
        .starts_with("nested too deeply"));
    assert!(expr_err(&"NOT ".repeat(MAX_NESTING + 1))
        .message
        .starts_with("nested too deeply"));
    let arrays = "ARRAY [1..2] OF ".repeat(MAX_NESTING + 1);
    let d = lib_err(&format!("TYPE A : {arrays} INT; END_TYPE"));
    assert!(d.message.starts_with("nested too deeply"));
    let inits = "[".repeat(MAX_NESTING + 1) + &"]".repeat(MAX_NESTING + 1);
    let d = lib_err(&format!(
        "PROGRAM P VAR a : INT := {inits}; END_VAR END_PROGRAM"
    ));
    assert!(d.message.starts_with("nested too deeply"));
}

#[test]
fn a_flat_chain_deeper_than_max_depth_is_refused() {
    let chain = |n: usize| vec!["a"; n].join(" + ");
    expr(&chain(MAX_DEPTH));
    let d = expr_err(&chain(MAX_DEPTH + 2));
    assert!(d.message.starts_with(&format!(
        "the expression is too deep: more than {MAX_DEPTH} levels"
    )));
    let members = "a".to_string() + &".b".repeat(MAX_DEPTH + 1);
    assert!(expr_err(&members)
        .message
        .starts_with("the expression is too deep"));
    // Depth is carried through parentheses, so they cannot hide it.
    let grouped = format!("({}) + ({})", chain(200), chain(200));
    expr(&grouped);
    let deep = format!("({}) * 2 + 1", chain(MAX_DEPTH));
    assert!(expr_err(&deep)
        .message
        .starts_with("the expression is too deep"));
}

#[test]
fn pathological_inputs_neither_overflow_the_stack_nor_panic() {
    let n = 200_000;
    let inputs = [
        "(".repeat(n),
        "NOT ".repeat(n),
        "-".repeat(n),
        "IF a THEN ".repeat(n),
        "REPEAT ".repeat(n),
        "x := ".to_string() + &vec!["a"; n].join(" + ") + ";",
        "x := ".to_string() + &vec!["a"; n].join(" ** ") + ";",
        "x := a".to_string() + &".b".repeat(n) + ";",
        "x := a".to_string() + &"[1]".repeat(n) + ";",
        "F(".repeat(n),
        "x := [".to_string() + &"[".repeat(n),
        ";".repeat(n),
        "(*".repeat(n),
    ];
    for input in &inputs {
        let _ = parse_statements(input);
        let _ = parse_expression(input);
        let _ = parse_library(&format!("PROGRAM P {input} END_PROGRAM"));
        let _ = parse_library(&format!("TYPE T : {input}"));
        let _ = parse_library(&format!("PROGRAM P VAR a : INT := {input}"));
    }
}

#[test]
fn a_text_over_the_token_limit_is_refused_before_it_is_parsed() {
    let text = ";".repeat(MAX_TOKENS + 1);
    let d = parse_statements(&text).expect_err("too many tokens");
    assert_eq!(d.pos as usize, MAX_TOKENS);
    assert!(
        d.message
            .contains(&format!("more than {MAX_TOKENS} tokens")),
        "{}",
        d.message
    );
    // At the cap, the text is lexed and parsed (here, to a syntax error at its first token).
    let d = parse_expression(&text[1..]).expect_err("not an expression");
    assert_eq!(d.message, "expected an expression, found ';'");
}

#[test]
fn a_text_over_the_size_limit_is_refused() {
    let text = " ".repeat(MAX_TEXT + 1);
    let d = parse_library(&text).expect_err("too large");
    assert!(
        d.message.contains("more than the limit of"),
        "{}",
        d.message
    );
}

/// A generated file of about `lines` lines: TYPEs, function blocks and programs.
fn large_file(lines: usize) -> String {
    let mut text = String::new();
    let mut i = 0;
    while text.lines().count() < lines {
        text.push_str(
            &SAMPLE
                .replace("Clamp", &format!("Clamp{i}"))
                .replace("Blink", &format!("Blink{i}"))
                .replace("Main", &format!("Main{i}"))
                .replace("Plant", &format!("Plant{i}")),
        );
        i += 1;
    }
    text
}

#[test]
fn a_5000_line_file_is_parsed() {
    let text = large_file(5000);
    let lines = text.lines().count();
    let start = std::time::Instant::now();
    let l = lib(&text);
    let elapsed = start.elapsed();
    // A figure to read with --nocapture (in release: cargo test --release); no assertion on it.
    eprintln!("parsed {lines} lines, {} bytes, in {elapsed:?}", text.len());
    assert_eq!(l.pous.len() % 3, 0);
    assert!(l.pous.len() >= 3 * 5000 / SAMPLE.lines().count());
}

// ---- Corrupted programs ----

fn all_entry_points(text: &str) {
    let _ = parse_library(text);
    let _ = parse_statements(text);
    let _ = parse_expression(text);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn a_truncated_program_never_panics(cut in 0..SAMPLE.len()) {
        all_entry_points(&String::from_utf8_lossy(&SAMPLE.as_bytes()[..cut]));
    }

    #[test]
    fn a_program_with_flipped_bytes_never_panics(
        flips in proptest::collection::vec((0..SAMPLE.len(), any::<u8>()), 1..8)
    ) {
        let mut bytes = SAMPLE.as_bytes().to_vec();
        for (at, byte) in flips {
            bytes[at] = byte;
        }
        all_entry_points(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn a_program_with_tokens_cut_out_never_panics(from in 0..SAMPLE.len(), len in 0usize..40) {
        let mut bytes = SAMPLE.as_bytes().to_vec();
        let to = (from + len).min(bytes.len());
        bytes.drain(from..to);
        all_entry_points(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn arbitrary_text_of_st_characters_never_panics(
        text in "[A-Za-z0-9_#.:;=<>()\\[\\]*+/&$'%, \n{}-]{0,200}"
    ) {
        all_entry_points(&text);
    }
}
