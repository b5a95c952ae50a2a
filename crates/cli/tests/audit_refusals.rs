//! A client that sends refused commands as fast as it can does not grow the PLC's audit log at
//! its own pace: a burst of refusals is logged one by one, then one a second of program time,
//! and the rest are counted in a `refusals_not_logged` record (docs/persistence.md).

mod common;

use std::time::Duration;

use common::{client, request, wait_for, RunningPlc};
use serde_json::Value;

const PLC: &str = "audited";
const SENT: usize = 400;

#[test]
fn a_flood_of_refused_commands_logs_a_burst_and_counts_the_rest() {
    let mut plc = RunningPlc::start(PLC, &[]);
    let (ops, replies) = client(plc.mqtt, "audit-flood", PLC);
    // Nothing is loaded: every `remove` reaches the scan thread and is refused there.
    for k in 0..SENT {
        request(
            &ops,
            PLC,
            "remove",
            format!("r{k}").as_bytes(),
            b"{}".to_vec(),
        );
    }
    // The broker may turn part of a flood away; what it lets through is answered. The flood is
    // over when no answer has come for two seconds.
    let answered = || replies.lock().map(|r| r.len()).unwrap_or(0);
    let mut seen = (answered(), std::time::Instant::now());
    wait_for("the replies to settle", Duration::from_secs(60), || {
        let now = answered();
        if now != seen.0 {
            seen = (now, std::time::Instant::now());
        }
        now > 0 && seen.1.elapsed() > Duration::from_secs(2)
    });
    let refused = replies
        .lock()
        .expect("replies")
        .values()
        .filter(|r| r["error"]["code"] == "refused")
        .count();
    assert!(
        refused > 2 * cetratus_persist::REFUSAL_BURST as usize,
        "the flood was refused, not turned away: {refused} of {SENT}"
    );
    let state = plc.state.path().to_path_buf();
    sigterm(&mut plc);

    let text = std::fs::read_to_string(state.join("audit.jsonl")).expect("the audit log");
    let records: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON record"))
        .collect();
    let logged = records.iter().filter(|r| r["what"] == "refused").count();
    let counted: u64 = records
        .iter()
        .filter(|r| r["what"] == "refusals_not_logged")
        .map(|r| r["detail"]["count"].as_u64().unwrap_or(0))
        .sum();
    assert_eq!(
        logged as u64 + counted,
        refused as u64,
        "every refusal is logged or counted: {logged} logged, {counted} counted"
    );
    // The flood took a few seconds of program time at most: the burst and one a second.
    let span_s = records
        .iter()
        .filter(|r| r["what"] == "refused")
        .filter_map(|r| r["time_us"].as_u64())
        .fold((u64::MAX, 0), |(lo, hi), t| (lo.min(t), hi.max(t)));
    let seconds = span_s.1.saturating_sub(span_s.0) / 1_000_000;
    assert!(
        logged as u64 <= cetratus_persist::REFUSAL_BURST + seconds + 1,
        "{logged} refusals logged one by one over {seconds} s"
    );
    assert!(counted > 0, "the rest of the flood is counted");
}

/// Stops the PLC as an operator would, so that the writer says what it counted last.
fn sigterm(plc: &mut RunningPlc) {
    let status = std::process::Command::new("kill")
        .args(["-TERM", &plc.process.id().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
    wait_for("the PLC to stop", Duration::from_secs(30), || {
        matches!(plc.process.0.try_wait(), Ok(Some(_)))
    });
}
