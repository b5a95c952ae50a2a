//! Action qualifiers (IEC 61131-3 SFC), computed after the marking update.

mod common;

use cetratus_net::{PlaceIdx, Tokens};
use cetratus_program::{ActError, ActionState, EvalCtx, Program, Value, Work};

const A: PlaceIdx = PlaceIdx(0);
const B: PlaceIdx = PlaceIdx(1);

/// Outputs o1..o4 (bool), a bool variable `flag`, and the given actions.
fn program(actions: &str) -> Program {
    let mut rest = String::new();
    for o in ["o1", "o2", "o3"] {
        rest.push_str(&format!("[[output]]\nname = \"{o}\"\ntype = \"bool\"\n"));
    }
    rest.push_str("[[output]]\nname = \"level\"\ntype = \"int\"\nsafe = 7\n");
    rest.push_str("[[variable]]\nname = \"flag\"\ntype = \"bool\"\n");
    rest.push_str(actions);
    common::program(&rest)
}

fn action(place: &str, q: &str, target: &str, duration: Option<&str>) -> String {
    let d = duration
        .map(|d| format!("duration = \"{d}\"\n"))
        .unwrap_or_default();
    format!("[[action]]\nplace = \"{place}\"\nqualifier = \"{q}\"\ntarget = \"{target}\"\n{d}")
}

/// The scan view of a program without inputs.
fn view<'a>(m: &'a [Tokens], since: &'a [Option<u64>], now_us: u64) -> EvalCtx<'a> {
    EvalCtx {
        inputs: &[],
        prev_inputs: &[],
        vars: &[],
        marking: m,
        place_since_us: since,
        place_dwell_us: &[],
        now_us,
    }
}

/// Drives the action state through scans; tracks `since` like the runtime does.
struct Cell {
    p: Program,
    st: ActionState,
    m: Vec<Tokens>,
    since: Vec<Option<u64>>,
    out: Vec<Value>,
    vars: Vec<Value>,
}

impl Cell {
    fn new(p: Program) -> Self {
        let m = p.net().initial_marking().0;
        let since = m.iter().map(|&t| (t > 0).then_some(0)).collect();
        let st = ActionState::new(&p);
        let mut c = Cell {
            out: vec![Value::Bool(true); p.outputs().len()],
            vars: vec![Value::Int(5), Value::Bool(false)],
            p,
            st,
            m,
            since,
        };
        let ctx = view(&c.m, &c.since, 0);
        c.st.start(&c.p, &ctx, &mut c.out, &mut c.vars, &mut Work::unlimited())
            .expect("no body");
        c
    }

    /// One scan at `now`: sets the given places' counts, then applies the actions.
    fn scan(&mut self, now: u64, set: &[(PlaceIdx, Tokens)]) -> Vec<bool> {
        let mut changes = Vec::new();
        for &(p, n) in set {
            let old = self.m[p.index()];
            if old != n {
                changes.push((p, old));
                self.m[p.index()] = n;
                if old == 0 {
                    self.since[p.index()] = Some(now);
                } else if n == 0 {
                    self.since[p.index()] = None;
                }
            }
        }
        let ctx = view(&self.m, &self.since, now);
        self.st
            .apply(
                &self.p,
                &ctx,
                &changes,
                &mut self.out,
                &mut self.vars,
                &mut Work::unlimited(),
            )
            .expect("no body");
        self.bools()
    }

    fn bools(&self) -> Vec<bool> {
        self.out
            .iter()
            .take(3)
            .map(|v| v.as_bool().unwrap_or(false))
            .collect()
    }
}

#[test]
fn n_is_on_while_the_place_is_marked_and_undriven_outputs_are_off() {
    let mut c = Cell::new(program(&action("A", "N", "o1", None)));
    assert_eq!(c.bools(), [true, false, false], "A is marked at M0");
    assert_eq!(
        c.out[3],
        Value::Int(0),
        "an output no action drives is its type's zero"
    );
    assert_eq!(c.scan(10, &[(A, 0)]), [false, false, false]);
}

#[test]
fn s_and_r_latch_on_entry_and_reset_wins_in_the_same_scan() {
    let acts = action("B", "S", "o1", None)
        + &action("C", "R", "o1", None)
        + &action("A", "R", "o2", None)
        + &action("B", "S", "o2", None);
    let mut c = Cell::new(program(&acts));
    assert!(!c.bools()[0]);
    assert_eq!(c.scan(10, &[(A, 0), (B, 1)]), [true, true, false]);
    assert_eq!(
        c.scan(20, &[(B, 0)]),
        [true, true, false],
        "a latch outlives the place"
    );
    assert_eq!(c.scan(30, &[(PlaceIdx(2), 0)]), [true, true, false]);
    assert_eq!(
        c.scan(40, &[(PlaceIdx(2), 1)]),
        [false, true, false],
        "R resets on entry"
    );
    // A and B entered together: A resets o2 while B sets it; reset dominates.
    assert_eq!(c.scan(50, &[(A, 1), (B, 1)]), [true, false, false]);
}

#[test]
fn p1_and_p0_pulse_for_one_scan_on_entry_and_on_exit() {
    let acts = action("B", "P1", "o1", None) + &action("B", "P0", "o2", None);
    let mut c = Cell::new(program(&acts));
    assert_eq!(c.scan(10, &[(B, 1)]), [true, false, false]);
    assert_eq!(c.scan(20, &[]), [false, false, false]);
    assert_eq!(
        c.scan(30, &[(B, 2)]),
        [false, false, false],
        "more tokens is not an entry"
    );
    assert_eq!(c.scan(40, &[(B, 0)]), [false, true, false]);
    assert_eq!(c.scan(50, &[]), [false, false, false]);
}

#[test]
fn l_is_on_at_most_its_duration_and_d_only_after_it() {
    let acts = action("B", "L", "o1", Some("2s")) + &action("B", "D", "o2", Some("2s"));
    let mut c = Cell::new(program(&acts));
    assert_eq!(c.scan(1_000_000, &[(B, 1)]), [true, false, false]);
    assert_eq!(c.st.next_deadline_us(), Some(3_000_000));
    assert_eq!(c.scan(2_999_999, &[]), [true, false, false]);
    assert_eq!(c.scan(3_000_000, &[]), [false, true, false]);
    assert_eq!(c.st.next_deadline_us(), None);
    assert_eq!(c.scan(4_000_000, &[(B, 0)]), [false, false, false]);
}

#[test]
fn a_bool_variable_can_be_an_action_target() {
    let mut c = Cell::new(program(&action("B", "N", "flag", None)));
    c.scan(10, &[(B, 1)]);
    assert_eq!(c.vars[1], Value::Bool(true));
    c.scan(20, &[(B, 0)]);
    assert_eq!(c.vars[1], Value::Bool(false));
    assert_eq!(
        c.vars[0],
        Value::Int(5),
        "variables no action drives are left alone"
    );
}

#[test]
fn safe_outputs_use_the_declared_safe_value_or_zero() {
    let p = program("");
    let mut out = vec![Value::Bool(true); 4];
    p.safe_outputs(&mut out);
    assert_eq!(
        out,
        [
            Value::Bool(false),
            Value::Bool(false),
            Value::Bool(false),
            Value::Int(7)
        ]
    );
}

#[test]
fn sd_is_on_after_its_delay_even_once_the_place_is_left_until_a_reset() {
    let acts = action("B", "SD", "o1", Some("2s")) + &action("A", "R", "o1", None);
    let mut c = Cell::new(program(&acts));
    assert_eq!(c.scan(1_000_000, &[(A, 0), (B, 1)]), [false, false, false]);
    assert_eq!(c.st.next_deadline_us(), Some(3_000_000));
    assert_eq!(c.scan(2_000_000, &[(B, 0)]), [false, false, false]);
    assert_eq!(
        c.scan(3_000_000, &[]),
        [true, false, false],
        "stored: the delay runs on after the place is left"
    );
    assert_eq!(c.scan(4_000_000, &[]), [true, false, false]);
    assert_eq!(c.scan(5_000_000, &[(A, 1)]), [false, false, false], "R");
    // A reset before the delay ends cancels it.
    c.scan(6_000_000, &[(A, 0), (B, 1)]);
    c.scan(6_500_000, &[(A, 1), (B, 0)]);
    assert_eq!(c.scan(9_000_000, &[]), [false, false, false]);
    assert_eq!(c.st.next_deadline_us(), None);
}

#[test]
fn ds_latches_only_when_the_place_stays_marked_for_its_delay() {
    let acts = action("B", "DS", "o1", Some("2s")) + &action("A", "R", "o1", None);
    let mut c = Cell::new(program(&acts));
    c.scan(1_000_000, &[(A, 0), (B, 1)]);
    assert_eq!(c.scan(2_000_000, &[(B, 0)]), [false, false, false]);
    assert_eq!(
        c.scan(9_000_000, &[]),
        [false, false, false],
        "left too early"
    );
    c.scan(10_000_000, &[(B, 1)]);
    assert_eq!(c.scan(12_000_000, &[]), [true, false, false]);
    assert_eq!(
        c.scan(13_000_000, &[(B, 0)]),
        [true, false, false],
        "stored once delayed"
    );
    assert_eq!(c.scan(14_000_000, &[(A, 1)]), [false, false, false]);
}

#[test]
fn sl_is_on_for_its_duration_from_entry_even_once_the_place_is_left() {
    let acts = action("B", "SL", "o1", Some("2s")) + &action("A", "R", "o1", None);
    let mut c = Cell::new(program(&acts));
    assert_eq!(c.scan(1_000_000, &[(A, 0), (B, 1)]), [true, false, false]);
    assert_eq!(c.scan(1_500_000, &[(B, 0)]), [true, false, false]);
    assert_eq!(c.st.next_deadline_us(), Some(3_000_000));
    assert_eq!(c.scan(3_000_000, &[]), [false, false, false]);
    assert_eq!(c.st.next_deadline_us(), None);
    // A reset ends it early.
    c.scan(4_000_000, &[(B, 1)]);
    assert_eq!(c.scan(4_100_000, &[(A, 1)]), [false, false, false]);
}

/// `program` with the given `[bodies]` text added after the actions.
fn with_bodies(actions: &str, bodies: &str) -> Program {
    program(&format!("{actions}\n[bodies]\n{bodies}"))
}

fn body_action(place: &str, q: &str, body: &str, duration: Option<&str>) -> String {
    let d = duration
        .map(|d| format!("duration = \"{d}\"\n"))
        .unwrap_or_default();
    format!("[[action]]\nplace = \"{place}\"\nqualifier = \"{q}\"\nbody = \"{body}\"\n{d}")
}

#[test]
fn an_n_body_runs_in_every_scan_while_marked_and_once_more_in_the_scan_it_is_left() {
    let p = with_bodies(
        &body_action("B", "N", "Count", None),
        "Count = 'v := v + 1'",
    );
    let mut c = Cell::new(p);
    assert_eq!(c.vars[0], Value::Int(5), "B is not marked at M0");
    c.scan(10, &[(A, 0), (B, 1)]);
    assert_eq!(c.vars[0], Value::Int(6));
    c.scan(20, &[]);
    assert!(!c.st.last_was_quiet(), "a running body is never quiet");
    assert_eq!(c.vars[0], Value::Int(7), "runs in every scan");
    c.scan(30, &[(B, 0)]);
    assert_eq!(c.vars[0], Value::Int(8), "the IEC final run");
    c.scan(40, &[]);
    c.scan(50, &[]);
    assert_eq!(c.vars[0], Value::Int(8));
    assert!(c.st.last_was_quiet());
}

#[test]
fn a_pulse_body_runs_once_with_no_final_run() {
    let p = with_bodies(
        &(body_action("B", "P1", "Up", None) + &body_action("B", "P0", "Down", None)),
        "Up = 'v := v + 10'\nDown = 'v := v - 1'",
    );
    let mut c = Cell::new(p);
    c.scan(10, &[(A, 0), (B, 1)]);
    assert_eq!(c.vars[0], Value::Int(15));
    c.scan(20, &[]);
    c.scan(30, &[]);
    assert_eq!(c.vars[0], Value::Int(15));
    c.scan(40, &[(B, 0)]);
    c.scan(50, &[]);
    assert_eq!(c.vars[0], Value::Int(14));
}

#[test]
fn a_stored_body_runs_after_its_place_is_left_until_a_reset_then_once_more() {
    let p = with_bodies(
        &(body_action("B", "S", "Count", None) + &body_action("C", "R", "Count", None)),
        "Count = 'v := v + 1'",
    );
    let mut c = Cell::new(p);
    c.scan(10, &[(A, 0), (B, 1)]);
    c.scan(20, &[(B, 0)]);
    c.scan(30, &[]);
    assert_eq!(c.vars[0], Value::Int(8));
    c.scan(40, &[(PlaceIdx(2), 0)]);
    c.scan(50, &[(PlaceIdx(2), 1)]);
    assert_eq!(
        c.vars[0],
        Value::Int(10),
        "9 at 40, and the final run at the reset"
    );
    c.scan(60, &[]);
    assert_eq!(c.vars[0], Value::Int(10));
}

#[test]
fn if_elif_else_take_the_first_true_arm_and_a_body_output_holds_its_value() {
    let body = "Pick = '''\nif v > 10 then\n  level := 3\nelif v > 5 then\n  level := 2\n  o1 := true\nelse\n  level := 1\nend\nv := v + 3\n'''";
    let p = with_bodies(&body_action("B", "N", "Pick", None), body);
    let mut c = Cell::new(p);
    // The container starts outputs at their type's zero; the test cell starts them on.
    c.out[0] = Value::Bool(false);
    c.scan(10, &[(A, 0), (B, 1)]);
    assert_eq!(
        (c.out[3], c.out[0], c.vars[0]),
        (Value::Int(1), Value::Bool(false), Value::Int(8))
    );
    c.scan(20, &[]);
    assert_eq!((c.out[3], c.out[0]), (Value::Int(2), Value::Bool(true)));
    c.scan(30, &[]);
    assert_eq!(c.out[3], Value::Int(3));
    c.scan(40, &[(B, 0)]);
    c.scan(50, &[]);
    assert_eq!(
        (c.out[3], c.out[0]),
        (Value::Int(3), Value::Bool(true)),
        "an output a body assigns keeps its value"
    );
}

#[test]
fn an_overflowing_body_fails_naming_its_line_and_column() {
    let p = with_bodies(
        &body_action("B", "N", "Big", None),
        "Big = '''\nv := 9223372036854775807\nv := v + 1\n'''",
    );
    let mut st = ActionState::new(&p);
    let (m, since) = (vec![0, 1, 2], vec![None, Some(0), Some(0)]);
    let (mut out, mut vars) = (
        vec![Value::Bool(false); 4],
        vec![Value::Int(0), Value::Bool(false)],
    );
    let err = st.start(
        &p,
        &view(&m, &since, 0),
        &mut out,
        &mut vars,
        &mut Work::unlimited(),
    );
    let Err(ActError::Body(err)) = err else {
        panic!("not a body's overflow: {err:?}")
    };
    assert_eq!((err.line, err.column), (2, 8), "{err}");
    assert!(
        err.to_string()
            .contains("action body `Big` failed at line 2, column 8: arithmetic overflow"),
        "{err}"
    );
}

#[test]
fn sd_ds_and_sl_bodies_follow_the_same_q_as_targets() {
    let p = with_bodies(
        &body_action("B", "SD", "Count", Some("1s")),
        "Count = 'v := v + 1'",
    );
    let mut c = Cell::new(p);
    c.scan(0, &[(A, 0), (B, 1)]);
    c.scan(500_000, &[(B, 0)]);
    assert_eq!(c.vars[0], Value::Int(5));
    c.scan(1_000_000, &[]);
    c.scan(1_100_000, &[]);
    assert_eq!(c.vars[0], Value::Int(7));
}

#[test]
fn a_body_that_would_pass_the_work_left_is_not_run_and_is_named() {
    let p = with_bodies(
        &body_action("B", "N", "Count", None),
        "Count = '''\nv := v + 1\n'''",
    );
    let cost = p.bodies()[0].cost();
    let (m, since) = (vec![0, 1, 2], vec![None, Some(0), Some(0)]);
    let ctx = view(&m, &since, 0);
    let (mut out, mut vars) = (
        vec![Value::Bool(false); 4],
        vec![Value::Int(5), Value::Bool(false)],
    );
    let mut st = ActionState::new(&p);
    let mut short = Work::within(cost - 1);
    let err = st.start(&p, &ctx, &mut out, &mut vars, &mut short);
    assert_eq!(
        err,
        Err(ActError::OutOfWork {
            body: "Count".into()
        })
    );
    assert_eq!(vars[0], Value::Int(5), "the body did not run");
    let mut enough = Work::within(cost);
    let mut st = ActionState::new(&p);
    st.start(&p, &ctx, &mut out, &mut vars, &mut enough)
        .expect("within its work");
    assert_eq!((vars[0], enough.used()), (Value::Int(6), cost));
}
