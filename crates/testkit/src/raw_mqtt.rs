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
    let (s, code) = try_connect(addr, id, ConnectOptions::default());
    assert_eq!(code, 0, "the broker accepts the client {id}");
    s
}

/// What a hand-written MQTT 3.1.1 CONNECT carries beside its client id.
#[derive(Clone, Copy, Debug, Default)]
pub struct ConnectOptions<'a> {
    /// A user name and password.
    pub login: Option<(&'a str, &'a str)>,
    /// A last will: its topic, its message, and whether it is retained (QoS 0).
    pub will: Option<(&'a str, &'a [u8], bool)>,
}

/// An MQTT 3.1.1 CONNECT of the client `id` (clean session, keep-alive 300 s) with `options`.
pub fn connect_packet(id: &str, options: ConnectOptions<'_>) -> Vec<u8> {
    let mut flags = 0x02u8;
    if let Some((_, _, retain)) = options.will {
        flags |= 0x04 | if retain { 0x20 } else { 0 };
    }
    if options.login.is_some() {
        flags |= 0xC0;
    }
    let mut body = mqtt_str("MQTT");
    body.extend_from_slice(&[4, flags, 0x01, 0x2C]);
    body.extend_from_slice(&mqtt_str(id));
    if let Some((topic, message, _)) = options.will {
        body.extend_from_slice(&mqtt_str(topic));
        body.extend_from_slice(&(message.len() as u16).to_be_bytes());
        body.extend_from_slice(message);
    }
    if let Some((user, password)) = options.login {
        body.extend_from_slice(&mqtt_str(user));
        body.extend_from_slice(&mqtt_str(password));
    }
    packet(0x10, &body)
}

/// Connects the client `id` to the broker at `addr` with `options` and returns the socket and the
/// return code of its CONNACK (0: accepted; 4: bad user name or password; 5: not authorised).
pub fn try_connect(
    addr: impl ToSocketAddrs,
    id: &str,
    options: ConnectOptions<'_>,
) -> (TcpStream, u8) {
    let mut s = TcpStream::connect(addr).expect("the client connects");
    s.set_read_timeout(Some(Duration::from_secs(30)))
        .expect("a read timeout");
    s.write_all(&connect_packet(id, options)).expect("CONNECT");
    let mut connack = [0u8; 4];
    s.read_exact(&mut connack).expect("CONNACK");
    assert_eq!(connack[..2], [0x20, 2], "a CONNACK: {connack:?}");
    (s, connack[3])
}

/// Whether the broker closes `s` within `within`, reading and dropping whatever it sends first.
pub fn closed_within(s: &mut TcpStream, within: Duration) -> bool {
    let end = std::time::Instant::now() + within;
    let mut buf = [0u8; 1024];
    while std::time::Instant::now() < end {
        s.set_read_timeout(Some(Duration::from_millis(200)))
            .expect("a read timeout");
        match s.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(_) => return true,
        }
    }
    false
}
