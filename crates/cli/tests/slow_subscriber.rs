//! A subscriber that reads just fast enough never to be disconnected must not make the PLC keep
//! what others publish for it.
//!
//! `cetratus run` on its embedded broker. An attacker's MQTT 3.1.1 client, written here on a
//! bare TCP socket, subscribes to a plant topic and then reads 16 KiB every 100 ms: each message
//! is written to it well within the broker's send timeout, so it is never disconnected. Meanwhile
//! a camera publishes 512 KiB messages on that topic at just under the broker's ingress limit for
//! 18 s (about 270 MiB). The embedded broker hands each message to the attacker's session; the
//! PLC's resident memory must grow by no more than what one session may hold
//! (`SESSION_INBOX_BYTES`, then `SESSION_QUEUE_BYTES` behind it) and a margin, the broker
//! must say that it dropped messages for that subscriber, a normal subscriber of the same topic
//! must go on receiving, and the PLC must go on cycling.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use cetratus_mct::{SESSION_INBOX_BYTES, SESSION_QUEUE_BYTES};
use rumqttc::v5::mqttbytes::v5::Packet;
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{Client, Event, MqttOptions};

mod common;

use common::raw_mqtt::{subscriber, Reading};
use common::{
    assert_cycles_on, camera, client, first_answer, primary_cycles, rss_kb, wait_for, RssSampler,
    RunningPlc,
};

const PLC: &str = "cell1";
/// A topic outside `cetratus/`, which anyone on an open broker may publish and read.
const TOPIC: &str = "plant/line1/camera";
/// One camera image.
const MESSAGE: usize = 512 << 10;
/// Images a second: 15 MiB/s, just under the ingress limit (16 MiB/s), so none is turned away
/// at the door and all of them reach the subscribers' sessions.
const PER_S: u32 = 30;
/// How long the camera publishes.
const FLOOD: Duration = Duration::from_secs(18);
/// Room for what else the flood costs the PLC besides the attacker's session: the camera's and
/// the normal subscriber's read and write buffers (a few images each), the allocator's slack
/// and the PLC's own work over 20 s.
const MARGIN_KB: u64 = 48 * 1024;

/// An MQTT 5 client on `topic` that reads as fast as it can, and the count of messages it
/// received.
fn normal_subscriber(port: u16, topic: &str) -> (Client, Arc<AtomicU64>) {
    let mut opts = MqttOptions::new("watcher", "127.0.0.1", port);
    opts.set_max_packet_size(Some(8 << 20));
    opts.set_keep_alive(Duration::from_secs(30));
    let (c, mut conn) = Client::new(opts, 64);
    let (got, subscribed) = (
        Arc::new(AtomicU64::new(0)),
        Arc::new(AtomicBool::new(false)),
    );
    let (g, sub) = (got.clone(), subscribed.clone());
    std::thread::spawn(move || {
        for ev in conn.iter() {
            match ev {
                Ok(Event::Incoming(Packet::SubAck(_))) => sub.store(true, Ordering::Release),
                Ok(Event::Incoming(Packet::Publish(_))) => {
                    g.fetch_add(1, Ordering::Relaxed);
                }
                Ok(_) => {}
                Err(_) => std::thread::sleep(Duration::from_millis(50)),
            }
        }
    });
    c.subscribe(topic, QoS::AtMostOnce)
        .expect("the watcher subscribes");
    wait_for(
        "the watcher's subscription",
        Duration::from_secs(10),
        || subscribed.load(Ordering::Acquire),
    );
    (c, got)
}

#[test]
fn a_slow_subscriber_does_not_make_the_plc_keep_what_others_publish_for_it() {
    let (plc, log) = RunningPlc::start_logged(PLC, &[]);
    let pid = plc.process.id();
    let (ops, replies) = client(plc.mqtt, "ops", PLC);
    let before = primary_cycles(&first_answer(&ops, &replies, PLC, Duration::from_secs(30)));
    let (_watcher, watched) = normal_subscriber(plc.mqtt, TOPIC);
    let stop = Arc::new(AtomicBool::new(false));
    let sipped = subscriber(plc.mqtt, "slow-reader", TOPIC, Reading::Sip, stop.clone());

    let rss_before = rss_kb(pid).expect("the PLC's memory");
    let sampler = RssSampler::start(pid);
    let images = PER_S * FLOOD.as_secs() as u32;
    camera(
        plc.mqtt,
        &[TOPIC.to_string()],
        MESSAGE,
        PER_S,
        images,
        QoS::AtMostOnce,
        false,
    );
    // The last images reach the sessions after the camera is done.
    std::thread::sleep(Duration::from_secs(2));
    let peak = sampler.peak_kb();
    let received_in_flood = watched.load(Ordering::Relaxed);

    // The watcher still receives: one more image after the flood reaches it.
    camera(
        plc.mqtt,
        &[TOPIC.to_string()],
        MESSAGE,
        PER_S,
        1,
        QoS::AtMostOnce,
        false,
    );
    wait_for(
        "an image after the flood at the normal subscriber",
        Duration::from_secs(30),
        || watched.load(Ordering::Relaxed) > received_in_flood,
    );
    // The PLC cycles on.
    assert_cycles_on(&ops, &replies, PLC, b"after-flood", before);
    stop.store(true, Ordering::Relaxed);

    let growth = peak.saturating_sub(rss_before);
    let session_kb = (SESSION_INBOX_BYTES + SESSION_QUEUE_BYTES) as u64 / 1024;
    let bound = session_kb + MARGIN_KB;
    eprintln!(
        "published {images} images of {MESSAGE} bytes ({} MiB); the attacker read {} KiB, the \
         watcher received {received_in_flood}; PLC RSS before {rss_before} kB, peak {peak} kB, \
         growth {growth} kB (bound {bound} kB: one session {session_kb} kB + margin {MARGIN_KB} \
         kB)",
        (images as usize * MESSAGE) >> 20,
        sipped.load(Ordering::Relaxed) / 1024,
    );
    let logged: Vec<String> = log.try_iter().collect();
    assert!(
        growth < bound,
        "the PLC's memory grew by {growth} kB while a slow subscriber was sent what others \
         published: more than one session may hold ({session_kb} kB) and a margin"
    );
    assert!(
        logged
            .iter()
            .any(|l| l.contains("was dropped: its session's inbox")),
        "the broker says it dropped messages for the slow subscriber; the log:\n{}",
        logged.join("\n")
    );
    drop(plc);
}
