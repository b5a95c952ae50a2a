//! Guard semantics: levels, edges, timers, arithmetic errors.

mod common;

use cetratus_net::{Tokens, TransIdx};
use cetratus_program::{EvalCtx, EvalErrorKind, Program, Value};

struct World {
    inputs: Vec<Value>,
    prev: Vec<Value>,
    vars: Vec<Value>,
    marking: Vec<Tokens>,
    since: Vec<Option<u64>>,
    now: u64,
}

impl World {
    fn new() -> Self {
        let i = vec![Value::Bool(false), Value::Int(0), Value::Real(0.0)];
        World {
            prev: i.clone(),
            inputs: i,
            vars: vec![Value::Int(5)],
            marking: vec![1, 0, 2],
            since: vec![Some(0), None, Some(0)],
            now: 0,
        }
    }

    fn ctx(&self) -> EvalCtx<'_> {
        EvalCtx {
            inputs: &self.inputs,
            prev_inputs: &self.prev,
            vars: &self.vars,
            marking: &self.marking,
            place_since_us: &self.since,
            place_dwell_us: &[],
            now_us: self.now,
        }
    }
}

fn guard(expr: &str) -> Program {
    common::program(&format!("[guards]\nT1 = \"{expr}\"\n"))
}

fn eval(p: &Program, w: &World) -> Result<bool, EvalErrorKind> {
    p.eval_guard(TransIdx(0), &w.ctx()).map_err(|e| e.kind)
}

#[test]
fn a_transition_without_a_guard_is_always_true() {
    let p = guard("x");
    assert!(!p.has_guard(TransIdx(1)));
    assert_eq!(p.eval_guard(TransIdx(1), &World::new().ctx()), Ok(true));
}

#[test]
fn guards_are_level_sensitive() {
    let p = guard("x && n >= 3");
    let mut w = World::new();
    assert_eq!(eval(&p, &w), Ok(false));
    w.inputs = vec![Value::Bool(true), Value::Int(3), Value::Real(0.0)];
    w.prev = w.inputs.clone();
    assert_eq!(eval(&p, &w), Ok(true));
    assert_eq!(eval(&p, &w), Ok(true), "still true while the level holds");
}

#[test]
fn rise_is_true_only_in_the_scan_in_which_the_input_went_up() {
    let p = guard("rise(x)");
    let q = guard("fall(x)");
    let mut w = World::new();
    assert_eq!(eval(&p, &w), Ok(false));
    w.inputs[0] = Value::Bool(true);
    assert_eq!(eval(&p, &w), Ok(true));
    assert_eq!(eval(&q, &w), Ok(false));
    w.prev[0] = Value::Bool(true);
    assert_eq!(eval(&p, &w), Ok(false), "the next scan sees no edge");
    w.inputs[0] = Value::Bool(false);
    assert_eq!(eval(&q, &w), Ok(true));
}

#[test]
fn a_place_timer_counts_from_the_scan_the_place_was_marked_and_is_zero_while_empty() {
    let p = guard("A.t >= 3s");
    let q = guard("t(B) == 0s");
    let mut w = World::new();
    w.since[0] = Some(1_000_000);
    w.now = 3_999_999;
    assert_eq!(eval(&p, &w), Ok(false));
    w.now = 4_000_000;
    assert_eq!(eval(&p, &w), Ok(true));
    assert_eq!(eval(&q, &w), Ok(true));
    w.marking[0] = 0;
    assert_eq!(eval(&p, &w), Ok(false), "an empty place's timer is 0");
}

#[test]
fn a_place_name_in_a_numeric_context_is_its_token_count() {
    let p = guard("C == 2 && B == 0 && A + C == 3");
    assert_eq!(eval(&p, &World::new()), Ok(true));
}

#[test]
fn variables_and_reals_take_part_in_arithmetic() {
    let p = guard("v * 2 - 1 == 9 && r / 2.0 < 1.0 && real(n) + 0.5 > 0.0 && int(1.9) == 1");
    assert_eq!(eval(&p, &World::new()), Ok(true));
}

#[test]
fn division_by_zero_is_an_error_not_a_panic() {
    let p = guard("10 / n > 1");
    let mut w = World::new();
    let err = p.eval_guard(TransIdx(0), &w.ctx()).err();
    assert_eq!(
        err.map(|e| (e.kind, e.column)),
        Some((EvalErrorKind::DivisionByZero, 4))
    );
    w.inputs[1] = Value::Int(2);
    assert_eq!(eval(&p, &w), Ok(true));
    assert_eq!(
        eval(&guard("r / 0.0 > 1.0"), &w),
        Err(EvalErrorKind::DivisionByZero)
    );
}

#[test]
fn int_overflow_is_an_error_not_a_wrap() {
    let mut w = World::new();
    w.inputs[1] = Value::Int(i64::MAX);
    assert_eq!(eval(&guard("n + 1 > 0"), &w), Err(EvalErrorKind::Overflow));
    assert_eq!(eval(&guard("n * 2 > 0"), &w), Err(EvalErrorKind::Overflow));
    w.inputs[1] = Value::Int(i64::MIN);
    assert_eq!(eval(&guard("-n > 0"), &w), Err(EvalErrorKind::Overflow));
    assert_eq!(eval(&guard("n / -1 > 0"), &w), Err(EvalErrorKind::Overflow));
    w.inputs[2] = Value::Real(f64::MAX);
    assert_eq!(
        eval(&guard("r * 2.0 > 0.0"), &w),
        Err(EvalErrorKind::Overflow)
    );
}

#[test]
fn and_and_or_short_circuit_so_a_guarded_division_is_safe() {
    let p = guard("n != 0 && 10 / n > 1 || !(n != 0)");
    assert_eq!(eval(&p, &World::new()), Ok(true));
}

#[test]
fn an_input_of_the_wrong_type_is_reported() {
    let p = guard("x");
    let mut w = World::new();
    w.inputs[0] = Value::Int(1);
    assert_eq!(eval(&p, &w), Err(EvalErrorKind::WrongType));
    w.inputs.clear();
    assert_eq!(eval(&p, &w), Err(EvalErrorKind::MissingValue));
}

#[test]
fn durations_add_and_compare_with_timers() {
    let p = guard("A.t >= 1s + 500ms");
    let mut w = World::new();
    w.now = 1_499_999;
    assert_eq!(eval(&p, &w), Ok(false));
    w.now = 1_500_000;
    assert_eq!(eval(&p, &w), Ok(true));
}
