//! The rollout's machine, fed the protocol's own payloads through [`View::take`] (the path
//! the broker's messages take), with the clock moved by hand.

use std::path::Path;
use std::time::{Duration, Instant};

use serde_json::{json, Value};

use super::*;
use crate::record::Target;

const BASE: &str = "b0b0b0b0b0b0b0b0";
const NEW: &str = "f1f1f1f1f1f1f1f1";

fn plan(extra: &str) -> Plan {
    let text = format!(
        "package = \"u1.cpkg\"\nselect = \"*\"\nstages = [\"1\", \"100%\"]\nquarantine = \"30s\"\n\
         probation = \"60s\"\nmax_parallel = 2\non_failure = \"stop\"\n{extra}"
    );
    Plan::parse(&text, "rollout.toml", Path::new(".")).unwrap()
}

fn rollout(extra: &str, ids: &[&str]) -> Rollout {
    let target = Target {
        update: "U.1 1.1.0".into(),
        program_hash: NEW.into(),
        base_hash: BASE.into(),
        may_differ: vec!["LM1".into()],
        file_sha256: "00".into(),
    };
    let ids: Vec<String> = ids.iter().map(|s| s.to_string()).collect();
    let stages = vec![ids[..1].to_vec(), ids[1..].to_vec()];
    Rollout::new(
        plan(extra),
        Record::new("t".into(), ("p", ""), target, stages),
    )
}

/// A PLC's retained state: PRIMARY A running `a`, B holding `b`, at program time `ms`.
fn state(status: &str, primary: &str, a: &str, b: Option<&str>, ms: u64) -> Value {
    let prog = |h: &str| json!({"name": "vernadat", "version": "1", "hash": h});
    let mut programs = json!({ "A": prog(a) });
    if let Some(b) = b {
        programs["B"] = prog(b);
    }
    let t = json!({"count":0,"last_ns":0,"max_ns":0,"mean_ns":0,"min_ns":0,"p50_ns":0,"p99_ns":0});
    json!({
        "online": true, "primary": primary, "status": status, "programs": programs,
        "cycle": {"cycle": t, "cycles": 1, "latency": t, "overruns": 0, "scan": t,
                  "time_ms": ms, "update": null},
        "updates": {"probation_ms": 60_000, "require_verdict": false},
    })
}

fn put(v: &mut View, plc: &str, leaf: &str, payload: &Value, now: Instant) {
    v.take(plc, leaf, payload.to_string().as_bytes(), None, now);
}

/// An `exec_info` whose candidate (B, running `NEW`) diverged on `out` in `n` cycles.
fn diverged(out: &str, n: u64) -> Value {
    let t = json!({"count":0,"last_ns":0,"max_ns":0,"mean_ns":0,"min_ns":0,"p50_ns":0,"p99_ns":0});
    json!([null, {
        "container": "B", "cycles": 10, "deadlock": false, "divergence": {out: n}, "drift": 0,
        "firings": {}, "first_cause": "DM2 never set", "last_cause": null, "marking": {},
        "max_drift": 0, "outputs": {}, "program": {"name": "u1", "version": "1", "hash": NEW},
        "role": "candidate", "scan": t, "verdicts": []
    }])
}

fn verbs(orders: &[Order]) -> Vec<(String, Verb)> {
    orders.iter().map(|o| (o.plc.clone(), o.verb)).collect()
}

/// Ticks and notes every order as sent, as the driver does.
fn tick(r: &mut Rollout, v: &mut View, now: Instant) -> Vec<(String, Verb)> {
    let orders = r.tick(v, now);
    for o in &orders {
        v.sent(
            &o.plc,
            o.verb,
            format!("{}-{}", o.plc, o.verb).into_bytes(),
            now,
        );
    }
    verbs(&orders)
}

#[test]
fn a_plc_passes_each_gate_in_turn_and_the_next_stage_begins_after_the_canary() {
    let mut r = rollout("", &["p1", "p2", "p3"]);
    let mut v = View::new("reply/x");
    let t0 = Instant::now();
    for id in ["p1", "p2", "p3"] {
        put(
            &mut v,
            id,
            "state",
            &state("idle", "A", BASE, None, 1000),
            t0,
        );
    }
    assert_eq!(tick(&mut r, &mut v, t0), [("p1".into(), Verb::Load)]);
    assert!(tick(&mut r, &mut v, t0).is_empty(), "waits for the install");
    put(
        &mut v,
        "p1",
        "state",
        &state("quarantine", "A", BASE, Some(NEW), 2000),
        t0,
    );
    assert!(tick(&mut r, &mut v, t0).is_empty());
    assert_eq!(r.record.plcs["p1"].step, Step::Quarantine);
    // 29 s of the PLC's own time in quarantine: not yet.
    put(
        &mut v,
        "p1",
        "state",
        &state("quarantine", "A", BASE, Some(NEW), 31_000),
        t0,
    );
    assert!(tick(&mut r, &mut v, t0).is_empty());
    put(
        &mut v,
        "p1",
        "state",
        &state("quarantine", "A", BASE, Some(NEW), 32_000),
        t0,
    );
    assert_eq!(tick(&mut r, &mut v, t0), [("p1".into(), Verb::Substitute)]);
    put(
        &mut v,
        "p1",
        "state",
        &state("probation", "B", BASE, Some(NEW), 33_000),
        t0,
    );
    assert!(tick(&mut r, &mut v, t0).is_empty());
    put(
        &mut v,
        "p1",
        "state",
        &state("probation", "B", BASE, Some(NEW), 93_000),
        t0,
    );
    assert_eq!(tick(&mut r, &mut v, t0), [("p1".into(), Verb::Accept)]);
    assert_eq!(r.record.stage, 1, "the canary is not done until accepted");
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "B", BASE, Some(NEW), 94_000),
        t0,
    );
    // The canary is done: stage 2 loads two at once (max_parallel).
    let next = tick(&mut r, &mut v, t0);
    assert_eq!(next, [("p2".into(), Verb::Load), ("p3".into(), Verb::Load)]);
    assert_eq!((r.record.stage, r.record.plcs["p1"].step), (2, Step::Done));
}

#[test]
fn undeclared_divergence_in_quarantine_halts_and_removes_the_candidate() {
    let mut r = rollout("", &["p1", "p2"]);
    let mut v = View::new("reply/x");
    v.watch(["p1".to_string(), "p2".to_string()]);
    let t0 = Instant::now();
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, None, 0),
        t0,
    );
    put(
        &mut v,
        "p2",
        "state",
        &state("idle", "A", BASE, None, 0),
        t0,
    );
    tick(&mut r, &mut v, t0);
    put(
        &mut v,
        "p1",
        "state",
        &state("quarantine", "A", BASE, Some(NEW), 10),
        t0,
    );
    tick(&mut r, &mut v, t0);
    // Divergence on LM1 is declared by the package: no failure.
    put(&mut v, "p1", "exec_info", &diverged("LM1", 4), t0);
    assert!(tick(&mut r, &mut v, t0).is_empty());
    put(&mut v, "p1", "exec_info", &diverged("DM2", 3), t0);
    assert_eq!(tick(&mut r, &mut v, t0), [("p1".into(), Verb::Remove)]);
    let why = r.record.plcs["p1"].note.clone().unwrap_or_default();
    assert!(why.contains("diverged on DM2 in 3 cycles"), "{why}");
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, None, 20),
        t0,
    );
    assert!(tick(&mut r, &mut v, t0).is_empty());
    assert_eq!(r.record.outcome, Outcome::Halted);
    assert_eq!(r.record.plcs["p1"].step, Step::Removed);
    assert_eq!(r.record.plcs["p2"].step, Step::Untouched, "never loaded");
}

#[test]
fn hold_leaves_the_plc_as_it_is_and_raises_the_alarm() {
    let mut r = rollout("", &["p1", "p2"]);
    r.plan.on_failure = OnFailure::Hold;
    let mut v = View::new("reply/x");
    v.watch(["p1".to_string()]);
    let t0 = Instant::now();
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, None, 0),
        t0,
    );
    tick(&mut r, &mut v, t0);
    put(
        &mut v,
        "p1",
        "state",
        &state("quarantine", "A", BASE, Some(NEW), 10),
        t0,
    );
    tick(&mut r, &mut v, t0);
    put(&mut v, "p1", "exec_info", &diverged("DM2", 1), t0);
    assert!(tick(&mut r, &mut v, t0).is_empty());
    assert_eq!((r.record.outcome, r.record.alarm), (Outcome::Halted, true));
    assert_eq!(r.record.plcs["p1"].step, Step::Quarantine);
}

#[test]
fn a_plc_on_another_base_is_skipped_and_one_on_the_new_program_is_done() {
    let mut r = rollout("", &["p1", "p2", "p3"]);
    let mut v = View::new("reply/x");
    let t0 = Instant::now();
    put(&mut v, "p1", "state", &state("idle", "A", NEW, None, 0), t0);
    put(
        &mut v,
        "p2",
        "state",
        &state("idle", "A", "cccccccccccccccc", None, 0),
        t0,
    );
    put(
        &mut v,
        "p3",
        "state",
        &state("idle", "A", BASE, None, 0),
        t0,
    );
    assert_eq!(tick(&mut r, &mut v, t0), [("p3".into(), Verb::Load)]);
    assert_eq!(r.record.plcs["p1"].step, Step::Done);
    assert_eq!(r.record.plcs["p2"].step, Step::Skipped);
    let why = r.record.plcs["p2"].note.clone().unwrap_or_default();
    assert!(why.contains("not the package's base b0b0b0b0b0b0"), "{why}");
}

#[test]
fn a_plc_with_an_update_under_way_halts_the_rollout_naming_it() {
    let mut r = rollout("", &["p1", "p2"]);
    let mut v = View::new("reply/x");
    let t0 = Instant::now();
    put(
        &mut v,
        "p1",
        "state",
        &state("quarantine", "A", BASE, Some("dd"), 0),
        t0,
    );
    assert!(tick(&mut r, &mut v, t0).is_empty());
    assert_eq!(r.record.outcome, Outcome::Halted);
    let why = r.record.reason.clone().unwrap_or_default();
    assert!(
        why.starts_with("p1: an update is already under way"),
        "{why}"
    );
}

#[test]
fn a_refused_load_halts_with_the_plcs_reason_and_touches_nothing() {
    let mut r = rollout("", &["p1", "p2"]);
    let mut v = View::new("reply/x");
    let t0 = Instant::now();
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, None, 0),
        t0,
    );
    tick(&mut r, &mut v, t0);
    let reply = json!({"ok": false, "request_id": 1, "verb": "load",
                       "error": {"code": "refused", "message": "not signed by a trusted key"}});
    let forged = Some(b"p1-unload".as_slice());
    v.take("p1", "reply/x", reply.to_string().as_bytes(), forged, t0);
    put(&mut v, "p1", "reply/x", &reply, t0);
    assert!(tick(&mut r, &mut v, t0).is_empty());
    assert_eq!(
        r.record.outcome,
        Outcome::Running,
        "a reply without the load's correlation"
    );
    let load = Some(b"p1-load".as_slice());
    v.take("p1", "reply/x", reply.to_string().as_bytes(), load, t0);
    assert!(tick(&mut r, &mut v, t0).is_empty());
    assert_eq!(r.record.outcome, Outcome::Halted);
    assert_eq!(r.record.plcs["p1"].step, Step::Untouched);
    let why = r.record.plcs["p1"].note.clone().unwrap_or_default();
    assert!(why.contains("its load was refused: not signed"), "{why}");
}

#[test]
fn a_plc_silent_past_the_plans_time_fails_and_one_that_reverts_in_probation_too() {
    let mut r = rollout("silent = \"5s\"", &["p1", "p2"]);
    let mut v = View::new("reply/x");
    let t0 = Instant::now();
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, None, 0),
        t0,
    );
    tick(&mut r, &mut v, t0);
    assert!(tick(&mut r, &mut v, t0 + Duration::from_secs(4)).is_empty());
    assert_eq!(r.record.outcome, Outcome::Running, "quiet, not yet silent");
    tick(&mut r, &mut v, t0 + Duration::from_secs(6));
    let why = r.record.reason.clone().unwrap_or_default();
    assert!(why.contains("silent for 6 s"), "{why}");

    let mut r = rollout("", &["p1", "p2"]);
    let mut v = View::new("reply/x");
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, None, 0),
        t0,
    );
    tick(&mut r, &mut v, t0);
    put(
        &mut v,
        "p1",
        "state",
        &state("probation", "B", BASE, Some(NEW), 10),
        t0,
    );
    tick(&mut r, &mut v, t0);
    assert_eq!(r.record.plcs["p1"].step, Step::Probation);
    let ev = json!({"kind": "reverted", "message": "the new primary stalls at P24"});
    put(&mut v, "p1", "events", &ev, t0);
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, Some(NEW), 20),
        t0,
    );
    tick(&mut r, &mut v, t0);
    assert_eq!(r.record.plcs["p1"].step, Step::Reverted);
    assert_eq!(r.record.outcome, Outcome::Halted);
    let why = r.record.reason.clone().unwrap_or_default();
    assert!(why.contains("reverted: the new primary stalls"), "{why}");
}

#[test]
fn pause_takes_no_plc_further_and_abort_reverts_the_one_in_probation() {
    let mut r = rollout("", &["p1", "p2"]);
    let mut v = View::new("reply/x");
    let t0 = Instant::now();
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, None, 0),
        t0,
    );
    tick(&mut r, &mut v, t0);
    put(
        &mut v,
        "p1",
        "state",
        &state("probation", "B", BASE, Some(NEW), 10),
        t0,
    );
    tick(&mut r, &mut v, t0);
    r.request(Request::Pause);
    put(
        &mut v,
        "p1",
        "state",
        &state("probation", "B", BASE, Some(NEW), 90_000),
        t0,
    );
    assert!(
        tick(&mut r, &mut v, t0).is_empty(),
        "no accept while paused"
    );
    r.request(Request::Abort);
    assert_eq!(tick(&mut r, &mut v, t0), [("p1".into(), Verb::Revert)]);
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, Some(NEW), 90_100),
        t0,
    );
    tick(&mut r, &mut v, t0);
    assert_eq!(r.record.outcome, Outcome::Aborted);
    assert_eq!(r.record.plcs["p1"].step, Step::Reverted);
}

#[test]
fn a_command_with_no_reply_past_the_silent_time_halts_the_rollout() {
    let mut r = rollout("silent = \"5s\"", &["p1", "p2"]);
    let mut v = View::new("reply/x");
    let t0 = Instant::now();
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, None, 0),
        t0,
    );
    assert_eq!(tick(&mut r, &mut v, t0), [("p1".into(), Verb::Load)]);
    // The PLC is heard all along, but its load is never answered (an ACL dropped it).
    let later = t0 + Duration::from_secs(6);
    put(
        &mut v,
        "p1",
        "state",
        &state("idle", "A", BASE, None, 60),
        later,
    );
    assert!(tick(&mut r, &mut v, later).is_empty());
    assert_eq!(r.record.outcome, Outcome::Halted);
    assert_eq!(r.record.plcs["p1"].step, Step::Untouched);
    let why = r.record.reason.clone().unwrap_or_default();
    assert!(why.contains("its load had no reply for 6 s"), "{why}");
}
