//! Every payload captured from the real PLC (tests/golden, see its README) reads into its type and
//! writes back to the same JSON value, and, except where noted, to the same bytes.

use std::path::{Path, PathBuf};

use cetratus_proto::{
    Accepted, EventMsg, ExecInfoMsg, IoMsg, NetMsg, Reply, Role, Slot, StatePayload, Status, Verb,
};
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::Value;

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

fn read(name: &str) -> String {
    std::fs::read_to_string(golden_dir().join(name)).expect("golden file readable")
}

/// The golden text without the whitespace outside strings: the payload as it was published
/// (the files keep the wire's key order).
fn minify(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let (mut in_str, mut escaped) = (false, false);
    for c in text.chars() {
        if in_str {
            out.push(c);
            if escaped {
                escaped = false;
            } else if c == '\\' {
                escaped = true;
            } else if c == '"' {
                in_str = false;
            }
        } else if c == '"' {
            in_str = true;
            out.push(c);
        } else if !c.is_whitespace() {
            out.push(c);
        }
    }
    out
}

/// Reads `name` as `T`, checks it writes back to the same value (and the same bytes when
/// `same_bytes`), and returns it.
fn round_trip<T: Serialize + DeserializeOwned>(name: &str, same_bytes: bool) -> T {
    let text = read(name);
    let golden: Value = serde_json::from_str(&text).expect("golden file is JSON");
    let typed: T = serde_json::from_str(&text)
        .unwrap_or_else(|e| panic!("{name} does not read as its type: {e}"));
    let back = serde_json::to_value(&typed).expect("serialisable");
    assert_eq!(back, golden, "{name}: the value changed");
    let from_value: T = serde_json::from_value(golden).expect("reads from a Value too");
    assert_eq!(
        serde_json::to_value(&from_value).expect("serialisable"),
        back,
        "{name}"
    );
    if same_bytes {
        let bytes = serde_json::to_string(&typed).expect("serialisable");
        assert_eq!(bytes, minify(&text), "{name}: the bytes changed");
    }
    typed
}

fn golden_files() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(golden_dir())
        .expect("golden dir")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".json"))
        .collect();
    names.sort();
    names
}

#[test]
fn every_golden_file_round_trips_through_its_type() {
    let files = golden_files();
    assert!(files.len() >= 30, "golden files missing: {files:?}");
    for name in &files {
        let stem = name.trim_end_matches(".json");
        // exec_info went through a serde_json::Value, which sorted `program`'s keys; the typed
        // ProgramInfo writes name, version, hash (the order `state` has always used).
        let has_exec_info = stem.contains("exec_info");
        if stem.starts_with("state") {
            round_trip::<StatePayload>(name, true);
        } else if stem.starts_with("exec_info") {
            round_trip::<ExecInfoMsg>(name, false);
        } else if stem.starts_with("io") {
            round_trip::<IoMsg>(name, true);
        } else if stem.starts_with("net") {
            round_trip::<NetMsg>(name, true);
        } else if stem.starts_with("events_") {
            let e: EventMsg = round_trip(name, true);
            let kind = if e.kind == "refused" && e.cycle.is_none() {
                "refused_prepare"
            } else {
                e.kind.as_str()
            };
            assert_eq!(stem, format!("events_{kind}"));
        } else if stem.starts_with("reply_") {
            let r: Reply = round_trip(name, !has_exec_info);
            check_reply_result(name, &r);
        } else if let Some(verb) = stem.strip_prefix("cmd_") {
            let verb: Verb = verb
                .trim_end_matches("_args")
                .parse()
                .expect("file named after a verb");
            let body: Value = serde_json::from_str(&read(name)).expect("JSON");
            let cmd = cetratus_proto::command_from_body(verb, body.clone())
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(cmd.verb(), verb);
            assert_eq!(cetratus_proto::command_body(&cmd), body, "{name}");
            assert_eq!(
                cetratus_proto::command_body(&cmd).to_string(),
                minify(&read(name)),
                "{name}"
            );
        } else {
            panic!("{name}: no type for this golden file; add it to this test");
        }
    }
}

fn check_reply_result(name: &str, r: &Reply) {
    match (&r.result, r.verb.as_str()) {
        (Some(v), "exec_info") => {
            let m: ExecInfoMsg = serde_json::from_value(v.clone())
                .unwrap_or_else(|e| panic!("{name}: result is not exec_info: {e}"));
            assert_eq!(&serde_json::to_value(&m).expect("serialisable"), v);
        }
        (Some(v), _) => {
            let a: Accepted = serde_json::from_value(v.clone())
                .unwrap_or_else(|e| panic!("{name}: result is not {{accepted}}: {e}"));
            assert!(a.accepted);
        }
        (None, _) => assert!(!r.ok && r.error.is_some(), "{name}"),
    }
}

#[test]
fn typed_fields_hold_what_the_plc_said() {
    let StatePayload::Online(s) = round_trip::<StatePayload>("state_quarantine.json", true) else {
        panic!("online");
    };
    assert_eq!(s.primary, Slot::A);
    assert_eq!(s.status, Status::Quarantine);
    assert!(s.programs.b.is_some());
    assert!(s.cycle.update.is_some());
    assert_eq!(
        round_trip::<StatePayload>("state_offline.json", true),
        StatePayload::Offline
    );
    let e: ExecInfoMsg = round_trip("exec_info_quarantine.json", false);
    let b = e.get(Slot::B).expect("B");
    assert_eq!(b.role, Role::Candidate);
    assert!(b.first_cause.is_some());
    assert!(b.verdicts.is_empty());
    let e: ExecInfoMsg = round_trip("exec_info.json", false);
    assert!(e.get(Slot::B).is_none());
    assert!(e.get(Slot::A).expect("A").input_quality.is_empty());
    let e: ExecInfoMsg = round_trip("exec_info_field_io.json", false);
    let q = &e.get(Slot::A).expect("A").input_quality;
    assert_eq!(q.len(), 1);
    assert_eq!(
        (q[0].device.as_str(), q[0].quality, q[0].link),
        (
            "cell",
            cetratus_proto::Quality::Good,
            cetratus_proto::LinkState::Up
        )
    );
    let io: IoMsg = round_trip("io.json", true);
    assert!(io.outputs_b.is_none());
    assert!(io.unix_ms.is_some());
    assert!(!io.samples.is_empty());
    assert!(io.samples.iter().all(|s| s.outputs_b.is_none()));
    let r: Reply = round_trip("reply_exec_info_correlation_null.json", false);
    assert_eq!(
        r.correlation,
        Some(Value::Null),
        "an explicit null is echoed"
    );
}

#[test]
fn a_command_refuses_an_unknown_field_and_a_publication_passes_it_over() {
    // What a PLC is sent: a misspelt argument is never taken for its default.
    let v = serde_json::json!({"mdoe": "keep"});
    assert!(cetratus_proto::command_from_body(Verb::Substitute, v).is_err());
    let v = serde_json::json!({"x": 1});
    assert!(cetratus_proto::command_from_body(Verb::Remove, v).is_err());
    // What a newer PLC publishes: read as this build knows it.
    let plain: StatePayload = serde_json::from_str(&read("state.json")).expect("state");
    let mut v: Value = serde_json::from_str(&read("state.json")).expect("JSON");
    v["cycle"]["extra"] = Value::from(1);
    v["extra"] = Value::from(2);
    assert_eq!(serde_json::from_value::<StatePayload>(v).ok(), Some(plain));
    let plain: IoMsg = serde_json::from_str(&read("io.json")).expect("io");
    let mut v: Value = serde_json::from_str(&read("io.json")).expect("JSON");
    v["extra"] = Value::from(1);
    assert_eq!(serde_json::from_value::<IoMsg>(v).ok(), Some(plain));
    let offline = serde_json::from_str::<StatePayload>(r#"{"online": false, "x": 1}"#);
    assert_eq!(offline.ok(), Some(StatePayload::Offline));
    let mut v: Value = serde_json::from_str(&read("events_substituted.json")).expect("JSON");
    v["kind"] = Value::from("teleported");
    let e: cetratus_proto::EventMsg = serde_json::from_value(v).expect("a newer kind is kept");
    assert_eq!(e.kind, "teleported");
}
