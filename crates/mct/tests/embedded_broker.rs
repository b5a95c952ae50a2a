//! The embedded broker, seen from MQTT clients: MQTT 5 request/reply properties, MQTT 3.1.1 and 5
//! on one port, retained messages, last wills, hashed passwords, the ACL, TLS, and a taken port.

mod common;

use std::net::{Ipv4Addr, SocketAddrV4};
use std::time::Duration;

use cetratus_mct::password::hash_password;
use cetratus_mct::{BrokerAccount, BrokerSettings, BrokerTls, EmbeddedBroker, MctError};
use common::*;
use rumqttc::v5::mqttbytes::v5::{LastWill, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;

const T: Duration = Duration::from_secs(5);

#[test]
fn embedded_broker_forwards_mqtt5_response_topic_and_correlation_data() {
    let broker = EmbeddedBroker::start(free_addr(), "cell1").expect("broker");
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
    let broker = EmbeddedBroker::start(free_addr(), "cell1").expect("broker");
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
    let broker = EmbeddedBroker::start(free_addr(), "cell1").expect("broker");
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
    let broker = EmbeddedBroker::start_with(
        BrokerSettings {
            accounts: vec![account("op", "s3cret", &[])],
            ..BrokerSettings::open(free_addr())
        },
        "cell1",
    )
    .expect("broker");
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
    let err = EmbeddedBroker::start(addr, "cell1").expect_err("port is taken");
    assert!(matches!(err, MctError::PortTaken { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("--mqtt 127.0.0.1:1884"), "{msg}");
    assert!(msg.contains("--broker mqtt://"), "{msg}");
}

fn account(name: &str, password: &str, plcs: &[&str]) -> BrokerAccount {
    BrokerAccount {
        name: name.into(),
        password_hash: hash_password(password).expect("hashes"),
        plcs: plcs.iter().map(|p| p.to_string()).collect(),
    }
}

/// A broker for `cell1` whose accounts are `ops` (may command cell1) and `other` (may command
/// cell2 only); both passwords are `pw`.
fn broker_with_accounts(tls: Option<BrokerTls>) -> EmbeddedBroker {
    EmbeddedBroker::start_with(
        BrokerSettings {
            addr: free_addr(),
            accounts: vec![
                account("ops", "pw", &["cell1"]),
                account("other", "pw", &["cell2"]),
            ],
            tls,
        },
        "cell1",
    )
    .expect("broker")
}

#[test]
fn an_account_commands_only_its_plcs_and_nobody_but_the_plc_publishes_its_state() {
    let broker = broker_with_accounts(None);
    let watcher = v5(broker.addr(), Some(("ops", "pw")));
    watcher.subscribe("cetratus/#");
    let intruder = v5(broker.addr(), Some(("other", "pw")));
    // The attack: an account of the plant commands a PLC it was not given, and forges the PLC's
    // state, events and a reply.
    for (topic, payload) in [
        ("cetratus/cell1/cmd/abort", "{}"),
        ("cetratus/cell1/state", r#"{"online":true,"primary":"B"}"#),
        ("cetratus/cell1/events", r#"{"kind":"substituted"}"#),
        ("cetratus/cell1/reply/dashboard-x", r#"{"ok":true}"#),
    ] {
        intruder
            .client
            .publish(topic, QoS::AtLeastOnce, true, payload)
            .expect("publish");
    }
    intruder
        .client
        .publish(
            "cetratus/cell2/cmd/abort",
            QoS::AtLeastOnce,
            false,
            "allowed",
        )
        .expect("publish");
    let allowed = watcher
        .next_on("cetratus/cell2/cmd/abort", T)
        .expect("a command for its own PLC passes");
    assert_eq!(allowed.payload, b"allowed");
    let seen: Vec<String> = watcher.rx.try_iter().map(|g| g.topic).collect();
    assert!(seen.is_empty(), "the broker passed on {seen:?}");
    // Nothing of it was retained either.
    let late = v5(broker.addr(), Some(("ops", "pw")));
    late.subscribe("cetratus/cell1/#");
    assert!(late
        .next_on("cetratus/cell1/state", Duration::from_millis(500))
        .is_none());
    // The account that may command cell1 does.
    let ops = v5(broker.addr(), Some(("ops", "pw")));
    ops.client
        .publish(
            "cetratus/cell1/cmd/exec_info",
            QoS::AtLeastOnce,
            false,
            "{}",
        )
        .expect("publish");
    assert!(watcher.next_on("cetratus/cell1/cmd/exec_info", T).is_some());
}

#[test]
fn a_client_that_claims_the_plcs_own_login_is_refused() {
    let broker = broker_with_accounts(None);
    for user in [cetratus_mct::PLC_USER, cetratus_mct::DASHBOARD_USER] {
        let mut o =
            rumqttc::v5::MqttOptions::new(unique("claim"), "127.0.0.1", broker.addr().port());
        o.set_credentials(user, "guess");
        let (_client, mut conn) = rumqttc::v5::Client::new(o, 4);
        let first = conn.iter().next().expect("an event");
        assert!(first.is_err(), "{user} with a guessed secret got {first:?}");
    }
    let login = broker.plc_login().clone();
    let plc = v5(broker.local_addr(), Some((&login.user, &login.password)));
    let watcher = v5(broker.addr(), Some(("ops", "pw")));
    watcher.subscribe("cetratus/cell1/state");
    plc.client
        .publish("cetratus/cell1/state", QoS::AtLeastOnce, false, "{}")
        .expect("publish");
    assert!(
        watcher.next_on("cetratus/cell1/state", T).is_some(),
        "the PLC publishes its state"
    );
}

#[test]
fn beyond_loopback_the_broker_refuses_to_start_without_tls_and_accounts() {
    let err = EmbeddedBroker::start(SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, 0).into(), "cell1")
        .expect_err("exposed");
    assert!(matches!(err, MctError::Exposed { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(
        msg.contains("0.0.0.0:0") && msg.contains("tls_cert") && msg.contains("[mqtt] users"),
        "{msg}"
    );
}

#[test]
fn with_tls_the_broker_speaks_only_tls_on_its_port_and_checks_the_login() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cert = rcgen::generate_simple_self_signed(vec!["localhost".into()]).expect("cert");
    let (cert_pem, key_pem) = (cert.cert.pem(), cert.key_pair.serialize_pem());
    std::fs::write(dir.path().join("cert.pem"), &cert_pem).expect("write");
    std::fs::write(dir.path().join("key.pem"), &key_pem).expect("write");
    let broker = broker_with_accounts(Some(BrokerTls {
        cert: dir.path().join("cert.pem"),
        key: dir.path().join("key.pem"),
    }));
    assert_ne!(
        broker.addr(),
        broker.local_addr(),
        "a loopback port of its own"
    );
    let port = broker.addr().port();
    // Plain MQTT on the TLS port gets nowhere.
    let mut o = rumqttc::v5::MqttOptions::new(unique("plain"), "127.0.0.1", port);
    o.set_credentials("ops", "pw");
    let (_c, mut conn) = rumqttc::v5::Client::new(o, 4);
    assert!(
        conn.iter().next().expect("an event").is_err(),
        "plain MQTT on the TLS port"
    );
    // TLS with the broker's certificate works, and the login is still checked.
    let tls = |password: &str| {
        let mut o = rumqttc::v5::MqttOptions::new(unique("tls"), "localhost", port);
        o.set_credentials("ops", password);
        o.set_transport(rumqttc::Transport::tls(
            cert_pem.clone().into_bytes(),
            None,
            None,
        ));
        o
    };
    let _ = rustls::crypto::ring::default_provider().install_default();
    let (_c, mut conn) = rumqttc::v5::Client::new(tls("wrong"), 4);
    assert!(
        conn.iter().next().expect("an event").is_err(),
        "a wrong password over TLS"
    );
    let ok = v5_with(tls("pw"));
    ok.subscribe("cetratus/cell1/cmd/#");
    ok.client
        .publish(
            "cetratus/cell1/cmd/exec_info",
            QoS::AtLeastOnce,
            false,
            "{}",
        )
        .expect("publish");
    assert!(ok.next_on("cetratus/cell1/cmd/exec_info", T).is_some());
}

/// Publishes `n` commands `topic` at QoS 1 as `user` (password `pw`), and returns how many the
/// broker acknowledged as passed and how many it refused.
fn command_acks(broker: &EmbeddedBroker, user: &str, topic: &str, n: u64) -> (u64, u64) {
    use rumqttc::v5::mqttbytes::v5::{Packet, PubAckReason};
    use rumqttc::v5::{Client, Event, MqttOptions};
    let addr = broker.addr();
    let mut o = MqttOptions::new(unique(user), addr.ip().to_string(), addr.port());
    o.set_credentials(user, "pw");
    let (client, mut conn) = Client::new(o, 256);
    let who = user.to_string();
    let counter = std::thread::spawn(move || {
        let (mut passed, mut refused) = (0, 0);
        for ev in conn.iter() {
            match ev {
                Ok(Event::Incoming(Packet::PubAck(a))) if a.reason == PubAckReason::Success => {
                    passed += 1
                }
                Ok(Event::Incoming(Packet::PubAck(_))) => refused += 1,
                Ok(_) => {}
                Err(e) => panic!("{who}'s connection: {e}"),
            }
            if passed + refused == n {
                break;
            }
        }
        (passed, refused)
    });
    for _ in 0..n {
        client
            .publish(topic, QoS::AtLeastOnce, false, "{}")
            .expect("publish");
    }
    counter.join().expect("the counter")
}

#[test]
fn commands_the_acl_refuses_spend_nothing_of_the_command_budget_of_those_who_may_command() {
    let broker = broker_with_accounts(None);
    // The attack: an account that may not command cell1 floods it, to leave no commands for
    // the operators who may.
    let flood = 3 * cetratus_mct::COMMAND_BURST as u64;
    let (passed, refused) = command_acks(&broker, "other", "cetratus/cell1/cmd/exec_info", flood);
    assert_eq!((passed, refused), (0, flood), "the ACL refuses every one");
    // Within the burst, every command of an account that may command passes.
    let within = cetratus_mct::COMMAND_BURST as u64 / 2;
    let (passed, refused) = command_acks(&broker, "ops", "cetratus/cell1/cmd/exec_info", within);
    assert_eq!((passed, refused), (within, 0));
}
