//! Who gets one of a server's connection slots, and how long an idle connection keeps it. The
//! Modbus servers, the OPC UA server's front listener and the dashboard's TLS handshakes use it
//! (docs/io.md, *Connections*; docs/security.md).
//!
//! A server has `max` slots. One address holds at most [`Slots::per_address`] of them, and the
//! last [`Slots::reserve`] go only to addresses that were served before (a real HMI, device or
//! browser, remembered for the server's lifetime, at most [`KNOWN_ADDRESSES`] of them): a host
//! that opens sockets and sends nothing can neither take every slot nor keep the known clients
//! out. A connection that sends nothing for the idle timeout is closed ([`Idle`]), so that even
//! slots taken by one address come back. How often a client may do something is [`rate`]'s.

pub mod rate;

use std::collections::{HashMap, VecDeque};
use std::future::Future;
use std::io;
use std::net::IpAddr;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

/// Addresses remembered as served before; the oldest is forgotten first.
pub const KNOWN_ADDRESSES: usize = 64;

/// The slots of one server.
#[derive(Debug)]
pub struct Slots {
    max: usize,
    open: HashMap<IpAddr, usize>,
    total: usize,
    known: VecDeque<IpAddr>,
}

/// A slot taken; it is given back when dropped.
#[derive(Debug)]
pub struct Slot {
    slots: Arc<Mutex<Slots>>,
    ip: IpAddr,
}

impl Slots {
    /// A server's `max` slots, shared by its connections.
    pub fn shared(max: usize) -> Arc<Mutex<Slots>> {
        Arc::new(Mutex::new(Slots {
            max: max.max(1),
            open: HashMap::new(),
            total: 0,
            known: VecDeque::new(),
        }))
    }

    /// The most slots one address holds: half of them, at least one.
    pub fn per_address(&self) -> usize {
        self.max.div_ceil(2)
    }

    /// The slots kept for known addresses: a quarter of them (none for a server of fewer than
    /// four).
    pub fn reserve(&self) -> usize {
        self.max / 4
    }

    /// Whether `ip` completed a request before.
    fn is_known(&self, ip: IpAddr) -> bool {
        self.known.contains(&ip)
    }

    /// Takes a slot for a connection from `ip`, or says why there is none.
    pub fn take(slots: &Arc<Mutex<Slots>>, ip: IpAddr) -> Result<Slot, Refusal> {
        let ip = ip.to_canonical();
        let mut s = lock(slots);
        let mine = s.open.get(&ip).copied().unwrap_or(0);
        let room = if s.is_known(ip) {
            s.max
        } else {
            s.max - s.reserve()
        };
        if s.total >= s.max {
            return Err(Refusal::Full);
        }
        if mine >= s.per_address() {
            return Err(Refusal::PerAddress);
        }
        if s.total >= room {
            return Err(Refusal::Reserved);
        }
        *s.open.entry(ip).or_default() += 1;
        s.total += 1;
        Ok(Slot {
            slots: slots.clone(),
            ip,
        })
    }
}

impl Slot {
    /// The connection completed a request: its address is known from now on.
    pub fn served(&self) {
        let mut s = lock(&self.slots);
        if s.is_known(self.ip) {
            return;
        }
        if s.known.len() >= KNOWN_ADDRESSES {
            s.known.pop_front();
        }
        s.known.push_back(self.ip);
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        let mut s = lock(&self.slots);
        s.total = s.total.saturating_sub(1);
        if let Some(n) = s.open.get_mut(&self.ip) {
            *n -= 1;
            if *n == 0 {
                s.open.remove(&self.ip);
            }
        }
    }
}

/// Why a connection got no slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// Every slot is taken.
    Full,
    /// Its address holds its share already.
    PerAddress,
    /// Only the reserve is left, and its address never completed a request.
    Reserved,
}

fn lock(s: &Mutex<Slots>) -> std::sync::MutexGuard<'_, Slots> {
    s.lock().unwrap_or_else(|e| e.into_inner())
}

/// What a [`Watched`] stream is told of its reads.
pub trait ReadWatch {
    /// `bytes` were just read (none at the end of the stream).
    fn read(&mut self, bytes: &[u8]);

    /// No byte is ready: `Ready` ends the read with that result instead (a timeout, say). The
    /// default waits.
    fn pending(&mut self, _cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Pending
    }
}

/// A stream whose reads a [`ReadWatch`] sees; what is written goes straight through (the
/// servers watch what their clients and their inner servers say, not what they are told).
pub struct Watched<S, W> {
    inner: S,
    watch: W,
}

impl<S, W> Watched<S, W> {
    /// `inner`, its reads shown to `watch`.
    pub fn new(inner: S, watch: W) -> Self {
        Watched { inner, watch }
    }
}

impl<S: AsyncRead + Unpin, W: ReadWatch + Unpin> AsyncRead for Watched<S, W> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let before = buf.filled().len();
        let this = &mut *self;
        match Pin::new(&mut this.inner).poll_read(cx, buf) {
            Poll::Ready(Ok(())) => {
                this.watch.read(&buf.filled()[before..]);
                Poll::Ready(Ok(()))
            }
            Poll::Ready(Err(e)) => Poll::Ready(Err(e)),
            Poll::Pending => this.watch.pending(cx),
        }
    }
}

impl<S: AsyncWrite + Unpin, W: Unpin> AsyncWrite for Watched<S, W> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.inner).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

/// A connection that ends with [`io::ErrorKind::TimedOut`] when its client sends nothing for a
/// while: `Idle::new(stream, IdleTimeout::after(duration))`.
pub type Idle<S> = Watched<S, IdleTimeout>;

/// The watch of an [`Idle`] connection: a deadline that each byte read moves on.
pub struct IdleTimeout {
    idle: Duration,
    deadline: Pin<Box<tokio::time::Sleep>>,
}

impl IdleTimeout {
    /// Ends the connection `idle` after the last byte from the client.
    pub fn after(idle: Duration) -> Self {
        IdleTimeout {
            idle,
            deadline: Box::pin(tokio::time::sleep(idle)),
        }
    }
}

impl ReadWatch for IdleTimeout {
    fn read(&mut self, bytes: &[u8]) {
        if !bytes.is_empty() {
            let next = tokio::time::Instant::now() + self.idle;
            self.deadline.as_mut().reset(next);
        }
    }

    fn pending(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        match self.deadline.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "the client sent nothing for the idle timeout",
            ))),
            Poll::Pending => Poll::Pending,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ip(last: u8) -> IpAddr {
        IpAddr::from([10, 0, 0, last])
    }

    #[test]
    fn one_address_takes_half_and_newcomers_leave_the_reserve_to_known_clients() {
        let slots = Slots::shared(8);
        let hmi = Slots::take(&slots, ip(1)).expect("the HMI");
        hmi.served();
        let idle: Vec<Slot> = (0..4)
            .map(|_| Slots::take(&slots, ip(9)).expect("a slot"))
            .collect();
        assert_eq!(Slots::take(&slots, ip(9)).unwrap_err(), Refusal::PerAddress);
        let more = Slots::take(&slots, ip(8)).expect("a sixth");
        // Six taken: the last two are the reserve.
        assert_eq!(Slots::take(&slots, ip(7)).unwrap_err(), Refusal::Reserved);
        let again = Slots::take(&slots, ip(1)).expect("the known HMI gets the reserve");
        drop((idle, more, again, hmi));
        assert!(Slots::take(&slots, ip(7)).is_ok(), "every slot came back");
    }

    #[tokio::test(start_paused = true)]
    async fn a_silent_connection_times_out_and_a_talking_one_does_not() {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};

        let (client, server) = tokio::io::duplex(64);
        let mut idle = Idle::new(server, IdleTimeout::after(Duration::from_secs(5)));
        let mut client = client;
        let talker = tokio::spawn(async move {
            for _ in 0..3 {
                tokio::time::sleep(Duration::from_secs(4)).await;
                client.write_all(b"x").await.expect("write");
            }
            client
        });
        let mut buf = [0u8; 1];
        for _ in 0..3 {
            idle.read_exact(&mut buf).await.expect("a byte within 5 s");
        }
        let _client = talker.await.expect("the talker");
        let err = idle.read(&mut buf).await.unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::TimedOut);
    }
}
