//! The Structured Text subset against a reference evaluator written from IEC 61131-3: random
//! expressions and statements, written as ST in random letter case, are imported (conditions
//! become guards, action bodies the runtime's statement code) and must give what the reference
//! gives when it interprets the same tree, errors included.
//!
//! The reference follows the IEC text plus the decisions of docs/sfc.md: INT is i64 with
//! overflow an error, `/` truncates towards zero and fails on zero, AND and OR evaluate their
//! right side only when the left does not decide (IEC leaves the order open), XOR is inequality
//! of BOOLs, and IF runs the first arm whose condition holds.

use cetratus_net::TransIdx;
use cetratus_program::{EvalCtx, Value};
use proptest::prelude::*;

const INTS: [&str; 3] = ["a", "b", "c"];
const BOOLS: [&str; 2] = ["x", "y"];

#[derive(Clone, Debug)]
enum I {
    Lit(i64),
    Var(usize),
    Neg(Box<I>),
    Bin(&'static str, Box<I>, Box<I>),
}

#[derive(Clone, Debug)]
enum B {
    Lit(bool),
    Var(usize),
    Not(Box<B>),
    Logic(&'static str, Box<B>, Box<B>),
    Cmp(&'static str, I, I),
    Same(bool, Box<B>, Box<B>),
}

#[derive(Clone, Debug)]
enum S {
    SetI(usize, I),
    SetB(usize, B),
    If(Vec<(B, Vec<S>)>, Vec<S>),
}

fn int() -> impl Strategy<Value = I> {
    let leaf = prop_oneof![
        4 => (0i64..1000).prop_map(I::Lit),
        1 => Just(I::Lit(i64::MAX)),
        4 => (0..INTS.len()).prop_map(I::Var),
    ];
    leaf.prop_recursive(3, 8, 2, |inner| {
        prop_oneof![
            inner.clone().prop_map(|e| I::Neg(Box::new(e))),
            (
                prop::sample::select(vec!["+", "-", "*", "/"]),
                inner.clone(),
                inner
            )
                .prop_map(|(o, l, r)| I::Bin(o, Box::new(l), Box::new(r))),
        ]
    })
}

fn boolean() -> impl Strategy<Value = B> {
    let leaf = prop_oneof![
        any::<bool>().prop_map(B::Lit),
        (0..BOOLS.len()).prop_map(B::Var),
        (
            prop::sample::select(vec!["=", "<>", "<", ">", "<=", ">="]),
            int(),
            int()
        )
            .prop_map(|(o, l, r)| B::Cmp(o, l, r)),
    ];
    leaf.prop_recursive(2, 6, 2, |inner| {
        prop_oneof![
            inner.clone().prop_map(|e| B::Not(Box::new(e))),
            (
                prop::sample::select(vec!["AND", "OR", "XOR", "&"]),
                inner.clone(),
                inner.clone()
            )
                .prop_map(|(o, l, r)| B::Logic(o, Box::new(l), Box::new(r))),
            (any::<bool>(), inner.clone(), inner).prop_map(|(eq, l, r)| B::Same(
                eq,
                Box::new(l),
                Box::new(r)
            )),
        ]
    })
}

fn statement() -> impl Strategy<Value = S> {
    let leaf = prop_oneof![
        ((0..INTS.len()), int()).prop_map(|(v, e)| S::SetI(v, e)),
        ((0..BOOLS.len()), boolean()).prop_map(|(v, e)| S::SetB(v, e)),
    ];
    leaf.prop_recursive(2, 8, 3, |inner| {
        (
            prop::collection::vec(
                (boolean(), prop::collection::vec(inner.clone(), 0..3)),
                1..3,
            ),
            prop::collection::vec(inner, 0..3),
        )
            .prop_map(|(arms, otherwise)| S::If(arms, otherwise))
    })
}

/// Writes a keyword or name in the case `upper` picks (IEC names are case-insensitive).
fn cased(s: &str, upper: bool) -> String {
    if upper {
        s.to_ascii_uppercase()
    } else {
        s.to_ascii_lowercase()
    }
}

fn st_int(e: &I, u: bool) -> String {
    match e {
        I::Lit(n) => n.to_string(),
        I::Var(v) => cased(INTS[*v], u),
        I::Neg(x) => format!("-({})", st_int(x, u)),
        I::Bin(o, l, r) => format!("({} {o} {})", st_int(l, u), st_int(r, !u)),
    }
}

fn st_bool(e: &B, u: bool) -> String {
    match e {
        B::Lit(b) => cased(if *b { "TRUE" } else { "FALSE" }, u),
        B::Var(v) => cased(BOOLS[*v], u),
        B::Not(x) => format!("{} ({})", cased("NOT", u), st_bool(x, !u)),
        B::Logic(o, l, r) => format!("({} {} {})", st_bool(l, u), cased(o, !u), st_bool(r, u)),
        B::Cmp(o, l, r) => format!("({} {o} {})", st_int(l, u), st_int(r, u)),
        B::Same(eq, l, r) => format!(
            "({} {} {})",
            st_bool(l, u),
            if *eq { "=" } else { "<>" },
            st_bool(r, !u)
        ),
    }
}

fn st_stmts(stmts: &[S], u: bool, out: &mut String) {
    for s in stmts {
        match s {
            S::SetI(v, e) => {
                out.push_str(&format!("{} := {};\n", cased(INTS[*v], u), st_int(e, !u)))
            }
            S::SetB(v, e) => {
                out.push_str(&format!("{} := {};\n", cased(BOOLS[*v], u), st_bool(e, !u)))
            }
            S::If(arms, otherwise) => {
                for (n, (c, body)) in arms.iter().enumerate() {
                    let kw = if n == 0 { "IF" } else { "ELSIF" };
                    out.push_str(&format!(
                        "{} {} {}\n",
                        cased(kw, u),
                        st_bool(c, u),
                        cased("THEN", !u)
                    ));
                    st_stmts(body, !u, out);
                }
                if !otherwise.is_empty() {
                    out.push_str(&format!("{}\n", cased("ELSE", u)));
                    st_stmts(otherwise, u, out);
                }
                out.push_str(&format!("{};\n", cased("END_IF", u)));
            }
        }
    }
}

/// The state the reference reads and writes.
#[derive(Clone, Debug, PartialEq)]
struct Env {
    ints: [i64; 3],
    bools: [bool; 2],
}

fn eval_int(e: &I, env: &Env) -> Option<i64> {
    match e {
        I::Lit(n) => Some(*n),
        I::Var(v) => Some(env.ints[*v]),
        I::Neg(x) => eval_int(x, env)?.checked_neg(),
        I::Bin(o, l, r) => {
            let (a, b) = (eval_int(l, env)?, eval_int(r, env)?);
            match *o {
                "+" => a.checked_add(b),
                "-" => a.checked_sub(b),
                "*" => a.checked_mul(b),
                _ => a.checked_div(b),
            }
        }
    }
}

fn eval_bool(e: &B, env: &Env) -> Option<bool> {
    match e {
        B::Lit(b) => Some(*b),
        B::Var(v) => Some(env.bools[*v]),
        B::Not(x) => Some(!eval_bool(x, env)?),
        B::Logic(o, l, r) => {
            let a = eval_bool(l, env)?;
            match *o {
                "AND" | "&" if !a => Some(false),
                "OR" if a => Some(true),
                "XOR" => Some(a != eval_bool(r, env)?),
                _ => eval_bool(r, env),
            }
        }
        B::Cmp(o, l, r) => {
            let (a, b) = (eval_int(l, env)?, eval_int(r, env)?);
            Some(match *o {
                "=" => a == b,
                "<>" => a != b,
                "<" => a < b,
                ">" => a > b,
                "<=" => a <= b,
                _ => a >= b,
            })
        }
        B::Same(eq, l, r) => {
            let (a, b) = (eval_bool(l, env)?, eval_bool(r, env)?);
            Some((a == b) == *eq)
        }
    }
}

fn exec(stmts: &[S], env: &mut Env) -> Option<()> {
    for s in stmts {
        match s {
            S::SetI(v, e) => env.ints[*v] = eval_int(e, env)?,
            S::SetB(v, e) => env.bools[*v] = eval_bool(e, env)?,
            S::If(arms, otherwise) => {
                let mut taken = false;
                for (c, body) in arms {
                    if eval_bool(c, env)? {
                        exec(body, env)?;
                        taken = true;
                        break;
                    }
                }
                if !taken {
                    exec(otherwise, env)?;
                }
            }
        }
    }
    Some(())
}

/// One POU with the variables, a step S0 whose N action runs `body`, and a transition whose
/// condition is `condition`.
fn project(condition: &str, body: &str) -> String {
    let var = |n: &str, t: &str| format!(r#"<variable name="{n}"><type><{t}/></type></variable>"#);
    let vars: String = INTS
        .iter()
        .map(|n| var(&n.to_ascii_uppercase(), "INT"))
        .chain(BOOLS.iter().map(|n| var(n, "BOOL")))
        .collect();
    format!(
        r#"<?xml version="1.0"?>
<project xmlns="http://www.plcopen.org/xml/tc6_0201"><types><pous>
<pou name="P" pouType="program"><interface><localVars>{vars}</localVars></interface>
<body><SFC>
<step localId="1" name="S0" initialStep="true"/>
<actionBlock localId="9"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<action localId="0" qualifier="N"><inline><ST><p><![CDATA[{body}]]></p></ST></inline></action>
</actionBlock>
<transition localId="2"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<condition><inline name=""><ST><p><![CDATA[{condition}]]></p></ST></inline></condition></transition>
<step localId="3" name="S1"><connectionPointIn><connection refLocalId="2"/></connectionPointIn></step>
<transition localId="4"><connectionPointIn><connection refLocalId="3"/></connectionPointIn>
<condition><inline name=""><ST><p>TRUE</p></ST></inline></condition></transition>
<jumpStep localId="5" targetName="S0"><connectionPointIn><connection refLocalId="4"/></connectionPointIn></jumpStep>
</SFC></body></pou></pous></types></project>"#
    )
}

fn values(env: &Env) -> Vec<Value> {
    env.ints
        .iter()
        .map(|&i| Value::Int(i))
        .chain(env.bools.iter().map(|&b| Value::Bool(b)))
        .collect()
}

fn env() -> impl Strategy<Value = Env> {
    (
        prop::array::uniform3(prop_oneof![-50i64..50, Just(i64::MIN), Just(i64::MAX)]),
        prop::array::uniform2(any::<bool>()),
    )
        .prop_map(|(ints, bools)| Env { ints, bools })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn translated_conditions_and_bodies_evaluate_like_the_reference(
        cond in boolean(),
        stmts in prop::collection::vec(statement(), 1..3),
        start in env(),
        upper in any::<bool>(),
    ) {
        let mut body = String::new();
        st_stmts(&stmts, upper, &mut body);
        let text = project(&st_bool(&cond, upper), &body);
        let imported = cetratus_sfc::import_str(&text, "ref.xml", None, "ref.pnml")
            .unwrap_or_else(|e| panic!("{e}\n{text}"));
        let p = &imported.program;
        let vars = values(&start);
        let marking = p.net().initial_marking().0;
        let since: Vec<Option<u64>> = marking.iter().map(|&m| (m > 0).then_some(0)).collect();
        let ctx = EvalCtx {
            inputs: &[],
            prev_inputs: &[],
            vars: &vars,
            marking: &marking,
            place_since_us: &since,
            place_dwell_us: &[],
            now_us: 0,
        };
        let guard = p.eval_guard(TransIdx(0), &ctx).ok();
        prop_assert_eq!(guard, eval_bool(&cond, &start), "condition {}", p.guard(TransIdx(0)).map_or("true", |g| g.source()));

        let mut reference = start.clone();
        let expected = exec(&stmts, &mut reference);
        let mut got = vars.clone();
        let mut outputs: Vec<Value> = Vec::new();
        let ran = p.bodies()[0].run(&ctx, &mut got, &mut outputs);
        prop_assert_eq!(ran.is_ok(), expected.is_some(), "{:?}\n{}", ran, p.bodies()[0].source());
        if expected.is_some() {
            prop_assert_eq!(got, values(&reference), "{}", p.bodies()[0].source());
        }
    }
}
