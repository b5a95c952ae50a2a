//! The PLC of the paper's Figure 1: containers A and B under PRIMARY and STATUS, composed of the
//! [`MessageRouter`], the [`Updater`] and the [`Monitor`], advanced one cycle at a time.
//!
//! [`Plc::cycle`] runs one cycle at program time `now`: first what is due at the cycle boundary
//! (an update's install, a substitution), then the Provider, the primary, the Dispatcher, and only
//! then the candidate and the Monitor, so a candidate never delays the plant's outputs. Commands ([`Plc::command`]) are accepted or refused between cycles; everything
//! they cause happens at the next boundary, so nothing is ever half-applied.

use std::ops::ControlFlow;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;

use cetratus_program::{PackageMeta, Program, Value};

use crate::clock::{InstallTiming, Stopwatch};
use crate::error::CommandError;
use crate::event::{Event, EventDetail, EventKind, EventLog, RevertReason};
use crate::monitor::{describe_kind, ExecInfo, Monitor, Pair, Role, Verdict, VerdictResult};
use crate::phase::Phase;
use crate::router::{IoGrowth, MessageRouter};
use crate::signature::{Comparison, Signature};
use crate::updater::{Command, Limits, UpdateContext, Updater, VIRTUAL_NS_PER_ENTRY};
use crate::watchdog::StallWatch;
use crate::{
    Container, Dispatcher, Provider, RuntimeError, SharedAdmission, Slot, Status, TimingStats,
};

/// The running side of the PLC, which the Updater changes at cycle boundaries: PRIMARY and its
/// container, the Message Router, the Monitor and the event log.
pub(crate) struct Core {
    pub primary_slot: Slot,
    pub primary: Container,
    pub router: MessageRouter,
    pub monitor: Monitor,
    pub log: EventLog,
    pub stopwatch: Box<dyn Stopwatch>,
    // Containers that left service, freed away from the scan thread.
    pub retired: Vec<Container>,
    // Signals appended to the I/O map at this boundary's install, for the I/O to serve.
    pub grown: Option<IoGrowth>,
    // Whether the node's I/O can serve signals the I/O map lacks.
    pub admission: Option<SharedAdmission>,
}

impl Core {
    /// Appends an update's new signals to the I/O map and to the Monitor's figures; the I/O
    /// hears of them before the cycle's inputs are read.
    pub(crate) fn grow_io(&mut self, grow: IoGrowth) {
        self.router.grow(&grow.inputs, &grow.outputs);
        let (ins, outs) = (
            self.router.io_inputs().len(),
            self.router.io_outputs().len(),
        );
        for st in &mut self.monitor.stats {
            st.divergent_cycles.resize(outs, 0);
        }
        self.monitor.recent.widen(ins, outs);
        self.grown = Some(grow);
    }
}

/// The PLC: two containers, PRIMARY, STATUS, the Message Router, the Updater and the Monitor.
pub struct Plc {
    core: Core,
    updater: Updater,
    deadlock_alarmed: bool,
    // The stall watchdog of the primary, and the container it watches.
    pub(crate) stall: StallWatch,
    stall_slot: Slot,
    cycle_stats: TimingStats,
    // The generation of the safe values the I/O was last given.
    safe_told: u64,
}

impl Plc {
    /// A PLC at cold start: A runs `program` from M0; its signals define the I/O map. Scan times,
    /// the watchdog and the install are measured by `stopwatch`.
    pub fn new(program: Arc<Program>, now_us: u64, stopwatch: Box<dyn Stopwatch>) -> Self {
        let mut plc = Self::bare(
            Container::new(program.clone(), now_us),
            Slot::A,
            now_us,
            &program,
            stopwatch,
        );
        plc.core.log.push(
            EventKind::ColdStart,
            format!(
                "cold start: A runs {} {} from M0",
                program.name(),
                program.version()
            ),
            None,
        );
        plc
    }

    /// A PLC whose I/O map is `io_program`'s signals, with `primary` in `slot` and no event yet.
    pub(crate) fn bare(
        primary: Container,
        slot: Slot,
        now_us: u64,
        io_program: &Program,
        stopwatch: Box<dyn Stopwatch>,
    ) -> Self {
        let router = MessageRouter::new(io_program, slot.index());
        let (inputs, outputs) = (router.io_inputs().len(), router.io_outputs().len());
        Plc {
            updater: Updater::new(Limits::for_period_us(
                io_program.scan_period().as_micros() as u64
            )),
            core: Core {
                primary_slot: slot,
                primary,
                router,
                monitor: Monitor::new(8192, inputs, outputs),
                log: EventLog::new(now_us),
                stopwatch,
                retired: Vec::with_capacity(2),
                grown: None,
                admission: None,
            },
            deadlock_alarmed: false,
            stall: StallWatch::new(now_us),
            stall_slot: slot,
            cycle_stats: TimingStats::new(),
            safe_told: 0,
        }
    }

    pub(crate) fn core_mut(&mut self) -> &mut Core {
        &mut self.core
    }

    /// Makes this PLC deterministic in virtual time: the install is charged by a cost model and
    /// the measured limits are relaxed ([`Limits::for_virtual_time`]).
    pub fn use_virtual_time(&mut self, period_us: u64) {
        self.updater.install_timing = InstallTiming::Model {
            ns_per_entry: VIRTUAL_NS_PER_ENTRY,
        };
        self.set_limits(Limits::for_virtual_time(period_us));
    }

    /// What an update needs to be prepared away from the scan thread.
    pub fn update_context(&self) -> UpdateContext {
        UpdateContext {
            primary: self.primary_program().clone(),
            io_inputs: self.core.router.io_inputs().to_vec(),
            io_outputs: self.core.router.io_outputs().to_vec(),
            primary_marking: self.core.primary.marking().to_vec(),
            cycle: self.cycles(),
            admission: self.core.admission.clone(),
        }
    }

    /// Lets updates use signals the running program does not, when `admission` (the node's I/O)
    /// can serve them: they are appended to the I/O map at the install.
    pub fn set_io_admission(&mut self, admission: SharedAdmission) {
        self.core.admission = Some(admission);
    }

    /// How the in-cycle install is timed.
    pub fn set_install_timing(&mut self, timing: InstallTiming) {
        self.updater.install_timing = timing;
    }
    /// Replaces the stopwatch.
    pub fn set_stopwatch(&mut self, sw: Box<dyn Stopwatch>) {
        self.core.stopwatch = sw;
    }
    /// Sets the Updater's and the watchdog's limits.
    pub fn set_limits(&mut self, limits: Limits) {
        self.updater.limits = limits;
    }
    /// The limits.
    pub fn limits(&self) -> Limits {
        self.updater.limits
    }
    /// PRIMARY.
    pub fn primary(&self) -> Slot {
        self.core.primary_slot
    }
    /// STATUS.
    pub fn status(&self) -> Status {
        self.updater.status()
    }
    /// Cycles run.
    pub fn cycles(&self) -> u64 {
        self.core.log.cycle
    }
    /// Program time of the last cycle.
    pub fn now_us(&self) -> u64 {
        self.core.log.now_us
    }
    /// A container, if it holds a program.
    pub fn container(&self, slot: Slot) -> Option<&Container> {
        if slot == self.core.primary_slot {
            Some(&self.core.primary)
        } else {
            self.updater.phase.secondary()
        }
    }
    /// The primary container.
    pub fn primary_container(&self) -> &Container {
        &self.core.primary
    }
    /// The primary's program.
    pub fn primary_program(&self) -> &Arc<Program> {
        self.core.primary.program()
    }
    /// The Message Router: the I/O map and the images.
    pub fn router(&self) -> &MessageRouter {
        &self.core.router
    }
    /// The Monitor.
    pub fn monitor(&self) -> &Monitor {
        &self.core.monitor
    }
    /// Input names of the I/O map.
    pub fn io_inputs(&self) -> &[String] {
        self.core.router.io_inputs()
    }
    /// Output names of the I/O map.
    pub fn io_outputs(&self) -> &[String] {
        self.core.router.io_outputs()
    }
    /// The input image of the last cycle.
    pub fn inputs(&self) -> &[Value] {
        self.core.router.inputs()
    }
    /// Continues from `image`, the I/O input image that the PLC whose state this one resumes
    /// read in its last cycle: the primary's next scan sees the edges between that cycle and its
    /// own, as the original PLC's would (a resumed container otherwise has no past, and its first
    /// scan sees no edge). A validation fork needs it to run on from the very cycle it forks.
    pub fn continue_inputs_from(&mut self, image: &[Value]) {
        let core = &mut self.core;
        core.router.set_last_inputs(image);
        let p = core.primary_slot.index();
        core.primary
            .continue_edges_from(core.router.last_inputs_for(p));
    }
    /// What the Dispatcher got in the last cycle.
    pub fn dispatched(&self) -> &[Value] {
        self.core.router.dispatched()
    }
    /// A container's outputs in I/O-map order (`None` when empty).
    pub fn outputs_of(&self, slot: Slot) -> Option<&[Value]> {
        self.container(slot)
            .map(|_| self.core.router.outputs(slot.index()))
    }
    /// Drift of the candidate in quarantine.
    pub fn drift(&self) -> Option<u64> {
        matches!(self.updater.phase, Phase::Quarantine(_))
            .then(|| self.core.monitor.stats[self.core.primary_slot.other().index()].drift)
    }
    /// Metadata of the update under way.
    pub fn update_meta(&self) -> Option<&PackageMeta> {
        self.updater.phase.meta()
    }
    /// Whole-cycle time (all containers, routing, Monitor).
    pub fn cycle_stats(&self) -> &TimingStats {
        &self.cycle_stats
    }
    /// Takes the events since the last call.
    pub fn drain_events(&mut self) -> Vec<Event> {
        self.core.log.drain()
    }
    /// The events not yet drained.
    pub fn pending_events(&self) -> &[Event] {
        self.core.log.pending()
    }
    /// Takes containers that left service, so they are freed away from the scan thread.
    pub fn take_retired(&mut self) -> Vec<Container> {
        std::mem::take(&mut self.core.retired)
    }

    /// Accepts or refuses a command. Accepted commands take effect at the next cycle boundary;
    /// every refusal is also an event with its reason.
    pub fn command(&mut self, cmd: Command) -> Result<(), CommandError> {
        let res = self.updater.command(cmd, &mut self.core);
        if let Err(reason) = &res {
            self.core
                .log
                .push(EventKind::Refused, reason.to_string(), None);
        }
        res
    }

    /// Takes the candidate in quarantine out of service for `reason`, as a fault of its own
    /// scan would (`candidate_fault`; the primary goes on). For what the node sees and the
    /// runtime does not, such as the primary's overruns in real time. False, and nothing done,
    /// when no candidate is in quarantine.
    pub fn fault_candidate(&mut self, reason: &str) -> bool {
        if self.updater.status() != Status::Quarantine {
            return false;
        }
        self.updater.drop_candidate(
            &mut self.core,
            EventKind::CandidateFault,
            format!("{reason}; the update is aborted and the primary goes on"),
        );
        true
    }

    /// One cycle at program time `now_us`.
    pub fn cycle<IO: Provider + Dispatcher + ?Sized>(&mut self, now_us: u64, io: &mut IO) {
        self.boundary(now_us, io);
        if self.updater.status() == Status::Fault {
            self.core.router.dispatch_safe(now_us, io);
            self.end_cycle(now_us, None);
            return;
        }
        // One reading before the primary, one after it, and in quarantine one after the
        // Dispatcher and one after the candidate.
        let t0 = self.core.stopwatch.now_ns();
        let mut mark = t0;
        let p = self.core.primary_slot;
        if self.primary_cycle(p, now_us, io, &mut mark).is_break() {
            self.end_cycle(now_us, None);
            return;
        }
        self.secondary_cycle(p, now_us, &mut mark);
        self.end_cycle(now_us, Some(mark.saturating_sub(t0)));
    }

    /// What is due at the cycle boundary, then the Provider: the I/O hears of grown signals and
    /// new safe values before it is read.
    #[inline]
    fn boundary<IO: Provider + Dispatcher + ?Sized>(&mut self, now_us: u64, io: &mut IO) {
        self.core.log.now_us = now_us;
        self.updater.boundary(&mut self.core);
        if let Some(g) = self.core.grown.take() {
            io.io_map_grew(&g.inputs, &g.outputs);
        }
        let safe = self.core.router.safe_generation();
        if safe != self.safe_told {
            self.safe_told = safe;
            io.safe_outputs(self.core.router.safe());
        }
        self.core.router.read(now_us, io);
    }

    /// Scans the primary `p` and dispatches its outputs; `Break` when it faulted outside
    /// probation, which puts the PLC in fault with the outputs at their safe values.
    #[inline]
    fn primary_cycle<IO: Provider + Dispatcher + ?Sized>(
        &mut self,
        p: Slot,
        now_us: u64,
        io: &mut IO,
        mark: &mut u64,
    ) -> ControlFlow<()> {
        let core = &mut self.core;
        let limits = self.updater.limits;
        let in_probation = matches!(self.updater.phase, Phase::Probation(_));
        if let Err(e) = scan_slot(core, None, p, now_us, mark, &limits) {
            let why = format!("primary {} faulted: {e}", p.as_str());
            if !in_probation {
                core.router.dispatch_safe(now_us, io);
                self.updater.primary_fault(core, why);
                return ControlFlow::Break(());
            }
            // In probation the fault is a cause to revert, and the old program takes over at
            // the next boundary. For this one cycle the outputs hold their last values (the
            // failed scan was rolled back): safe values would stop a machine mid-cut for one
            // cycle. The shadow scans on, so that its own marking stays current should the
            // projection be refused.
            core.router.dispatch(p.index(), now_us, io);
            self.updater.request_revert(core, RevertReason::Fault, why);
            return ControlFlow::Continue(());
        }
        // Dispatcher: PRIMARY's outputs only, before the candidate runs, so that the time
        // the candidate takes never delays the plant's outputs.
        core.router.dispatch(p.index(), now_us, io);
        self.deadlock_alarm(p);
        self.stall_watchdog(p, now_us);
        if in_probation {
            self.probation_invariants(p);
        }
        ControlFlow::Continue(())
    }

    /// A new primary on probation that breaks an invariant its program declares is reverted;
    /// the marking only changes when something fires.
    fn probation_invariants(&mut self, p: Slot) {
        let core = &mut self.core;
        if core.primary.fired().is_empty() {
            return;
        }
        if let Err(v) = core
            .primary
            .program()
            .check_invariants(core.primary.marking())
        {
            self.updater.request_revert(
                core,
                RevertReason::Invariant,
                format!("primary {} reached an invalid marking: {v}", p.as_str()),
            );
        }
    }

    /// The secondary, isolated: the candidate in quarantine or the shadow in probation, none
    /// otherwise. An error, a panic, an invalid marking, a scan stopped by its work budget or
    /// one that overran its time budget takes it out of service after its scan.
    #[inline]
    fn secondary_cycle(&mut self, p: Slot, now_us: u64, mark: &mut u64) {
        let core = &mut self.core;
        let limits = self.updater.limits;
        let (secondary, plan, shadow) = match &mut self.updater.phase {
            Phase::Quarantine(q) => (&mut q.candidate, &q.plan, false),
            Phase::Probation(pr) => (&mut pr.shadow, &pr.plan, true),
            _ => return,
        };
        let c = p.other();
        let role = if shadow { "shadow" } else { "candidate" };
        *mark = core.stopwatch.now_ns();
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            scan_slot(core, Some(&mut *secondary), c, now_us, mark, &limits)
        }));
        let took = core.monitor.stats[c.index()].scan.summary_last();
        let fault = secondary_fault(role, outcome, secondary, took, &limits);
        if fault.is_none() {
            // In probation the shadow is the old program: its transitions map onto the new
            // primary's the other way round, and the projection reads the primary's marking.
            let (to_primary, from_primary) = if shadow {
                (&plan.from_primary, &plan.to_primary)
            } else {
                (&plan.to_primary, &plan.from_primary)
            };
            let pair = Pair {
                primary_slot: p,
                primary: &core.primary,
                candidate: secondary,
                to_primary,
                from_primary,
                projection: &plan.projection,
                shadow,
            };
            let cycle = core.log.cycle;
            core.monitor
                .observe_quarantine(&pair, &core.router, cycle, now_us);
        }
        match fault {
            Some(reason) if shadow => self.updater.drop_shadow(core, reason),
            Some(reason) => self.updater.drop_candidate(
                core,
                EventKind::CandidateFault,
                format!("{reason}; the update is aborted and the primary goes on"),
            ),
            None if !shadow => self.judge_quarantine(c),
            None => {}
        }
    }

    /// Deadlock alarm: no transition of the primary enabled while the inputs change; once per
    /// episode.
    fn deadlock_alarm(&mut self, p: Slot) {
        let core = &mut self.core;
        let deadlocked = core.primary.engine().deadlocked();
        core.monitor.stats[p.index()].deadlocked = deadlocked;
        if !deadlocked {
            self.deadlock_alarmed = false;
        } else if !self.deadlock_alarmed && core.router.inputs() != core.router.prev_inputs() {
            self.deadlock_alarmed = true;
            core.log.push(
                EventKind::DeadlockAlarm,
                format!(
                    "primary {} is deadlocked: no transition is enabled while its inputs change",
                    p.as_str()
                ),
                None,
            );
        }
    }

    /// Stall watchdog: a watched place marked too long, or no firing too long while one is
    /// marked; an alarm once per episode, and a cause to revert during probation.
    fn stall_watchdog(&mut self, p: Slot, now_us: u64) {
        if self.stall_slot != p {
            self.stall.restart(now_us);
            self.stall_slot = p;
        }
        let core = &mut self.core;
        if let Some(stall) = self.stall.check(&core.primary, now_us) {
            let why = format!(
                "primary {} stalls: {}",
                p.as_str(),
                self.stall.describe(stall, &core.primary)
            );
            core.log.push(
                EventKind::StallAlarm,
                why.clone(),
                Some(EventDetail::Stall {
                    waited_us: stall.waited_us(),
                }),
            );
            self.updater.request_revert(core, RevertReason::Stall, why);
        }
        core.monitor.stats[p.index()].stalled = self.stall.stalled();
    }

    fn end_cycle(&mut self, now_us: u64, took_ns: Option<u64>) {
        let status = self.updater.status();
        let (has_a, has_b) = (
            self.container(Slot::A).is_some(),
            self.container(Slot::B).is_some(),
        );
        let core = &mut self.core;
        let router = &core.router;
        // What the plant got: the primary's outputs, with the outputs it lacks at their held
        // values, or the safe values in fault.
        let dispatched = router.dispatched_bits();
        core.monitor.recent.record(
            core.log.cycle,
            now_us,
            core.primary_slot,
            status,
            router.input_bits().words(),
            has_a.then(|| router.output_bits(0).words()),
            has_b.then(|| router.output_bits(1).words()),
            dispatched.words(),
        );
        // A warm start refuses a cycle count near the top; a count that got there anyway stops
        // rather than wraps to 0.
        self.core.log.cycle = self.core.log.cycle.saturating_add(1);
        if let Some(ns) = took_ns {
            self.cycle_stats.record(ns);
        }
    }

    /// `program_exec_info` of both containers.
    pub fn exec_info(&self) -> [Option<ExecInfo>; 2] {
        let role = match self.updater.phase {
            Phase::Probation(_) => Role::Shadow,
            _ => Role::Candidate,
        };
        let mut info = self.core.monitor.exec_info(
            [self.container(Slot::A), self.container(Slot::B)],
            self.core.primary_slot,
            role,
            self.core.router.io_outputs(),
        );
        // The verdicts belong to the update's program: the candidate, or the new primary.
        let p = self.core.primary_slot;
        let (slot, plan) = match &self.updater.phase {
            Phase::Quarantine(q) => (p.other(), &q.plan),
            Phase::Probation(pr) => (p, &pr.plan),
            _ => return info,
        };
        if let Some(e) = info[slot.index()].as_mut() {
            e.verdicts = plan.verdicts.clone();
            e.changes = plan.meta.declared_changes();
        }
        info
    }

    /// The update under way as resolved against the program it replaces (the candidate's in
    /// quarantine, the new primary's in probation), for a validation run on a fork.
    pub fn resolved_update(&self) -> Option<cetratus_program::ResolvedUpdate> {
        let (program, plan) = match &self.updater.phase {
            Phase::Quarantine(q) => (q.candidate.program(), &q.plan),
            Phase::Probation(p) => (self.core.primary.program(), &p.plan),
            _ => return None,
        };
        Some(cetratus_program::ResolvedUpdate {
            program: program.clone(),
            transform: plan.transform.clone(),
            projection: plan.projection.clone(),
            meta: plan.meta.clone(),
        })
    }

    /// Attaches a verdict on the update under way, when its program is still `program_hash`
    /// (in quarantine or probation), with a `verdict` event. A failing verdict during probation
    /// reverts at the next cycle boundary. A twin verdict in quarantine that brings a
    /// divergence signature starts the comparison of the quarantine with it. Returns whether
    /// it was attached.
    pub fn add_verdict(&mut self, program_hash: &[u8; 32], verdict: Verdict) -> bool {
        let core = &mut self.core;
        let (program, scans) = match &self.updater.phase {
            Phase::Quarantine(q) => (q.candidate.program(), Some(q.candidate.scans())),
            Phase::Probation(_) => (core.primary.program(), None),
            _ => return false,
        };
        if program.hash() != *program_hash {
            return false;
        }
        if let (Some(signature), Some(scans)) = (&verdict.signature, scans) {
            let c = core.primary_slot.other();
            let stats = &mut core.monitor.stats[c.index()];
            stats.comparison = Some(Comparison::new(
                signature.clone(),
                core.router.io_outputs(),
                &stats.divergences,
                scans,
            ));
        }
        self.record_verdict(verdict);
        true
    }

    /// Keeps `verdict` as the latest of its kind on the update under way, with its event; a
    /// failing one during probation reverts at the next cycle boundary.
    fn record_verdict(&mut self, verdict: Verdict) {
        let core = &mut self.core;
        let (plan, probation) = match &mut self.updater.phase {
            Phase::Quarantine(q) => (&mut q.plan, false),
            Phase::Probation(p) => (&mut p.plan, true),
            _ => return,
        };
        let text = format!(
            "{} verdict on {} {}: {}{}",
            verdict.kind.as_str(),
            plan.meta.name,
            plan.meta.version,
            verdict.result.as_str(),
            if verdict.reasons.is_empty() {
                String::new()
            } else {
                format!(": {}", verdict.reasons.join("; "))
            }
        );
        let detail = Some(EventDetail::Verdict {
            kind: verdict.kind,
            result: verdict.result,
        });
        let failed = verdict.result == VerdictResult::Fail;
        plan.verdicts.retain(|v| v.kind != verdict.kind);
        plan.verdicts.push(verdict);
        core.log.push(EventKind::Verdict, text.clone(), detail);
        if probation && failed {
            self.updater
                .request_revert(core, RevertReason::Verdict, text);
        }
    }

    /// Whether the verdicts on the candidate in quarantine allow its substitution where a
    /// verdict is required ([`UpdatePlan::verdict_gap`](crate::phase::UpdatePlan)).
    pub fn verdicts_allow_substitution(&self) -> bool {
        matches!(&self.updater.phase, Phase::Quarantine(q) if q.plan.verdict_gap().is_none())
    }

    /// The kinds of divergence the candidate in quarantine has shown so far, as the signature
    /// a quarantine on the plant is compared with (`signature.rs`); `None` outside quarantine.
    pub fn divergence_signature(&self) -> Option<Signature> {
        let Phase::Quarantine(q) = &self.updater.phase else {
            return None;
        };
        let core = &self.core;
        let seen = &core.monitor.stats[core.primary_slot.other().index()].divergences;
        let names = core.router.io_outputs();
        let (mut kinds, mut words) = (Vec::new(), Vec::new());
        for k in seen.kinds() {
            let Some(name) = names.get(k.output as usize) else {
                continue;
            };
            words.push(describe_kind(name, k.cause, &q.candidate, &core.primary));
            kinds.push((name.clone(), k.cause));
        }
        Some(Signature {
            kinds,
            words,
            complete: !seen.overflowed(),
            horizon_cycles: u64::MAX,
        })
    }

    /// The quarantine verdict, when the comparison of the quarantine with the twin's signature
    /// makes one due: a fail at the first divergence the twin never showed, a pass once the
    /// quarantine has run `quarantine_cycles` and shown every output the twin showed diverging.
    fn judge_quarantine(&mut self, c: Slot) {
        let min = self.updater.limits.quarantine_cycles;
        let core = &mut self.core;
        let Phase::Quarantine(q) = &self.updater.phase else {
            return;
        };
        let Some(cmp) = core.monitor.stats[c.index()].comparison.as_mut() else {
            return;
        };
        let scans = q.candidate.scans();
        let Some(result) = cmp.due(scans, min) else {
            return;
        };
        cmp.given = Some(result);
        let verdict = crate::signature::verdict(
            cmp,
            result,
            scans,
            core.router.io_outputs(),
            (&q.candidate, &core.primary),
        );
        self.record_verdict(verdict);
    }

    /// Enters fault (a warm start of a PLC that was in fault).
    pub(crate) fn enter_fault(&mut self) {
        self.updater.phase = Phase::Fault;
    }
}

/// Why a secondary's scan takes it out of service, `None` when it does not: a panic, an
/// error, an invalid marking, or a scan over its time budget.
fn secondary_fault(
    role: &str,
    outcome: std::thread::Result<Result<(), RuntimeError>>,
    secondary: &Container,
    took: u64,
    limits: &Limits,
) -> Option<String> {
    match outcome {
        Err(panic) => Some(format!(
            "{role} panicked: {}",
            panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into())
        )),
        Ok(Err(e)) => Some(format!("{role} faulted: {e}")),
        Ok(Ok(())) => {
            // The marking only changes when something fires.
            let broken = (!secondary.fired().is_empty())
                .then(|| {
                    secondary
                        .program()
                        .check_invariants(secondary.marking())
                        .err()
                })
                .flatten();
            if let Some(v) = broken {
                Some(format!("{role} reached an invalid marking: {v}"))
            } else if took > limits.candidate_budget_ns {
                Some(format!(
                    "{role} scan took {} µs, over its budget of {} µs",
                    took / 1000,
                    limits.candidate_budget_ns / 1000
                ))
            } else {
                None
            }
        }
    }
}

/// Scans container `slot` (the primary when `candidate` is `None`); `mark` is the stopwatch
/// reading at which the scan starts and becomes the one at which it ends.
fn scan_slot(
    core: &mut Core,
    candidate: Option<&mut Container>,
    slot: Slot,
    now_us: u64,
    mark: &mut u64,
    limits: &Limits,
) -> Result<(), RuntimeError> {
    let i = slot.index();
    let is_primary = candidate.is_none();
    let (c, work_budget) = match candidate {
        Some(c) => (c, limits.candidate_instruction_budget),
        None => (&mut core.primary, limits.primary_instruction_budget),
    };
    #[cfg(feature = "fault-injection")]
    crate::inject::before_scan(c.program().name(), c.program().version())?;
    // The image is rebuilt only when the inputs changed, so the container need not compare.
    let (image, unchanged) = core.router.image(i);
    let r = c.scan_within(now_us, image, unchanged, work_budget);
    let end = core.stopwatch.now_ns();
    let took = end.saturating_sub(*mark);
    *mark = end;
    core.monitor.stats[i].scan.record(took);
    r?;
    core.router.collect(i, c);
    if is_primary && took > limits.watchdog_ns {
        return Err(RuntimeError::Watchdog {
            took_us: took / 1000,
            limit_us: limits.watchdog_ns / 1000,
        });
    }
    Ok(())
}
