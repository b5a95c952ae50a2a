//! Where `now` comes from. The engine never reads a clock; the cycle asks one and passes the time in.

use std::time::Instant;

/// A source of the current time in microseconds since the clock's start.
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

/// The monotonic clock of the machine.
#[derive(Clone, Debug)]
pub struct RealClock {
    start: Instant,
}

impl RealClock {
    /// A clock whose zero is now.
    pub fn new() -> Self {
        RealClock {
            start: Instant::now(),
        }
    }
    /// The instant of the clock's zero.
    pub fn start(&self) -> Instant {
        self.start
    }
}

impl Default for RealClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for RealClock {
    fn now_us(&self) -> u64 {
        self.start.elapsed().as_micros() as u64
    }
}
