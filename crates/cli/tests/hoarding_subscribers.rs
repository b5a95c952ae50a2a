//! Subscribers that make the embedded broker hold messages for them must not make the PLC's
//! memory depend on what others publish: neither one subscriber that takes every message and
//! never acknowledges it (its deliver queue and in-flight window), nor many slow subscribers at
//! once (all sessions together).
//!
//! `cetratus run` on its embedded broker; the attackers are MQTT 3.1.1 clients on bare sockets
//! (`common::raw_mqtt`), and a camera publishes images just under the broker's ingress limit
//! (16 MiB/s), each image on one topic, so that no two sessions share a payload and what they
//! hold adds up. The PLC's resident memory must grow by no more than the bound that holds
//! (`SESSION_INBOX_BYTES` and `SESSION_QUEUE_BYTES` for one session, `SESSIONS_BYTES` for all)
//! and a margin; the broker must say which bound dropped messages; and the PLC must go on
//! cycling and answering an operator's command. The two tests run one at a time: each measures
//! the memory of its own PLC.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use cetratus_mct::{SESSIONS_BYTES, SESSION_FLOOR_BYTES, SESSION_INBOX_BYTES, SESSION_QUEUE_BYTES};
use rumqttc::v5::mqttbytes::QoS;

mod common;

use common::raw_mqtt::{subscriber, Reading};
use common::{
    assert_cycles_on, camera, client, first_answer, primary_cycles, rss_kb, RssSampler, RunningPlc,
};

const PLC: &str = "cell1";
/// How long the camera publishes.
const FLOOD: Duration = Duration::from_secs(20);
/// Room for what else the flood costs the PLC besides what the sessions hold: the camera's read
/// buffer and each attacker's write buffer (an image each), the allocator's slack and the PLC's
/// own work over 20 s.
const MARGIN_KB: u64 = 48 * 1024;

/// One test at a time: each measures its own PLC's memory while it floods it.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Starts the PLC and `attackers` on their topics, floods them with images of `size` bytes at
/// `qos`, checks that the PLC cycles on and answers an operator, and returns the growth of its
/// resident memory in kB and its log.
fn flood(attackers: &[(String, Reading)], size: usize, qos: QoS, tiny: bool) -> (u64, Vec<String>) {
    let (plc, log) = RunningPlc::start_logged(PLC, &[]);
    let pid = plc.process.id();
    let (ops, replies) = client(plc.mqtt, "ops", PLC);
    let before = primary_cycles(&first_answer(&ops, &replies, PLC, Duration::from_secs(30)));
    let stop = Arc::new(AtomicBool::new(false));
    let read: Vec<_> = attackers
        .iter()
        .enumerate()
        .map(|(k, (topic, reading))| {
            let id = format!("hoarder-{k}");
            subscriber(plc.mqtt, &id, topic, *reading, stop.clone())
        })
        .collect();
    let topics: Vec<String> = attackers.iter().map(|(t, _)| t.clone()).collect();

    let rss_before = rss_kb(pid).expect("the PLC's memory");
    let sampler = RssSampler::start(pid);
    // Just under the ingress limit, so that every image reaches the sessions.
    let per_s = ((15 << 20) / size) as u32;
    let images = per_s * FLOOD.as_secs() as u32;
    camera(plc.mqtt, &topics, size, per_s, images, qos, tiny);
    // The last images reach the sessions after the camera is done.
    std::thread::sleep(Duration::from_secs(2));
    let peak = sampler.peak_kb();

    // The PLC cycles on, and an operator's command is answered while the attackers still hold
    // what they hold.
    assert_cycles_on(&ops, &replies, PLC, b"after-flood", before);
    stop.store(true, Ordering::Relaxed);

    let growth = peak.saturating_sub(rss_before);
    let taken: Vec<u64> = read
        .iter()
        .map(|r| r.load(Ordering::Relaxed) >> 10)
        .collect();
    eprintln!(
        "published {images} images of {size} bytes ({} MiB) on {} topics; the attackers read \
         {taken:?} KiB; PLC RSS before {rss_before} kB, peak {peak} kB, growth {growth} kB",
        (images as usize * size) >> 20,
        topics.len(),
    );
    let logged: Vec<String> = log.try_iter().collect();
    drop(plc);
    (growth, logged)
}

#[test]
fn a_subscriber_that_never_acknowledges_does_not_make_the_plc_keep_its_deliver_queue() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    // 3 MiB images at QoS 1: without a bound in bytes the session keeps 16 in flight and 64
    // queued behind them, 240 MiB, however the inbox is bounded.
    let attackers = [("plant/line1/camera".to_owned(), Reading::NeverAcknowledge)];
    let (growth, logged) = flood(&attackers, 3 << 20, QoS::AtLeastOnce, false);
    let session_kb = (SESSION_INBOX_BYTES + SESSION_QUEUE_BYTES) as u64 / 1024;
    let bound = session_kb + MARGIN_KB;
    eprintln!("bound {bound} kB: one session {session_kb} kB + margin {MARGIN_KB} kB");
    assert!(
        growth < bound,
        "the PLC's memory grew by {growth} kB while a subscriber took every message and \
         acknowledged none: more than one session may hold ({session_kb} kB) and a margin"
    );
    assert!(
        logged.iter().any(|l| l.contains("its deliver queue")),
        "the broker says it dropped messages at the subscriber's deliver queue; the log:\n{}",
        logged.join("\n")
    );
}

#[test]
fn many_slow_subscribers_together_hold_no_more_than_the_brokers_total() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    // Ten slow readers of a topic each: each session may hold its inbox and its queue (24 MiB),
    // 240 MiB for the ten, of which a 20 s flood fills about 180 MiB; all of them together may
    // hold SESSIONS_BYTES.
    let attackers: Vec<(String, Reading)> = (0..10)
        .map(|k| (format!("plant/line1/camera{k}"), Reading::Sip))
        .collect();
    let (growth, logged) = flood(&attackers, 512 << 10, QoS::AtMostOnce, false);
    // Each session's inbox and queue may pass the total by their floor.
    let total_kb = (SESSIONS_BYTES + 2 * attackers.len() * SESSION_FLOOR_BYTES) as u64 / 1024;
    let bound = total_kb + MARGIN_KB;
    eprintln!("bound {bound} kB: all sessions {total_kb} kB + margin {MARGIN_KB} kB");
    assert!(
        growth < bound,
        "the PLC's memory grew by {growth} kB while {} slow subscribers were sent what others \
         published: more than all sessions together may hold ({total_kb} kB) and a margin",
        attackers.len()
    );
    assert!(
        logged
            .iter()
            .any(|l| l.contains("what all sessions hold together")),
        "the broker says it dropped messages at its total; the log:\n{}",
        logged.join("\n")
    );
}

#[test]
fn tiny_messages_read_with_large_ones_do_not_keep_them_for_a_subscriber() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    // Each 3 MiB image, on a topic no one reads, is followed at once by a message of 64 bytes to
    // the attacker, who keeps 80 of them (16 in flight, 64 queued). The broker reads both
    // packets into one buffer: a tiny message that shared the image's buffer must not keep it.
    let attackers = [("plant/line1/tiny".to_owned(), Reading::NeverAcknowledge)];
    let (growth, _) = flood(&attackers, 3 << 20, QoS::AtMostOnce, true);
    let session_kb = (SESSION_INBOX_BYTES + SESSION_QUEUE_BYTES) as u64 / 1024;
    let bound = session_kb + MARGIN_KB;
    eprintln!("bound {bound} kB: one session {session_kb} kB + margin {MARGIN_KB} kB");
    assert!(
        growth < bound,
        "the PLC's memory grew by {growth} kB while a subscriber kept tiny messages read together \
         with large ones: more than one session may hold ({session_kb} kB) and a margin"
    );
}
