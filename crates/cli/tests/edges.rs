//! Numbers at the edge of their range, against the real binary: a `within` that would overflow
//! when turned into microseconds, and a state file whose counters are at `u64::MAX`. Each must be
//! refused with a message that says what to do, and nothing may crash.

mod common;

use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

use cetratus_testkit::ports::free_port;
use common::{client, first_answer, reply, request, RunningPlc};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn cetratus(args: &[&str], dir: Option<&Path>) -> Output {
    let mut cmd = Command::new(BIN);
    cmd.args(args);
    if let Some(d) = dir {
        cmd.arg(d);
    }
    cmd.output().expect("cetratus runs")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

#[test]
fn a_substitute_whose_within_overflows_is_refused_and_the_plc_goes_on_answering() {
    let plc = RunningPlc::start("edge1", &[]);
    let (c, replies) = client(plc.mqtt, "edge-client", "edge1");
    first_answer(&c, &replies, "edge1", Duration::from_secs(30));
    for (corr, within) in [
        (&b"max"[..], u64::MAX),
        (b"wraps", u64::MAX / 1000 + 1),
        (b"25h", 25 * 3_600_000),
    ] {
        let body = format!("{{\"within_ms\": {within}}}").into_bytes();
        request(&c, "edge1", "substitute", corr, body);
        let r = reply(&replies, corr, Duration::from_secs(30));
        assert_eq!(r["ok"], false, "{r}");
        assert_eq!(r["error"]["code"], "malformed", "{r}");
        let m = r["error"]["message"].as_str().unwrap_or("");
        assert!(m.contains("within_ms") && m.contains("24 h"), "{m}");
    }
    request(&c, "edge1", "exec_info", b"after", b"{}".to_vec());
    let r = reply(&replies, b"after", Duration::from_secs(30));
    assert_eq!(r["ok"], true, "the PLC still answers: {r}");
}

#[test]
fn the_cli_refuses_a_substitute_within_over_24_hours_before_sending_it() {
    // Nothing listens on the broker port: the refusal must come first.
    let broker = format!("mqtt://127.0.0.1:{}", free_port());
    for within in ["25h", "1000000000000h"] {
        let out = cetratus(
            &[
                "substitute",
                "--within",
                within,
                "--plc",
                "edge1",
                "--broker",
                &broker,
            ],
            None,
        );
        assert!(!out.status.success());
        let t = text(&out);
        assert!(t.contains("--within") && t.contains("24 h"), "{t}");
        assert!(!t.contains("panicked"), "{t}");
    }
}

/// A change made to a state file.
type Edit = fn(&mut serde_json::Value);

/// A state directory written by a short virtual run, with `edit` applied to its state file.
fn state_with(edit: impl Fn(&mut serde_json::Value)) -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("a state directory");
    let program = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/vernadat/vernadat.toml"
    );
    let out = cetratus(
        &[
            "run",
            program,
            "--twin",
            "vernadat",
            "--virtual",
            "--for",
            "1s",
            "--state-dir",
        ],
        Some(dir.path()),
    );
    assert!(out.status.success(), "{}", text(&out));
    let path = dir.path().join("state.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("state.json"))
            .expect("state.json is JSON");
    edit(&mut v);
    std::fs::write(&path, v.to_string()).expect("state.json is written");
    dir
}

#[test]
fn a_state_file_with_counters_at_u64_max_is_refused_by_state_and_by_a_warm_start() {
    let program = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/vernadat/vernadat.toml"
    );
    let edits: [(&str, Edit); 3] = [
        ("cycle", |v| v["snapshot"]["cycle"] = u64::MAX.into()),
        ("time_us", |v| v["snapshot"]["time_us"] = u64::MAX.into()),
        ("seq", |v| v["seq"] = u64::MAX.into()),
    ];
    for (field, edit) in edits {
        let dir = state_with(edit);
        let out = cetratus(&["state"], Some(dir.path()));
        let t = text(&out);
        assert!(
            !out.status.success(),
            "{field}: `state` reports a problem: {t}"
        );
        assert!(t.contains(field) && t.contains("--cold"), "{field}: {t}");
        assert!(!t.contains("panicked"), "{field}: {t}");

        let out = cetratus(
            &[
                "run",
                program,
                "--twin",
                "vernadat",
                "--virtual",
                "--for",
                "1s",
                "--state-dir",
            ],
            Some(dir.path()),
        );
        let t = text(&out);
        assert!(
            !out.status.success(),
            "{field}: the warm start is refused: {t}"
        );
        assert!(t.contains(field) && t.contains("--cold"), "{field}: {t}");
        assert!(!t.contains("panicked"), "{field}: {t}");

        // The way out the message gives works.
        let out = cetratus(
            &[
                "run",
                program,
                "--twin",
                "vernadat",
                "--virtual",
                "--for",
                "1s",
                "--cold",
                "--state-dir",
            ],
            Some(dir.path()),
        );
        assert!(out.status.success(), "{field}: --cold: {}", text(&out));
    }
}
