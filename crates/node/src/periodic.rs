//! The real-time loop of the scan thread: cycles at absolute deadlines of the wall clock,
//! measured as the OpenPLC v4 runtime measures them (cycle time, latency, overruns).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use cetratus_runtime::LoopTiming;

/// Calls `body(now_us, timing so far)` every `period_us` of program time, sleeping to absolute deadlines of the
/// wall clock (`speed` program seconds per wall second), until `until_us`, until `stop` is set or
/// until `body` returns false. A cycle that overruns skips the deadlines already missed instead
/// of running a burst of late cycles. Returns the program time reached.
pub fn run_periodic(
    period_us: u64,
    until_us: u64,
    speed: f64,
    stop: &AtomicBool,
    timing: &mut LoopTiming,
    mut body: impl FnMut(u64, &LoopTiming) -> bool,
) -> u64 {
    let speed = if speed.is_finite() && speed > 0.0 {
        speed
    } else {
        1.0
    };
    // A thread's sleeps may end up to its timer slack (50 µs by default) late, so that the kernel
    // can batch wake-ups; the scan thread's deadlines are worth more than that. (SCHED_FIFO
    // threads have none anyway.)
    #[cfg(target_os = "linux")]
    let _ = nix::sys::prctl::set_timerslack(1);
    let wall_period = Duration::from_secs_f64(period_us.max(1) as f64 / 1e6 / speed);
    let origin = Instant::now();
    let mut last_start: Option<Instant> = None;
    let mut k: u64 = 0;
    loop {
        let now_us = k * period_us;
        if now_us >= until_us || stop.load(Ordering::Relaxed) {
            return now_us;
        }
        let planned = origin + wall_period.mul_f64(k as f64);
        let before = Instant::now();
        if planned > before {
            std::thread::sleep(planned - before);
        }
        let start = Instant::now();
        timing
            .latency
            .record(start.saturating_duration_since(planned).as_nanos() as u64);
        if let Some(last) = last_start {
            timing.cycle.record((start - last).as_nanos() as u64);
        }
        last_start = Some(start);
        if !body(now_us, timing) {
            return now_us;
        }
        let next = planned + wall_period;
        let end = Instant::now();
        if end > next {
            timing.overruns += 1;
            let behind = (end - planned).as_secs_f64() / wall_period.as_secs_f64();
            k += behind.floor().max(1.0) as u64;
        } else {
            k += 1;
        }
    }
}
