//! Structured fuzzing of the guard language on stable Rust: the parser and
//! `Program::compile_condition` (the path of a `substitute` condition that comes over MQTT) return
//! a guard or an error for any text, and never panic; a guard that compiles evaluates to a value or
//! an error for any values of the signals it reads, and prints back to the same tree. The texts
//! are arbitrary, or sequences of the language's own tokens with the values that hit its edges
//! (overflowing numbers and durations, unknown names, outputs, stray operators).

mod common;

use std::sync::OnceLock;

use cetratus_program::guard::parse;
use cetratus_program::{EvalCtx, Program, Type, Value};
use cetratus_testkit::programs;
use proptest::collection::vec;
use proptest::prelude::*;

/// The Vernadat example, loaded once.
fn vernadat() -> &'static Program {
    static P: OnceLock<Program> = OnceLock::new();
    P.get_or_init(|| programs::example("vernadat/vernadat.toml"))
}

/// The small program of the behaviour tests (bool, int and real inputs, an int variable).
fn small() -> &'static Program {
    static P: OnceLock<Program> = OnceLock::new();
    P.get_or_init(|| common::program(""))
}

const TOKENS: &[&str] = &[
    // Names of the small program (inputs x, n, r; variable v; places A, B, C) and of Vernadat.
    "x",
    "n",
    "r",
    "v",
    "A",
    "B",
    "C",
    "PE",
    "FCM1",
    "P10",
    "H",
    "CM1",
    "nope",
    // Functions, timers, literals.
    "t",
    "rise",
    "fall",
    "real",
    "int",
    "true",
    "false",
    ".t",
    "0",
    "1",
    "7",
    "9223372036854775807",
    "9223372036854775808",
    "1.5",
    "0.0",
    "1e308",
    "1e309",
    "2e-5",
    "500ms",
    "1s",
    "0s",
    "0.5us",
    "9223372036854775807us",
    "18446744073709551615us",
    "3sec",
    "1e3ms",
    // Operators and punctuation.
    "&&",
    "||",
    "!",
    "==",
    "!=",
    "<",
    "<=",
    ">",
    ">=",
    "=",
    "+",
    "-",
    "*",
    "/",
    "(",
    ")",
    "(",
    ")",
    ".",
    ",",
    "&",
    "|",
    "é",
];

/// A sequence of tokens, with or without spaces between them.
fn soup() -> impl Strategy<Value = String> {
    (vec(prop::sample::select(TOKENS), 0..40), any::<bool>())
        .prop_map(|(toks, spaced)| toks.join(if spaced { " " } else { "" }))
}

/// A well-typed-looking guard over the small program: comparisons joined by `&&`/`||`, with
/// arithmetic inside, so that many compile and reach the evaluator.
fn plausible() -> impl Strategy<Value = String> {
    let int_atom = prop::sample::select(
        &[
            "n",
            "v",
            "A",
            "B",
            "C",
            "0",
            "1",
            "9223372036854775807",
            "int(r)",
            "-n",
        ][..],
    );
    let real_atom = prop::sample::select(&["r", "0.0", "1.5", "1e308", "real(n)", "-r"][..]);
    let int_op = prop::sample::select(&["+", "-", "*", "/"][..]);
    let cmp = prop::sample::select(&["==", "!=", "<", "<=", ">", ">="][..]);
    let int_expr = (int_atom.clone(), int_op.clone(), int_atom)
        .prop_map(|(a, op, b)| format!("({a} {op} {b})"));
    let real_expr =
        (real_atom.clone(), int_op, real_atom).prop_map(|(a, op, b)| format!("({a} {op} {b})"));
    let condition = prop_oneof![
        (int_expr.clone(), cmp.clone(), int_expr).prop_map(|(a, c, b)| format!("{a} {c} {b}")),
        (real_expr.clone(), cmp, real_expr).prop_map(|(a, c, b)| format!("{a} {c} {b}")),
        prop::sample::select(&["x", "!x", "rise(x)", "fall(x)", "A.t >= 1s", "t(C) < 500ms"][..])
            .prop_map(str::to_string),
    ];
    (vec(condition, 1..6), vec(any::<bool>(), 5)).prop_map(|(conds, ors)| {
        let mut s = conds[0].clone();
        for (c, or) in conds[1..].iter().zip(ors) {
            s.push_str(if or { " || " } else { " && " });
            s.push_str(c);
        }
        s
    })
}

/// Values for the small program's signals, of their declared types or of another type.
fn values(types: &[Type]) -> impl Strategy<Value = Vec<Value>> {
    let n = types.len();
    let types = types.to_vec();
    (
        vec(any::<bool>(), n),
        vec(any::<i64>(), n),
        vec(any::<f64>(), n),
        vec(0..8u8, n),
    )
        .prop_map(move |(b, i, r, pick)| {
            (0..n)
                .map(|k| match (pick[k], types[k]) {
                    // One value in eight has the wrong type.
                    (0, Type::Bool) => Value::Int(i[k]),
                    (0, _) => Value::Bool(b[k]),
                    (_, Type::Bool) => Value::Bool(b[k]),
                    (_, Type::Int) => Value::Int(i[k]),
                    (_, Type::Real) => Value::Real(r[k]),
                })
                .collect()
        })
}

/// One scan's worth of values for the small program, with markings and times at their edges.
#[derive(Debug, Clone)]
struct World {
    inputs: Vec<Value>,
    prev: Vec<Value>,
    vars: Vec<Value>,
    marking: Vec<u32>,
    since: Vec<Option<u64>>,
    now: u64,
}

fn world() -> impl Strategy<Value = World> {
    let small = small();
    let inputs: Vec<Type> = small.inputs().iter().map(|s| s.ty).collect();
    let vars: Vec<Type> = small.variables().iter().map(|s| s.ty).collect();
    (
        values(&inputs),
        values(&inputs),
        values(&vars),
        vec(prop_oneof![Just(0u32), Just(u32::MAX), any::<u32>()], 0..5),
        vec(any::<Option<u64>>(), 0..5),
        any::<u64>(),
    )
        .prop_map(|(inputs, prev, vars, marking, since, now)| World {
            inputs,
            prev,
            vars,
            marking,
            since,
            now,
        })
}

fn check_compiled(p: &Program, text: &str, w: &World) -> Result<(), TestCaseError> {
    let Ok(g) = p.compile_condition(text) else {
        return Ok(());
    };
    let ctx = EvalCtx {
        inputs: &w.inputs,
        prev_inputs: &w.prev,
        vars: &w.vars,
        marking: &w.marking,
        place_since_us: &w.since,
        place_dwell_us: &[],
        now_us: w.now,
    };
    let _ = g.eval(&ctx);
    let printed = g.expr().to_string();
    let again = parse(&printed);
    prop_assert!(
        again.as_ref().ok() == Some(g.expr()),
        "{printed}: {again:?}"
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_text_parses_or_is_refused(text in "\\PC{0,200}") {
        let _ = parse(&text);
        let _ = vernadat().compile_condition(&text);
    }

    #[test]
    fn token_soup_compiles_or_is_refused_and_what_compiles_evaluates(
        text in soup(),
        w in world(),
    ) {
        let _ = parse(&text);
        let _ = vernadat().compile_condition(&text);
        check_compiled(small(), &text, &w)?;
    }

    #[test]
    fn plausible_guards_compile_and_evaluate_to_a_value_or_an_error(
        text in plausible(),
        w in world(),
    ) {
        check_compiled(small(), &text, &w)?;
    }
}
