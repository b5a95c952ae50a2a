//! The Festo processing station with its reject branch, run by the real binary in virtual time:
//! `cetratus run examples/festo/festo.toml --twin festo --virtual --for 1h --defect-rate 5% --json`.

use std::process::Command;

use cetratus_testkit::paths::example;
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// Runs the Festo example for `length` of program time and returns the JSON summary.
fn run_festo(length: &str, extra: &[&str]) -> Value {
    let program = example("festo/festo.toml");
    let out = Command::new(BIN)
        .arg("run")
        .arg(&program)
        .args(["--twin", "festo", "--virtual", "--for", length, "--json"])
        .args(extra)
        .output()
        .expect("run cetratus");
    assert!(
        out.status.success(),
        "cetratus run failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("run --json prints one JSON object")
}

fn count(summary: &Value, name: &str) -> u64 {
    summary["counters"][name]
        .as_u64()
        .unwrap_or_else(|| panic!("no counter {name} in {summary}"))
}

#[test]
fn an_hour_at_five_percent_defects_rejects_every_defective_part_and_drills_every_good_one() {
    let s = run_festo("1h", &["--defect-rate", "5%", "--seed", "1"]);
    let supplied = count(&s, "parts_supplied");
    let defective = count(&s, "parts_defective");
    let rejected = count(&s, "parts_rejected");
    let good = count(&s, "parts_good");
    println!(
        "festo, 1 h at 5 % defects: {supplied} supplied, {defective} defective, {rejected} rejected, \
         {good} good, {} twin faults",
        s["twin_faults"]
    );
    assert_eq!(s["twin_faults"], 0, "{s}");
    assert_eq!(s["faults"], Value::Array(Vec::new()), "{s}");
    // One part every 5 s: 720 in the hour, about 36 of them defective.
    assert_eq!(supplied, 720);
    assert!(
        (20..=60).contains(&defective),
        "{defective} defective parts"
    );
    // A defective part is rejected at the tester, so only one not yet tested can be left.
    assert!(
        defective - rejected <= 1,
        "{defective} defective, {rejected} rejected"
    );
    assert_eq!(count(&s, "parts_rejected_good"), 0);
    assert_eq!(count(&s, "parts_ejected_defective"), 0);
    // Every good part that left was tested and drilled.
    assert_eq!(count(&s, "parts_ejected_incomplete"), 0);
    assert_eq!(good, count(&s, "parts_ejected"));
    assert!(
        supplied - rejected - good <= 4,
        "the table holds at most four parts between the input and the ejector"
    );
    assert_eq!(s["parts_finished"], good, "a finished part is a good one");
}

#[test]
fn the_seed_decides_which_parts_are_defective_and_the_same_seed_gives_the_same_counts() {
    let a = run_festo("600s", &["--defect-rate", "0.2", "--seed", "7"]);
    let b = run_festo("600s", &["--defect-rate", "0.2", "--seed", "7"]);
    let c = run_festo("600s", &["--defect-rate", "0.2", "--seed", "8"]);
    assert_eq!(a["counters"], b["counters"]);
    assert_eq!(a["firings"], b["firings"]);
    assert_ne!(a["counters"], c["counters"], "the seed had no effect");
}

#[test]
fn without_a_defect_rate_every_part_is_good() {
    let s = run_festo("600s", &[]);
    assert_eq!(count(&s, "parts_defective"), 0);
    assert_eq!(count(&s, "parts_rejected"), 0);
    assert_eq!(s["twin_faults"], 0, "{s}");
}

#[test]
fn a_defect_rate_is_refused_when_it_is_not_a_share_or_the_twin_makes_no_defects() {
    let refused = |args: &[&str]| {
        let out = Command::new(BIN)
            .arg("run")
            .args(args)
            .args(["--virtual", "--for", "1s"])
            .output()
            .expect("run cetratus");
        assert!(!out.status.success(), "{args:?} was accepted");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let festo = example("festo/festo.toml");
    let festo = festo.to_str().expect("a UTF-8 path");
    let err = refused(&[festo, "--twin", "festo", "--defect-rate", "120%"]);
    assert!(
        err.contains("--defect-rate") && err.contains("between 0 and 1"),
        "{err}"
    );
    let vernadat = example("vernadat/vernadat.toml");
    let vernadat = vernadat.to_str().expect("a UTF-8 path");
    let err = refused(&[vernadat, "--twin", "vernadat", "--defect-rate", "5%"]);
    assert!(err.contains("makes no defective parts"), "{err}");
}
