//! The front listener of the OPC UA server: it holds the public port, closes at once the
//! connections that get no slot or come faster than their address's rate, and relays the others
//! to the server's own listener on a loopback port.
//!
//! async-opcua limits sessions but not connections. The front shares the `max_connections`
//! slots out as the Modbus servers do ([`cetratus_slots`]): one address holds at most half of
//! them, and the last quarter is kept for addresses that opened a secure channel before (a
//! real HMI or twin client), so that a host that says hello and then nothing can neither take
//! every slot nor keep the known clients out. A connection whose client sends no byte for
//! [`IDLE_TIMEOUT`] is closed.

use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use tokio::net::{TcpListener, TcpStream};

use super::Shared;
use cetratus_slots::rate::PerAddress;
use cetratus_slots::{Idle, IdleTimeout, ReadWatch, Slot, Slots, Watched};

/// A connection whose client sends no byte for this long is closed. An OPC UA client with a
/// session publishes, reads or renews far more often; one that only said hello does not.
pub const IDLE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(60);

/// Relays every accepted connection that gets one of `max` slots to `inner`; runs until dropped.
pub(crate) async fn relay(public: TcpListener, inner: SocketAddr, max: usize, shared: Arc<Shared>) {
    let slots = Slots::shared(max);
    let mut rates = PerAddress::new(super::limit::CONNECTIONS_PER_ADDRESS);
    loop {
        let Ok((client, from)) = public.accept().await else {
            // Out of descriptors, say: wait a little rather than spin.
            tokio::time::sleep(std::time::Duration::from_millis(10)).await;
            continue;
        };
        let slot = if rates.admit(from.ip(), std::time::Instant::now()) {
            Slots::take(&slots, from.ip()).ok()
        } else {
            None
        };
        let Some(slot) = slot else {
            shared
                .counters
                .refused_connections
                .fetch_add(1, Ordering::Relaxed);
            drop(client);
            continue;
        };
        tokio::spawn(async move {
            if let Ok(server) = TcpStream::connect(inner).await {
                let _ = client.set_nodelay(true);
                let _ = server.set_nodelay(true);
                let mut client = Idle::new(client, IdleTimeout::after(IDLE_TIMEOUT));
                let mut server = Watched::new(server, OpenWatch::new(slot));
                let _ = tokio::io::copy_bidirectional(&mut client, &mut server).await;
            }
        });
    }
}

/// The server's side of a relayed connection, read message by message (OPC UA Part 6, 7.1.2:
/// a three-letter type, a chunk letter, and the message's size, little-endian, header
/// included): once the server answers an `OPN`, the client opened a secure channel, and its
/// address counts as served from then on. The slot is given back when the connection ends.
struct OpenWatch {
    slot: Slot,
    scan: HeaderScan,
}

impl OpenWatch {
    fn new(slot: Slot) -> Self {
        OpenWatch {
            slot,
            scan: HeaderScan::default(),
        }
    }
}

/// Where the scan of the server's messages stands.
#[derive(Default)]
struct HeaderScan {
    header: [u8; 8],
    have: usize,
    /// Bytes of the current message's body still to pass.
    skip: usize,
    /// An `OPN` was seen (or the stream made no sense): nothing more to look for.
    done: bool,
}

impl HeaderScan {
    /// Reads `bytes`, the next ones from the server; true when they hold the header of an `OPN`.
    fn feed(&mut self, mut bytes: &[u8]) -> bool {
        while !self.done && !bytes.is_empty() {
            if self.skip > 0 {
                let n = self.skip.min(bytes.len());
                self.skip -= n;
                bytes = &bytes[n..];
                continue;
            }
            let n = (8 - self.have).min(bytes.len());
            self.header[self.have..self.have + n].copy_from_slice(&bytes[..n]);
            self.have += n;
            bytes = &bytes[n..];
            if self.have < 8 {
                continue;
            }
            self.have = 0;
            if &self.header[..3] == b"OPN" {
                self.done = true;
                return true;
            }
            let size = u32::from_le_bytes([
                self.header[4],
                self.header[5],
                self.header[6],
                self.header[7],
            ]) as usize;
            // A message shorter than its header: not OPC UA; stop looking.
            self.done = size < 8;
            self.skip = size.saturating_sub(8);
        }
        false
    }
}

impl ReadWatch for OpenWatch {
    fn read(&mut self, bytes: &[u8]) {
        if self.scan.feed(bytes) {
            self.slot.served();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::HeaderScan;

    fn message(kind: &[u8; 3], body: usize) -> Vec<u8> {
        let mut m = kind.to_vec();
        m.push(b'F');
        m.extend_from_slice(&((body + 8) as u32).to_le_bytes());
        m.extend(std::iter::repeat_n(0xAB, body));
        m
    }

    #[test]
    fn an_opn_after_an_ack_is_found_however_the_bytes_are_cut() {
        let mut stream = message(b"ACK", 20);
        stream.extend(message(b"OPN", 100));
        for cut in 1..stream.len() {
            let mut scan = HeaderScan::default();
            let found = stream.chunks(cut).any(|c| scan.feed(c));
            assert!(found, "cut into pieces of {cut}");
        }
    }

    #[test]
    fn an_opn_inside_a_body_or_after_an_error_is_not_taken_for_one() {
        let mut scan = HeaderScan::default();
        let mut stream = message(b"ACK", 0);
        let mut body = message(b"MSG", 16);
        body[12..15].copy_from_slice(b"OPN");
        stream.extend(body);
        assert!(!scan.feed(&stream));
        let mut bad = HeaderScan::default();
        let mut short = message(b"ERR", 0);
        short[4..8].copy_from_slice(&3u32.to_le_bytes());
        short.extend(message(b"OPN", 0));
        assert!(!bad.feed(&short));
    }
}
