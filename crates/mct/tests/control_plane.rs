//! The control plane end to end on the embedded broker: a fake scan loop answers commands through
//! the MctLink; clients speak MQTT 5 (rumqttc, paho-mqtt) and MQTT 3.1.1 (`reply_to`).

mod common;

use std::net::SocketAddr;
use std::process::Command;
use std::time::Duration;

use cetratus_mct::{start, BrokerChoice, MqttConfig, MqttHandle};
use cetratus_proto::MAX_PAYLOAD;
use common::*;
use rumqttc::v5::mqttbytes::v5::PublishProperties;
use rumqttc::v5::mqttbytes::QoS;
use serde_json::{json, Value};

const T: Duration = Duration::from_secs(10);

fn plc(id: &str) -> (MqttHandle, FakeScan, SocketAddr) {
    let mut cfg = MqttConfig::new(id);
    cfg.broker = BrokerChoice::Embedded(cetratus_mct::BrokerSettings::open(free_addr()));
    cfg.publish_period = Duration::from_millis(50);
    let (link, handle) = start(cfg).expect("start");
    assert!(handle.wait_connected(T), "the PLC client did not connect");
    let addr = handle.broker_addr().expect("embedded");
    (handle, FakeScan::start(link), addr)
}

fn request(
    c: &V5,
    topic: &str,
    payload: impl Into<Vec<u8>>,
    reply: &str,
    correlation: &[u8],
) -> Got {
    let props = PublishProperties {
        response_topic: Some(reply.into()),
        correlation_data: Some(correlation.to_vec().into()),
        ..Default::default()
    };
    c.client
        .publish_with_properties(topic, QoS::AtLeastOnce, false, payload.into(), props)
        .expect("publish");
    c.next_on(reply, T)
        .unwrap_or_else(|| panic!("no reply on {reply} for {topic}"))
}

#[test]
fn an_mqtt5_command_gets_its_reply_with_the_correlation_data() {
    let (handle, scan, addr) = plc("cell1");
    let c = v5(addr, None);
    c.subscribe("cetratus/cell1/reply/me");
    let got = request(
        &c,
        "cetratus/cell1/cmd/exec_info",
        "{}",
        "cetratus/cell1/reply/me",
        b"corr-1",
    );
    assert_eq!(got.correlation.as_deref(), Some(&b"corr-1"[..]));
    let body = got.json();
    assert_eq!(body["ok"], true);
    assert_eq!(body["verb"], "exec_info");
    assert!(body["result"]["A"]["cycles"].as_u64().is_some());
    let refused = request(
        &c,
        "cetratus/cell1/cmd/load",
        r#"{"package_b64":"aGVsbG8="}"#,
        "cetratus/cell1/reply/me",
        b"corr-2",
    )
    .json();
    assert_eq!(refused["ok"], false);
    assert_eq!(refused["error"]["code"], "refused");
    assert!(scan.stop() >= 2);
    handle.shutdown();
}

#[test]
fn a_paho_mqtt5_client_does_request_reply_against_the_plc() {
    let ok = Command::new("python3")
        .args(["-c", "import paho.mqtt"])
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    if !ok {
        eprintln!(
            "\n!!!!!!!! SKIPPED: python3 with paho-mqtt missing (pip install paho-mqtt) !!!!!!!!\n"
        );
        return;
    }
    let (handle, scan, addr) = plc("cell-paho");
    let script =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/mqtt_request.py");
    let out = Command::new("python3")
        .arg(&script)
        .args(["--host", "127.0.0.1", "--port", &addr.port().to_string()])
        .args([
            "--topic",
            "cetratus/cell-paho/cmd/substitute",
            "--payload",
            r#"{"mode":"retransform"}"#,
        ])
        .output()
        .expect("run python3");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "paho client failed: {stdout} {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_str(stdout.trim()).expect("JSON from the script");
    assert_eq!(v["correlation_matches"], true);
    assert_eq!(v["reply"]["ok"], true);
    assert_eq!(v["reply"]["result"]["verb"], "substitute");
    scan.stop();
    handle.shutdown();
}

#[test]
fn an_mqtt311_command_with_reply_to_gets_a_reply_on_the_embedded_broker() {
    let (handle, scan, addr) = plc("cell311");
    let c = v311(addr);
    c.subscribe("cetratus/cell311/reply/ops");
    let cmd = json!({"reply_to": "cetratus/cell311/reply/ops", "correlation": "abc-7"});
    c.client
        .publish(
            "cetratus/cell311/cmd/remove",
            rumqttc::QoS::AtLeastOnce,
            false,
            cmd.to_string(),
        )
        .expect("publish");
    let payload = c.next_on("cetratus/cell311/reply/ops", T).expect("a reply");
    let body: Value = serde_json::from_slice(&payload).expect("JSON");
    assert_eq!(body["ok"], true);
    assert_eq!(body["correlation"], "abc-7");
    assert_eq!(body["verb"], "remove");
    scan.stop();
    handle.shutdown();
}

#[test]
fn fuzzed_commands_all_get_error_replies_and_the_responder_keeps_working() {
    let (handle, scan, addr) = plc("fuzz");
    let c = v5(addr, None);
    c.subscribe("cetratus/fuzz/reply/fz");
    c.subscribe("cetratus/fuzz/events");
    // A deterministic generator: the same fuzz on every run.
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut rnd = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let mut cases: Vec<(String, Vec<u8>, &str)> = Vec::new();
    for i in 0..20 {
        let len = (rnd() % 300) as usize;
        let bytes: Vec<u8> = (0..len).map(|_| rnd() as u8).collect();
        let verb = ["load", "substitute", "remove"][i % 3];
        // `remove` takes an empty payload as "no arguments"; random bytes are never valid JSON objects here.
        cases.push((
            format!("cetratus/fuzz/cmd/{verb}"),
            [b"\x00".as_slice(), &bytes].concat(),
            "malformed",
        ));
    }
    for bad in [
        r#"[1,2,3]"#,
        r#""load""#,
        r#"{"package_b64": 12}"#,
        r#"{"package_b64": "***"}"#,
        r#"{"nope": true}"#,
        "{",
        "null",
    ] {
        cases.push((
            "cetratus/fuzz/cmd/load".into(),
            bad.as_bytes().to_vec(),
            "malformed",
        ));
    }
    cases.push((
        "cetratus/fuzz/cmd/substitute".into(),
        br#"{"mode":"sideways"}"#.to_vec(),
        "malformed",
    ));
    cases.push((
        "cetratus/fuzz/cmd/remove".into(),
        br#"{"force":true}"#.to_vec(),
        "malformed",
    ));
    cases.push((
        "cetratus/fuzz/cmd/load".into(),
        br#"{"package_b64":"aGk=","allow_unsigned":true}"#.to_vec(),
        "not_allowed",
    ));
    cases.push((
        "cetratus/fuzz/cmd/selfdestruct".into(),
        b"{}".to_vec(),
        "unknown_verb",
    ));
    cases.push((
        "cetratus/fuzz/cmd/load".into(),
        vec![b'a'; MAX_PAYLOAD + 10],
        "too_large",
    ));
    let huge_json = format!(r#"{{"package_b64":"{}"}}"#, "A".repeat(MAX_PAYLOAD + 4));
    cases.push((
        "cetratus/fuzz/cmd/load".into(),
        huge_json.into_bytes(),
        "too_large",
    ));
    for (i, (topic, payload, code)) in cases.iter().enumerate() {
        let corr = format!("c{i}");
        let got = request(
            &c,
            topic,
            payload.clone(),
            "cetratus/fuzz/reply/fz",
            corr.as_bytes(),
        );
        assert_eq!(
            got.correlation.as_deref(),
            Some(corr.as_bytes()),
            "case {i}"
        );
        let body = got.json();
        assert_eq!(body["ok"], false, "case {i}: {body}");
        assert_eq!(body["error"]["code"], *code, "case {i}: {body}");
        assert!(body["error"]["message"]
            .as_str()
            .is_some_and(|m| !m.is_empty()));
    }
    let ev = next_matching(&c.rx, T, |g: &Got| {
        g.topic == "cetratus/fuzz/events" && g.json()["kind"] == "command_rejected"
    });
    assert!(ev.is_some(), "rejections are published as events");
    let fine = request(
        &c,
        "cetratus/fuzz/cmd/abort",
        "{}",
        "cetratus/fuzz/reply/fz",
        b"after",
    )
    .json();
    assert_eq!(fine["ok"], true, "the responder still works: {fine}");
    scan.stop();
    handle.shutdown();
}

#[test]
fn state_is_retained_and_io_is_published_periodically() {
    let (handle, scan, addr) = plc("cell-st");
    std::thread::sleep(Duration::from_millis(300));
    let late = v5(addr, None);
    late.subscribe("cetratus/cell-st/state");
    let st = late
        .next_on("cetratus/cell-st/state", T)
        .expect("retained state");
    assert!(st.retain);
    let v = st.json();
    assert_eq!(
        (
            v["online"].clone(),
            v["primary"].clone(),
            v["status"].clone()
        ),
        (json!(true), json!("A"), json!("idle"))
    );
    assert_eq!(v["programs"]["A"]["name"], "vernadat");
    late.subscribe("cetratus/cell-st/io");
    assert!(
        late.next_on("cetratus/cell-st/io", T).is_some(),
        "io is published periodically"
    );
    scan.stop();
    handle.shutdown();
}
