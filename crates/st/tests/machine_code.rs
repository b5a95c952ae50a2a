//! The machine code against the interpreter (docs/st.md, *Machine code*): the same programs, the
//! same inputs and times, and after every scan the same state, slot for slot (but the
//! temporaries, which nothing reads after a run) and byte for byte,
//! the same work charged and the same faults at the same places. The interpreter is the
//! reference that MATIEC checks (`differential.rs`); this checks the translation against it on
//! every instruction the generator makes, and on the faults it does not make.
#![cfg(feature = "jit")]

use cetratus_st::{compile, parse, Fault, State, Unit, Work};
use cetratus_testkit::stgen;

mod common;
use common::write_input;

/// Runs `unit` from its initial state, `scans` times, on both paths, feeding `inputs(k)` before
/// scan `k` and a budget of `budget` units a scan; panics at the first difference.
fn agree(
    unit: &Unit,
    scans: usize,
    budget: u64,
    mut inputs: impl FnMut(usize, &mut State),
) -> Vec<Result<(), Fault>> {
    assert!(
        unit.prepare_machine_code(),
        "{}: not in machine code",
        unit.name
    );
    assert!(unit.in_machine_code());
    let (mut native, mut reference) = (unit.new_state(), unit.new_state());
    let code = &unit.code;
    let mut results = Vec::new();
    for k in 0..scans {
        inputs(k, &mut native);
        inputs(k, &mut reference);
        let now = k as i64 * 10_000_000;
        let (mut w1, mut w2) = (Work::within(budget), Work::within(budget));
        let got = unit.run(&mut native, now, &mut w1);
        let want = unit.run_interpreted(&mut reference, now, &mut w2);
        assert_eq!(got, want, "{}: scan {k}: the results differ", unit.name);
        assert_eq!(w1.used(), w2.used(), "{}: scan {k}: work", unit.name);
        // A temporary is only stored where something may read it: after the run, it may hold
        // an older value in machine code.
        let differs = |&i: &usize| native.slots[i] != reference.slots[i] && !code.is_temp(i as u32);
        if let Some(at) = (0..native.slots.len()).find(differs) {
            panic!(
                "{}: scan {k}: slot {at} is {:#x} in machine code, {:#x} interpreted",
                unit.name, native.slots[at], reference.slots[at]
            );
        }
        assert!(
            native.text == reference.text,
            "{}: scan {k}: text",
            unit.name
        );
        results.push(got);
        if results.last().is_some_and(Result::is_err) {
            break;
        }
    }
    results
}

#[test]
fn a_thousand_random_programs_run_the_same_in_machine_code_as_interpreted() {
    for seed in 0..4u64 {
        let batch = stgen::generate(0x0c0d_e000 + seed, 250, 40);
        let lib = parse::parse_library(&batch.source).expect("the generated batch parses");
        for case in &batch.cases {
            let unit = compile(&lib, Some(&case.program)).expect("a generated program compiles");
            assert!(!unit.in_machine_code(), "translated before it was asked");
            let vars: Vec<_> = (case.inputs.iter())
                .map(|(n, _)| unit.var(n).expect("an input").clone())
                .collect();
            agree(&unit, case.scans.len(), u64::MAX, |k, state| {
                for (v, text) in vars.iter().zip(&case.scans[k]) {
                    write_input(state, v, text);
                }
            });
        }
    }
}

/// Compiles the PROGRAM of `source`.
fn unit(source: &str) -> Unit {
    let lib = parse::parse_library(source).unwrap_or_else(|d| panic!("{}", d.message));
    compile(&lib, None).unwrap_or_else(|d| panic!("{}", d.message))
}

#[test]
fn faults_are_the_same_in_machine_code_at_the_same_place() {
    let u = unit(
        "PROGRAM P
           VAR_INPUT d : DINT; i : INT; END_VAR
           VAR_OUTPUT q : DINT; m : LINT; n : LINT; a : ARRAY[1..4] OF DINT; END_VAR
           m := LINT#-9223372036854775807 - 1;
           n := m / -1 + m MOD -1;
           q := 100 / d;
           a[i] := q;
         END_PROGRAM",
    );
    let var = |n: &str| u.var(n).expect("a variable").at.slots as usize;
    let (d, i) = (var("d"), var("i"));
    // d = 0 divides by zero; then i = 7 is out of the array's bounds.
    let results = agree(&u, 3, u64::MAX, |k, s| {
        s.slots[d] = if k == 0 { 0 } else { 4 };
        s.slots[i] = if k == 1 { 7 } else { 2 };
    });
    assert!(matches!(
        results[0],
        Err(Fault {
            kind: cetratus_st::code::FaultKind::DivisionByZero,
            ..
        })
    ));
}

#[test]
fn a_loop_stops_at_the_budget_having_charged_the_same_work() {
    let u = unit(
        "PROGRAM P
           VAR_OUTPUT n : DINT; END_VAR
           WHILE TRUE DO n := n + 1; END_WHILE;
         END_PROGRAM",
    );
    for budget in [0, 1, 2, 3, 10, 1000, 12_345] {
        let r = agree(&u, 1, budget, |_, _| {});
        assert!(
            matches!(
                r[0],
                Err(Fault {
                    kind: cetratus_st::code::FaultKind::Budget,
                    ..
                })
            ),
            "budget {budget}: {:?}",
            r[0]
        );
    }
}

#[test]
fn reals_that_do_not_compare_are_unequal_and_unordered_as_in_c() {
    let u = unit(
        "PROGRAM P
           VAR_INPUT x : REAL; y : LREAL; END_VAR
           VAR_OUTPUT lt, gt, le, ge, eq, ne, dlt, dne, b : BOOL; z : REAL; END_VAR
           z := x - x;
           lt := z < x; gt := z > x; le := z <= x; ge := z >= x; eq := z = z; ne := z <> z;
           dlt := y < y; dne := y <> y;
           b := REAL_TO_BOOL(z);
         END_PROGRAM",
    );
    let (x, y) = (
        u.var("x").expect("x").at.slots as usize,
        u.var("y").expect("y").at.slots as usize,
    );
    agree(&u, 2, u64::MAX, |k, s| {
        s.slots[x] = u64::from(if k == 0 { f32::INFINITY } else { 1.5f32 }.to_bits());
        s.slots[y] = f64::NAN.to_bits();
    });
    let mut state = u.new_state();
    state.slots[x] = u64::from(f32::INFINITY.to_bits());
    state.slots[y] = f64::NAN.to_bits();
    u.run(&mut state, 0, &mut Work::unlimited())
        .expect("a scan");
    let get = |n: &str| state.slots[u.var(n).expect("a flag").at.slots as usize];
    for (name, want) in [
        ("lt", 0),
        ("gt", 0),
        ("le", 0),
        ("ge", 0),
        ("eq", 0),
        ("ne", 1),
        ("dlt", 0),
        ("dne", 1),
        ("b", 1),
    ] {
        assert_eq!(get(name), want, "{name} of a NaN");
    }
}

/// Code past the translation's limit (`jit::MAX_OPS`) is not translated, so that no load spends
/// more than the limit's time on it, and the scan runs it on the interpreter.
#[test]
fn code_past_the_limit_runs_on_the_interpreter() {
    let increments = cetratus_st::jit::MAX_OPS / 2 + 1;
    let mut source = String::from("PROGRAM Long\n  VAR_OUTPUT x : DINT; y : DINT; END_VAR\n");
    for _ in 0..increments {
        source.push_str("  x := x + 1; y := x;\n");
    }
    source.push_str("END_PROGRAM\n");
    let u = unit(&source);
    assert!(
        u.code.ops.len() > cetratus_st::jit::MAX_OPS,
        "{}",
        u.code.ops.len()
    );
    assert!(
        !u.prepare_machine_code(),
        "code past the limit is not translated"
    );
    assert!(!u.in_machine_code());
    let mut state = u.new_state();
    u.run(&mut state, 0, &mut Work::unlimited())
        .expect("a scan on the interpreter");
    let x = state.slots[u.var("x").expect("x").at.slots as usize];
    assert_eq!(x, increments as u64);
}
