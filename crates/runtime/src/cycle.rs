//! The scan cycle: read the input image, scan, write the output image; in virtual or real time.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use cetratus_program::Value;
use serde::Serialize;

use crate::{Container, Dispatcher, Provider, RuntimeError, ScanOutcome, Summary, TimingStats};

/// Drives one container against its drivers and measures every cycle.
///
/// Names follow the OpenPLC v4 runtime: *scan time* is the body (read, scan, write), *cycle time*
/// is start to start, *latency* is the actual start minus the planned start, and an *overrun* is a
/// cycle whose body ends after the next planned start.
#[derive(Clone, Debug)]
pub struct ScanCycle {
    container: Container,
    inputs: Vec<Value>,
    safe: Vec<Value>,
    period_us: u64,
    scan: TimingStats,
    timing: LoopTiming,
}

/// The timing figures of a run, in nanoseconds.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct CycleFigures {
    /// Cycles run.
    pub cycles: u64,
    /// The configured period in microseconds.
    pub period_us: u64,
    /// The body of each cycle.
    pub scan: Summary,
    /// Start to start (real time only).
    pub cycle: Summary,
    /// Actual start minus planned start (real time only).
    pub latency: Summary,
    /// Cycles whose body ran past the next planned start.
    pub overruns: u64,
}

impl ScanCycle {
    /// A cycle around `container` with the program's scan period.
    pub fn new(container: Container) -> Self {
        let period_us = container.program().scan_period().as_micros() as u64;
        let inputs = container.inputs().to_vec();
        let mut safe = container.outputs().to_vec();
        container.safe_outputs(&mut safe);
        ScanCycle {
            container,
            inputs,
            safe,
            period_us: period_us.max(1),
            scan: TimingStats::new(),
            timing: LoopTiming::default(),
        }
    }

    /// The container.
    pub fn container(&self) -> &Container {
        &self.container
    }

    /// The period in microseconds.
    pub fn period_us(&self) -> u64 {
        self.period_us
    }

    /// Overrides the program's scan period (benches, commissioning at another rate).
    pub fn set_period_us(&mut self, period_us: u64) {
        self.period_us = period_us.max(1);
    }

    /// The figures so far.
    pub fn figures(&self) -> CycleFigures {
        CycleFigures {
            cycles: self.scan.summary().count,
            period_us: self.period_us,
            scan: self.scan.summary(),
            cycle: self.timing.cycle.summary(),
            latency: self.timing.latency.summary(),
            overruns: self.timing.overruns,
        }
    }

    /// One cycle at program time `now_us`. On a scan error the safe output values are dispatched
    /// and the error is returned; the container's state is as after the previous scan.
    pub fn cycle<IO: Provider + Dispatcher>(
        &mut self,
        now_us: u64,
        io: &mut IO,
    ) -> Result<ScanOutcome, RuntimeError> {
        let t0 = quanta::Instant::now();
        io.read_inputs(now_us, &mut self.inputs);
        let result = self.container.scan(now_us, &self.inputs);
        match &result {
            Ok(_) => io.write_outputs(now_us, self.container.outputs()),
            Err(_) => io.write_outputs(now_us, &self.safe),
        }
        self.scan.record(t0.elapsed().as_nanos() as u64);
        result
    }

    /// Runs cycles in virtual time from `from_us` while the time is below `until_us`, calling
    /// `observe` after each cycle. Stops at the first scan error.
    pub fn run_virtual<IO: Provider + Dispatcher>(
        &mut self,
        from_us: u64,
        until_us: u64,
        io: &mut IO,
        mut observe: impl FnMut(&ScanCycle, u64, &mut IO),
    ) -> Result<u64, RuntimeError> {
        let mut now = from_us;
        while now < until_us {
            self.cycle(now, io)?;
            observe(self, now, io);
            now += self.period_us;
        }
        Ok(now)
    }

    /// Runs cycles in real time, sleeping to absolute deadlines, until `until_us` of program time
    /// or until `stop` is set. `speed` > 1 runs the program clock faster than the wall clock.
    /// Returns the program time reached.
    pub fn run_realtime<IO: Provider + Dispatcher>(
        &mut self,
        until_us: u64,
        speed: f64,
        stop: &AtomicBool,
        io: &mut IO,
        mut observe: impl FnMut(&ScanCycle, u64, &mut IO),
    ) -> Result<u64, RuntimeError> {
        let period_us = self.period_us;
        let mut timing = std::mem::take(&mut self.timing);
        let mut result = Ok(());
        let reached = run_periodic(
            period_us,
            until_us,
            speed,
            stop,
            &mut timing,
            |now_us, _| match self.cycle(now_us, io) {
                Ok(_) => {
                    observe(self, now_us, io);
                    true
                }
                Err(e) => {
                    result = Err(e);
                    false
                }
            },
        );
        self.timing = timing;
        result.map(|()| reached)
    }
}

/// What the real-time loop measures: cycle time (start to start), latency (actual start minus
/// planned start) and overruns.
#[derive(Clone, Debug, Default)]
pub struct LoopTiming {
    /// Start to start.
    pub cycle: TimingStats,
    /// Actual start minus planned start.
    pub latency: TimingStats,
    /// Cycles whose body ran past the next planned start.
    pub overruns: u64,
}

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
