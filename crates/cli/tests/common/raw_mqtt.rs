//! Attackers' MQTT 3.1.1 subscribers, written on a bare TCP socket so that they can do what no
//! well-behaved client library does: read a few bytes now and then, or read everything and never
//! acknowledge it.

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// What a slow subscriber reads at a time, every 100 ms: 160 KiB/s, so that a 512 KiB message
/// is written to it in about 3 s, well within rmqtt's send timeout (10 s).
pub const SIP: usize = 16 << 10;

/// How an attacker reads what the broker sends it.
#[derive(Clone, Copy, Debug)]
pub enum Reading {
    /// Subscribed at QoS 0; reads [`SIP`] bytes every 100 ms, so that it is never disconnected
    /// and its session always has a write under way.
    Sip,
    /// Subscribed at QoS 1; reads everything as fast as it comes, and never acknowledges a
    /// message, so that its in-flight window stays full and its session queues the rest.
    NeverAcknowledge,
}

pub use cetratus_testkit::raw_mqtt::{connect, mqtt_str, packet};

/// Connects the client `id` to the broker on `port`, subscribes to `topic` and then reads as
/// `reading` says until `stop`; returns the count of bytes it read.
pub fn subscriber(
    port: u16,
    id: &str,
    topic: &str,
    reading: Reading,
    stop: Arc<AtomicBool>,
) -> Arc<AtomicU64> {
    let mut s = connect(("127.0.0.1", port), id);
    s.set_read_timeout(Some(Duration::from_secs(10)))
        .expect("a read timeout");
    let qos = match reading {
        Reading::Sip => 0,
        Reading::NeverAcknowledge => 1,
    };
    // SUBSCRIBE, packet id 1.
    let mut subscribe = vec![0, 1];
    subscribe.extend_from_slice(&mqtt_str(topic));
    subscribe.push(qos);
    s.write_all(&packet(0x82, &subscribe)).expect("SUBSCRIBE");
    let mut suback = [0u8; 5];
    s.read_exact(&mut suback).expect("SUBACK");
    assert_eq!(
        suback,
        [0x90, 3, 0, 1, qos],
        "the broker grants QoS {qos} to {id}"
    );
    let read = Arc::new(AtomicU64::new(0));
    let counted = read.clone();
    std::thread::spawn(move || {
        let mut buf = vec![0u8; SIP];
        if let Reading::NeverAcknowledge = reading {
            buf.resize(1 << 20, 0);
            s.set_read_timeout(Some(Duration::from_millis(200)))
                .expect("a read timeout");
        }
        while !stop.load(Ordering::Relaxed) {
            if let Reading::Sip = reading {
                std::thread::sleep(Duration::from_millis(100));
            }
            match s.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => {
                    counted.fetch_add(n as u64, Ordering::Relaxed);
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(_) => break,
            }
        }
    });
    read
}
