//! `Program::eval_guard`, `Program::check_invariants`, `ActionState::apply` (bodies included),
//! `StateTransform::apply` and `Projection::drift` never allocate.

mod common;

use cetratus_net::{PlaceIdx, TransIdx};
use cetratus_program::{ActionState, EvalCtx, Value, Work};
use cetratus_testkit::CountingAlloc;

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc::new();

#[test]
fn evaluating_guards_and_applying_actions_does_not_allocate() {
    let p = common::program(
        "[[output]]\nname = \"o\"\ntype = \"bool\"\n\
         [[output]]\nname = \"q\"\ntype = \"bool\"\n\
         [guards]\nT1 = \"rise(x) || (A.t >= 3s && n / 2 + v * 3 > 1 && real(n) < r + 1.5) || C == 2\"\n\
         T2 = \"10 / n > 1\"\n\
         [[action]]\nplace = \"A\"\nqualifier = \"N\"\ntarget = \"o\"\n\
         [[action]]\nplace = \"B\"\nqualifier = \"S\"\ntarget = \"q\"\n\
         [[action]]\nplace = \"B\"\nqualifier = \"L\"\ntarget = \"o\"\nduration = \"2s\"\n\
         [[action]]\nplace = \"A\"\nqualifier = \"P0\"\ntarget = \"q\"\n\
         [[action]]\nplace = \"C\"\nqualifier = \"N\"\nbody = \"Work\"\n\
         [[action]]\nplace = \"B\"\nqualifier = \"SL\"\nbody = \"Work\"\nduration = \"1s\"\n\
         [bodies]\nWork = '''\nif v > 3 && B.dwell < 1h then\n  v := v * 2 / 2 - 1\nelif n == 0 then\n  v := 0\nelse\n  v := v + 1\nend\n'''\n\
         [[invariant]]\nexpr = \"A + B = 1\"\n",
    );
    let inputs = [Value::Bool(true), Value::Int(0), Value::Real(0.25)];
    let prev = [Value::Bool(false), Value::Int(0), Value::Real(0.25)];
    let vars = [Value::Int(5)];
    let marking = [0u32, 1, 2];
    let since = [None, Some(1_000_000), Some(0)];
    let ctx = EvalCtx {
        inputs: &inputs,
        prev_inputs: &prev,
        vars: &vars,
        marking: &marking,
        place_since_us: &since,
        place_dwell_us: &[],
        now_us: 4_000_000,
    };
    let mut state = ActionState::new(&p);
    let mut out = vec![Value::Bool(false); 2];
    let mut vars_out = vec![Value::Int(5)];
    let changes = [(PlaceIdx(0), 1), (PlaceIdx(1), 0)];

    let mut results = [Ok(false), Ok(false)];
    let mut inv = Ok(());
    let n = ALLOC.during(|| {
        for _ in 0..100 {
            results[0] = p.eval_guard(TransIdx(0), &ctx);
            results[1] = p.eval_guard(TransIdx(1), &ctx);
            inv = p.check_invariants(&marking);
            let mut work = Work::unlimited();
            let _ = state.apply(&p, &ctx, &changes, &mut out, &mut vars_out, &mut work);
        }
    });
    assert_eq!(n, 0, "allocations in the scan path");
    assert_eq!(results[0], Ok(true));
    assert!(
        results[1].is_err(),
        "division by zero is an error, and reporting it does not allocate"
    );
    assert!(inv.is_ok());
    assert_eq!(out, [Value::Bool(false), Value::Bool(true)]);
}

#[test]
fn applying_a_state_transform_and_measuring_drift_does_not_allocate() {
    use cetratus_program::{Projection, StateTransform};
    use std::collections::BTreeMap;

    let old = cetratus_testkit::programs::example("vernadat/u1.toml");
    let new = cetratus_testkit::programs::example("vernadat/u2.toml");
    let st =
        StateTransform::generated(&old, &new, &BTreeMap::new()).unwrap_or_else(|e| panic!("{e}"));
    let pi = Projection::generated(old.net(), new.net()).expect("projection");
    let m_old = old.net().initial_marking();
    let since_old = [Some(5u64); 13];
    let mut m_new = [0u32; 15];
    let mut since_new = [None; 15];
    let mut result = Ok(());
    let mut drift = u64::MAX;
    let n = ALLOC.during(|| {
        for _ in 0..100 {
            result = st.apply(m_old.as_slice(), &new, &mut m_new);
            st.apply_timers(&since_old, &m_new, 1_000, &mut since_new);
            drift = pi.drift(&m_new, m_old.as_slice());
        }
    });
    assert_eq!(n, 0, "allocations at the cycle boundary");
    assert!(result.is_ok());
    assert_eq!(drift, 0);
    assert_eq!(since_new[0], Some(5), "H is kept and keeps its timer");
    assert_eq!(since_new[13], None, "P30 is empty");
}
