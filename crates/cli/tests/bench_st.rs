//! `cetratus bench st` end to end: the four programs run on both sides, agree on their outputs
//! after the last scan (the bench refuses a figure otherwise), and each gets a ratio; the long
//! file is imported and translated into machine code; without MATIEC the bench says so and
//! measures Cetratus's side alone. `cetratus bench export` the same way.

use std::process::Command;

use cetratus_testkit::matiec::Matiec;
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn bench(args: &[&str]) -> Value {
    bench_of("st", args)
}

fn bench_of(which: &str, args: &[&str]) -> Value {
    let out = Command::new(BIN)
        .args(["bench", which, "--quick", "--json"])
        .args(args)
        .output()
        .expect("cetratus runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

#[test]
fn every_program_runs_on_both_sides_with_the_same_outputs_and_gets_a_ratio() {
    let matiec = Matiec::get().unwrap_or_else(|e| panic!("{e}"));
    let dir = matiec.dir().to_str().expect("a UTF-8 path");
    let f = bench(&["--matiec", dir]);
    assert_eq!(f["matiec_skipped"], Value::Null, "{f}");
    let programs = f["programs"].as_array().expect("programs");
    let names: Vec<&str> = programs.iter().filter_map(|p| p["name"].as_str()).collect();
    assert_eq!(names, ["pid", "rungs", "machine", "filter"]);
    for p in programs {
        for key in [
            "cetratus_ns",
            "pass_ns",
            "interpreted_ns",
            "matiec_ns",
            "ratio",
        ] {
            assert!(p[key].as_f64().is_some_and(|v| v > 0.0), "{key}: {p}");
        }
        if cfg!(any(target_arch = "x86_64", target_arch = "aarch64")) {
            assert_eq!(p["machine_code"], Value::Bool(true), "{p}");
        }
    }
    assert!(
        f["import_lines"].as_u64().is_some_and(|n| n >= 4_800),
        "{f}"
    );
    assert!(
        f["translate_ops"].as_u64().is_some_and(|n| n >= 10_000),
        "{f}"
    );
    if cfg!(any(target_arch = "x86_64", target_arch = "aarch64")) {
        assert!(f["translate_ms"].as_f64().is_some_and(|ms| ms > 0.0), "{f}");
    }
}

#[test]
fn without_matiec_the_bench_says_why_and_measures_cetratus_alone() {
    let f = bench(&["--matiec", "/nonexistent-matiec"]);
    let why = f["matiec_skipped"].as_str().expect("a reason");
    assert!(why.contains("no MATIEC install dir"), "{why}");
    assert!(f["programs"][0]["matiec_ns"].is_null(), "{f}");
    assert!(f["programs"][0]["cetratus_ns"].as_f64().is_some(), "{f}");
}

/// `cetratus bench export`: both programs exported, compiled and run on both sides, and the
/// SFC cell written back as its chart beside its import.
#[test]
fn bench_export_measures_both_programs_and_the_chart() {
    let matiec = Matiec::get().unwrap_or_else(|e| panic!("{e}"));
    let dir = matiec.dir().to_str().expect("a UTF-8 path");
    let f = bench_of("export", &["--matiec", dir]);
    assert_eq!(f["matiec_skipped"], Value::Null, "{f}");
    for p in f["programs"].as_array().expect("programs") {
        for key in ["export_ms", "cetratus_ns", "compiled_ns"] {
            assert!(p[key].as_f64().is_some_and(|v| v > 0.0), "{key}: {p}");
        }
    }
    let chart = &f["chart"];
    assert_eq!(chart["steps"], 10, "{chart}");
    for key in ["export_ms", "import_ms"] {
        assert!(
            chart[key].as_f64().is_some_and(|v| v > 0.0),
            "{key}: {chart}"
        );
    }
}
