//! `cetratus check --property / --reach / --always` against the real binary, on the shared
//! fixtures whose answers are known (../shared/fixtures/README.md) and on a program file; bad
//! predicates, hostile ones included, get an error that names the column.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn fixture(rel: &str) -> PathBuf {
    cetratus_testkit::paths::fixture(rel)
}

fn run(file: &PathBuf, args: &[&str]) -> Output {
    Command::new(BIN)
        .arg("check")
        .arg(file)
        .args(args)
        .output()
        .expect("cetratus runs")
}

fn json(file: &PathBuf, args: &[&str]) -> Value {
    let out = run(file, &[args, &["--json"]].concat());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.stderr.is_empty(), "no progress in --json mode");
    serde_json::from_slice(&out.stdout).expect("a JSON report")
}

fn strings(v: &Value) -> Vec<String> {
    v.as_array()
        .expect("a list")
        .iter()
        .map(|s| s.as_str().expect("an id").to_string())
        .collect()
}

#[test]
fn the_philosophers_deadlock_is_found_with_a_witness_and_the_token_ring_has_none() {
    let phil = fixture("mcc/Philosophers-PT-000005.pnml");
    let full = json(&phil, &[]);
    let r = json(&phil, &["--property", "deadlock"]);
    assert_eq!(r["property"], "deadlock", "{r}");
    assert_eq!(r["holds"], true, "{r}");
    assert_eq!(r["reduction"], "stubborn", "{r}");
    assert_eq!(r["witness_shortest"], false, "{r}");
    assert_eq!(
        strings(&r["witness"]).len(),
        5,
        "five philosophers take one fork each: {r}"
    );
    let plain = json(&phil, &["--property", "deadlock", "--no-reduction"]);
    assert_eq!(plain["witness"], full["deadlock_witness"], "{plain}");
    assert_eq!(plain["witness_shortest"], true, "{plain}");
    assert_eq!(full["property"], Value::Null);

    let ring = json(
        &fixture("mcc/TokenRing-PT-005.pnml"),
        &["--property", "deadlock"],
    );
    assert_eq!(ring["holds"], false, "{ring}");
    assert_eq!(ring["witness"], Value::Null, "{ring}");
    let simple = json(&fixture("pipe5/simpleNet.xml"), &["--property", "deadlock"]);
    assert_eq!(simple["holds"], true, "{simple}");
}

#[test]
fn live_reversible_safe_and_bounded_agree_with_the_full_check_on_every_mcc_fixture() {
    for f in [
        "mcc/Philosophers-PT-000005.pnml",
        "mcc/TokenRing-PT-005.pnml",
        "mcc/FMS-PT-00002.pnml",
        "pipe/ProducerConsumer.xml",
        "pipe5/inhibitorArc.xml",
    ] {
        let file = fixture(f);
        let full = json(&file, &[]);
        for p in ["live", "reversible", "safe", "bounded"] {
            let r = json(&file, &["--property", p]);
            assert_eq!(r["holds"], full[p], "{f} {p}: {r}");
            assert_eq!(r["witness"].is_null(), r["holds"] == true, "{f} {p}: {r}");
        }
    }
}

#[test]
fn reach_and_always_take_place_names_in_a_bare_pnml_file_and_in_a_program() {
    let phil = fixture("mcc/Philosophers-PT-000005.pnml");
    let r = json(&phil, &["--reach", "Eat_1 == 1 && Eat_3 == 1"]);
    assert_eq!(r["holds"], true, "{r}");
    assert_eq!(
        strings(&r["witness"]).len(),
        4,
        "two philosophers take two forks: {r}"
    );
    let r = json(&phil, &["--reach", "Eat_1 + Eat_2 >= 2"]);
    assert_eq!(r["holds"], false, "neighbours share a fork: {r}");
    let r = json(&phil, &["--always", "Eat_1 + Eat_2 <= 1"]);
    assert_eq!(r["holds"], true, "{r}");
    let r = json(&phil, &["--always", "Fork_1 == 1"]);
    assert_eq!(r["holds"], false, "{r}");
    assert!(!strings(&r["witness"]).is_empty(), "{r}");

    let program = cetratus_testkit::paths::example("vernadat/u1.toml");
    let r = json(&program, &["--reach", "P10 >= 1 && P20 == 0"]);
    assert!(r["holds"].is_boolean(), "{r}");
    assert_eq!(r["property"], "reach P10 >= 1 && P20 == 0", "{r}");
}

#[test]
fn the_text_report_names_the_property_its_answer_and_the_witness() {
    let out = run(
        &fixture("mcc/Philosophers-PT-000005.pnml"),
        &["--property", "deadlock"],
    );
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("property deadlock: yes"), "{text}");
    assert!(text.contains("witness: "), "{text}");
}

fn refused(args: &[&str]) -> String {
    let out = run(&fixture("mcc/Philosophers-PT-000005.pnml"), args);
    assert!(matches!(out.status.code(), Some(1 | 2)), "{out:?}");
    assert!(out.stdout.is_empty());
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn bad_predicates_are_refused_with_the_column_at_fault() {
    let e = refused(&["--reach", "Eat_1 >= "]);
    assert!(e.contains("at column 10"), "{e}");
    let e = refused(&["--reach", "Eat_1 = 1"]);
    assert!(e.contains("at column 7") && e.contains("=="), "{e}");
    let e = refused(&["--always", "Eat_9 == 0"]);
    assert!(
        e.contains("no place \"Eat_9\"") && e.contains("at column 1"),
        "{e}"
    );
    let e = refused(&["--reach", "(Eat_1 == 1"]);
    assert!(e.contains("never closed"), "{e}");
    let e = refused(&["--property", "fair"]);
    assert!(e.contains("fair"), "{e}");
}

#[test]
fn hostile_predicates_end_in_an_error_not_a_crash() {
    // Deep nesting would overflow the stack of a recursive parser.
    let deep = format!("{}Eat_1 == 1{}", "(".repeat(50_000), ")".repeat(50_000));
    let e = refused(&["--reach", &deep]);
    assert!(e.contains("bytes long"), "{e}");
    let nested = format!("{}Eat_1 == 1{}", "(".repeat(1_000), ")".repeat(1_000));
    let e = refused(&["--reach", &nested]);
    assert!(e.contains("deeper than 256"), "{e}");
    let nots = format!("{}Eat_1 == 1", "!".repeat(60_000));
    let out = run(
        &fixture("mcc/Philosophers-PT-000005.pnml"),
        &["--json", "--reach", &nots],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let e = refused(&["--reach", "Eat_1 == 99999999999999999999"]);
    assert!(e.contains("too large"), "{e}");
    let e = refused(&[
        "--reach",
        "9223372036854775807*Eat_1 + 9223372036854775807*Eat_1 > 0",
    ]);
    assert!(e.contains("too large"), "{e}");
}
