//! Floods against the real binary: what others publish must not decide how much memory the PLC
//! uses, and the PLC must go on answering while it is flooded.
//!
//! `cetratus run` on its embedded broker (with the embedded dashboard) receives 300 `load`
//! commands of about 1 MB each and 50 messages of 3 MB on another PLC's `events` topic, all sent
//! as fast as a client can. Its resident memory is sampled throughout; it must stay under a bound
//! that does not grow with the flood, some commands must be answered `busy` (the queues are
//! bounded in bytes), and `exec_info` must still be answered afterwards.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use base64::Engine as _;
use rumqttc::v5::mqttbytes::QoS;
use serde_json::Value;

/// The PLC's resident memory may not pass this, whatever is sent to it.
const RSS_BOUND_KB: u64 = 256 * 1024;

const PLC: &str = "cell1";

mod common;

use common::{client, first_answer, reply, request, rss_kb, RssSampler, RunningPlc};

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
