//! The client side against a real plant broker: a mosquitto started on a free port, and the
//! mosquitto command-line clients as the operator's tools.

mod common;

use std::process::{Command, Stdio};
use std::time::Duration;

use cetratus_mct::{start, BrokerChoice, MqttConfig, MqttHandle};
use common::*;
use serde_json::{json, Value};

const T: Duration = Duration::from_secs(10);

fn plc(id: &str, m: &Mosquitto) -> (MqttHandle, FakeScan) {
    let mut cfg = MqttConfig::new(id);
    cfg.broker = BrokerChoice::External {
        url: format!("mqtt://{}", m.addr),
        user: None,
        password: None,
    };
    cfg.publish_period = Duration::from_millis(50);
    let (link, handle) = start(cfg).expect("start");
    assert!(
        handle.wait_connected(T),
        "the PLC client did not connect to mosquitto"
    );
    (handle, FakeScan::start(link))
}

fn sub_one(m: &Mosquitto, topic: &str, retained_only: bool) -> Value {
    let mut cmd = Command::new("mosquitto_sub");
    cmd.args([
        "-h",
        "127.0.0.1",
        "-p",
        &m.addr.port().to_string(),
        "-t",
        topic,
        "-C",
        "1",
        "-W",
        "10",
    ]);
    if retained_only {
        cmd.arg("--retained-only");
    }
    let out = cmd.output().expect("run mosquitto_sub");
    assert!(
        out.status.success(),
        "mosquitto_sub: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON from mosquitto_sub")
}

#[test]
fn mosquitto_sub_reads_the_retained_state_published_through_the_client_side() {
    let Some(m) = Mosquitto::start() else { return };
    let (handle, scan) = plc("plant1", &m);
    std::thread::sleep(Duration::from_millis(300));
    let st = sub_one(&m, "cetratus/plant1/state", true);
    assert_eq!(st["online"], true);
    assert_eq!(st["primary"], "A");
    assert_eq!(st["status"], "idle");
    scan.stop();
    handle.shutdown();
    // A clean shutdown replaces the retained state with the same message the last will carries.
    let st = sub_one(&m, "cetratus/plant1/state", true);
    assert_eq!(st, json!({"online": false}));
}

#[test]
fn mosquitto_pub_command_with_reply_to_gets_a_reply() {
    let Some(m) = Mosquitto::start() else { return };
    let (handle, scan) = plc("plant2", &m);
    let port = m.addr.port().to_string();
    let sub = Command::new("mosquitto_sub")
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &port,
            "-t",
            "ops/plant2/reply",
            "-C",
            "1",
            "-W",
            "10",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn mosquitto_sub");
    // mosquitto_sub has no "subscribed" signal; give it a moment before the command goes out.
    std::thread::sleep(Duration::from_millis(500));
    let cmd = json!({"reply_to": "ops/plant2/reply", "correlation": 99});
    let status = Command::new("mosquitto_pub")
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &port,
            "-t",
            "cetratus/plant2/cmd/reset",
            "-q",
            "1",
            "-m",
            &cmd.to_string(),
        ])
        .status()
        .expect("run mosquitto_pub");
    assert!(status.success());
    let out = sub.wait_with_output().expect("mosquitto_sub output");
    let body: Value = serde_json::from_slice(&out.stdout).expect("JSON reply");
    assert_eq!(body["ok"], true);
    assert_eq!(body["verb"], "reset");
    assert_eq!(body["correlation"], 99);
    scan.stop();
    handle.shutdown();
}

#[test]
fn mosquitto_pub_of_a_malformed_command_gets_an_error_reply_and_an_event() {
    let Some(m) = Mosquitto::start() else { return };
    let (handle, scan) = plc("plant3", &m);
    let port = m.addr.port().to_string();
    let sub = Command::new("mosquitto_sub")
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &port,
            "-t",
            "ops/plant3/reply",
            "-t",
            "cetratus/plant3/events",
            "-C",
            "2",
            "-W",
            "10",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn mosquitto_sub");
    std::thread::sleep(Duration::from_millis(500));
    let status = Command::new("mosquitto_pub")
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &port,
            "-t",
            "cetratus/plant3/cmd/substitute",
            "-q",
            "1",
        ])
        .args(["-m", r#"{"reply_to":"ops/plant3/reply","mode":"teleport"}"#])
        .status()
        .expect("run mosquitto_pub");
    assert!(status.success());
    let out = sub.wait_with_output().expect("mosquitto_sub output");
    let lines: Vec<Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect();
    assert!(
        lines
            .iter()
            .any(|v| v["ok"] == false && v["error"]["code"] == "malformed"),
        "{lines:?}"
    );
    assert!(
        lines.iter().any(|v| v["kind"] == "command_rejected"),
        "{lines:?}"
    );
    scan.stop();
    handle.shutdown();
}

#[test]
fn an_unreachable_plant_broker_does_not_stop_start_and_shutdown() {
    let mut cfg = MqttConfig::new("lonely");
    cfg.broker = BrokerChoice::External {
        url: format!("mqtt://{}", free_addr()),
        user: None,
        password: None,
    };
    let (link, handle) = start(cfg).expect("start even without a broker");
    assert!(!handle.wait_connected(Duration::from_millis(300)));
    // The scan side keeps running: sends never block.
    for _ in 0..1000 {
        let _ = link.send(cetratus_mct::Outgoing::Io(common::io(0)));
    }
    handle.shutdown();
}
