//! `[updates]` in the local configuration sets stateTransTimeout: a virtual run of the paper's
//! U.1 then U.2, whose installs a virtual run charges 980 ns and 1100 ns, with a budget of 1 µs
//! between them.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// The demo's files (program, U.1 and U.2 signed, the key's `trusted/`) and a `config/`
/// directory holding `config`.
fn demo_files(config: &str) -> tempfile::TempDir {
    let dir = cetratus_testkit::process::demo_files(BIN);
    let c = dir.path().join("config");
    std::fs::write(c.join("config.toml"), config).expect("config.toml");
    use std::os::unix::fs::PermissionsExt;
    for p in [c.clone(), c.join("config.toml")] {
        let mode = if p.is_dir() { 0o700 } else { 0o600 };
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(mode)).expect("chmod");
    }
    dir
}

/// The audit log's `(what, detail)` of a virtual run loading U.1 at 10 s, substituting it at
/// 20 s, accepting it at 22 s and loading U.2 at 25 s.
fn run_updates(d: &Path) -> Vec<(String, Value)> {
    let state = tempfile::tempdir().expect("a state directory");
    let p = |x: &Path| x.display().to_string();
    let out = Command::new(BIN)
        .arg("run")
        .arg(d.join("vernadat.toml"))
        .args(["--twin", "vernadat", "--virtual", "--for", "30s", "--json"])
        .args(["--trust", &p(&d.join("trusted"))])
        .args(["--config", &p(&d.join("config"))])
        .args(["--at", &format!("10s load {}", p(&d.join("u1.cpkg")))])
        .args(["--at", "20s substitute"])
        .args(["--at", "22s accept"])
        .args(["--at", &format!("25s load {}", p(&d.join("u2.cpkg")))])
        .arg("--state-dir")
        .arg(state.path())
        .output()
        .expect("cetratus run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::read_to_string(state.path().join("audit.jsonl"))
        .expect("the audit log")
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).expect("an audit record"))
        .map(|r| {
            (
                r["what"].as_str().unwrap_or("").to_string(),
                r["detail"].clone(),
            )
        })
        .collect()
}

fn installs(audit: &[(String, Value)]) -> Vec<(&str, u64)> {
    audit
        .iter()
        .filter(|(w, _)| w == "quarantine_started" || w == "state_trans_timeout")
        .map(|(w, d)| (w.as_str(), d["budget_ns"].as_u64().unwrap_or(0)))
        .collect()
}

#[test]
fn state_trans_timeout_set_in_the_updates_section_refuses_an_install_that_takes_longer() {
    let demo = demo_files("[updates]\nstate_trans_timeout = \"1us\"\n");
    let audit = run_updates(demo.path());
    assert_eq!(
        installs(&audit),
        [("quarantine_started", 1000), ("state_trans_timeout", 1000)],
        "U.1 fits 1 µs, U.2 does not: {audit:?}"
    );
}

#[test]
fn without_the_setting_state_trans_timeout_is_one_scan_period() {
    let demo = demo_files("");
    let audit = run_updates(demo.path());
    assert_eq!(
        installs(&audit),
        [
            ("quarantine_started", 10_000_000),
            ("quarantine_started", 10_000_000)
        ],
        "{audit:?}"
    );
}
