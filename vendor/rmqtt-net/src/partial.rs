// cetratus: this whole file is added by the patch (vendor/README.md): what a connection's codec
// cetratus: buffers hold, counted. A packet is read whole into the connection's read buffer before
// cetratus: it is decoded, so a client that sends all but the end of a large packet makes the
// cetratus: broker hold it for as long as it likes; and a read or write buffer that grew for one
// cetratus: large packet kept that size for the life of the connection.

use std::net::SocketAddr; // cetratus: see above
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering}; // cetratus: see above
use std::sync::Arc; // cetratus: see above

/// cetratus: called on each connection disconnected for the total: the count so far, the client's
/// cetratus: address, and the bytes of its incomplete packet
pub type OnRefused = Box<dyn Fn(u64, SocketAddr, usize) + Send + Sync>; // cetratus: see above

/// cetratus: bytes of packets that the connections of the listeners given the same one have begun
/// cetratus: to receive and not yet received whole (`Builder::partials_budget`); a connection whose
/// cetratus: incomplete packet would take the total past `max` is disconnected. An incomplete packet
/// cetratus: of up to `floor` bytes is not counted, so the total may pass `max` by `floor` a connection.
pub struct PartialsBudget {
    used: AtomicUsize,             // cetratus: bytes booked by all connections
    max: usize,                    // cetratus: the most `used` may hold
    floor: usize,                  // cetratus: what a connection may always hold
    refused: AtomicU64,            // cetratus: connections disconnected for the total
    on_refused: Option<OnRefused>, // cetratus: told of each of them
} // cetratus: end of PartialsBudget

impl std::fmt::Debug for PartialsBudget {
    // cetratus: Builder is Debug
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // cetratus: see above
        f.debug_struct("PartialsBudget") // cetratus: see above
            .field("used", &self.used) // cetratus: see above
            .field("max", &self.max) // cetratus: see above
            .field("floor", &self.floor) // cetratus: see above
            .field("refused", &self.refused) // cetratus: see above
            .finish_non_exhaustive() // cetratus: see above
    } // cetratus: end of fmt
} // cetratus: end of impl Debug

impl PartialsBudget {
    /// cetratus: a total of `max` bytes, of which each connection's first `floor` are not counted
    pub fn new(max: usize, floor: usize) -> Self {
        // cetratus: see above
        Self { used: AtomicUsize::new(0), max, floor, refused: AtomicU64::new(0), on_refused: None }
        // cetratus: nothing booked
    } // cetratus: end of new

    /// cetratus: calls `f` on each connection disconnected for the total
    pub fn on_refused(mut self, f: OnRefused) -> Self {
        // cetratus: see above
        self.on_refused = Some(f); // cetratus: see above
        self // cetratus: see above
    } // cetratus: end of on_refused

    /// cetratus: the bytes booked now
    pub fn used(&self) -> usize {
        // cetratus: see above
        self.used.load(Ordering::Acquire) // cetratus: see above
    } // cetratus: end of used

    /// cetratus: the connections disconnected for the total so far
    pub fn refused(&self) -> u64 {
        // cetratus: see above
        self.refused.load(Ordering::Relaxed) // cetratus: see above
    } // cetratus: end of refused
} // cetratus: end of impl PartialsBudget

/// cetratus: one connection's booking in the total; given back when the connection is dropped
#[derive(Debug, Default)]
pub(crate) struct Partial {
    budget: Option<Arc<PartialsBudget>>, // cetratus: the listener's total, if any
    booked: usize,                       // cetratus: what this connection has booked in it
    exempt: bool,                        // cetratus: a login of the reserve: not counted
} // cetratus: end of Partial

impl Partial {
    /// cetratus: a connection of a listener with `budget`
    pub(crate) fn new(budget: Option<Arc<PartialsBudget>>) -> Self {
        // cetratus: see above
        Self { budget, booked: 0, exempt: false } // cetratus: see above
    } // cetratus: end of new

    /// cetratus: the connection's login is one of the reserve's: its packets are not counted
    pub(crate) fn exempt(&mut self) {
        // cetratus: see above
        self.exempt = true; // cetratus: see above
        self.hold(0); // cetratus: gives back what it booked
    } // cetratus: end of exempt

    /// cetratus: books `len` bytes of an incomplete packet in place of what was booked; false, and
    /// cetratus: nothing more booked, when that would take the total past its most
    pub(crate) fn hold(&mut self, len: usize) -> bool {
        // cetratus: see above
        let Some(b) = &self.budget else { return true }; // cetratus: no total, as published
        let want = if self.exempt || len <= b.floor { 0 } else { len }; // cetratus: the floor is free
        if want <= self.booked {
            // cetratus: less than before: give back
            b.used.fetch_sub(self.booked - want, Ordering::AcqRel); // cetratus: see above
            self.booked = want; // cetratus: see above
            return true; // cetratus: see above
        } // cetratus: end of giving back
        let more = want - self.booked; // cetratus: more than before: book, checked and added in one step
        let booked = b.used.fetch_update(Ordering::AcqRel, Ordering::Acquire, |u| {
            // cetratus: see above
            u.checked_add(more).filter(|&n| n <= b.max) // cetratus: see above
        }); // cetratus: see above
        if booked.is_ok() {
            // cetratus: see above
            self.booked = want; // cetratus: see above
            return true; // cetratus: see above
        } // cetratus: see above
        b.refused.fetch_add(1, Ordering::Relaxed); // cetratus: counted; the caller tells (refused_by)
        false // cetratus: see above
    } // cetratus: end of hold

    /// cetratus: tells the total's `on_refused` of a connection from `addr` refused with `len` bytes
    pub(crate) fn refused_by(&self, addr: SocketAddr, len: usize) {
        // cetratus: see above
        if let Some(b) = &self.budget {
            // cetratus: see above
            if let Some(f) = &b.on_refused {
                // cetratus: see above
                f(b.refused(), addr, len); // cetratus: see above
            } // cetratus: see above
        } // cetratus: see above
    } // cetratus: end of refused_by
} // cetratus: end of impl Partial

impl Drop for Partial {
    // cetratus: a connection gone gives back what it booked
    fn drop(&mut self) {
        // cetratus: see above
        self.hold(0); // cetratus: see above
    } // cetratus: end of drop
} // cetratus: end of impl Drop

/// cetratus: the most a connection reads from its socket at a time (what it zeroes first)
const READ_CHUNK: usize = 64 * 1024; // cetratus: see above

/// cetratus: a connection's socket, metered: before each read it books, in the listener's
/// cetratus: `PartialsBudget`, the capacity of the read buffer it reads into (what it holds and
/// cetratus: the room the read may fill), so that no byte is read into memory not counted first; a
/// cetratus: read the total cannot take fails, and the client is disconnected. The capacity, not
/// cetratus: the bytes received: rmqtt-codec reserves a packet's whole length as soon as it has
/// cetratus: read its header, and the parts of such regions filled by clients refused later added
/// cetratus: up in the process's memory. stream.rs books the capacity again after each read
/// cetratus: (`Metered::sync`).
#[derive(Debug)]
pub struct Metered<Io> {
    inner: Io,                // cetratus: the socket
    partial: Partial,         // cetratus: this connection's booking
    held: usize,              // cetratus: bytes in the read buffer, as far as it knows
    refused: Option<usize>,   // cetratus: the bytes it held when the total refused a read
} // cetratus: end of Metered

impl<Io> Metered<Io> {
    /// cetratus: the socket `inner` of a listener with `budget`
    pub(crate) fn new(inner: Io, budget: Option<Arc<PartialsBudget>>) -> Self {
        // cetratus: see above
        Self { inner, partial: Partial::new(budget), held: 0, refused: None } // cetratus: see above
    } // cetratus: end of new

    /// cetratus: the read buffer holds `len` bytes in `capacity` (after a decode, or given back):
    /// cetratus: books the capacity in place of what was booked
    pub(crate) fn sync(&mut self, len: usize, capacity: usize) -> bool {
        // cetratus: see above
        self.held = len; // cetratus: see above
        self.partial.hold(capacity) // cetratus: see above
    } // cetratus: end of sync

    /// cetratus: a read the total refused, with the bytes held then; the booking is given back
    pub(crate) fn take_refused(&mut self) -> Option<usize> {
        // cetratus: see above
        let held = self.refused.take()?; // cetratus: see above
        self.sync(0, 0); // cetratus: see above
        Some(held) // cetratus: see above
    } // cetratus: end of take_refused

    /// cetratus: see Partial::exempt
    pub(crate) fn exempt(&mut self) {
        // cetratus: see above
        self.partial.exempt(); // cetratus: see above
    } // cetratus: end of exempt

    /// cetratus: see Partial::refused_by
    pub(crate) fn refused_by(&self, addr: SocketAddr, len: usize) {
        // cetratus: see above
        self.partial.refused_by(addr, len); // cetratus: see above
    } // cetratus: end of refused_by
} // cetratus: end of impl Metered

impl<Io: tokio::io::AsyncRead + Unpin> tokio::io::AsyncRead for Metered<Io> {
    // cetratus: see Metered
    fn poll_read(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &mut tokio::io::ReadBuf<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        // cetratus: see above
        let this = self.get_mut(); // cetratus: see above
        let chunk = buf.remaining().min(READ_CHUNK); // cetratus: see above
        if !this.partial.hold(this.held + buf.remaining()) {
            // cetratus: the total cannot take it: nothing read
            this.refused = Some(this.held); // cetratus: see above
            return std::task::Poll::Ready(Err(std::io::Error::other("partials_budget is full"))); // cetratus: see above
        } // cetratus: see above
        // cetratus: at most the chunk booked; initialised first (the crate has no unsafe code to say
        // cetratus: that the inner reader did it), which costs a memset of what the read may fill
        let mut sub = tokio::io::ReadBuf::new(buf.initialize_unfilled_to(chunk)); // cetratus: see above
        let polled = std::pin::Pin::new(&mut this.inner).poll_read(cx, &mut sub); // cetratus: see above
        let n = sub.filled().len(); // cetratus: see above
        buf.advance(n); // cetratus: see above
        this.held += n; // cetratus: the capacity, and so the booking, stays
        polled // cetratus: see above
    } // cetratus: end of poll_read
} // cetratus: end of impl AsyncRead

impl<Io: tokio::io::AsyncWrite + Unpin> tokio::io::AsyncWrite for Metered<Io> {
    // cetratus: writes pass through
    fn poll_write(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &[u8],
    ) -> std::task::Poll<std::io::Result<usize>> {
        // cetratus: see above
        std::pin::Pin::new(&mut self.get_mut().inner).poll_write(cx, buf) // cetratus: see above
    } // cetratus: see above

    fn poll_write_vectored(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> std::task::Poll<std::io::Result<usize>> {
        // cetratus: see above
        std::pin::Pin::new(&mut self.get_mut().inner).poll_write_vectored(cx, bufs) // cetratus: see above
    } // cetratus: see above

    fn is_write_vectored(&self) -> bool {
        // cetratus: see above
        self.inner.is_write_vectored() // cetratus: see above
    } // cetratus: see above

    fn poll_flush(self: std::pin::Pin<&mut Self>, cx: &mut std::task::Context<'_>) -> std::task::Poll<std::io::Result<()>> {
        // cetratus: see above
        std::pin::Pin::new(&mut self.get_mut().inner).poll_flush(cx) // cetratus: see above
    } // cetratus: see above

    fn poll_shutdown(self: std::pin::Pin<&mut Self>, cx: &mut std::task::Context<'_>) -> std::task::Poll<std::io::Result<()>> {
        // cetratus: see above
        std::pin::Pin::new(&mut self.get_mut().inner).poll_shutdown(cx) // cetratus: see above
    } // cetratus: see above
} // cetratus: end of impl AsyncWrite
