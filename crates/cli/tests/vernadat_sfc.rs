//! The Vernadat cell written by hand as an SFC (examples/vernadat-sfc): imported through the real
//! binary it runs an hour on the twin in virtual time like the Petri-net version, and its U.1
//! (the buffer grows to 9 slots) loads from the PLCopen files, runs in quarantine and substitutes.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn example(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(rel)
}

fn cetratus(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("cetratus runs")
}

fn ok(out: Output) -> String {
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

fn s(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

/// Imports the SFC cell into `dir` and returns its program file.
fn import(dir: &Path) -> PathBuf {
    let xml = example("vernadat-sfc/vernadat-sfc.xml");
    ok(cetratus(&["import", "plcopen", s(&xml), "-o", s(dir)]));
    dir.join("Cell.toml")
}

/// `parts finished` of a `run` report.
fn parts(report: &str) -> i64 {
    report
        .lines()
        .find_map(|l| l.trim().strip_prefix("parts finished"))
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("no parts count in {report}"))
}

#[test]
fn the_sfc_cell_runs_an_hour_on_the_twin_like_the_petri_net_cell() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let program = import(dir.path());
    let hour = |p: &Path| {
        ok(cetratus(&[
            "run",
            s(p),
            "--twin",
            "vernadat",
            "--virtual",
            "--for",
            "1h",
        ]))
    };
    let sfc = hour(&program);
    let net = hour(&example("vernadat/vernadat.toml"));
    assert!(sfc.contains("faults          none"), "{sfc}");
    assert!(sfc.contains("parts_scrapped  0"), "{sfc}");
    let (a, b) = (parts(&sfc), parts(&net));
    assert!((a - b).abs() <= 1, "SFC {a} parts, net {b}\n{sfc}\n{net}");
    assert!(a >= 440, "{sfc}");
}

#[test]
fn the_sfc_u1_loads_runs_in_quarantine_and_substitutes() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let program = import(&d.join("cell"));
    let key = d.join("operator.key");
    ok(cetratus(&["package", "keygen", "--out", s(&key)]));
    let trusted = d.join("trusted");
    std::fs::create_dir(&trusted).expect("a trust directory");
    std::fs::copy(d.join("operator.key.pub"), trusted.join("operator.pub"))
        .expect("trusts the key");
    std::fs::create_dir(d.join("config")).expect("a configuration directory");
    let pkg = d.join("u1.cpkg");
    let built = ok(cetratus(&[
        "package",
        "build",
        s(&example("vernadat-sfc/u1.package.toml")),
        "--key",
        s(&key),
        "--out",
        s(&pkg),
    ]));
    assert!(built.contains("U.1 buffer capacity 9 (SFC)"), "{built}");
    let state = d.join("state");
    let run = ok(cetratus(&[
        "run",
        s(&program),
        "--twin",
        "vernadat",
        "--virtual",
        "--for",
        "120s",
        "--trust",
        s(&trusted),
        "--config",
        s(&d.join("config")),
        "--at",
        &format!("10s load {}", s(&pkg)),
        "--at",
        "60s substitute",
        "--state-dir",
        s(&state),
    ]));
    assert!(run.contains("faults          none"), "{run}");
    let audit = std::fs::read_to_string(state.join("audit.jsonl")).expect("the audit log");
    let whats: Vec<String> = audit
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).expect("a record"))
        .map(|r| r["what"].as_str().unwrap_or("").to_string())
        .collect();
    let at = |w: &str| whats.iter().position(|x| x == w);
    let (q, sub) = (at("quarantine_started"), at("substituted"));
    assert!(q.is_some() && sub.is_some() && q < sub, "{whats:?}");
    assert!(!whats.iter().any(|w| w.contains("fault")), "{whats:?}");
}
