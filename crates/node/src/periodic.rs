//! The real-time loop of the scan thread: cycles at absolute deadlines of the monotonic clock,
//! measured as the OpenPLC v4 runtime measures them (cycle time, latency, overruns).
//!
//! The thread sleeps to each deadline itself (`clock_nanosleep` with `TIMER_ABSTIME`, as
//! `cyclictest` does), not for the time left until it: a relative sleep is armed from the moment
//! the kernel reads the clock in the call, so any delay between computing the time left and
//! entering the call (a preemption, an interrupt, a host that holds the virtual CPU) would be
//! added to the wake-up. The latency of a cycle is its start minus its deadline, read right after
//! the wake-up.

use std::sync::atomic::{AtomicBool, Ordering};

use cetratus_runtime::LoopTiming;

/// Calls `body(now_us, timing so far)` every `period_us` of program time, sleeping to absolute deadlines of the
/// monotonic clock (`speed` program seconds per wall second), until `until_us`, until `stop` is set or
/// until `body` returns false. A cycle that overruns skips the deadlines already missed instead
/// of running a burst of late cycles. Returns the program time reached. The samples are added to
/// `timing`, so that calls made one after the other with the same `timing` accumulate.
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
    let wall_period_ns = period_us.max(1) as f64 * 1e3 / speed;
    let origin = clock::now_ns();
    let mut last_start: Option<u64> = None;
    let mut k: u64 = 0;
    loop {
        let now_us = k * period_us;
        if now_us >= until_us || stop.load(Ordering::Relaxed) {
            return now_us;
        }
        let planned = origin + (k as f64 * wall_period_ns).round() as u64;
        clock::sleep_until(planned);
        let start = clock::now_ns();
        timing.latency.record(start.saturating_sub(planned));
        if let Some(last) = last_start {
            timing.cycle.record(start.saturating_sub(last));
        }
        last_start = Some(start);
        if !body(now_us, timing) {
            return now_us;
        }
        let next = origin + ((k + 1) as f64 * wall_period_ns).round() as u64;
        let end = clock::now_ns();
        if end > next {
            timing.overruns += 1;
            let behind = (end - planned) as f64 / wall_period_ns;
            k += behind.floor().max(1.0) as u64;
        } else {
            k += 1;
        }
    }
}

/// The monotonic clock in nanoseconds, and sleeping to a time of it.
#[cfg(target_os = "linux")]
mod clock {
    use nix::errno::Errno;
    use nix::sys::time::TimeSpec;
    use nix::time::{clock_gettime, clock_nanosleep, ClockId, ClockNanosleepFlags};

    const NS: u64 = 1_000_000_000;

    /// `CLOCK_MONOTONIC` (the clock of `std::time::Instant`), in nanoseconds.
    pub fn now_ns() -> u64 {
        // It cannot fail on Linux: the clock always exists and the argument is valid.
        clock_gettime(ClockId::CLOCK_MONOTONIC)
            .map(|t| t.tv_sec() as u64 * NS + t.tv_nsec() as u64)
            .unwrap_or(0)
    }

    /// Returns at `deadline_ns` of [`now_ns`] or right after; at once when it has passed.
    pub fn sleep_until(deadline_ns: u64) {
        let at = TimeSpec::new((deadline_ns / NS) as _, (deadline_ns % NS) as _);
        // A signal handled by this thread ends the sleep early: sleep again to the same time.
        while let Err(Errno::EINTR) = clock_nanosleep(
            ClockId::CLOCK_MONOTONIC,
            ClockNanosleepFlags::TIMER_ABSTIME,
            &at,
        ) {}
    }
}

/// Elsewhere: `std::time::Instant` and a relative sleep.
#[cfg(not(target_os = "linux"))]
mod clock {
    use std::sync::OnceLock;
    use std::time::{Duration, Instant};

    static ORIGIN: OnceLock<Instant> = OnceLock::new();

    pub fn now_ns() -> u64 {
        ORIGIN.get_or_init(Instant::now).elapsed().as_nanos() as u64
    }

    pub fn sleep_until(deadline_ns: u64) {
        let now = now_ns();
        if deadline_ns > now {
            std::thread::sleep(Duration::from_nanos(deadline_ns - now));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_cycle_starts_before_its_deadline_and_every_start_is_measured() {
        let stop = AtomicBool::new(false);
        let mut timing = LoopTiming::default();
        let mut seen = Vec::new();
        let t0 = clock::now_ns();
        let reached = run_periodic(2_000, 20_000, 1.0, &stop, &mut timing, |now, _| {
            seen.push((now, clock::now_ns() - t0));
            true
        });
        assert_eq!(reached, 20_000);
        // A cycle that overran (a loaded machine) skips deadlines: the program times are planned
        // ones, increasing, and every body ran at or after its deadline.
        assert!(!seen.is_empty());
        for (now, at_ns) in &seen {
            assert_eq!(now % 2_000, 0, "{now}");
            assert!(*at_ns >= now * 1_000, "cycle {now} µs ran {at_ns} ns in");
        }
        assert!(seen.windows(2).all(|w| w[0].0 < w[1].0));
        assert_eq!(timing.latency.summary().count, seen.len() as u64);
        assert_eq!(timing.cycle.summary().count, seen.len() as u64 - 1);

        // A second run with the same figures adds to them.
        let before = seen.len() as u64;
        run_periodic(2_000, 4_000, 1.0, &stop, &mut timing, |_, _| true);
        let after = timing.latency.summary().count;
        assert!(
            (before + 1..=before + 2).contains(&after),
            "{before} then {after}"
        );
    }

    #[test]
    fn a_stop_or_a_body_returning_false_ends_the_loop() {
        let mut timing = LoopTiming::default();
        let stop = AtomicBool::new(true);
        assert_eq!(
            run_periodic(1_000, 1_000_000, 1.0, &stop, &mut timing, |_, _| true),
            0
        );
        let go = AtomicBool::new(false);
        let mut n = 0;
        let reached = run_periodic(1_000, 1_000_000, 1.0, &go, &mut timing, |_, _| {
            n += 1;
            n < 3
        });
        assert_eq!(n, 3);
        assert!(reached >= 2_000, "{reached}");
    }
}
