//! The three kinds of time the runtime meets, each injected; nothing in this crate reads a clock.
//!
//! * **Program time** (`now_us`, microseconds) is an argument of every cycle. A [`Clock`] supplies
//!   it: virtual in tests, twins and validation, real on a machine (the node's real-time loop).
//! * **Measured durations** (scan times, the watchdog, the candidate's budget, the in-cycle install)
//!   come from a [`Stopwatch`]: a real one on a machine, a [`ManualStopwatch`] where a test or a
//!   virtual run wants them deterministic.
//! * **Wall-clock timestamps** (the audit log) come from a [`WallClock`].
//!
//! The implementations that read the machine's clocks live in `cetratus-node`.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::SystemTime;

/// A source of program time in microseconds since the clock's start.
pub trait Clock {
    /// Microseconds since the start.
    fn now_us(&self) -> u64;
}

/// Time that moves only when told to: tests, twins and validation run on it.
#[derive(Clone, Debug, Default)]
pub struct VirtualClock {
    now_us: u64,
}

impl VirtualClock {
    /// A clock at zero.
    pub fn new() -> Self {
        Self::default()
    }
    /// Moves time forward.
    pub fn advance_us(&mut self, us: u64) {
        self.now_us += us;
    }
    /// Sets the time.
    pub fn set_us(&mut self, us: u64) {
        self.now_us = us;
    }
}

impl Clock for VirtualClock {
    fn now_us(&self) -> u64 {
        self.now_us
    }
}

/// Measures durations on the scan thread. Readings are monotonic nanoseconds from an origin of
/// the stopwatch's choosing; only differences mean anything.
pub trait Stopwatch: Send {
    /// The current reading, in nanoseconds.
    fn now_ns(&mut self) -> u64;
}

/// A stopwatch that moves only when told to, shareable with the test that drives it: every
/// duration is exactly what the test says.
#[derive(Clone, Debug, Default)]
pub struct ManualStopwatch(Arc<AtomicU64>);

impl ManualStopwatch {
    /// A stopwatch at zero.
    pub fn new() -> Self {
        Self::default()
    }
    /// Moves it forward by `ns`.
    pub fn advance_ns(&self, ns: u64) {
        self.0.fetch_add(ns, Ordering::Relaxed);
    }
}

impl Stopwatch for ManualStopwatch {
    fn now_ns(&mut self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }
}

/// How long the in-cycle install of an update is taken to last, for stateTransTimeout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum InstallTiming {
    /// As measured by the PLC's [`Stopwatch`].
    #[default]
    Measured,
    /// A cost model, for virtual time: this many nanoseconds per entry the install touches, so
    /// that a simulation decides the same way on every machine.
    Model {
        /// Nanoseconds charged per entry.
        ns_per_entry: u64,
    },
}

/// Wall-clock time, for timestamps that people read (the audit log).
pub trait WallClock: Send + Sync {
    /// The current wall-clock time.
    fn now(&self) -> SystemTime;
}

/// A wall clock stopped at one instant: tests and virtual runs.
#[derive(Clone, Copy, Debug)]
pub struct FixedWallClock(pub SystemTime);

impl WallClock for FixedWallClock {
    fn now(&self) -> SystemTime {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_manual_stopwatch_moves_only_when_told_and_its_clones_share_the_reading() {
        let sw = ManualStopwatch::new();
        let mut seen = sw.clone();
        assert_eq!(seen.now_ns(), 0);
        sw.advance_ns(1_500);
        assert_eq!(seen.now_ns(), 1_500);
    }
}
