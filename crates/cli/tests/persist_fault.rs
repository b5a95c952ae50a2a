//! A state directory that cannot be written is an alarm the operator sees, and the PLC saves
//! again by itself once it can (docs/persistence.md, *When the disk fails*).
//!
//! Against the real binary: a directory is put where the PLC writes `state.json.tmp`, so that
//! every commit fails (this works for root too, unlike taking the write permission away). The
//! PLC must raise `persist_failed` on `events`, carry `persist_fault` in its retained `state`,
//! cycle on, and once the directory is gone raise `persist_recovered`, drop the fault and commit
//! newer snapshots.

use std::time::Duration;

use serde_json::Value;

mod common;

use common::{watch_all, RunningPlc};

const PLC: &str = "pf1";

/// The cycle `state.json` was committed at.
fn committed_cycle(state: &std::path::Path) -> Option<u64> {
    let text = std::fs::read_to_string(state.join("state.json")).ok()?;
    serde_json::from_str::<Value>(&text).ok()?["snapshot"]["cycle"].as_u64()
}

fn messages(seen: &std::sync::Mutex<Vec<Vec<u8>>>) -> Vec<Value> {
    seen.lock()
        .expect("seen")
        .iter()
        .filter_map(|p| serde_json::from_slice(p).ok())
        .collect()
}

fn event_seen(seen: &std::sync::Mutex<Vec<Vec<u8>>>, kind: &str) -> Option<Value> {
    messages(seen).into_iter().find(|m| m["kind"] == kind)
}

/// The newest retained `state` seen.
fn last_state(seen: &std::sync::Mutex<Vec<Vec<u8>>>) -> Option<Value> {
    messages(seen)
        .into_iter()
        .rev()
        .find(|m| m["online"] == true)
}

#[test]
fn a_state_directory_that_cannot_be_written_raises_an_alarm_and_the_plc_saves_again_after() {
    let plc = RunningPlc::start(PLC, &[]);
    let state = plc.state.path().to_path_buf();
    let topics = [
        format!("cetratus/{PLC}/state"),
        format!("cetratus/{PLC}/events"),
    ];
    let (_watcher, seen) = watch_all(plc.mqtt, "watcher", &[&topics[0], &topics[1]]);
    common::wait_for("a first snapshot", Duration::from_secs(30), || {
        committed_cycle(&state).is_some()
    });

    let block = state.join("state.json.tmp");
    // The writer holds a `state.json.tmp` of its own for an instant at each commit: the directory
    // goes in between two.
    common::wait_for(
        "a directory in the way of the commit",
        Duration::from_secs(10),
        || std::fs::create_dir(&block).is_ok(),
    );
    std::fs::write(block.join("keep"), b"x").expect("a file in it");
    common::wait_for("persist_failed on events", Duration::from_secs(60), || {
        event_seen(&seen, "persist_failed").is_some()
    });
    let failed = event_seen(&seen, "persist_failed").expect("seen");
    let said = failed["message"].as_str().unwrap_or("");
    assert!(
        said.contains("state.json.tmp") && said.contains("restart"),
        "{said}"
    );
    common::wait_for("persist_fault in state", Duration::from_secs(20), || {
        last_state(&seen).is_some_and(|s| s["persist_fault"]["error"].is_string())
    });
    let stuck = committed_cycle(&state).expect("the last committed snapshot");
    let fault = last_state(&seen).expect("a state")["persist_fault"].clone();
    assert_eq!(fault["saved_cycle"].as_u64(), Some(stuck), "{fault}");
    let cycles = |s: &Value| s["cycle"]["cycles"].as_u64().unwrap_or(0);
    let before = last_state(&seen).map_or(0, |s| cycles(&s));
    common::wait_for(
        "cycles while the disk fails",
        Duration::from_secs(20),
        || last_state(&seen).is_some_and(|s| cycles(&s) > before + 50),
    );
    assert_eq!(
        committed_cycle(&state),
        Some(stuck),
        "no commit got through"
    );

    std::fs::remove_dir_all(&block).expect("the block removed");
    common::wait_for(
        "persist_recovered on events",
        Duration::from_secs(20),
        || event_seen(&seen, "persist_recovered").is_some(),
    );
    common::wait_for(
        "a state without persist_fault",
        Duration::from_secs(20),
        || last_state(&seen).is_some_and(|s| s.get("persist_fault").is_none()),
    );
    common::wait_for("a newer snapshot", Duration::from_secs(20), || {
        committed_cycle(&state).is_some_and(|c| c > stuck)
    });
}
