use super::*;

const GOOD: &str = r#"
package = "u1.cpkg"
select = "line=1"
stages = ["1", "20%", "100%"]   # cumulative; the first is the canary
quarantine = "30s"
require_verdict = false
probation = "60s"
max_parallel = 5
on_failure = "stop"
"#;

fn fleet(n: usize) -> Vec<(String, Labels)> {
    (0..n)
        .map(|i| {
            let mut l = Labels::new();
            l.insert("line".into(), if i % 4 == 3 { "2" } else { "1" }.into());
            l.insert("cell".into(), format!("press-{i}"));
            (format!("plc-{i:02}"), l)
        })
        .collect()
}

fn refusal(text: &str) -> String {
    Plan::parse(text, "rollout.toml", Path::new("/plans"))
        .expect_err("refused")
        .to_string()
}

#[test]
fn the_example_plan_reads_and_its_stages_split_the_selection_cumulatively() {
    let plan = Plan::parse(GOOD, "rollout.toml", Path::new("/plans")).unwrap();
    assert_eq!(plan.package, Path::new("/plans/u1.cpkg"));
    assert_eq!(
        (plan.quarantine_us, plan.probation_us),
        (30_000_000, 60_000_000)
    );
    assert_eq!((plan.max_parallel, plan.on_failure), (5, OnFailure::Stop));
    // 20 PLCs, 15 of line 1: the canary, then 20% of 15 rounded up (3), then the rest.
    let stages = plan.stage_members(&fleet(20)).unwrap();
    let sizes: Vec<usize> = stages.iter().map(Vec::len).collect();
    assert_eq!(sizes, [1, 2, 12]);
    assert_eq!(stages[0], ["plc-00"]);
    assert!(stages.concat().iter().all(|id| id != "plc-03"));
}

#[test]
fn a_named_canary_and_label_groups_are_stages_too_and_the_last_takes_the_rest() {
    let text = GOOD.replace(
        r#"stages = ["1", "20%", "100%"]"#,
        r#"stages = ["plc-05", "cell=press-1*", "50%"]"#,
    );
    let plan = Plan::parse(&text, "rollout.toml", Path::new(".")).unwrap();
    let stages = plan.stage_members(&fleet(20)).unwrap();
    assert_eq!(stages[0], ["plc-05"]);
    // press-1, press-10 … press-18 of line 1 (press-11, press-15 and press-19 are line 2).
    assert_eq!(stages[1].len(), 8, "{:?}", stages[1]);
    assert_eq!(stages.concat().len(), 15);
}

#[test]
fn an_empty_selection_is_refused_naming_the_selector() {
    let plan = Plan::parse(&GOOD.replace("line=1", "line=9"), "r", Path::new(".")).unwrap();
    let e = plan.stage_members(&fleet(4)).unwrap_err().to_string();
    assert!(e.contains("`line=9` picks no PLC"), "{e}");
}

#[test]
fn bad_plans_are_refused_with_the_key_and_what_to_write() {
    for (from, to, says) in [
        (
            "max_parallel = 5",
            "max_parallel = 0",
            "`max_parallel` is 0",
        ),
        (
            r#"quarantine = "30s""#,
            r#"quarantine = "30""#,
            "`quarantine` `30`",
        ),
        (
            r#"probation = "60s""#,
            r#"probation = "soon""#,
            "`probation` `soon`",
        ),
        (
            r#"on_failure = "stop""#,
            r#"on_failure = "panic""#,
            "unknown variant `panic`",
        ),
        (
            r#"select = "line=1""#,
            r#"select = """#,
            "an empty selector",
        ),
        (r#"["1", "20%", "100%"]"#, "[]", "has 0 stages"),
        (
            r#"["1", "20%", "100%"]"#,
            r#"["1", "150%"]"#,
            "a share is 1% to 100%",
        ),
        (
            r#"["1", "20%", "100%"]"#,
            r#"["5", "2"]"#,
            "stages are cumulative",
        ),
        (
            r#"["1", "20%", "100%"]"#,
            r#"["0"]"#,
            "a count is 1 or more",
        ),
        (
            r#"package = "u1.cpkg""#,
            r#"package = " ""#,
            "`package` is empty",
        ),
        (
            "max_parallel = 5",
            "max_parallel = 5\nspeed = 3",
            "unknown field `speed`",
        ),
        (r#"package = "u1.cpkg""#, "", "missing field `package`"),
    ] {
        let text = GOOD.replace(from, to);
        assert_ne!(text, GOOD, "{from}");
        let e = refusal(&text);
        assert!(e.contains(says) && e.contains("rollout.toml"), "{to}: {e}");
    }
    let e = refusal("this is not toml [");
    assert!(e.contains("rollout.toml"), "{e}");
}

#[test]
fn an_oversized_plan_file_is_refused_before_it_is_read() {
    let dir = std::env::temp_dir().join(format!("cetratus-plan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("rollout.toml");
    std::fs::write(&path, "#".repeat(MAX_PLAN_BYTES + 1)).unwrap();
    let e = Plan::load(&path).unwrap_err().to_string();
    assert!(e.contains("more than the 65536"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
