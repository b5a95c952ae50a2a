//! Action qualifiers (IEC 61131-3 SFC), computed after the marking update.

mod common;

use cetratus_net::{PlaceIdx, Tokens};
use cetratus_program::{ActionState, Program, Value};

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
        c.st.start(&c.p, &c.m, &c.since, 0, &mut c.out, &mut c.vars);
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
        self.st.apply(
            &self.p,
            &self.m,
            &changes,
            &self.since,
            now,
            &mut self.out,
            &mut self.vars,
        );
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
