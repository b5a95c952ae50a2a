//! The scan cycle of one container: read the input image, scan, write the output image. The
//! real-time loop that calls it at absolute deadlines belongs to the node (`cetratus-node`); here
//! are the figures it fills in.

use cetratus_program::Value;
use serde::Serialize;

use crate::clock::Stopwatch;
use crate::{Container, Dispatcher, Provider, RuntimeError, ScanOutcome, Summary, TimingStats};

/// Drives one container against its drivers and measures every cycle.
///
/// Names follow the OpenPLC v4 runtime: *scan time* is the body (read, scan, write), *cycle time*
/// is start to start, *latency* is the actual start minus the planned start, and an *overrun* is a
/// cycle whose body ends after the next planned start.
pub struct ScanCycle {
    container: Container,
    stopwatch: Box<dyn Stopwatch>,
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
    /// A cycle around `container` with the program's scan period, its scans timed by `stopwatch`.
    pub fn new(container: Container, stopwatch: Box<dyn Stopwatch>) -> Self {
        let period_us = container.program().scan_period().as_micros() as u64;
        let inputs = container.inputs().to_vec();
        let mut safe = container.outputs().to_vec();
        container.safe_outputs(&mut safe);
        ScanCycle {
            container,
            stopwatch,
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
        let t0 = self.stopwatch.now_ns();
        io.read_inputs(now_us, &mut self.inputs);
        let result = self.container.scan(now_us, &self.inputs);
        match &result {
            Ok(_) => io.write_outputs(now_us, self.container.outputs()),
            Err(_) => io.write_outputs(now_us, &self.safe),
        }
        let t1 = self.stopwatch.now_ns();
        self.scan.record(t1.saturating_sub(t0));
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

    /// Takes the real-time loop's figures (cycle time, latency, overruns) into [`Self::figures`].
    pub fn set_timing(&mut self, timing: LoopTiming) {
        self.timing = timing;
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

impl LoopTiming {
    /// Adds `other`'s samples and overruns to these (runs measured apart, counted as one).
    pub fn add(&mut self, other: &LoopTiming) {
        self.cycle.add(&other.cycle);
        self.latency.add(&other.latency);
        self.overruns += other.overruns;
    }
}
