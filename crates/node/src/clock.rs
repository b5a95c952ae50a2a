//! The machine's clocks, injected into the runtime (which reads none of its own). Program time
//! needs none here: in real time, each cycle's program time is its planned start on the periodic
//! schedule ([`crate::periodic`]); in virtual time a `VirtualClock` advances by the period.

use cetratus_runtime::Stopwatch;

pub use cetratus_persist::SystemWallClock;

/// Measured durations from the CPU's time-stamp counter (a few nanoseconds a reading), zero at
/// creation.
#[derive(Clone, Debug)]
pub struct MonotonicStopwatch {
    origin: quanta::Instant,
}

impl MonotonicStopwatch {
    /// A stopwatch whose zero is now.
    pub fn new() -> Self {
        MonotonicStopwatch {
            origin: quanta::Instant::now(),
        }
    }

    /// The same, boxed for a [`cetratus_runtime::Plc`].
    pub fn boxed() -> Box<dyn Stopwatch> {
        Box::new(Self::new())
    }
}

impl Default for MonotonicStopwatch {
    fn default() -> Self {
        Self::new()
    }
}

impl Stopwatch for MonotonicStopwatch {
    fn now_ns(&mut self) -> u64 {
        (quanta::Instant::now() - self.origin).as_nanos() as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stopwatch_measures_a_sleep() {
        let mut sw = MonotonicStopwatch::new();
        let a = sw.now_ns();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let b = sw.now_ns();
        assert!(b - a >= 2_000_000, "{a} then {b}");
    }
}
