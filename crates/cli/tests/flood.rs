//! Floods against the real binary: what others publish must not decide how much memory the PLC
//! uses, nor how many commands it answers, and the PLC must go on answering while it is flooded.
//!
//! `cetratus run` on its embedded broker (with the embedded dashboard) receives 300 `load`
//! commands of about 1 MB each and 50 messages of 3 MB on another PLC's `events` topic, all sent
//! as fast as a client can. Its resident memory is sampled throughout; it must stay under a bound
//! that does not grow with the flood, some commands must be answered `busy` (the queues are
//! bounded in bytes), and `exec_info` must still be answered afterwards.
//!
//! Then 10,000 small `exec_info` requests, as fast as a client can: the broker passes on no
//! more than its command rate allows over the time they took, answers a few more `busy`, and
//! refuses the rest with a reason; the PLC keeps cycling and answers normally afterwards.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use base64::Engine as _;
use cetratus_mct::{BUSY_ANSWERS_PER_S, BUSY_BURST, COMMANDS_PER_S, COMMAND_BURST, STRIKES};
use rumqttc::v5::mqttbytes::QoS;
use serde_json::Value;

/// The PLC's resident memory may not pass this, whatever is sent to it.
const RSS_BOUND_KB: u64 = 256 * 1024;

const PLC: &str = "cell1";

mod common;

use common::{
    client, first_answer, poll_reply, reply, reply_topic, request, rss_kb, RssSampler, RunningPlc,
};

/// Bytes that look random and are the same on every run (SplitMix64).
fn noise(n: usize) -> Vec<u8> {
    let mut x = 0x5EED_u64;
    (0..n)
        .map(|_| {
            x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = x;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            (z ^ (z >> 31)) as u8
        })
        .collect()
}

#[test]
fn a_flood_of_large_commands_and_events_leaves_the_plcs_memory_bounded_and_it_answers() {
    let plc = RunningPlc::start(PLC, &[]);
    let pid = plc.process.id();
    let (flood, replies) = client(plc.mqtt, "flood", PLC);
    // The PLC answers before the flood: its MQTT side is up.
    first_answer(&flood, &replies, PLC, Duration::from_secs(30));
    let rss_before = rss_kb(pid).expect("the PLC's memory");
    let sampler = RssSampler::start(pid);

    // 300 `load` commands of about 1 MB (just under the 1 MiB command limit): random bytes, so
    // each is verified and refused; 50 `events` of 3 MB for a PLC that does not exist.
    let load = format!(
        "{{\"package_b64\":\"{}\"}}",
        base64::engine::general_purpose::STANDARD.encode(noise(760_000))
    )
    .into_bytes();
    assert!(
        load.len() > 1_000_000 && load.len() < 1 << 20,
        "{}",
        load.len()
    );
    for k in 0..300u32 {
        request(
            &flood,
            PLC,
            "load",
            format!("load-{k}").as_bytes(),
            load.clone(),
        );
    }
    let event = format!(
        "{{\"kind\":\"flood\",\"message\":\"{}\"}}",
        "y".repeat(3_000_000)
    )
    .into_bytes();
    for _ in 0..50 {
        flood
            .publish("cetratus/x/events", QoS::AtMostOnce, false, event.clone())
            .expect("the flood client queues an event");
    }
    // Until the answers stop coming (a broker may drop answers to a client that floods it).
    let end = Instant::now() + Duration::from_secs(60);
    let (mut seen, mut quiet_since) = (0, Instant::now());
    while Instant::now() < end && quiet_since.elapsed() < Duration::from_secs(3) {
        let n = replies.lock().expect("replies").len();
        if n != seen {
            (seen, quiet_since) = (n, Instant::now());
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    request(&flood, PLC, "exec_info", b"after", b"{}".to_vec());
    let after = reply(&replies, b"after", Duration::from_secs(30));
    let peak = sampler.peak_kb();

    let mut codes: BTreeMap<String, usize> = BTreeMap::new();
    for (k, v) in replies.lock().expect("replies").iter() {
        if k.starts_with(b"load-") {
            let code = v["error"]["code"].as_str().unwrap_or("ok").to_string();
            *codes.entry(code).or_default() += 1;
        }
    }
    eprintln!("RSS before {rss_before} kB, peak {peak} kB; load replies by code: {codes:?}");
    assert_eq!(after["ok"], true, "{after}");
    assert!(
        after["result"][0]["cycles"].as_u64().is_some(),
        "exec_info names the primary's cycles: {after}"
    );
    assert!(
        peak < RSS_BOUND_KB,
        "the PLC's memory peaked at {peak} kB (before the flood {rss_before} kB): what others \
         send must not decide it"
    );
    assert!(
        codes.get("busy").copied().unwrap_or(0) > 0,
        "a flood of large commands fills the queue, and the PLC says so: {codes:?}"
    );
    assert!(
        codes.keys().all(|c| c == "busy" || c == "refused"),
        "every load is refused or turned away busy: {codes:?}"
    );

    // The PLC counts what it turned away where operators look: in its retained `state` (which
    // this client's collector files under the empty correlation data).
    let busy = codes.get("busy").copied().unwrap_or(0) as u64;
    flood
        .subscribe(format!("cetratus/{PLC}/state"), QoS::AtLeastOnce)
        .expect("subscribe to the state");
    let mut control = Value::Null;
    common::wait_for(
        "a state that counts the commands answered busy",
        Duration::from_secs(30),
        || {
            control = replies
                .lock()
                .expect("replies")
                .get(b"".as_slice())
                .map_or(Value::Null, |state| state["control"].clone());
            control["commands_busy"].as_u64().unwrap_or(0) >= busy
        },
    );
    eprintln!("state.control after the flood: {control}");
    drop(plc);
}

/// What the command flood's client saw: its publishes acknowledged by the broker, by outcome;
/// and the replies to them, by code.
#[derive(Clone, Default)]
struct FloodTally {
    accepted: u64,
    refused: u64,
    reasons: std::collections::BTreeSet<String>,
    last_ack: Option<Instant>,
    /// Times the broker dropped the flood's connection.
    disconnects: u64,
    replies: BTreeMap<String, u64>,
    busy_messages: std::collections::BTreeSet<String>,
}

#[test]
fn a_flood_of_small_commands_is_passed_on_only_at_the_brokers_command_rate() {
    use rumqttc::v5::mqttbytes::v5::{Packet, PubAckReason, PublishProperties};
    use rumqttc::v5::{Client, Event, MqttOptions};
    use std::sync::Mutex;

    const N: u64 = 10_000;
    let plc = RunningPlc::start(PLC, &[]);
    let (probe, replies) = client(plc.mqtt, "probe", PLC);
    let before = first_answer(&probe, &replies, PLC, Duration::from_secs(30));

    // The flooding client, at QoS 1 so that the broker's refusals come back with their reason.
    let mut opts = MqttOptions::new("flood", "127.0.0.1", plc.mqtt);
    opts.set_keep_alive(Duration::from_secs(30));
    let (flood, mut conn) = Client::new(opts, 1024);
    let tally: Arc<Mutex<FloodTally>> = Arc::default();
    let connected = Arc::new(AtomicBool::new(false));
    {
        let (tally, connected) = (tally.clone(), connected.clone());
        std::thread::spawn(move || {
            for ev in conn.iter() {
                let mut t = tally.lock().expect("tally");
                match ev {
                    Ok(Event::Incoming(Packet::ConnAck(_))) => {
                        connected.store(true, Ordering::Release)
                    }
                    Ok(Event::Incoming(Packet::PubAck(ack))) => {
                        t.last_ack = Some(Instant::now());
                        if ack.reason == PubAckReason::Success {
                            t.accepted += 1;
                        } else {
                            t.refused += 1;
                            let why = ack.properties.and_then(|p| p.reason_string);
                            t.reasons.insert(format!(
                                "{:?}: {}",
                                ack.reason,
                                why.unwrap_or_default()
                            ));
                        }
                    }
                    Ok(Event::Incoming(Packet::Disconnect(_))) => t.disconnects += 1,
                    Ok(_) => {}
                    Err(_) => {
                        t.disconnects += 1;
                        drop(t);
                        std::thread::sleep(Duration::from_millis(50));
                    }
                }
            }
        });
    }
    // The replies go to the probe: a client that floods is held back by the broker, and with it
    // its own subscriptions.
    let replies_to = reply_topic(PLC);
    common::wait_for("the flood's connection", Duration::from_secs(10), || {
        connected.load(Ordering::Acquire)
    });

    let start = Instant::now();
    for k in 0..N {
        let props = PublishProperties {
            response_topic: Some(replies_to.clone()),
            correlation_data: Some(format!("flood-{k}").into_bytes().into()),
            ..PublishProperties::default()
        };
        flood
            .publish_with_properties(
                format!("cetratus/{PLC}/cmd/exec_info"),
                QoS::AtLeastOnce,
                false,
                b"{}".to_vec(),
                props,
            )
            .expect("the flood client queues a command");
    }
    // The broker disconnects a client it goes on refusing, with what it had queued: the rest
    // of the flood is sent again on each new connection, or lost with one.
    common::wait_for(
        "the broker to acknowledge or drop every command",
        Duration::from_secs(300),
        || {
            let t = tally.lock().expect("tally");
            let quiet = t
                .last_ack
                .is_some_and(|l| l.elapsed() > Duration::from_secs(3));
            t.accepted + t.refused >= N || (t.disconnects > 0 && quiet)
        },
    );
    // Every command the broker passed on was charged between the first publish and the last
    // acknowledgement: at most the bursts and the rates over that time.
    let elapsed = {
        let t = tally.lock().expect("tally");
        t.last_ack.map_or(Duration::ZERO, |l| l - start)
    };
    // Until the replies stop coming.
    let flood_replies = || -> Vec<Value> {
        let r = replies.lock().expect("replies");
        r.iter()
            .filter(|(k, _)| k.starts_with(b"flood-"))
            .map(|(_, v)| v.clone())
            .collect()
    };
    let (mut seen, mut quiet_since) = (0, Instant::now());
    while quiet_since.elapsed() < Duration::from_secs(3) {
        let n = flood_replies().len();
        if n != seen {
            (seen, quiet_since) = (n, Instant::now());
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let secs = elapsed.as_secs_f64();
    // The buckets' bound holds exactly over that time (one clock, the machine's); a little more
    // for rounding.
    let passed_bound = 1.02 * (COMMAND_BURST + COMMANDS_PER_S * secs) + 10.0;
    let busy_bound = 1.02 * (BUSY_BURST + BUSY_ANSWERS_PER_S * secs) + 10.0;
    let mut t = tally.lock().expect("tally").clone();
    for v in flood_replies() {
        let code = v["error"]["code"].as_str().unwrap_or("ok").to_string();
        if code == "busy" {
            let m = v["error"]["message"].as_str().unwrap_or_default();
            t.busy_messages.insert(m.to_string());
        }
        *t.replies.entry(code).or_default() += 1;
    }
    eprintln!(
        "{N} exec_info in {secs:.2} s: {} passed by the broker, {} refused {:?}; replies by code \
         {:?}; busy messages {:?}",
        t.accepted, t.refused, t.reasons, t.replies, t.busy_messages
    );
    assert!(
        (t.accepted as f64) <= passed_bound + busy_bound,
        "the broker passed on {} of {N} commands in {secs:.2} s; its limits allow at most \
         {passed_bound:.0} + {busy_bound:.0}",
        t.accepted
    );
    let ok = t.replies.get("ok").copied().unwrap_or(0);
    assert!(
        (ok as f64) <= passed_bound,
        "{ok} full exec_info answers in {secs:.2} s, over the command rate's {passed_bound:.0}"
    );
    assert!(
        ok > 0,
        "the commands within the rate are answered: {:?}",
        t.replies
    );
    // A flood that a loaded machine sends no faster than the limits is only held to them; one
    // that goes past them must have been answered busy, and then refused.
    if (N as f64) > passed_bound {
        assert!(
            t.busy_messages
                .iter()
                .any(|m| m.contains("embedded broker passes them on")),
            "some commands past the rate are answered busy, saying why: {:?}",
            t.busy_messages
        );
    }
    if (N as f64) > passed_bound + busy_bound {
        assert!(
            t.reasons.iter().any(|r| r.starts_with("NotAuthorized")
                && r.contains("commands a second")
                && r.contains("wait for each reply")),
            "a refused sender hears what and what to do: {:?}",
            t.reasons
        );
    }
    assert!(
        t.refused < u64::from(STRIKES) || t.disconnects > 0,
        "a client refused {} times without a break is disconnected, with its backlog",
        t.refused
    );

    // The PLC kept cycling, and a command once the bucket has refilled is answered normally.
    std::thread::sleep(Duration::from_secs_f64(
        COMMAND_BURST / COMMANDS_PER_S + 0.5,
    ));
    request(&probe, PLC, "exec_info", b"after", b"{}".to_vec());
    let after = reply(&replies, b"after", Duration::from_secs(30));
    assert_eq!(after["ok"], true, "{after}");
    let cycles = |v: &Value| v["result"][0]["cycles"].as_u64().unwrap_or(0);
    assert!(
        cycles(&after) > cycles(&before),
        "the PLC went on cycling: {before} then {after}"
    );
    drop(plc);
}

/// A bare MQTT 5 client `id` (clean start, keep-alive 300 s, no properties), connected.
fn connect_v5(port: u16, id: &str) -> std::net::TcpStream {
    use std::io::{Read, Write};
    let mut body = common::raw_mqtt::mqtt_str("MQTT");
    body.extend_from_slice(&[5, 0x02, 0x01, 0x2C, 0]);
    body.extend_from_slice(&common::raw_mqtt::mqtt_str(id));
    let mut s = std::net::TcpStream::connect(("127.0.0.1", port)).expect("connects");
    s.write_all(&common::raw_mqtt::packet(0x10, &body))
        .expect("CONNECT");
    let mut connack = [0u8; 4];
    s.read_exact(&mut connack).expect("CONNACK");
    assert_eq!((connack[0], connack[3]), (0x20, 0), "accepted: {connack:?}");
    s
}

/// An MQTT 5 PUBLISH at QoS 0 of a command on `topic` that asks for its reply on `reply_to`.
fn command_v5(topic: &str, reply_to: &str, correlation: &[u8]) -> Vec<u8> {
    let mut props = vec![0x08];
    props.extend_from_slice(&common::raw_mqtt::mqtt_str(reply_to));
    props.push(0x09);
    props.extend_from_slice(&(correlation.len() as u16).to_be_bytes());
    props.extend_from_slice(correlation);
    let mut body = common::raw_mqtt::mqtt_str(topic);
    assert!(props.len() < 128, "one byte of property length");
    body.push(props.len() as u8);
    body.extend_from_slice(&props);
    body.extend_from_slice(b"{}");
    common::raw_mqtt::packet(0x30, &body)
}

#[test]
fn a_flood_that_stops_leaves_no_backlog_that_keeps_operators_waiting() {
    use std::io::Write;

    let plc = RunningPlc::start(PLC, &[]);
    let (probe, replies) = client(plc.mqtt, "probe", PLC);
    first_answer(&probe, &replies, PLC, Duration::from_secs(30));

    // A bare MQTT 5 client writes `exec_info` requests, each asking for a reply, at QoS 0 as
    // fast as its socket takes them, for 5 s; then it stops writing and keeps its connection
    // open: what it wrote and the broker has not read waits in the two sockets.
    let command = command_v5(
        &format!("cetratus/{PLC}/cmd/exec_info"),
        &reply_topic(PLC),
        b"flood",
    );
    let batch = command.repeat(256);
    let mut flood = connect_v5(plc.mqtt, "flood");
    flood
        .set_write_timeout(Some(Duration::from_millis(100)))
        .expect("a write timeout");
    let (start, mut written) = (Instant::now(), 0u64);
    while start.elapsed() < Duration::from_secs(5) {
        match flood.write(&batch) {
            Ok(n) => written += n as u64,
            // Full, or closed by the broker.
            Err(_) => std::thread::sleep(Duration::from_millis(10)),
        }
    }
    eprintln!(
        "the flood wrote {} commands",
        written / command.len() as u64
    );

    // An operator asks once the flood has stopped: the broker must not still be busy with it.
    let asked = Instant::now();
    // The requests of the flood already queued at the PLC (at most 64) are answered first, and
    // a QoS 0 command may be dropped by a bounded queue while the backlog drains: the operator
    // asks again, as one clicks again, every 2 s, for at most 30 s.
    let mut answer = Value::Null;
    for k in 0..15u8 {
        let corr = format!("after-flood-{k}").into_bytes();
        request(&probe, PLC, "exec_info", &corr, b"{}".to_vec());
        answer = poll_reply(&replies, &corr, Duration::from_secs(2)).unwrap_or(Value::Null);
        if answer["ok"] == true {
            break;
        }
        if !answer.is_null() {
            std::thread::sleep(Duration::from_secs(1));
        }
    }
    assert_eq!(
        answer["ok"], true,
        "the operator's command within 30 s of the flood: {answer}"
    );
    eprintln!("answered {:?} after the flood stopped", asked.elapsed());
    drop(flood);
}
