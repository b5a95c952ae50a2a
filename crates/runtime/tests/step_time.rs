//! `P.dwell`, IEC's `Step.T`: while a place is marked it counts as `P.t` does; once the place is
//! left it keeps how long it was marked, until the place is marked again.

use std::sync::Arc;

use cetratus_program::{EvalCtx, Program, Value};
use cetratus_runtime::Container;

fn program() -> Arc<Program> {
    let src = "[program]\nname = \"dwell\"\nversion = \"1\"\n\
        [[input]]\nname = \"x\"\ntype = \"bool\"\n\
        [guards]\nT1 = \"x\"\nT2 = \"!x\"\nT3 = \"false\"\n";
    Arc::new(
        Program::from_sources(src, "dwell.toml", cetratus_testkit::nets::small())
            .unwrap_or_else(|e| panic!("{e}")),
    )
}

/// Evaluates `condition` on the container's state at `now_us`.
fn holds(c: &Container, condition: &str, now_us: u64) -> bool {
    let g = c.program().compile_condition(condition).expect("compiles");
    let ctx = EvalCtx {
        inputs: c.inputs(),
        prev_inputs: c.inputs(),
        vars: c.variables(),
        marking: c.marking(),
        place_since_us: c.place_since_us(),
        place_dwell_us: c.place_dwell_us(),
        now_us,
    };
    g.eval(&ctx).expect("evaluates")
}

#[test]
fn a_step_time_keeps_its_value_after_the_step_is_left_until_it_is_entered_again() {
    let mut c = Container::new(program(), 0);
    let on = [Value::Bool(true)];
    let off = [Value::Bool(false)];
    c.scan(0, &off).expect("scans");
    assert!(holds(&c, "B.dwell == 0s && B.t == 0s", 0), "never marked");
    c.scan(10_000, &on).expect("A -> B");
    assert!(holds(&c, "B.dwell == 20ms && B.t == 20ms", 30_000));
    c.scan(50_000, &off).expect("B -> A");
    // B was marked from 10 ms to 50 ms: its dwell stays 40 ms, its `.t` is 0 s.
    assert!(holds(&c, "B.dwell == 40ms && B.t == 0s", 90_000));
    c.scan(100_000, &off).expect("scans");
    assert!(holds(&c, "B.dwell == 40ms", 500_000));
    c.scan(600_000, &on).expect("A -> B again");
    assert!(
        holds(&c, "B.dwell == 5ms", 605_000),
        "reset on the new activation"
    );
}
