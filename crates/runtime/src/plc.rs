//! The PLC of the paper's Figure 1: containers A and B, PRIMARY and STATUS, the Message Router, the
//! Updater and the Monitor, advanced one cycle at a time.
//!
//! [`Plc::cycle`] runs one cycle at program time `now`: first what is due at the cycle boundary
//! (an update's install, a substitution), then the Provider, the containers, the Dispatcher and the
//! Monitor. Commands ([`Plc::command`]) are accepted or refused between cycles; everything they
//! cause happens at the next boundary, so nothing is ever half-applied.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;

use cetratus_net::{Tokens, TransIdx};
use cetratus_program::{
    EvalCtx, Guard, PackageMeta, Program, Projection, ResolvedUpdate, StateTransform, TrustStore,
    UpdatePackage, Value,
};
use serde::Serialize;

use crate::monitor::{
    describe_cause, Cause, ContainerStats, CycleRecord, ExecInfo, Monitor, ProgramId, Slot, Status,
};
use crate::{Blocker, Container, Dispatcher, Provider, RuntimeError, TimingStats};

/// Measures the in-cycle part of an update, injected like the clock so virtual runs stay
/// deterministic.
pub trait Stopwatch: Send {
    /// Starts a measurement.
    fn start(&mut self);
    /// Ends it; `work` is the number of entries the install touched. Returns nanoseconds.
    fn stop(&mut self, work: u64) -> u64;
}

/// The machine's monotonic clock.
#[derive(Debug, Default)]
pub struct RealStopwatch(Option<std::time::Instant>);

impl Stopwatch for RealStopwatch {
    fn start(&mut self) {
        self.0 = Some(std::time::Instant::now());
    }
    fn stop(&mut self, _work: u64) -> u64 {
        self.0.take().map_or(0, |t| t.elapsed().as_nanos() as u64)
    }
}

/// A cost model for virtual time: `ns_per_unit` per entry touched.
#[derive(Debug, Clone, Copy)]
pub struct ModelStopwatch {
    /// Nanoseconds charged per entry.
    pub ns_per_unit: u64,
}

impl Stopwatch for ModelStopwatch {
    fn start(&mut self) {}
    fn stop(&mut self, work: u64) -> u64 {
        work * self.ns_per_unit
    }
}

/// How the candidate's marking is taken at substitution (DESIGN §4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SubstituteMode {
    /// Recompute `ST·M_primary + ST_base` at the switch: consistent with the plant by construction.
    #[default]
    Retransform,
    /// Keep the candidate's own marking; only when drift is 0, unless forced.
    Keep,
}

impl std::str::FromStr for SubstituteMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "retransform" => Ok(SubstituteMode::Retransform),
            "keep" => Ok(SubstituteMode::Keep),
            o => Err(format!(
                "unknown substitution mode `{o}`; expected retransform or keep"
            )),
        }
    }
}

/// A substitution request, its condition compiled against the primary program.
pub struct SubstituteRequest {
    /// Retransform (default) or keep.
    pub mode: SubstituteMode,
    /// Wait until this condition over the primary holds.
    pub when: Option<(String, Guard)>,
    /// Give up after this long (program time) when `when` never holds.
    pub within_us: Option<u64>,
    /// Keep even with drift.
    pub force: bool,
}

/// An update verified, resolved and built away from the scan thread, ready to install.
pub struct PreparedUpdate {
    meta: PackageMeta,
    base_hash: [u8; 32],
    transform: StateTransform,
    projection: Projection,
    container: Container,
    scratch_marking: Vec<Tokens>,
    scratch_since: Vec<Option<u64>>,
    in_map: Vec<usize>,
    out_map: Vec<Option<usize>>,
    // Candidate transition → the primary's transition of the same id.
    to_primary: Vec<Option<TransIdx>>,
    // Primary transition → the candidate's transition of the same id.
    from_primary: Vec<Option<TransIdx>>,
    // The candidate's safe output values in I/O-map order, for when it is PRIMARY.
    safe: Vec<Value>,
    // Candidate latch / variable → the primary's of the same name, carried over at the switch.
    latch_map: Vec<Option<u32>>,
    var_map: Vec<Option<u32>>,
    work: u64,
}

impl PreparedUpdate {
    /// The package's metadata.
    pub fn meta(&self) -> &PackageMeta {
        &self.meta
    }
}

/// What building an update needs from the running PLC, cloned so it can be done on any thread.
#[derive(Clone)]
pub struct UpdateContext {
    /// The running primary program.
    pub primary: Arc<Program>,
    /// Input names of the I/O map.
    pub io_inputs: Vec<String>,
    /// Output names of the I/O map.
    pub io_outputs: Vec<String>,
}

impl UpdateContext {
    /// Verifies a package file against the trusted keys, resolves it against the running program
    /// and builds the candidate container: everything but the in-cycle install.
    pub fn prepare_package(
        &self,
        bytes: &[u8],
        trust: &TrustStore,
        allow_unsigned: bool,
        force: bool,
    ) -> Result<PreparedUpdate, String> {
        let pkg = UpdatePackage::verify(bytes, trust, allow_unsigned)
            .map_err(|e| format!("package refused: {e}"))?;
        let resolved = pkg
            .resolve(&self.primary, force)
            .map_err(|e| format!("package refused: {e}"))?;
        Plc::prepare(&self.primary, &self.io_inputs, &self.io_outputs, resolved)
            .map_err(|e| format!("package refused: {e}"))
    }
}

/// A command from the operator or the MCT.
// Commands are few and move once; boxing the substitution would only add an allocation.
#[allow(clippy::large_enum_variant)]
pub enum Command {
    /// Install a prepared update into the secondary container.
    Load(Box<PreparedUpdate>),
    /// Make the candidate PRIMARY.
    Substitute(SubstituteRequest),
    /// Drop the candidate in quarantine.
    Remove,
    /// Cancel whatever update is under way.
    Abort,
    /// Leave the fault state.
    Reset,
}

/// Something that happened, for the event stream and the audit log.
#[derive(Clone, Debug, Serialize)]
pub struct Event {
    /// Cycle index at which it happened.
    pub cycle: u64,
    /// Program time in microseconds.
    pub time_us: u64,
    /// What (snake_case), e.g. `load_accepted`, `state_trans_timeout`, `substituted`.
    pub kind: &'static str,
    /// In words: what, why, and what to do.
    pub message: String,
    /// Figures that go with it (drift, install time, mode).
    #[serde(skip_serializing_if = "serde_json::Value::is_null")]
    pub detail: serde_json::Value,
}

/// Limits of the Updater and the watchdog.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// stateTransTimeout: budget of the in-cycle install, in ns. Defaults to one scan period.
    pub state_trans_timeout_ns: u64,
    /// A candidate scan longer than this (ns) in quarantine aborts the update.
    pub candidate_budget_ns: u64,
    /// A primary scan longer than this (ns) is a primary fault.
    pub watchdog_ns: u64,
}

impl Limits {
    /// Limits for a run in virtual time: the install budget is one period as measured by a
    /// [`ModelStopwatch`] (deterministic), and the wall-clock watchdog and candidate budget are
    /// one second, so that an operating system that preempts the process does not turn a
    /// simulation into a fault.
    pub fn for_virtual_time(period_us: u64) -> Self {
        Limits {
            state_trans_timeout_ns: period_us.saturating_mul(1000),
            candidate_budget_ns: 1_000_000_000,
            watchdog_ns: 1_000_000_000,
        }
    }

    /// The defaults for a scan period: stateTransTimeout is one period (the paper's "within one
    /// execution cycle"); the watchdog and the candidate's budget are ten periods, so that a scan
    /// the operating system preempted once does not stop a cell or abort an update, while a
    /// runaway program is still caught.
    pub fn for_period_us(period_us: u64) -> Self {
        let ns = period_us.saturating_mul(1000);
        Limits {
            state_trans_timeout_ns: ns,
            candidate_budget_ns: ns.saturating_mul(10),
            watchdog_ns: ns.saturating_mul(10),
        }
    }
}

struct Quarantine {
    meta: PackageMeta,
    transform: StateTransform,
    projection: Projection,
    to_primary: Vec<Option<TransIdx>>,
    from_primary: Vec<Option<TransIdx>>,
    scratch_marking: Vec<Tokens>,
    scratch_since: Vec<Option<u64>>,
    safe: Vec<Value>,
    latch_map: Vec<Option<u32>>,
    var_map: Vec<Option<u32>>,
    pending: Option<(SubstituteRequest, u64)>,
    started_us: u64,
}

/// The PLC: two containers, PRIMARY, STATUS, the Updater and the Monitor.
pub struct Plc {
    slots: [Option<Container>; 2],
    primary: Slot,
    status: Status,
    setup: Option<Box<PreparedUpdate>>,
    quarantine: Option<Quarantine>,
    // The I/O map: signal names of the Provider's and the Dispatcher's images.
    io_inputs: Vec<String>,
    io_outputs: Vec<String>,
    inputs: Vec<Value>,
    prev_inputs: Vec<Value>,
    images: [Vec<Value>; 2],
    in_maps: [Vec<usize>; 2],
    out_maps: [Vec<Option<usize>>; 2],
    io_outs: [Vec<Value>; 2],
    // Bit masks of the images, kept up to date only when an image changes.
    in_bits: u64,
    out_bits: [u64; 2],
    inputs_changed: bool,
    // Every output of the I/O map is boolean and there are at most 64: images fit a bit mask.
    bool_outputs: bool,
    // A container's input image or mapped outputs must be rebuilt (new install, warm start).
    stale: [bool; 2],
    dispatched: Vec<Value>,
    safe: Vec<Value>,
    stopwatch: Box<dyn Stopwatch>,
    limits: Limits,
    /// The Monitor.
    pub monitor: Monitor,
    events: Vec<Event>,
    cycle: u64,
    now_us: u64,
    deadlock_alarmed: bool,
    retired: Vec<Container>,
    cycle_stats: TimingStats,
}

fn map_by_name(from: &[String], to: &[cetratus_program::Signal]) -> Vec<Option<usize>> {
    from.iter()
        .map(|n| to.iter().position(|s| &s.name == n))
        .collect()
}

fn bits(values: &[Value]) -> u64 {
    values.iter().enumerate().take(64).fold(0, |acc, (i, v)| {
        if matches!(v, Value::Bool(true)) || matches!(v, Value::Int(x) if *x != 0) {
            acc | (1 << i)
        } else {
            acc
        }
    })
}

/// What a [`ModelStopwatch`] charges per entry an install touches in a virtual run.
pub const VIRTUAL_NS_PER_ENTRY: u64 = 20;

impl Plc {
    /// Makes this PLC deterministic in virtual time: the install is measured by a cost model and
    /// the wall-clock limits are relaxed ([`Limits::for_virtual_time`]).
    pub fn use_virtual_time(&mut self, period_us: u64) {
        self.set_stopwatch(Box::new(ModelStopwatch {
            ns_per_unit: VIRTUAL_NS_PER_ENTRY,
        }));
        self.set_limits(Limits::for_virtual_time(period_us));
    }

    /// A PLC at cold start: A runs `program` from M0; its signals define the I/O map.
    pub fn new(program: Arc<Program>, now_us: u64) -> Self {
        let io_inputs: Vec<String> = program.inputs().iter().map(|s| s.name.clone()).collect();
        let io_outputs: Vec<String> = program.outputs().iter().map(|s| s.name.clone()).collect();
        let container = Container::new(program.clone(), now_us);
        let mut safe = vec![Value::Bool(false); io_outputs.len()];
        program.safe_outputs(&mut safe);
        let limits = Limits::for_period_us(program.scan_period().as_micros() as u64);
        let mut plc = Plc {
            images: [container.inputs().to_vec(), Vec::new()],
            in_maps: [(0..io_inputs.len()).collect(), Vec::new()],
            out_maps: [(0..io_outputs.len()).map(Some).collect(), Vec::new()],
            io_outs: [
                vec![Value::Bool(false); io_outputs.len()],
                vec![Value::Bool(false); io_outputs.len()],
            ],
            in_bits: bits(container.inputs()),
            out_bits: [0, 0],
            inputs_changed: true,
            bool_outputs: program.outputs().len() <= 64
                && program
                    .outputs()
                    .iter()
                    .all(|s| s.ty == cetratus_program::Type::Bool),
            stale: [true, true],
            inputs: container.inputs().to_vec(),
            prev_inputs: container.inputs().to_vec(),
            dispatched: vec![Value::Bool(false); io_outputs.len()],
            slots: [Some(container), None],
            primary: Slot::A,
            status: Status::Idle,
            setup: None,
            quarantine: None,
            monitor: Monitor::new(8192, io_outputs.len()),
            io_inputs,
            io_outputs,
            safe,
            stopwatch: Box::new(RealStopwatch::default()),
            limits,
            events: Vec::with_capacity(64),
            cycle: 0,
            now_us,
            deadlock_alarmed: false,
            retired: Vec::with_capacity(2),
            cycle_stats: TimingStats::new(),
        };
        plc.event(
            "cold_start",
            format!(
                "cold start: A runs {} {} from M0",
                program.name(),
                program.version()
            ),
            serde_json::Value::Null,
        );
        plc
    }

    /// What an update needs to be prepared away from the scan thread.
    pub fn update_context(&self) -> UpdateContext {
        UpdateContext {
            primary: self.primary_program().clone(),
            io_inputs: self.io_inputs.clone(),
            io_outputs: self.io_outputs.clone(),
        }
    }

    /// Replaces the stopwatch of the Updater (a cost model for virtual runs).
    pub fn set_stopwatch(&mut self, sw: Box<dyn Stopwatch>) {
        self.stopwatch = sw;
    }
    /// Sets the Updater's and the watchdog's limits.
    pub fn set_limits(&mut self, limits: Limits) {
        self.limits = limits;
    }
    /// The limits.
    pub fn limits(&self) -> Limits {
        self.limits
    }
    /// PRIMARY.
    pub fn primary(&self) -> Slot {
        self.primary
    }
    /// STATUS.
    pub fn status(&self) -> Status {
        self.status
    }
    /// Cycles run.
    pub fn cycles(&self) -> u64 {
        self.cycle
    }
    /// Program time of the last cycle.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }
    /// A container, if it holds a program.
    pub fn container(&self, slot: Slot) -> Option<&Container> {
        self.slots[slot.index()].as_ref()
    }
    /// The primary container.
    pub fn primary_container(&self) -> &Container {
        self.slots[self.primary.index()]
            .as_ref()
            .expect("the primary container always holds a program")
    }
    /// The primary's program.
    pub fn primary_program(&self) -> &Arc<Program> {
        self.primary_container().program()
    }
    /// Input names of the I/O map.
    pub fn io_inputs(&self) -> &[String] {
        &self.io_inputs
    }
    /// Output names of the I/O map.
    pub fn io_outputs(&self) -> &[String] {
        &self.io_outputs
    }
    /// The input image of the last cycle.
    pub fn inputs(&self) -> &[Value] {
        &self.inputs
    }
    /// What the Dispatcher got in the last cycle.
    pub fn dispatched(&self) -> &[Value] {
        &self.dispatched
    }
    /// A container's outputs in I/O-map order (`None` when empty).
    pub fn outputs_of(&self, slot: Slot) -> Option<&[Value]> {
        self.slots[slot.index()]
            .as_ref()
            .map(|_| &self.io_outs[slot.index()][..])
    }
    /// Drift of the candidate in quarantine.
    pub fn drift(&self) -> Option<u64> {
        self.quarantine
            .as_ref()
            .map(|_| self.monitor.stats[self.primary.other().index()].drift)
    }
    /// Metadata of the update under way.
    pub fn update_meta(&self) -> Option<&PackageMeta> {
        self.setup
            .as_ref()
            .map(|s| &s.meta)
            .or(self.quarantine.as_ref().map(|q| &q.meta))
    }
    /// Whole-cycle time (all containers, routing, Monitor).
    pub fn cycle_stats(&self) -> &TimingStats {
        &self.cycle_stats
    }
    /// Takes the events since the last call.
    pub fn drain_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }
    /// The events not yet drained.
    pub fn pending_events(&self) -> &[Event] {
        &self.events
    }
    /// Takes containers that left service, so they are freed away from the scan thread.
    pub fn take_retired(&mut self) -> Vec<Container> {
        std::mem::take(&mut self.retired)
    }

    fn event(&mut self, kind: &'static str, message: String, detail: serde_json::Value) {
        self.events.push(Event {
            cycle: self.cycle,
            time_us: self.now_us,
            kind,
            message,
            detail,
        });
    }

    /// Builds an update away from the scan thread: the candidate container, its I/O maps and the
    /// transition correspondence used by the Monitor. Refuses a candidate whose signals the I/O
    /// map lacks.
    pub fn prepare(
        primary: &Program,
        io_inputs: &[String],
        io_outputs: &[String],
        update: ResolvedUpdate,
    ) -> Result<PreparedUpdate, String> {
        let program = update.program.clone();
        let mut in_map = Vec::with_capacity(program.inputs().len());
        for s in program.inputs() {
            match io_inputs.iter().position(|n| *n == s.name) {
                Some(i) => in_map.push(i),
                None => {
                    return Err(format!(
                        "the candidate reads input `{}`, which the running I/O map does not provide ({}); keep the I/O map or restart with the new program",
                        s.name,
                        io_inputs.join(", ")
                    ))
                }
            }
        }
        for s in program.outputs() {
            if !io_outputs.contains(&s.name) {
                return Err(format!(
                    "the candidate drives output `{}`, which the running I/O map does not have ({})",
                    s.name,
                    io_outputs.join(", ")
                ));
            }
        }
        let out_map = map_by_name(io_outputs, program.outputs());
        let (pn, cn) = (primary.net(), program.net());
        let to_primary = cn
            .transitions()
            .iter()
            .map(|t| pn.transition_by_id(&t.id))
            .collect();
        let from_primary = pn
            .transitions()
            .iter()
            .map(|t| cn.transition_by_id(&t.id))
            .collect();
        let np = cn.num_places();
        let safe = safe_image(&out_map, &program);
        let latch_map = retained_latch_map(&program, primary);
        let var_map = program
            .variables()
            .iter()
            .map(|v| {
                primary
                    .variables()
                    .iter()
                    .position(|w| w.name == v.name && w.ty == v.ty)
                    .map(|j| j as u32)
            })
            .collect();
        let work =
            (update.transform.rows() + update.transform.cols() + np + cn.num_transitions()) as u64;
        Ok(PreparedUpdate {
            base_hash: primary.hash(),
            container: Container::new(program, 0),
            scratch_marking: vec![0; np],
            scratch_since: vec![None; np],
            in_map,
            out_map,
            to_primary,
            from_primary,
            safe,
            latch_map,
            var_map,
            work,
            meta: update.meta,
            transform: update.transform,
            projection: update.projection,
        })
    }

    /// Accepts or refuses a command. Accepted commands take effect at the next cycle boundary;
    /// every refusal is also an event with its reason.
    pub fn command(&mut self, cmd: Command) -> Result<(), String> {
        let res = self.command_inner(cmd);
        if let Err(reason) = &res {
            self.event("refused", reason.clone(), serde_json::Value::Null);
        }
        res
    }

    fn command_inner(&mut self, cmd: Command) -> Result<(), String> {
        match cmd {
            Command::Load(p) => {
                match self.status {
                    Status::Idle => {}
                    Status::Fault => return Err("load refused: the PLC is in fault; reset it first".into()),
                    s => return Err(format!("load refused: an update is already under way (status {}); substitute, remove or abort it first", s.name())),
                }
                if p.base_hash != self.primary_program().hash() {
                    return Err("load refused: the update was prepared against another running program; load it again".into());
                }
                let msg = format!(
                    "load accepted: {} {} goes into {} at the next cycle",
                    p.meta.name,
                    p.meta.version,
                    self.primary.other().name()
                );
                self.setup = Some(p);
                self.status = Status::Setup;
                self.event("load_accepted", msg, serde_json::Value::Null);
                Ok(())
            }
            Command::Substitute(req) => {
                if self.status != Status::Quarantine {
                    return Err(format!(
                        "substitute refused: no candidate in quarantine (status {})",
                        self.status.name()
                    ));
                }
                let q = self
                    .quarantine
                    .as_mut()
                    .expect("quarantine state exists in quarantine");
                if q.pending.is_some() {
                    return Err(
                        "substitute refused: a substitution is already waiting; abort it first"
                            .into(),
                    );
                }
                let deadline = req
                    .within_us
                    .map_or(u64::MAX, |w| self.now_us.saturating_add(w));
                let msg = match &req.when {
                    Some((text, _)) => format!("substitution waits for `{text}`"),
                    None => "substitution at the next cycle".to_string(),
                };
                q.pending = Some((req, deadline));
                self.event("substitute_accepted", msg, serde_json::Value::Null);
                Ok(())
            }
            Command::Remove => {
                if self.status != Status::Quarantine {
                    return Err(format!(
                        "remove refused: no candidate in quarantine (status {})",
                        self.status.name()
                    ));
                }
                self.drop_candidate(
                    "removed",
                    "the candidate was removed by the operator".into(),
                );
                Ok(())
            }
            Command::Abort => match self.status {
                Status::Setup => {
                    self.setup = None;
                    self.status = Status::Idle;
                    self.event(
                        "aborted",
                        "the update was aborted before its install".into(),
                        serde_json::Value::Null,
                    );
                    Ok(())
                }
                Status::Quarantine => {
                    self.drop_candidate(
                        "aborted",
                        "the update was aborted; the candidate is removed".into(),
                    );
                    Ok(())
                }
                s => Err(format!(
                    "abort refused: no update under way (status {})",
                    s.name()
                )),
            },
            Command::Reset => {
                if self.status != Status::Fault {
                    return Err(format!(
                        "reset refused: the PLC is not in fault (status {})",
                        self.status.name()
                    ));
                }
                self.status = Status::Idle;
                // Inputs kept changing while in fault; rebuild the images at the next scan.
                self.stale = [true, true];
                self.event(
                    "reset",
                    "fault reset by the operator: the primary resumes from its last good state"
                        .into(),
                    serde_json::Value::Null,
                );
                Ok(())
            }
        }
    }

    fn drop_candidate(&mut self, kind: &'static str, message: String) {
        let other = self.primary.other().index();
        if let Some(c) = self.slots[other].take() {
            self.retired.push(c);
        }
        self.quarantine = None;
        self.status = Status::Idle;
        self.event(kind, message, serde_json::Value::Null);
    }

    /// One cycle at program time `now_us`.
    pub fn cycle<IO: Provider + Dispatcher>(&mut self, now_us: u64, io: &mut IO) {
        self.now_us = now_us;
        self.boundary(now_us);
        self.prev_inputs.copy_from_slice(&self.inputs);
        io.read_inputs(now_us, &mut self.inputs);
        self.inputs_changed = self.inputs != self.prev_inputs;
        if self.inputs_changed {
            self.in_bits = bits(&self.inputs);
        }

        if self.status == Status::Fault {
            io.write_outputs(now_us, &self.safe);
            self.dispatched.copy_from_slice(&self.safe);
            self.record(now_us);
            self.cycle += 1;
            return;
        }

        // Primary.
        let p = self.primary.index();
        // One timestamp before the primary and one after each container: the scans are timed
        // back to back, so the clock is read once per container plus once.
        let t0 = quanta::Instant::now();
        let mut mark = t0;
        if let Err(e) = self.scan_slot(p, now_us, &mut mark) {
            self.primary_fault(format!("primary {} faulted: {e}", self.primary.name()), io);
            self.record(now_us);
            self.cycle += 1;
            return;
        }

        // Candidate, isolated: an error, a panic, an invalid marking or an overrun aborts the update.
        if self.status == Status::Quarantine {
            let c = self.primary.other().index();
            let outcome = catch_unwind(AssertUnwindSafe(|| self.scan_slot(c, now_us, &mut mark)));
            let took = self.monitor.stats[c].scan.summary_last();
            let fault = match outcome {
                Err(panic) => Some(format!(
                    "candidate panicked: {}",
                    panic
                        .downcast_ref::<&str>()
                        .map(|s| s.to_string())
                        .or_else(|| panic.downcast_ref::<String>().cloned())
                        .unwrap_or_else(|| "unknown panic".into())
                )),
                Ok(Err(e)) => Some(format!("candidate faulted: {e}")),
                Ok(Ok(())) => {
                    let cand = self.slots[c]
                        .as_ref()
                        .expect("candidate present in quarantine");
                    // The marking only changes when something fires.
                    let broken = (!cand.fired().is_empty())
                        .then(|| cand.program().check_invariants(cand.marking()).err())
                        .flatten();
                    if let Some(v) = broken {
                        Some(format!("candidate reached an invalid marking: {v}"))
                    } else if took > self.limits.candidate_budget_ns {
                        Some(format!(
                            "candidate scan took {} µs, over its budget of {} µs",
                            took / 1000,
                            self.limits.candidate_budget_ns / 1000
                        ))
                    } else {
                        None
                    }
                }
            };
            if let Some(reason) = fault {
                self.drop_candidate(
                    "candidate_fault",
                    format!("{reason}; the update is aborted and the primary goes on"),
                );
            } else {
                self.monitor_quarantine(now_us);
            }
        }

        // Dispatcher: PRIMARY's outputs only.
        self.dispatched.copy_from_slice(&self.io_outs[p]);
        io.write_outputs(now_us, &self.dispatched);

        // Deadlock alarm: no transition enabled while the inputs change.
        let deadlocked = self.primary_container().engine().enabled().is_empty();
        self.monitor.stats[p].deadlocked = deadlocked;
        if !deadlocked {
            self.deadlock_alarmed = false;
        } else if !self.deadlock_alarmed && self.inputs != self.prev_inputs {
            self.deadlock_alarmed = true;
            self.event(
                "deadlock_alarm",
                format!(
                    "primary {} is deadlocked: no transition is enabled while its inputs change",
                    self.primary.name()
                ),
                serde_json::Value::Null,
            );
        }
        self.record(now_us);
        self.cycle += 1;
        self.cycle_stats.record((mark - t0).as_nanos() as u64);
    }

    /// Scans container `i`; `mark` is the time the scan starts and becomes the time it ends.
    fn scan_slot(
        &mut self,
        i: usize,
        now_us: u64,
        mark: &mut quanta::Instant,
    ) -> Result<(), RuntimeError> {
        if self.inputs_changed || self.stale[i] {
            for (v, &j) in self.images[i].iter_mut().zip(&self.in_maps[i]) {
                *v = self.inputs[j];
            }
        }
        let c = self.slots[i]
            .as_mut()
            .expect("scanned slots hold a program");
        #[cfg(feature = "fault-injection")]
        crate::inject::before_scan(c.program().name(), c.program().version())?;
        // The image is rebuilt only when the inputs changed, so the container need not compare.
        let unchanged = !self.inputs_changed && !self.stale[i];
        let r = c.scan_hinted(now_us, &self.images[i], unchanged);
        let end = quanta::Instant::now();
        let took = (end - *mark).as_nanos() as u64;
        *mark = end;
        self.monitor.stats[i].scan.record(took);
        r?;
        if c.outputs_may_have_changed() || self.stale[i] {
            for (o, m) in self.io_outs[i].iter_mut().zip(&self.out_maps[i]) {
                *o = m.map_or(Value::Bool(false), |k| c.outputs()[k]);
            }
            self.out_bits[i] = bits(&self.io_outs[i]);
        }
        self.stale[i] = false;
        if i == self.primary.index() && took > self.limits.watchdog_ns {
            return Err(RuntimeError::Watchdog {
                took_us: took / 1000,
                limit_us: self.limits.watchdog_ns / 1000,
            });
        }
        Ok(())
    }

    fn primary_fault<IO: Dispatcher>(&mut self, message: String, io: &mut IO) {
        io.write_outputs(self.now_us, &self.safe);
        self.dispatched.copy_from_slice(&self.safe);
        if self.status == Status::Quarantine || self.status == Status::Setup {
            let other = self.primary.other().index();
            if let Some(c) = self.slots[other].take() {
                self.retired.push(c);
            }
            self.quarantine = None;
            self.setup = None;
            self.event(
                "update_discarded",
                "the update under way is discarded because the primary faulted".into(),
                serde_json::Value::Null,
            );
        }
        self.status = Status::Fault;
        self.event(
            "primary_fault",
            format!("{message}; safe output values are driven until an operator resets"),
            serde_json::Value::Null,
        );
    }

    fn monitor_quarantine(&mut self, now_us: u64) {
        let p = self.primary.index();
        let c = self.primary.other().index();
        let q = self
            .quarantine
            .as_ref()
            .expect("quarantine state exists in quarantine");
        let (pc, cc) = (
            self.slots[p].as_ref().expect("primary present"),
            self.slots[c].as_ref().expect("candidate present"),
        );
        // Drift only moves when a marking does.
        let stats_c = &self.monitor.stats[c];
        let drift = if pc.fired().is_empty() && cc.fired().is_empty() && stats_c.drift_valid {
            stats_c.drift
        } else {
            q.projection.drift(cc.marking(), pc.marking())
        };
        let stats = &mut self.monitor.stats[c];
        stats.drift = drift;
        stats.drift_valid = true;
        stats.max_drift = stats.max_drift.max(drift);
        stats.deadlocked = cc.engine().enabled().is_empty();

        // Divergence per signal, and its derived cause. Boolean images compare as bit masks: most
        // cycles the two agree and this is one comparison.
        let mut differs = false;
        if self.bool_outputs {
            let mut diff = self.out_bits[p] ^ self.out_bits[c];
            differs = diff != 0;
            while diff != 0 {
                let k = diff.trailing_zeros() as usize;
                stats.divergent_cycles[k] += 1;
                diff &= diff - 1;
            }
        } else {
            for (k, (a, b)) in self.io_outs[p].iter().zip(&self.io_outs[c]).enumerate() {
                if a != b {
                    stats.divergent_cycles[k] += 1;
                    differs = true;
                }
            }
        }
        let fired_diff = if pc.fired().is_empty() && cc.fired().is_empty() {
            None
        } else {
            Self::first_difference(pc, cc, &q.to_primary, &q.from_primary, self.primary)
        };
        if let Some((slot, t)) = fired_diff {
            let (fired, other, other_t) = if slot == self.primary {
                (pc, cc, q.from_primary[t.index()])
            } else {
                (cc, pc, q.to_primary[t.index()])
            };
            let _ = fired;
            let blocked = other_t.map_or(Blocker::Absent, |u| other.blocker(u));
            let cause = Cause {
                cycle: self.cycle,
                time_us: now_us,
                fired_in: slot,
                transition: t,
                blocked,
            };
            if differs || stats.last_cause.is_none() {
                stats.last_cause = Some(cause);
                if stats.first_cause.is_none() {
                    stats.first_cause = Some(cause);
                }
            }
        }
    }

    /// The first transition in visiting order (priority, then declaration) that fired in one
    /// container and not in the other; on a tie of rank, the primary's.
    fn first_difference(
        pc: &Container,
        cc: &Container,
        to_primary: &[Option<TransIdx>],
        from_primary: &[Option<TransIdx>],
        primary: Slot,
    ) -> Option<(Slot, TransIdx)> {
        let only = |a: &Container, b: &Container, map: &[Option<TransIdx>]| {
            a.fired()
                .iter()
                .copied()
                .filter(|t| !map[t.index()].is_some_and(|u| b.fired().contains(&u)))
                .min_by_key(|&t| a.program().net().rank(t))
        };
        let p = only(pc, cc, from_primary).map(|t| (pc.program().net().rank(t), primary, t));
        let c = only(cc, pc, to_primary).map(|t| (cc.program().net().rank(t), primary.other(), t));
        match (p, c) {
            (Some(a), Some(b)) => Some(if b.0 < a.0 { (b.1, b.2) } else { (a.1, a.2) }),
            (Some(a), None) => Some((a.1, a.2)),
            (None, Some(b)) => Some((b.1, b.2)),
            (None, None) => None,
        }
    }

    fn record(&mut self, now_us: u64) {
        let out = |s: Slot| {
            self.slots[s.index()]
                .as_ref()
                .map(|_| self.out_bits[s.index()])
        };
        let dispatched = if self.status == Status::Fault {
            bits(&self.dispatched)
        } else {
            self.out_bits[self.primary.index()]
        };
        let r = CycleRecord {
            cycle: self.cycle,
            time_us: now_us,
            primary: self.primary,
            status: self.status,
            inputs: self.in_bits,
            outputs_a: out(Slot::A),
            outputs_b: out(Slot::B),
            dispatched,
        };
        self.monitor.record(r);
    }

    /// What is due at the cycle boundary: an install, a substitution, a substitution's timeout.
    fn boundary(&mut self, now_us: u64) {
        if self.status == Status::Setup {
            self.install(now_us);
        }
        if self.status == Status::Quarantine {
            self.try_substitute(now_us);
        }
    }

    fn install(&mut self, now_us: u64) {
        let Some(mut up) = self.setup.take() else {
            return;
        };
        let primary = self.slots[self.primary.index()]
            .as_ref()
            .expect("primary present");
        self.stopwatch.start();
        let result = up
            .transform
            .apply(
                primary.marking(),
                up.container.program(),
                &mut up.scratch_marking,
            )
            .map_err(|e| e.to_string())
            .and_then(|()| {
                up.transform.apply_timers(
                    primary.place_since_us(),
                    &up.scratch_marking,
                    now_us,
                    &mut up.scratch_since,
                );
                up.container
                    .set_state(&up.scratch_marking, &up.scratch_since)
                    .map_err(|e| e.to_string())?;
                // Latches and variables the program shares with the primary carry over, as the
                // marking does: an S that latched before the update stays latched.
                up.container.carry_from(primary, &up.latch_map, &up.var_map);
                Ok(())
            });
        let took = self.stopwatch.stop(up.work);
        if let Err(reason) = result {
            self.status = Status::Idle;
            self.event("transform_refused", format!("state transformation refused: {reason}; the secondary is emptied and the primary goes on"), serde_json::Value::Null);
            return;
        }
        if took > self.limits.state_trans_timeout_ns {
            self.status = Status::Idle;
            self.event(
                "state_trans_timeout",
                format!(
                    "stateTransTimeout: the install took {} ns, over its budget of {} ns; the update is aborted and the primary goes on",
                    took, self.limits.state_trans_timeout_ns
                ),
                serde_json::json!({ "install_ns": took, "budget_ns": self.limits.state_trans_timeout_ns }),
            );
            return;
        }
        let s = self.primary.other().index();
        let up = *up;
        self.images[s] = up.container.inputs().to_vec();
        self.stale[s] = true;
        self.in_maps[s] = up.in_map;
        self.out_maps[s] = up.out_map;
        self.monitor.stats[s] = ContainerStats::new(self.io_outputs.len());
        let name = format!("{} {}", up.meta.name, up.meta.version);
        self.slots[s] = Some(up.container);
        self.quarantine = Some(Quarantine {
            meta: up.meta,
            transform: up.transform,
            projection: up.projection,
            to_primary: up.to_primary,
            from_primary: up.from_primary,
            scratch_marking: up.scratch_marking,
            scratch_since: up.scratch_since,
            safe: up.safe,
            latch_map: up.latch_map,
            var_map: up.var_map,
            pending: None,
            started_us: now_us,
        });
        self.status = Status::Quarantine;
        self.event(
            "quarantine_started",
            format!("{name} installed in {} within one cycle; it runs in quarantine, its outputs withheld", self.primary.other().name()),
            serde_json::json!({ "install_ns": took, "budget_ns": self.limits.state_trans_timeout_ns }),
        );
    }

    fn try_substitute(&mut self, now_us: u64) {
        let p = self.primary.index();
        let c = self.primary.other().index();
        let Some(q) = self.quarantine.as_mut() else {
            return;
        };
        let Some((req, deadline)) = q.pending.as_ref() else {
            return;
        };
        let primary = self.slots[p].as_ref().expect("primary present");
        if let Some((text, guard)) = &req.when {
            let ctx = EvalCtx {
                inputs: primary.inputs(),
                prev_inputs: primary.inputs(),
                vars: primary.variables(),
                marking: primary.marking(),
                place_since_us: primary.place_since_us(),
                now_us,
            };
            let holds = match guard.eval(&ctx) {
                Ok(h) => h,
                Err(e) => {
                    let msg = format!("substitution given up: the condition `{text}` failed to evaluate ({e}); the candidate stays in quarantine");
                    q.pending = None;
                    self.event("substitute_timeout", msg, serde_json::Value::Null);
                    return;
                }
            };
            if !holds {
                if now_us >= *deadline {
                    let msg = format!("substitution given up: `{text}` did not hold within the time allowed; the candidate stays in quarantine");
                    q.pending = None;
                    self.event("substitute_timeout", msg, serde_json::Value::Null);
                }
                return;
            }
        }
        let (mode, force) = (req.mode, req.force);
        let drift = self.monitor.stats[c].drift;
        if mode == SubstituteMode::Keep && drift != 0 && !force {
            q.pending = None;
            self.event("refused", format!("substitute refused: mode keep needs drift 0 but the candidate has drifted by {drift} tokens; use retransform, or force"), serde_json::json!({ "drift": drift }));
            return;
        }
        if mode == SubstituteMode::Retransform {
            let res = q
                .transform
                .apply(
                    primary.marking(),
                    self.slots[c].as_ref().expect("candidate present").program(),
                    &mut q.scratch_marking,
                )
                .map_err(|e| e.to_string());
            if let Err(reason) = res {
                q.pending = None;
                self.event("refused", format!("substitute refused: the retransform failed: {reason}; the candidate stays in quarantine"), serde_json::Value::Null);
                return;
            }
            q.transform.apply_timers(
                primary.place_since_us(),
                &q.scratch_marking,
                now_us,
                &mut q.scratch_since,
            );
            let (primary, cand) = primary_and_candidate(&mut self.slots, self.primary);
            if let Err(e) = cand.set_state(&q.scratch_marking, &q.scratch_since) {
                q.pending = None;
                self.event(
                    "refused",
                    format!("substitute refused: {e}"),
                    serde_json::Value::Null,
                );
                return;
            }
            // Consistent with the plant by construction: the latches and variables too.
            cand.carry_from(primary, &q.latch_map, &q.var_map);
            self.stale[c] = true;
        }
        let meta = q.meta.clone();
        let started = q.started_us;
        // The safe values of the program that now drives the outputs.
        std::mem::swap(&mut self.safe, &mut q.safe);
        self.quarantine = None;
        let old = self.primary;
        self.primary = old.other();
        if let Some(c) = self.slots[old.index()].take() {
            self.retired.push(c);
        }
        self.status = Status::Idle;
        self.event(
            "substituted",
            format!(
                "PRIMARY = {}: {} {} drives the outputs ({} mode, drift {} at the switch, {:.1} s in quarantine); {} stops",
                self.primary.name(),
                meta.name,
                meta.version,
                match mode {
                    SubstituteMode::Retransform => "retransform",
                    SubstituteMode::Keep => "keep",
                },
                drift,
                (now_us - started) as f64 / 1e6,
                old.name()
            ),
            serde_json::json!({ "drift": drift, "mode": mode }),
        );
    }

    /// `program_exec_info` of both containers.
    pub fn exec_info(&self) -> [Option<ExecInfo>; 2] {
        let describe = |s: &ContainerStats, slot: Slot| -> (Option<String>, Option<String>) {
            let text = |c: &Option<Cause>| {
                c.as_ref().and_then(|cause| {
                    let fired = self.slots[cause.fired_in.index()].as_ref()?;
                    let other = self.slots[cause.fired_in.other().index()].as_ref()?;
                    Some(describe_cause(cause, fired, other))
                })
            };
            let _ = slot;
            (text(&s.first_cause), text(&s.last_cause))
        };
        [Slot::A, Slot::B].map(|slot| {
            let c = self.slots[slot.index()].as_ref()?;
            let s = &self.monitor.stats[slot.index()];
            let net = c.program().net();
            let is_primary = slot == self.primary;
            let (first_cause, last_cause) = if is_primary {
                (None, None)
            } else {
                describe(s, slot)
            };
            Some(ExecInfo {
                container: slot,
                role: if is_primary { "primary" } else { "candidate" },
                program: ProgramId::of(c),
                cycles: c.scans(),
                scan: s.scan.summary(),
                firings: net
                    .transitions()
                    .iter()
                    .zip(c.firings())
                    .map(|(t, &n)| (t.id.clone(), n))
                    .collect(),
                marking: net
                    .places()
                    .iter()
                    .zip(c.marking())
                    .map(|(p, &m)| (p.id.clone(), m))
                    .collect(),
                outputs: c
                    .program()
                    .outputs()
                    .iter()
                    .zip(c.outputs())
                    .map(|(s, v)| (s.name.clone(), value_json(*v)))
                    .collect(),
                divergence: if is_primary {
                    Default::default()
                } else {
                    self.io_outputs
                        .iter()
                        .zip(&s.divergent_cycles)
                        .filter(|(_, &n)| n > 0)
                        .map(|(n, &k)| (n.clone(), k))
                        .collect()
                },
                first_cause,
                last_cause,
                drift: if is_primary { 0 } else { s.drift },
                max_drift: if is_primary { 0 } else { s.max_drift },
                deadlock: s.deadlocked,
                verdicts: Vec::new(),
            })
        })
    }
}

/// The state of one container, as persisted.
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize, PartialEq)]
pub struct ContainerSnapshot {
    /// Hex SHA-256 of its program.
    pub program_hash: String,
    /// The marking.
    pub marking: Vec<Tokens>,
    /// When each place went from empty to marked.
    pub place_since_us: Vec<Option<u64>>,
    /// The variables, as JSON scalars.
    pub variables: Vec<serde_json::Value>,
    /// The S/R latches.
    pub latches: Vec<bool>,
}

/// Everything a warm start needs, written by the persistence thread.
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize, PartialEq)]
pub struct PlcSnapshot {
    /// Cycle index of the snapshot.
    pub cycle: u64,
    /// Program time of the snapshot.
    pub time_us: u64,
    /// PRIMARY ("A"/"B").
    pub primary: Option<Slot>,
    /// STATUS.
    pub status: Option<Status>,
    /// Containers A and B.
    pub containers: [Option<ContainerSnapshot>; 2],
    /// The update under way, in words.
    pub update: Option<String>,
}

impl Plc {
    /// Copies the state into `snap`, reusing its buffers.
    pub fn snapshot_into(&self, snap: &mut PlcSnapshot) {
        snap.cycle = self.cycle;
        snap.time_us = self.now_us;
        snap.primary = Some(self.primary);
        snap.status = Some(self.status);
        for slot in [Slot::A, Slot::B] {
            let i = slot.index();
            match &self.slots[i] {
                None => snap.containers[i] = None,
                Some(c) => {
                    let s = snap.containers[i].get_or_insert_with(Default::default);
                    let hash = c.program().hash_hex();
                    // Reuses the buffer: no allocation once the hash is known.
                    if s.program_hash != hash {
                        s.program_hash.clear();
                        s.program_hash.push_str(hash);
                    }
                    s.marking.clear();
                    s.marking.extend_from_slice(c.marking());
                    s.place_since_us.clear();
                    s.place_since_us.extend_from_slice(c.place_since_us());
                    s.variables.clear();
                    s.variables
                        .extend(c.variables().iter().map(|v| value_json(*v)));
                    s.latches.clear();
                    s.latches.extend_from_slice(c.latches());
                }
            }
        }
        snap.update = self
            .update_meta()
            .map(|m| format!("{} {}", m.name, m.version));
    }

    /// A warm start: the saved PRIMARY resumes its last committed marking, timers, variables and
    /// latches; an update that was under way is discarded, with an event (DESIGN §4). A PLC that
    /// was in fault comes back in fault. `program` finds a program by its hash.
    pub fn warm_start(
        snap: &PlcSnapshot,
        program: impl Fn(&str) -> Option<Arc<Program>>,
        io_program: Arc<Program>,
    ) -> Result<Plc, String> {
        let primary = snap.primary.ok_or("the saved state has no PRIMARY")?;
        let cs = snap.containers[primary.index()]
            .as_ref()
            .ok_or("the saved state has no program in the PRIMARY container")?;
        let prog = program(&cs.program_hash).ok_or_else(|| {
            format!(
                "the saved state refers to program {} which the state directory does not hold",
                cs.program_hash
            )
        })?;
        if cs.marking.len() != prog.net().num_places() {
            return Err(format!(
                "the saved marking has {} places but program {} has {}",
                cs.marking.len(),
                prog.name(),
                prog.net().num_places()
            ));
        }
        if let Err(v) = prog.check_invariants(&cs.marking) {
            return Err(format!("the saved marking breaks an invariant: {v}"));
        }
        let now = snap.time_us;
        let container = Container::with_state(prog.clone(), &cs.marking, &cs.place_since_us, now)
            .map_err(|e| e.to_string())?;
        let mut plc = Plc::new(io_program, now);
        plc.events.clear();
        let vars: Vec<Value> = prog
            .variables()
            .iter()
            .zip(&cs.variables)
            .map(|(s, j)| match s.ty {
                cetratus_program::Type::Bool => Value::Bool(j.as_bool().unwrap_or(false)),
                cetratus_program::Type::Int => Value::Int(j.as_i64().unwrap_or(0)),
                cetratus_program::Type::Real => Value::Real(j.as_f64().unwrap_or(0.0)),
            })
            .collect();
        let mut container = container;
        container.restore_retained(&vars, &cs.latches);
        container.resume_without_entry();
        let i = primary.index();
        plc.images[i] = container.inputs().to_vec();
        plc.stale[i] = true;
        plc.in_maps[i] = prog
            .inputs()
            .iter()
            .map(|s| {
                plc.io_inputs
                    .iter()
                    .position(|n| *n == s.name)
                    .ok_or(s.name.clone())
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(|n| format!("the saved program reads input `{n}` which the I/O map lacks"))?;
        plc.out_maps[i] = map_by_name(&plc.io_outputs, prog.outputs());
        plc.safe = safe_image(&plc.out_maps[i], &prog);
        plc.slots = [None, None];
        plc.slots[i] = Some(container);
        plc.primary = primary;
        plc.cycle = snap.cycle;
        plc.now_us = now;
        plc.status = if snap.status == Some(Status::Fault) {
            Status::Fault
        } else {
            Status::Idle
        };
        plc.event(
            "warm_start",
            format!(
                "warm start: PRIMARY = {} resumes {} {} at cycle {} ({:.3} s)",
                primary.name(),
                prog.name(),
                prog.version(),
                snap.cycle,
                now as f64 / 1e6
            ),
            serde_json::Value::Null,
        );
        if matches!(snap.status, Some(Status::Setup) | Some(Status::Quarantine)) {
            plc.event(
                "update_discarded",
                format!(
                    "the update under way at the crash ({}) is discarded; load it again",
                    snap.update.as_deref().unwrap_or("unnamed")
                ),
                serde_json::Value::Null,
            );
        }
        if plc.status == Status::Fault {
            plc.event(
                "primary_fault",
                "the PLC was in fault when it stopped; it stays in fault until an operator resets"
                    .into(),
                serde_json::Value::Null,
            );
        }
        Ok(plc)
    }
}

/// The primary container and the candidate, borrowed together.
fn primary_and_candidate(
    slots: &mut [Option<Container>; 2],
    primary: Slot,
) -> (&Container, &mut Container) {
    let [a, b] = slots;
    let (p, c) = match primary {
        Slot::A => (a, b),
        Slot::B => (b, a),
    };
    (
        p.as_ref().expect("primary present"),
        c.as_mut().expect("candidate present"),
    )
}

/// A program's safe output values in the order of the I/O map, through its output map (off for
/// outputs it lacks).
fn safe_image(out_map: &[Option<usize>], program: &Program) -> Vec<Value> {
    let mut own = vec![Value::Bool(false); program.outputs().len()];
    program.safe_outputs(&mut own);
    out_map
        .iter()
        .map(|m| m.map_or(Value::Bool(false), |k| own[k]))
        .collect()
}

/// For each latch (action target) of `program`, the latch of `primary` driving the signal of the
/// same kind and name.
fn retained_latch_map(program: &Program, primary: &Program) -> Vec<Option<u32>> {
    use cetratus_program::Target;
    let name = |p: &Program, t: &Target| match *t {
        Target::Output(i) => (0u8, p.outputs()[i as usize].name.clone()),
        Target::Variable(i) => (1u8, p.variables()[i as usize].name.clone()),
    };
    let theirs: Vec<(u8, String)> = primary
        .action_targets()
        .iter()
        .map(|t| name(primary, t))
        .collect();
    program
        .action_targets()
        .iter()
        .map(|t| {
            let mine = name(program, t);
            theirs.iter().position(|x| *x == mine).map(|j| j as u32)
        })
        .collect()
}

/// A value as plain JSON.
pub fn value_json(v: Value) -> serde_json::Value {
    match v {
        Value::Bool(b) => b.into(),
        Value::Int(i) => i.into(),
        Value::Real(x) => x.into(),
    }
}
