//! The parser's tests, by topic; this file holds what they share.

use proptest::prelude::*;

use super::{
    parse_expression, parse_library, parse_statements, MAX_DEPTH, MAX_NESTING, MAX_TEXT, MAX_TOKENS,
};
use crate::ast::{
    Arg, BinOp, CaseLabel, Expr, ExprKind, Init, Library, Literal, PouKind, Section, Stmt,
    StmtKind, TypeDeclKind, TypeRef, UnOp,
};
use crate::error::{Diagnostic, Source};

pub(super) fn located(text: &str, d: Diagnostic) -> String {
    Source {
        origin: "test.st",
        text,
    }
    .error(d)
    .to_string()
}

pub(super) fn lib(text: &str) -> Library {
    parse_library(text).unwrap_or_else(|d| panic!("{}", located(text, d)))
}

pub(super) fn stmts(text: &str) -> Vec<Stmt> {
    parse_statements(text).unwrap_or_else(|d| panic!("{}", located(text, d)))
}

pub(super) fn expr(text: &str) -> Expr {
    parse_expression(text).unwrap_or_else(|d| panic!("{}", located(text, d)))
}

pub(super) fn lib_err(text: &str) -> Diagnostic {
    parse_library(text).expect_err("the text should be refused")
}

pub(super) fn stmts_err(text: &str) -> Diagnostic {
    parse_statements(text).expect_err("the body should be refused")
}

pub(super) fn expr_err(text: &str) -> Diagnostic {
    parse_expression(text).expect_err("the expression should be refused")
}

/// The expression fully parenthesised, to compare trees.
pub(super) fn show(e: &Expr) -> String {
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

pub(super) fn show_lit(l: &Literal) -> String {
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

pub(super) fn show_arg(a: &Arg) -> String {
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

pub(super) fn lit(text: &str) -> Literal {
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

mod declarations;
mod expressions;
mod refusals;
mod statements;
