//! One client must not stop or steer a PLC through its embedded broker, tried against the real
//! binary (docs/security.md, *Embedded broker*): a topic of thousands of levels, a last will on
//! a topic its client may not publish, and a client that takes the PLC's own client id.

mod common;

use std::io::{Read, Write};
use std::time::Duration;

use cetratus_mct::MAX_TOPIC_LEVELS;
use cetratus_testkit::raw_mqtt::{
    closed_within, connect, mqtt_str, packet, try_connect, ConnectOptions,
};
use common::{assert_cycles_on, client, first_answer, primary_cycles, watch, RunningPlc};

/// Sends a SUBSCRIBE of `filter` on `s`; returns the SUBACK's return code.
fn suback_code(s: &mut std::net::TcpStream, packet_id: u16, filter: &str) -> u8 {
    let mut body = packet_id.to_be_bytes().to_vec();
    body.extend_from_slice(&mqtt_str(filter));
    body.push(0);
    s.write_all(&packet(0x82, &body)).expect("SUBSCRIBE");
    let mut ack = [0u8; 5];
    s.read_exact(&mut ack).expect("SUBACK");
    let id = packet_id.to_be_bytes();
    assert_eq!(ack[..4], [0x90, 3, id[0], id[1]], "a SUBACK: {ack:?}");
    ack[4]
}

#[test]
fn a_topic_of_thousands_of_levels_is_refused_with_its_reason_code_and_the_plc_cycles_on() {
    let mut plc = RunningPlc::start("deep1", &[]);
    let (ops, replies) = client(plc.mqtt, "ops-deep1", "deep1");
    let before = primary_cycles(&first_answer(
        &ops,
        &replies,
        "deep1",
        Duration::from_secs(30),
    ));
    let addr = ("127.0.0.1", plc.mqtt);

    // 6,000 levels overflowed a broker thread's stack and aborted the whole process.
    let mut s = connect(addr, "deep-sub");
    let deep = vec!["a"; 6000].join("/");
    assert_eq!(suback_code(&mut s, 1, &deep), 0x80, "refused");
    let deepest = vec!["a"; MAX_TOPIC_LEVELS].join("/");
    assert_eq!(suback_code(&mut s, 2, &deepest), 0, "the deepest allowed");
    assert_eq!(
        suback_code(&mut s, 3, &format!("{deepest}/#")),
        0x80,
        "one level too many"
    );

    // A retained PUBLISH of 8,000 levels, and one of a single level of 5 KiB: the broker
    // closes the connection of each.
    for (id, topic) in [
        ("deep-pub", vec!["b"; 8000].join("/")),
        ("long-pub", "c".repeat(5 << 10)),
    ] {
        let mut p = connect(addr, id);
        let mut body = mqtt_str(&topic);
        body.extend_from_slice(b"x");
        p.write_all(&packet(0x31, &body)).expect("PUBLISH");
        assert!(
            closed_within(&mut p, Duration::from_secs(10)),
            "{id}: the broker closes the connection"
        );
    }
    assert!(
        matches!(plc.process.0.try_wait(), Ok(None)),
        "the PLC runs on"
    );
    assert_cycles_on(&ops, &replies, "deep1", b"after", before);
}

#[test]
fn a_will_on_a_topic_only_the_plc_publishes_is_refused_at_connect() {
    let plc = RunningPlc::start("will1", &[]);
    let addr = ("127.0.0.1", plc.mqtt);
    // A forged retained `net` was drawn on the dashboard as a safe, idle PLC.
    for (id, topic) in [
        ("forger-1", "cetratus/will1/net"),
        ("forger-2", "cetratus/will1/state"),
    ] {
        let will = Some((topic, &b"{}"[..], true));
        let (_s, code) = try_connect(addr, id, ConnectOptions { login: None, will });
        assert_eq!(code, 5, "a will on {topic} is not authorised");
    }
    // The broker is anonymous: anyone may command, so a will that commands is as good as a
    // command, and a will outside Cetratus's topics is anyone's.
    for (id, topic) in [
        ("willing-1", "cetratus/will1/cmd/abort"),
        ("willing-2", "plant/line1/alive"),
    ] {
        let will = Some((topic, &b"{}"[..], false));
        let (_s, code) = try_connect(addr, id, ConnectOptions { login: None, will });
        assert_eq!(code, 0, "a will on {topic} is taken");
    }
}

#[test]
fn no_login_takes_over_the_client_id_of_the_plc_or_of_its_dashboard() {
    let (plc, log) = RunningPlc::start_logged("idt1", &[]);
    let (ops, replies) = client(plc.mqtt, "ops-idt1", "idt1");
    let before = primary_cycles(&first_answer(
        &ops,
        &replies,
        "idt1",
        Duration::from_secs(30),
    ));
    let (_watcher, states) = watch(plc.mqtt, "cetratus/idt1/state");
    common::wait_for("the retained state", Duration::from_secs(10), || {
        !states.lock().expect("seen").is_empty()
    });
    let addr = ("127.0.0.1", plc.mqtt);
    // The id the PLC had before its ids were reserved is anyone's now; the reserved ones are
    // refused, again and again.
    let (_old, code) = try_connect(addr, "cetratus-idt1", ConnectOptions::default());
    assert_eq!(code, 0, "the old id is no longer the PLC's");
    for _ in 0..5 {
        for id in ["$cetratus-plc-idt1", "$cetratus-dashboard-1-2"] {
            let (_s, code) = try_connect(addr, id, ConnectOptions::default());
            assert_eq!(code, 5, "{id} is reserved for the PLC's own clients");
        }
    }
    assert_cycles_on(&ops, &replies, "idt1", b"after", before);
    let offline = states
        .lock()
        .expect("seen")
        .iter()
        .any(|p| String::from_utf8_lossy(p).contains("\"online\":false"));
    assert!(
        !offline,
        "the PLC was never cut off (its will says offline)"
    );
    // Ten attempts: logged on the 1st, 2nd, 4th and 8th, with the count, not once each.
    let mut lines = 0;
    common::wait_for("the log lines", Duration::from_secs(10), || {
        lines += log
            .try_iter()
            .filter(|l| l.contains("reserved for the PLC's own clients"))
            .count();
        lines >= 4
    });
    assert_eq!(lines, 4, "the broker logs the attempts, counted");
}

#[test]
fn past_max_clients_a_connect_is_refused_and_the_plc_answers_on() {
    use cetratus_mct::MAX_CLIENTS;
    let plc = RunningPlc::start("many1", &[]);
    let (ops, replies) = client(plc.mqtt, "ops-many1", "many1");
    let before = primary_cycles(&first_answer(
        &ops,
        &replies,
        "many1",
        Duration::from_secs(30),
    ));
    let addr = ("127.0.0.1", plc.mqtt);
    // 3,000 clients were once accepted against a documented 256.
    let (mut held, mut refused) = (Vec::new(), 0);
    for k in 0..MAX_CLIENTS + 20 {
        let (s, code) = try_connect(addr, &format!("many-{k}"), ConnectOptions::default());
        match code {
            0 => held.push(s),
            3 => refused += 1,
            other => panic!("CONNACK {other} for client {k}"),
        }
    }
    assert!(held.len() < MAX_CLIENTS, "{} held", held.len());
    assert!(refused >= 20, "{refused} refused");
    assert_cycles_on(&ops, &replies, "many1", b"full", before);
    drop(held);
    common::wait_for("a session free again", Duration::from_secs(10), || {
        try_connect(addr, "after", ConnectOptions::default()).1 == 0
    });
}
