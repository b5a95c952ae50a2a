//! MQTT 3.1.1 packets written by hand on a bare TCP socket, for attackers that do what no
//! well-behaved client library does: announce a packet and stall in its middle, read a few bytes
//! now and then, or never acknowledge.

use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

/// A fixed header of `kind` that announces `remaining` bytes, for a packet sent in parts.
pub fn fixed_header(kind: u8, mut remaining: usize) -> Vec<u8> {
    let mut out = vec![kind];
    loop {
        let mut byte = (remaining % 128) as u8;
        remaining /= 128;
        if remaining > 0 {
            byte |= 0x80;
        }
        out.push(byte);
        if remaining == 0 {
            return out;
        }
    }
}

/// An MQTT packet with a fixed header of `kind` and the remaining length encoded.
pub fn packet(kind: u8, body: &[u8]) -> Vec<u8> {
    let mut out = fixed_header(kind, body.len());
    out.extend_from_slice(body);
    out
}

/// A UTF-8 string as MQTT encodes it: its length in two bytes, then the bytes.
pub fn mqtt_str(s: &str) -> Vec<u8> {
    let mut out = (s.len() as u16).to_be_bytes().to_vec();
    out.extend_from_slice(s.as_bytes());
    out
}

/// Connects the anonymous client `id` to the broker at `addr` as MQTT 3.1.1 (clean session,
/// keep-alive 300 s, longer than any test, so that it never needs to ping), and checks that the
/// broker accepts it.
pub fn connect(addr: impl ToSocketAddrs, id: &str) -> TcpStream {
    let mut s = TcpStream::connect(addr).expect("the client connects");
    s.set_read_timeout(Some(Duration::from_secs(30)))
        .expect("a read timeout");
    let mut connect = mqtt_str("MQTT");
    connect.extend_from_slice(&[4, 0x02, 0x01, 0x2C]);
    connect.extend_from_slice(&mqtt_str(id));
    s.write_all(&packet(0x10, &connect)).expect("CONNECT");
    let mut connack = [0u8; 4];
    s.read_exact(&mut connack).expect("CONNACK");
    assert_eq!(
        connack,
        [0x20, 2, 0, 0],
        "the broker accepts the client {id}"
    );
    s
}
