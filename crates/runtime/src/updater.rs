//! The Updater of the paper's Figure 1: the live-update process. It owns the [`Phase`]
//! (STATUS and the secondary container), accepts or refuses commands between cycles, and does at
//! the cycle boundary what they cause: the install within stateTransTimeout and the
//! substitution.
//!
//! Building an update (verifying the package, resolving it against the running program, building
//! the candidate container) happens away from the scan thread, through an [`UpdateContext`];
//! only the install, which is bounded by the size of the transformation, runs in the cycle (the
//! preparation is in `prepare.rs`).

use cetratus_net::NetError;
use cetratus_program::{EvalCtx, Guard, TransformError, Value};

use crate::clock::InstallTiming;
use crate::error::CommandError;
use crate::event::{EventDetail, EventKind, RevertReason};
use crate::monitor::ContainerStats;
use crate::phase::{Ending, Phase, Probation, Quarantine, UpdatePlan};
use crate::plc::Core;
pub use crate::prepare::{PreparedUpdate, UpdateContext};
use crate::{Container, Slot, Status};
use cetratus_vocab::Verb;

pub use cetratus_vocab::SubstituteMode;

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

impl SubstituteRequest {
    /// Substitute at the next cycle, in `mode`.
    pub fn now(mode: SubstituteMode) -> Self {
        SubstituteRequest {
            mode,
            when: None,
            within_us: None,
            force: false,
        }
    }
}

/// A command from the operator or the dashboard: a prepared update to install, a substitution
/// request, or a verb without arguments. `exec_info` is a query that the node answers from
/// [`crate::Plc::program_exec_info`]; the Updater refuses it.
pub type Command = cetratus_vocab::Command<Box<PreparedUpdate>, SubstituteRequest>;

/// The default candidate budget, in instructions per microsecond of the scan period. The
/// interpreter takes 1.7 to 2.7 ns an instruction on the development machine (docs/performance.md,
/// *A candidate's work in instructions*), so a candidate at its budget takes 4 to 7 % of the
/// period, and the primary keeps the rest; the programs a cell runs need far less (Vernadat:
/// under 200 a scan).
pub const INSTRUCTIONS_PER_US: u64 = 25;

/// Limits of the Updater and the watchdog.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// stateTransTimeout: budget of the in-cycle install, in ns. Defaults to one scan period.
    pub state_trans_timeout_ns: u64,
    /// A candidate scan longer than this (ns) in quarantine aborts the update, after the scan.
    pub candidate_budget_ns: u64,
    /// A candidate scan is stopped midway, and the update aborted, before it does more than
    /// this many units of [`cetratus_program::Work`]: the instructions of the guards it evaluates
    /// and of the bodies it runs, and one per firing (docs/design.md §2: a runaway candidate must
    /// not take the primary's time). Counted, not timed, so a virtual run decides the same.
    pub candidate_instruction_budget: u64,
    /// A primary scan is stopped midway, and the PLC faults (safe outputs), before it does more
    /// than this many units of work: what bounds a loop of Structured Text that would never end.
    pub primary_instruction_budget: u64,
    /// A primary scan longer than this (ns) is a primary fault.
    pub watchdog_ns: u64,
    /// The probation window after a substitution, in µs of program time; 0: none, the old
    /// program stops at the switch.
    pub probation_us: u64,
    /// A substitution is refused unless the latest twin verdict on the candidate passed (and
    /// the quarantine verdict, when the twin recorded a divergence signature).
    pub require_verdict: bool,
    /// The least cycles a candidate's quarantine runs, compared with the twin's signature,
    /// before its quarantine verdict may pass.
    pub quarantine_cycles: u64,
    /// How long an operator's `revert` may wait, in µs of program time, for a cycle boundary
    /// at which a marking of the old program agrees with the plant; past it the revert is
    /// refused and the new program stays in control (docs/live-update.md, *Probation and
    /// rollback*).
    pub revert_wait_us: u64,
}

/// The default of [`Limits::quarantine_cycles`]: five seconds at a 10 ms period.
pub const DEFAULT_QUARANTINE_CYCLES: u64 = 500;

/// The default of [`Limits::revert_wait_us`]: two seconds of program time.
pub const DEFAULT_REVERT_WAIT_US: u64 = 2_000_000;

impl Limits {
    /// Limits for a run in virtual time: the install budget is one period, and the measured
    /// watchdog and candidate budget are one second, so that an operating system that preempts
    /// the process does not turn a simulation into a fault.
    pub fn for_virtual_time(period_us: u64) -> Self {
        Limits {
            state_trans_timeout_ns: period_us.saturating_mul(1000),
            candidate_budget_ns: 1_000_000_000,
            candidate_instruction_budget: Self::work_budget_for_period_us(period_us),
            primary_instruction_budget: Self::primary_budget_for_period_us(period_us),
            watchdog_ns: 1_000_000_000,
            probation_us: 0,
            require_verdict: false,
            quarantine_cycles: DEFAULT_QUARANTINE_CYCLES,
            revert_wait_us: DEFAULT_REVERT_WAIT_US,
        }
    }

    /// The default work budget of a candidate scan: [`INSTRUCTIONS_PER_US`] per microsecond of
    /// the period (250 000 for 10 ms, 50 000 for 2 ms), at least 1 000.
    pub fn work_budget_for_period_us(period_us: u64) -> u64 {
        period_us.saturating_mul(INSTRUCTIONS_PER_US).max(1000)
    }

    /// The default work budget of a primary scan: ten times a candidate's, as the watchdog is
    /// ten periods: room for a scan that does more than usual, and still a bound on a loop
    /// that never ends (2 500 000 for 10 ms).
    pub fn primary_budget_for_period_us(period_us: u64) -> u64 {
        Self::work_budget_for_period_us(period_us).saturating_mul(10)
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
            candidate_instruction_budget: Self::work_budget_for_period_us(period_us),
            primary_instruction_budget: Self::primary_budget_for_period_us(period_us),
            watchdog_ns: ns.saturating_mul(10),
            probation_us: 0,
            require_verdict: false,
            quarantine_cycles: DEFAULT_QUARANTINE_CYCLES,
            revert_wait_us: DEFAULT_REVERT_WAIT_US,
        }
    }
}

/// What a cost-model install charges per entry it touches in a virtual run.
pub const VIRTUAL_NS_PER_ENTRY: u64 = 20;

/// The Updater: the phase, and the limits it enforces.
pub struct Updater {
    pub(crate) phase: Phase,
    pub(crate) limits: Limits,
    pub(crate) install_timing: InstallTiming,
}

impl Updater {
    pub(crate) fn new(limits: Limits) -> Self {
        Updater {
            phase: Phase::Idle,
            limits,
            install_timing: InstallTiming::Measured,
        }
    }

    /// STATUS.
    pub fn status(&self) -> Status {
        self.phase.status()
    }

    /// Accepts or refuses a command; what it causes happens at the next cycle boundary. One
    /// method a verb.
    pub(crate) fn command(&mut self, cmd: Command, core: &mut Core) -> Result<(), CommandError> {
        match cmd {
            Command::Load(p) => self.load(p, core),
            Command::Substitute(req) => self.substitute(req, core),
            Command::Remove => self.remove(core),
            Command::Abort => self.abort(core),
            Command::Revert => self.ask_probation_end(
                "revert",
                Ending::Revert {
                    reason: RevertReason::Operator,
                    detected_cycle: core.log.cycle,
                    why: "the operator reverted".into(),
                    asked_us: core.log.now_us,
                },
            ),
            Command::Accept => self.ask_probation_end("accept", Ending::Accept),
            Command::Reset => self.reset(core),
            Command::ExecInfo => Err(CommandError::Query {
                verb: Verb::ExecInfo,
            }),
        }
    }

    /// `load`: only when idle, and only a package prepared against the running primary.
    fn load(&mut self, p: Box<PreparedUpdate>, core: &mut Core) -> Result<(), CommandError> {
        match self.status() {
            Status::Idle => {}
            Status::Fault => return Err(CommandError::LoadInFault),
            Status::Probation => return Err(CommandError::LoadInProbation),
            status => return Err(CommandError::LoadBusy { status }),
        }
        if p.base_hash != core.primary.program().hash() {
            return Err(CommandError::StalePreparation);
        }
        let meta = &p.quarantine.plan.meta;
        let msg = format!(
            "load accepted: {} {} goes into {} at the next cycle",
            meta.name,
            meta.version,
            core.primary_slot.other().as_str()
        );
        core.log.push(EventKind::LoadAccepted, msg, None);
        for v in &p.quarantine.plan.verdicts {
            let reasons = if v.reasons.is_empty() {
                String::new()
            } else {
                format!(": {}", v.reasons.join("; "))
            };
            core.log.push(
                EventKind::Verdict,
                format!(
                    "{} verdict on {} {}: {}{reasons}",
                    v.kind, meta.name, meta.version, v.result
                ),
                Some(EventDetail::Verdict {
                    kind: v.kind,
                    result: v.result,
                }),
            );
        }
        self.phase = Phase::Setup(p);
        Ok(())
    }

    /// `substitute`: only in quarantine, one at a time, and with a passing twin verdict when
    /// the limits require one.
    fn substitute(&mut self, req: SubstituteRequest, core: &mut Core) -> Result<(), CommandError> {
        let status = self.status();
        let require_verdict = self.limits.require_verdict;
        let Phase::Quarantine(q) = &mut self.phase else {
            return Err(CommandError::NoCandidate {
                verb: "substitute",
                status,
            });
        };
        if q.pending.is_some() {
            return Err(CommandError::SubstitutionWaiting);
        }
        if require_verdict {
            if let Some(have) = q.plan.verdict_gap() {
                return Err(CommandError::VerdictRequired { have });
            }
        }
        let deadline = req
            .within_us
            .map_or(u64::MAX, |w| core.log.now_us.saturating_add(w));
        let msg = match &req.when {
            Some((text, _)) => format!("substitution waits for `{text}`"),
            None => "substitution at the next cycle".to_string(),
        };
        q.pending = Some((req, deadline));
        core.log.push(EventKind::SubstituteAccepted, msg, None);
        Ok(())
    }

    /// `remove`: only in quarantine.
    fn remove(&mut self, core: &mut Core) -> Result<(), CommandError> {
        let status = self.status();
        if status != Status::Quarantine {
            return Err(CommandError::NoCandidate {
                verb: "remove",
                status,
            });
        }
        let why = "the candidate was removed by the operator".into();
        self.drop_candidate(core, EventKind::Removed, why);
        Ok(())
    }

    /// `abort`: in setup (before the install) or in quarantine.
    fn abort(&mut self, core: &mut Core) -> Result<(), CommandError> {
        match self.status() {
            Status::Setup => {
                self.phase = Phase::Idle;
                let why = "the update was aborted before its install".into();
                core.log.push(EventKind::Aborted, why, None);
                Ok(())
            }
            Status::Quarantine => {
                let why = "the update was aborted; the candidate is removed".into();
                self.drop_candidate(core, EventKind::Aborted, why);
                Ok(())
            }
            status => Err(CommandError::NothingToAbort { status }),
        }
    }

    /// `revert` and `accept`: only in probation, and once; the probation ends at the next cycle
    /// boundary as `ending` says.
    fn ask_probation_end(
        &mut self,
        verb: &'static str,
        ending: Ending,
    ) -> Result<(), CommandError> {
        let status = self.status();
        let Phase::Probation(p) = &mut self.phase else {
            return Err(CommandError::NotInProbation { verb, status });
        };
        if p.ending.is_some() {
            return Err(CommandError::ProbationEnding { verb });
        }
        p.ending = Some(ending);
        Ok(())
    }

    /// `reset`: only in fault; the primary resumes from its last good state.
    fn reset(&mut self, core: &mut Core) -> Result<(), CommandError> {
        let status = self.status();
        if status != Status::Fault {
            return Err(CommandError::NotInFault { status });
        }
        self.phase = Phase::Idle;
        // Inputs kept changing while in fault; rebuild the images at the next scan.
        core.router.mark_all_stale();
        let why = "fault reset by the operator: the primary resumes from its last good state";
        core.log.push(EventKind::Reset, why.into(), None);
        Ok(())
    }

    /// Empties the secondary container and goes back to idle.
    pub(crate) fn drop_candidate(&mut self, core: &mut Core, kind: EventKind, message: String) {
        if let Phase::Quarantine(q) = std::mem::replace(&mut self.phase, Phase::Idle) {
            core.retired.push(q.candidate);
        }
        core.log.push(kind, message, None);
    }

    /// The primary faulted: an update under way is discarded and the PLC enters fault.
    pub(crate) fn primary_fault(&mut self, core: &mut Core, message: String) {
        match std::mem::replace(&mut self.phase, Phase::Fault) {
            Phase::Quarantine(q) => {
                core.retired.push(q.candidate);
                core.log.push(
                    EventKind::UpdateDiscarded,
                    "the update under way is discarded because the primary faulted".into(),
                    None,
                );
            }
            Phase::Probation(p) => {
                core.retired.push(p.shadow);
                core.log.push(
                    EventKind::UpdateDiscarded,
                    "the update under way is discarded because the primary faulted".into(),
                    None,
                );
            }
            Phase::Setup(_) => core.log.push(
                EventKind::UpdateDiscarded,
                "the update under way is discarded because the primary faulted".into(),
                None,
            ),
            Phase::Idle | Phase::Fault => {}
        }
        core.log.push(
            EventKind::PrimaryFault,
            format!("{message}; safe output values are driven until an operator resets"),
            None,
        );
    }

    /// What is due at the cycle boundary: an install, a substitution, a substitution's timeout,
    /// the end of probation (window over, accept or revert).
    pub(crate) fn boundary(&mut self, core: &mut Core) {
        if matches!(self.phase, Phase::Probation(_)) {
            self.end_probation(core);
        }
        if matches!(self.phase, Phase::Setup(_)) {
            self.install(core);
        }
        if matches!(self.phase, Phase::Quarantine(_)) {
            self.try_substitute(core);
        }
    }

    fn install(&mut self, core: &mut Core) {
        let Phase::Setup(mut up) = std::mem::replace(&mut self.phase, Phase::Idle) else {
            return;
        };
        let now_us = core.log.now_us;
        let primary = &core.primary;
        let start = core.stopwatch.now_ns();
        let Quarantine {
            candidate, plan, ..
        } = &mut *up.quarantine;
        let result = carry_state(plan, candidate, primary, now_us);
        let took = match self.install_timing {
            InstallTiming::Measured => core.stopwatch.now_ns().saturating_sub(start),
            InstallTiming::Model { ns_per_entry } => up.work.saturating_mul(ns_per_entry),
        };
        let budget = self.limits.state_trans_timeout_ns;
        if let Err(reason) = result {
            core.log.push(EventKind::TransformRefused, format!("state transformation refused: {reason}; the secondary is emptied and the primary goes on"), None);
            return;
        }
        let detail = Some(EventDetail::Install {
            install_ns: took,
            budget_ns: budget,
        });
        if took > budget {
            core.log.push(
                EventKind::StateTransTimeout,
                format!(
                    "stateTransTimeout: the install took {took} ns, over its budget of {budget} ns; the update is aborted and the primary goes on"
                ),
                detail,
            );
            return;
        }
        let s = core.primary_slot.other();
        let here = (
            core.router.io_inputs().len(),
            core.router.io_outputs().len(),
        );
        if up.grow.from != here {
            core.log.push(
                EventKind::TransformRefused,
                "the I/O map changed since the package was prepared (another update added signals to it); the secondary is emptied and the primary goes on: load the package again".to_string(),
                None,
            );
            return;
        }
        // Everything below was built with the candidate, off the scan thread.
        let PreparedUpdate {
            mut quarantine,
            in_map,
            out_map,
            image,
            stats,
            installed: [in_a, in_b],
            grow,
            ..
        } = *up;
        if !grow.inputs.is_empty() || !grow.outputs.is_empty() {
            core.grow_io(grow);
        }
        core.router
            .attach(s.index(), image, in_map, out_map, &quarantine.plan.safe);
        // The candidate's first scan sees the edges of this cycle, as the primary's does.
        quarantine
            .candidate
            .continue_edges_from(core.router.last_inputs_for(s.index()));
        core.monitor.stats[s.index()] = stats;
        quarantine.started_us = now_us;
        self.phase = Phase::Quarantine(quarantine);
        let message = if s == Slot::A { in_a } else { in_b };
        core.log.push(EventKind::QuarantineStarted, message, detail);
    }

    /// Substitutes once a pending request may: its condition holds, the candidate's drift
    /// allows its mode, and a retransform succeeds; a request that cannot is given up.
    fn try_substitute(&mut self, core: &mut Core) {
        let now_us = core.log.now_us;
        let Phase::Quarantine(q) = &mut self.phase else {
            return;
        };
        let Some((req, deadline)) = q.pending.as_ref() else {
            return;
        };
        match condition_met(req, *deadline, &core.primary, now_us) {
            Ok(true) => {}
            Ok(false) => return,
            Err(why) => {
                give_up(q, core, EventKind::SubstituteTimeout, why, None);
                return;
            }
        }
        let (mode, force) = (req.mode, req.force);
        let c = core.primary_slot.other();
        let drift = core.monitor.stats[c.index()].drift;
        if mode == SubstituteMode::Keep && drift != 0 && !force {
            let why = format!("substitute refused: mode keep needs drift 0 but the candidate has drifted by {drift} tokens; use retransform, or force");
            give_up(
                q,
                core,
                EventKind::Refused,
                why,
                Some(EventDetail::Drift { drift }),
            );
            return;
        }
        if mode == SubstituteMode::Retransform {
            let Quarantine {
                candidate, plan, ..
            } = &mut **q;
            if let Err(e) = carry_state(plan, candidate, &core.primary, now_us) {
                let why = match e {
                    CarryError::Transform(reason) => format!("substitute refused: the retransform failed: {reason}; the candidate stays in quarantine"),
                    CarryError::State(e) => format!("substitute refused: {e}"),
                };
                give_up(q, core, EventKind::Refused, why, None);
                return;
            }
            core.router.mark_stale(c.index());
        }
        self.switch(core, mode, drift);
    }

    /// PRIMARY flips to the candidate, whose safe values now drive the outputs; the old
    /// primary stops, or stays as a shadow for the probation window.
    fn switch(&mut self, core: &mut Core, mode: SubstituteMode, drift: u64) {
        let now_us = core.log.now_us;
        let c = core.primary_slot.other();
        let Phase::Quarantine(q) = std::mem::replace(&mut self.phase, Phase::Idle) else {
            unreachable!("a substitution switches from quarantine");
        };
        let mut q = *q;
        // The new primary's edge memory continues from the inputs the old primary saw in its
        // last scan, so that an edge in the switch cycle is not lost.
        q.candidate
            .continue_edges_from(core.router.last_inputs_for(c.index()));
        // The safe values of the program that now drives the outputs.
        core.router.drive_safe(c.index(), &mut q.plan.safe);
        let old = core.primary_slot;
        core.primary_slot = c;
        let old_primary = std::mem::replace(&mut core.primary, q.candidate);
        let window = self.limits.probation_us;
        let fate = if window == 0 {
            "stops"
        } else {
            "stays as a shadow"
        };
        let text = format!(
            "PRIMARY = {}: {} {} drives the outputs ({} mode, drift {} at the switch, {:.1} s in quarantine); {} {fate}",
            c.as_str(),
            q.plan.meta.name,
            q.plan.meta.version,
            mode.as_str(),
            drift,
            now_us.saturating_sub(q.started_us) as f64 / 1e6,
            old.as_str(),
        );
        core.log.push(
            EventKind::Substituted,
            text,
            Some(EventDetail::Substitution { drift, mode }),
        );
        if window == 0 {
            core.retired.push(old_primary);
            return;
        }
        self.start_probation(core, old, old_primary, q.plan);
    }

    /// Quarantine reversed: the old program runs in slot `old` on the same inputs, its outputs
    /// withheld, until the window ends or the new primary gives a cause to revert.
    fn start_probation(&mut self, core: &mut Core, old: Slot, shadow: Container, plan: UpdatePlan) {
        let now_us = core.log.now_us;
        let window = self.limits.probation_us;
        let ends_us = now_us.saturating_add(window);
        core.monitor.stats[old.index()] = ContainerStats::new(core.router.io_outputs().len());
        core.log.push(
            EventKind::ProbationStarted,
            format!(
                "probation for {:.1} s: {} runs the old program as a shadow; the PLC reverts to it if {} {} faults, stalls or breaks an invariant, or on `revert`; `accept` ends probation",
                window as f64 / 1e6,
                old.as_str(),
                plan.meta.name,
                plan.meta.version,
            ),
            Some(EventDetail::Probation { ends_us }),
        );
        self.phase = Phase::Probation(Box::new(Probation {
            shadow,
            plan,
            started_us: now_us,
            ends_us,
            ending: None,
        }));
    }
}

/// Whether a pending substitution's condition holds over the primary now (no condition always
/// does); `Err` gives the request up, saying why: its condition failed, or its time ran out.
fn condition_met(
    req: &SubstituteRequest,
    deadline: u64,
    primary: &Container,
    now_us: u64,
) -> Result<bool, String> {
    let Some((text, guard)) = &req.when else {
        return Ok(true);
    };
    let ctx = EvalCtx {
        // The condition is compiled against the primary: it reads the primary's image.
        inputs: primary.inputs(),
        prev_inputs: primary.inputs(),
        vars: primary.variables(),
        marking: primary.marking(),
        place_since_us: primary.place_since_us(),
        place_dwell_us: primary.place_dwell_us(),
        now_us,
    };
    match guard.eval(&ctx) {
        Ok(true) => Ok(true),
        Ok(false) if now_us >= deadline => Err(format!("substitution given up: `{text}` did not hold within the time allowed; the candidate stays in quarantine")),
        Ok(false) => Ok(false),
        Err(e) => Err(format!("substitution given up: the condition `{text}` failed to evaluate ({e}); the candidate stays in quarantine")),
    }
}

/// Drops the pending substitution with the event that says why; the candidate stays in
/// quarantine, and a new request may follow.
fn give_up(
    q: &mut Quarantine,
    core: &mut Core,
    kind: EventKind,
    message: String,
    detail: Option<EventDetail>,
) {
    q.pending = None;
    core.log.push(kind, message, detail);
}

/// Why the primary's state could not be carried into the candidate: the transform refused the
/// marking, or the candidate refused the transformed state.
enum CarryError {
    Transform(TransformError),
    State(NetError),
}

impl std::fmt::Display for CarryError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CarryError::Transform(e) => e.fmt(f),
            CarryError::State(e) => e.fmt(f),
        }
    }
}

/// Carries the primary's state into the candidate through the plan, at an install and at a
/// retransforming substitution alike: marking, timers, then the latches and variables the
/// programs share. Allocates nothing but an error.
fn carry_state(
    plan: &mut UpdatePlan,
    candidate: &mut Container,
    primary: &Container,
    now_us: u64,
) -> Result<(), CarryError> {
    plan.transform
        .apply(
            primary.marking(),
            candidate.program(),
            &mut plan.scratch_marking,
        )
        .map_err(CarryError::Transform)?;
    plan.transform.apply_timers(
        primary.place_since_us(),
        &plan.scratch_marking,
        now_us,
        &mut plan.scratch_since,
    );
    candidate
        .set_state(&plan.scratch_marking, &plan.scratch_since)
        .map_err(CarryError::State)?;
    // Latches and variables the program shares with the primary carry over, as the marking
    // does: an S that latched before the update stays latched.
    candidate.carry_from(primary, &plan.latch_map, &plan.var_map, &plan.st_map);
    Ok(())
}

/// A value as plain JSON.
pub fn value_json(v: Value) -> serde_json::Value {
    match v {
        Value::Bool(b) => b.into(),
        Value::Int(i) => i.into(),
        Value::Real(x) => x.into(),
    }
}
