//! The client side against a real plant broker: a mosquitto started on a free port, and the
//! mosquitto command-line clients as the operator's tools.

mod common;

use std::time::Duration;

use cetratus_mct::{start, BrokerChoice, MqttConfig, MqttHandle};
use cetratus_testkit::mqtt;
use common::*;
use serde_json::{json, Value};

const T: Duration = Duration::from_secs(10);

fn plc(id: &str, m: &Mosquitto) -> (MqttHandle, FakeScan) {
    let mut cfg = MqttConfig::new(id);
    cfg.broker = BrokerChoice::External {
        url: format!("mqtt://{}", m.addr()),
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

fn sub_one(m: &Mosquitto, topic: &str) -> Value {
    mqtt::sub_one(m.port(), topic, 10, true)
        .unwrap_or_else(|| panic!("no retained JSON message on {topic} within 10 s"))
}

#[test]
fn mosquitto_sub_reads_the_retained_state_published_through_the_client_side() {
    let Some(m) = mosquitto() else { return };
    let (handle, scan) = plc("plant1", &m);
    std::thread::sleep(Duration::from_millis(300));
    let st = sub_one(&m, "cetratus/plant1/state");
    assert_eq!(st["online"], true);
    assert_eq!(st["primary"], "A");
    assert_eq!(st["status"], "idle");
    scan.stop();
    handle.shutdown();
    // A clean shutdown replaces the retained state with the same message the last will carries.
    let st = sub_one(&m, "cetratus/plant1/state");
    assert_eq!(st, json!({"online": false}));
}

#[test]
fn mosquitto_pub_command_with_reply_to_gets_a_reply() {
    let Some(m) = mosquitto() else { return };
    let (handle, scan) = plc("plant2", &m);
    let body = mqtt::request_v311(
        m.port(),
        "cetratus/plant2/cmd/reset",
        json!({"correlation": 99}),
        "cetratus/plant2/reply/ops",
    );
    assert_eq!(body["ok"], true);
    assert_eq!(body["verb"], "reset");
    assert_eq!(body["correlation"], 99);
    scan.stop();
    handle.shutdown();
}

#[test]
fn mosquitto_pub_of_a_malformed_command_gets_an_error_reply_and_an_event() {
    let Some(m) = mosquitto() else { return };
    let (handle, scan) = plc("plant3", &m);
    let sub = mqtt::Sub::start(
        m.port(),
        &["cetratus/plant3/reply/ops", "cetratus/plant3/events"],
        2,
        10,
    );
    mqtt::publish(
        m.port(),
        "cetratus/plant3/cmd/substitute",
        br#"{"reply_to":"cetratus/plant3/reply/ops","mode":"teleport"}"#,
    );
    let lines = sub.messages();
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
