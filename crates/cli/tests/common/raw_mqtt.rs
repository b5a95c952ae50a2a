//! Attackers' MQTT 3.1.1 subscribers, written on a bare TCP socket so that they can do what no
//! well-behaved client library does: read a few bytes now and then, or read everything and never
//! acknowledge it.

use std::io::{Read, Write};
use std::net::TcpStream;
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

/// An MQTT packet with a fixed header of `kind` and the remaining length encoded.
pub fn packet(kind: u8, body: &[u8]) -> Vec<u8> {
    let mut out = vec![kind];
    let mut n = body.len();
    loop {
        let mut byte = (n % 128) as u8;
        n /= 128;
        if n > 0 {
            byte |= 0x80;
        }
        out.push(byte);
        if n == 0 {
            break;
        }
    }
    out.extend_from_slice(body);
    out
}

/// A UTF-8 string as MQTT encodes it: its length in two bytes, then the bytes.
pub fn mqtt_str(s: &str) -> Vec<u8> {
    let mut out = (s.len() as u16).to_be_bytes().to_vec();
    out.extend_from_slice(s.as_bytes());
    out
}

/// Connects the client `id` to the broker on `port`, subscribes to `topic` and then reads as
/// `reading` says until `stop`; returns the count of bytes it read.
pub fn subscriber(
    port: u16,
    id: &str,
    topic: &str,
    reading: Reading,
    stop: Arc<AtomicBool>,
) -> Arc<AtomicU64> {
    let mut s = TcpStream::connect(("127.0.0.1", port)).expect("the attacker connects");
    s.set_read_timeout(Some(Duration::from_secs(10)))
        .expect("a read timeout");
    // CONNECT: protocol "MQTT" level 4, clean session, keep-alive 300 s (longer than the test:
    // the attacker never needs to ping).
    let mut connect = mqtt_str("MQTT");
    connect.extend_from_slice(&[4, 0x02, 0x01, 0x2C]);
    connect.extend_from_slice(&mqtt_str(id));
    s.write_all(&packet(0x10, &connect)).expect("CONNECT");
    let mut connack = [0u8; 4];
    s.read_exact(&mut connack).expect("CONNACK");
    assert_eq!(
        connack,
        [0x20, 2, 0, 0],
        "the broker accepts the attacker {id}"
    );
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
