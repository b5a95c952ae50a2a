//! The client commands report what their command caused, not only that the PLC accepted it:
//! `substitute`, `remove` and `abort` wait for their outcome event, print it, exit non-zero when
//! it is a refusal, and exit 3 when a waiting substitution outlasts `--timeout`.

mod common;

use std::process::{Command, Output};

use common::RunningPlc;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

struct Client {
    plc: &'static str,
    mqtt: String,
}

impl Client {
    fn run(&self, args: &[&str]) -> Output {
        Command::new(BIN)
            .args(args)
            .args(["--plc", self.plc, "--mqtt", &self.mqtt])
            .output()
            .expect("the client runs")
    }
}

fn text(out: &Output) -> String {
    format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

#[test]
fn substitute_remove_and_abort_wait_for_their_outcome_and_exit_by_it() {
    let files = cetratus_testkit::process::demo_files(BIN);
    let trusted = files.path().join("trusted").display().to_string();
    let u1 = files.path().join("u1.cpkg").display().to_string();
    let plc = RunningPlc::start("outcomes1", &["--trust", &trusted]);
    let c = Client {
        plc: "outcomes1",
        mqtt: format!("127.0.0.1:{}", plc.mqtt),
    };

    let out = c.run(&["load", &u1]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));

    // A condition that never holds: still pending when the client stops waiting.
    let out = c.run(&[
        "substitute",
        "--when",
        "P10 == 5",
        "--within",
        "1h",
        "--timeout",
        "2s",
    ]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out));
    assert!(text(&out).contains("still pending"), "{}", text(&out));

    // Abort takes the waiting substitution with the candidate.
    let out = c.run(&["abort"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("abort: aborted:"),
        "{}",
        text(&out)
    );

    // A condition that fails to evaluate: the substitution is given up at the boundary, and
    // the client says so with a non-zero exit.
    let out = c.run(&["load", &u1]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let out = c.run(&["substitute", "--when", "P10 / (P10 - P10) > 0"]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert!(
        text(&out).contains("substitute failed: substitute_timeout"),
        "{}",
        text(&out)
    );

    // Remove: the candidate is gone when the client returns.
    let out = c.run(&["remove", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(v["outcome"], "done", "{v}");
    assert_eq!(v["event"]["kind"], "removed", "{v}");

    // A plain substitution: done when PRIMARY has flipped.
    let out = c.run(&["load", &u1]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let out = c.run(&["substitute"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("substitute: substituted: PRIMARY = B"),
        "{}",
        text(&out)
    );

    // Refused in the reply: nothing to remove.
    let out = c.run(&["remove"]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert!(text(&out).contains("remove refused"), "{}", text(&out));
}

#[test]
fn revert_and_accept_end_probation_wait_for_their_outcome_and_exit_by_it() {
    let files = cetratus_testkit::process::demo_files(BIN);
    let trusted = files.path().join("trusted").display().to_string();
    let u1 = files.path().join("u1.cpkg").display().to_string();
    // No `[updates] probation` in the configuration: a minute of probation by default.
    let plc = RunningPlc::start("outcomes2", &["--trust", &trusted]);
    let c = Client {
        plc: "outcomes2",
        mqtt: format!("127.0.0.1:{}", plc.mqtt),
    };
    let stdout = |out: &Output| String::from_utf8_lossy(&out.stdout).to_string();

    // Nothing on probation yet. (The embedded broker may still be coming up on a loaded
    // machine: a connection it closes is tried again.)
    let mut out = c.run(&["revert"]);
    for _ in 0..30 {
        if !text(&out).contains("MQTT connection") {
            break;
        }
        std::thread::sleep(std::time::Duration::from_secs(1));
        out = c.run(&["revert"]);
    }
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert!(text(&out).contains("revert refused"), "{}", text(&out));

    // Revert: the old program drives the outputs again when the client returns. The load's
    // reply carries the analysis gate's verdict, and so does the candidate's exec_info.
    let out = c.run(&["load", &u1, "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    let verdict = &v["reply"]["result"]["verdicts"][0];
    assert_eq!(
        (verdict["kind"].as_str(), verdict["result"].as_str()),
        (Some("analysis"), Some("pass")),
        "{v}"
    );
    let out = c.run(&["exec-info", "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).expect("exec_info");
    assert_eq!(
        info["result"][1]["verdicts"][0]["kind"], "analysis",
        "{info}"
    );
    let out = c.run(&["substitute"]);
    assert!(
        stdout(&out).contains("A stays as a shadow"),
        "{}",
        text(&out)
    );
    let out = c.run(&["status", "--json"]);
    let state: serde_json::Value = serde_json::from_slice(&out.stdout).expect("the state");
    assert_eq!(
        (state["primary"].as_str(), state["status"].as_str()),
        (Some("B"), Some("probation")),
        "{state}"
    );
    // The same state and figures as text, read through proto's types.
    let out = c.run(&["status"]);
    assert!(
        stdout(&out).contains("PRIMARY B   STATUS probation"),
        "{}",
        text(&out)
    );
    let out = c.run(&["exec-info"]);
    assert!(stdout(&out).contains("B (primary): "), "{}", text(&out));
    assert!(!stdout(&out).contains("not read"), "{}", text(&out));
    let out = c.run(&["revert", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(v["event"]["kind"], "reverted", "{v}");
    assert_eq!(v["event"]["detail"]["reason"], "operator", "{v}");
    assert!(
        v["event"]["message"]
            .as_str()
            .is_some_and(|m| m.starts_with("PRIMARY = A")),
        "{v}"
    );

    // The same package loads again against the old program; accept makes it final.
    assert_eq!(c.run(&["load", &u1]).status.code(), Some(0));
    assert_eq!(c.run(&["substitute"]).status.code(), Some(0));
    let out = c.run(&["accept"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(stdout(&out).contains("accept: accepted:"), "{}", text(&out));
    let out = c.run(&["accept"]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert!(text(&out).contains("accept refused"), "{}", text(&out));
}
