//! The embedded broker, seen from MQTT clients: MQTT 5 request/reply properties, MQTT 3.1.1 and 5
//! on one port, retained messages, last wills, passwords, and a taken port.

mod common;

use std::time::Duration;

use cetratus_mct::{EmbeddedBroker, MctError};
use common::*;
use rumqttc::v5::mqttbytes::v5::{LastWill, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;

const T: Duration = Duration::from_secs(5);

#[test]
fn embedded_broker_forwards_mqtt5_response_topic_and_correlation_data() {
    let broker = EmbeddedBroker::start(free_addr(), vec![]).expect("broker");
    let sub = v5(broker.addr(), None);
    sub.subscribe("req/#");
    let publisher = v5(broker.addr(), None);
    let props = PublishProperties {
        response_topic: Some("reply/here".into()),
        correlation_data: Some(vec![0, 1, 2, 255].into()),
        ..Default::default()
    };
    publisher
        .client
        .publish_with_properties("req/x", QoS::AtLeastOnce, false, "ping", props)
        .expect("publish");
    let got = sub.next_on("req/x", T).expect("forwarded");
    assert_eq!(got.payload, b"ping");
    assert_eq!(got.response_topic.as_deref(), Some("reply/here"));
    assert_eq!(got.correlation.as_deref(), Some(&[0u8, 1, 2, 255][..]));
}

#[test]
fn embedded_broker_serves_mqtt311_and_mqtt5_clients_on_one_port() {
    let broker = EmbeddedBroker::start(free_addr(), vec![]).expect("broker");
    let addr = broker.addr();
    let five = v5(addr, None);
    five.subscribe("mix/#");
    let c311 = v311(addr);
    c311.subscribe("back/#");
    c311.client
        .publish("mix/a", rumqttc::QoS::AtLeastOnce, false, "from 3.1.1")
        .expect("publish");
    assert_eq!(
        five.next_on("mix/a", T).expect("3.1.1 → 5").payload,
        b"from 3.1.1"
    );
    five.client
        .publish("back/b", QoS::AtLeastOnce, false, "from 5")
        .expect("publish");
    let payload = c311.next_on("back/b", T).expect("5 → 3.1.1");
    assert_eq!(payload, b"from 5");
}

#[test]
fn embedded_broker_keeps_retained_messages_and_publishes_last_wills() {
    let broker = EmbeddedBroker::start(free_addr(), vec![]).expect("broker");
    let publisher = v5(broker.addr(), None);
    publisher
        .client
        .publish("keep/me", QoS::AtLeastOnce, true, "kept")
        .expect("publish");
    std::thread::sleep(Duration::from_millis(200));
    let late = v5(broker.addr(), None);
    late.subscribe("keep/#");
    let got = late
        .next_on("keep/me", T)
        .expect("retained message delivered to a late subscriber");
    assert!(got.retain);
    assert_eq!(got.payload, b"kept");

    late.subscribe("will/#");
    let mut o = rumqttc::v5::MqttOptions::new(
        unique("dying"),
        broker.addr().ip().to_string(),
        broker.addr().port(),
    );
    o.set_last_will(LastWill::new(
        "will/x",
        "gone",
        QoS::AtLeastOnce,
        false,
        None,
    ));
    let dying = v5_with(o);
    dying.subscribe("nothing");
    dying.kill();
    assert_eq!(
        late.next_on("will/x", T).expect("last will").payload,
        b"gone"
    );
}

#[test]
fn embedded_broker_accepts_configured_users_and_refuses_a_wrong_password() {
    let broker =
        EmbeddedBroker::start(free_addr(), vec![("op".into(), "s3cret".into())]).expect("broker");
    let good = v5(broker.addr(), Some(("op", "s3cret")));
    good.subscribe("a/b");
    let (client, mut conn) = rumqttc::v5::Client::new(
        {
            let mut o = rumqttc::v5::MqttOptions::new(
                unique("bad"),
                broker.addr().ip().to_string(),
                broker.addr().port(),
            );
            o.set_credentials("op", "wrong");
            o
        },
        4,
    );
    let first = conn.iter().next().expect("an event");
    assert!(
        first.is_err(),
        "a wrong password must be refused, got {first:?}"
    );
    drop(client);
}

#[test]
fn a_taken_port_gives_an_error_that_says_how_to_choose_another() {
    let holder = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = holder.local_addr().expect("addr");
    let err = EmbeddedBroker::start(addr, vec![]).expect_err("port is taken");
    assert!(matches!(err, MctError::PortTaken { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("--mqtt 127.0.0.1:1884"), "{msg}");
    assert!(msg.contains("--broker mqtt://"), "{msg}");
}
