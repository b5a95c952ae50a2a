//! Action bodies that do not load: each refusal names the file, line and column, and says what
//! to do. None is a crash, whatever the nesting.

mod common;

fn refused(bodies: &str, actions: &str) -> String {
    let src = format!(
        "[program]\nname = \"small\"\nversion = \"1\"\n\
         [[input]]\nname = \"x\"\ntype = \"bool\"\n\
         [[output]]\nname = \"o\"\ntype = \"int\"\n\
         [[variable]]\nname = \"v\"\ntype = \"int\"\n\
         [[variable]]\nname = \"r\"\ntype = \"real\"\n\
         {actions}\n[bodies]\n{bodies}"
    );
    match cetratus_program::Program::from_sources(&src, "b.toml", cetratus_testkit::nets::small()) {
        Ok(_) => panic!("loaded: {bodies}"),
        Err(e) => e.to_string(),
    }
}

const RUN_X: &str = "[[action]]\nplace = \"A\"\nqualifier = \"N\"\nbody = \"X\"\n";

#[test]
fn type_errors_unknown_names_and_inputs_are_refused_at_their_column() {
    for (body, at, what) in [
        (
            "X = 'v := r'",
            "b.toml:22:11",
            "`v` is int but the value is real",
        ),
        ("X = 'v := w + 1'", "b.toml:22:11", "unknown name `w`"),
        ("X = 'x := true'", "b.toml:22:6", "is an input"),
        ("X = 'v := A.t'", "b.toml:22:11", "duration"),
        ("X = 'if v then'", "b.toml:22:9", "must be a bool"),
        ("X = 'if v > 1 then'", "b.toml:22:6", "has no `end`"),
        ("X = 'else'", "b.toml:22:6", "`else` without an `if`"),
        (
            "X = 'if true then; else; elif true then; end'",
            "b.toml:22:",
            "after `else`",
        ),
        ("X = 'v = 1'", "b.toml:22:6", "is not a statement"),
        ("X = 'WHILE v < 3 DO'", "b.toml:22:6", "is not a statement"),
    ] {
        let e = refused(body, RUN_X);
        assert!(e.starts_with(at), "{body}: {e}");
        assert!(e.contains(what), "{body}: {e}");
        assert!(e.contains("in the body X"), "{e}");
    }
}

#[test]
fn an_action_needs_a_declared_body_and_every_body_an_action() {
    let e = refused("Y = 'v := 1'", RUN_X);
    assert!(e.contains("no body `X` in [bodies]"), "{e}");
    let e = refused("X = 'v := 1'\nY = 'v := 2'", RUN_X);
    assert!(e.contains("the body Y is run by no action"), "{e}");
    let both = "[[action]]\nplace = \"A\"\nqualifier = \"N\"\nbody = \"X\"\ntarget = \"o\"\n";
    assert!(refused("X = 'v := 1'", both).contains("not both"));
}

#[test]
fn if_nested_past_the_limit_is_refused_and_any_depth_is_no_crash() {
    for depth in [33usize, 10_000] {
        let text = "if true then\n".repeat(depth) + &"end\n".repeat(depth);
        let e = refused(&format!("X = '''\n{text}'''"), RUN_X);
        assert!(
            e.contains("nested more than 32 deep") || e.contains("longer than"),
            "{e}"
        );
    }
    let many = "v := 1\n".repeat(600);
    let e = refused(&format!("X = '''\n{many}'''"), RUN_X);
    assert!(e.contains("more than 512 statements"), "{e}");
}

mod fuzz {
    use cetratus_program::{ActionState, EvalCtx, Program, Value, Work};
    use proptest::prelude::*;

    fn token() -> impl Strategy<Value = &'static str> {
        prop::sample::select(vec![
            "if ",
            "elif ",
            "else",
            "end",
            " then",
            "v",
            "r",
            "o",
            "x",
            ":=",
            " := ",
            "=",
            "+",
            "-",
            "*",
            "/",
            "(",
            ")",
            "1",
            "0",
            "9223372036854775807",
            "1.5",
            "true",
            "&&",
            "||",
            "!",
            ">",
            "==",
            "A.t",
            "B.dwell",
            "3s",
            "real(",
            "int(",
            "\n",
            ";",
            "#",
            " ",
        ])
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        #[test]
        fn token_soup_bodies_load_or_are_refused_and_what_loads_runs_or_fails_cleanly(
            toks in prop::collection::vec(token(), 0..60),
        ) {
            let body: String = toks.concat();
            let src = format!(
                "[program]\nname = \"s\"\nversion = \"1\"\n\
                 [[input]]\nname = \"x\"\ntype = \"bool\"\n\
                 [[output]]\nname = \"o\"\ntype = \"int\"\n\
                 [[variable]]\nname = \"v\"\ntype = \"int\"\n\
                 [[variable]]\nname = \"r\"\ntype = \"real\"\n\
                 [[action]]\nplace = \"A\"\nqualifier = \"N\"\nbody = \"X\"\n\
                 [bodies]\nX = '''\n{body}'''\n"
            );
            let Ok(p) = Program::from_sources(&src, "f.toml", cetratus_testkit::nets::small()) else {
                return Ok(());
            };
            let mut st = ActionState::new(&p);
            let (m, since) = (vec![1u32, 0, 2], vec![Some(0), None, Some(0)]);
            let ctx = EvalCtx {
                inputs: &[Value::Bool(true)],
                prev_inputs: &[Value::Bool(false)],
                vars: &[],
                marking: &m,
                place_since_us: &since,
                place_dwell_us: &[],
                now_us: 5_000_000,
            };
            let (mut out, mut vars) = (vec![Value::Int(0)], vec![Value::Int(3), Value::Real(0.5)]);
            let _ = st.start(&p, &ctx, &mut out, &mut vars, &mut Work::unlimited());
            prop_assert!(matches!(vars[0], Value::Int(_)) && matches!(vars[1], Value::Real(_)));
            prop_assert!(matches!(out[0], Value::Int(_)));
        }
    }
}
