//! The Updater's phase: an enum, checked at run time, whose every variant owns exactly the data
//! it needs, so PRIMARY, STATUS and the secondary container can never disagree (docs/design.md §4).

use cetratus_net::{Tokens, TransIdx};
use cetratus_program::{PackageMeta, Projection, StateTransform, Value};

use crate::container::Rehearsal;
use crate::event::RevertReason;
use crate::updater::{PreparedUpdate, SubstituteRequest};
use crate::Container;

pub use cetratus_vocab::Status;

/// What an installed update keeps for the Monitor and for the substitution.
pub(crate) struct UpdatePlan {
    pub meta: PackageMeta,
    pub transform: StateTransform,
    pub projection: Projection,
    // Candidate transition → the primary's transition of the same id.
    pub to_primary: Vec<Option<TransIdx>>,
    // Primary transition → the candidate's transition of the same id.
    pub from_primary: Vec<Option<TransIdx>>,
    // Buffers of the in-cycle transforms, sized once.
    pub scratch_marking: Vec<Tokens>,
    pub scratch_since: Vec<Option<u64>>,
    // The candidate's safe output values in I/O-map order, for when it is PRIMARY.
    pub safe: Vec<Value>,
    // Candidate latch / variable → the primary's of the same name, carried over at the switch.
    pub latch_map: Vec<Option<u32>>,
    pub var_map: Vec<Option<u32>>,
    // The candidate's Structured Text variables from the primary's, by name and layout.
    pub st_map: cetratus_program::st::StCarry,
    // The way back, for a revert in probation, sized once away from the scan thread: the
    // primary's latch / variable → the candidate's of the same name, and buffers of the
    // projection into the primary's place space.
    pub back_latch_map: Vec<Option<u32>>,
    // What validation said of the update's program, for its exec_info.
    pub verdicts: Vec<crate::monitor::Verdict>,
    pub back_var_map: Vec<Option<u32>>,
    pub back_st_map: cetratus_program::st::StCarry,
    pub back_marking: Vec<Tokens>,
    pub back_since: Vec<Option<u64>>,
    // Scratch for rehearsing what the old program would drive from a marking, at a revert.
    pub rehearsal: Rehearsal,
}

impl UpdatePlan {
    /// What the verdicts lack for a substitution that requires them, in words; `None` when they
    /// allow it: a passing twin verdict (or a warning), and when that verdict brought a
    /// divergence signature, a passing quarantine verdict too.
    pub fn verdict_gap(&self) -> Option<&'static str> {
        use cetratus_vocab::{VerdictKind, VerdictResult};
        let of = |kind| self.verdicts.iter().find(|v| v.kind == kind);
        let twin = of(VerdictKind::Twin);
        match twin.map(|v| v.result) {
            None => return Some("no twin verdict yet"),
            Some(VerdictResult::Fail) => return Some("a failing twin verdict"),
            Some(VerdictResult::Pass | VerdictResult::Warn) => {}
        }
        if twin.is_some_and(|v| v.signature.is_none()) {
            return None;
        }
        match of(VerdictKind::Quarantine).map(|v| v.result) {
            Some(VerdictResult::Pass | VerdictResult::Warn) => None,
            Some(VerdictResult::Fail) => {
                Some("a failing quarantine verdict: a divergence the twin never showed")
            }
            None => Some(
                "no quarantine verdict yet: the quarantine has not yet shown what the twin showed",
            ),
        }
    }
}

/// A candidate running in quarantine.
pub(crate) struct Quarantine {
    pub candidate: Container,
    pub plan: UpdatePlan,
    /// A substitution waiting for its condition, with its deadline (program time).
    pub pending: Option<(SubstituteRequest, u64)>,
    pub started_us: u64,
}

/// The window after a substitution in which the old program stays resident as a shadow: same
/// inputs, outputs withheld (quarantine reversed).
pub(crate) struct Probation {
    pub shadow: Container,
    /// The update's plan; its safe values are the shadow's since the switch.
    pub plan: UpdatePlan,
    pub started_us: u64,
    /// Program time at which the window is over and the update final.
    pub ends_us: u64,
    /// How probation ends at the next cycle boundary, once decided.
    pub ending: Option<Ending>,
}

/// How a probation ends at the next cycle boundary.
pub(crate) enum Ending {
    /// The update is final: accepted by the operator.
    Accept,
    /// PRIMARY flips back to the shadow.
    Revert {
        reason: RevertReason,
        /// The cycle in which the cause was seen (for the revert latency).
        detected_cycle: u64,
        /// What was seen, in words.
        why: String,
        /// Program time of the request: an operator's revert waits from then on for a marking
        /// that agrees with the plant, at most `revert_wait_us`.
        asked_us: u64,
    },
}

/// The Updater's phase. `Fault` keeps the primary's last good state; leaving it needs a reset.
pub(crate) enum Phase {
    Idle,
    Setup(Box<PreparedUpdate>),
    Quarantine(Box<Quarantine>),
    Probation(Box<Probation>),
    Fault,
}

impl Phase {
    pub fn status(&self) -> Status {
        match self {
            Phase::Idle => Status::Idle,
            Phase::Setup(_) => Status::Setup,
            Phase::Quarantine(_) => Status::Quarantine,
            Phase::Probation(_) => Status::Probation,
            Phase::Fault => Status::Fault,
        }
    }

    /// The container beside the primary: the candidate in quarantine, the shadow in probation.
    pub fn secondary(&self) -> Option<&Container> {
        match self {
            Phase::Quarantine(q) => Some(&q.candidate),
            Phase::Probation(p) => Some(&p.shadow),
            _ => None,
        }
    }

    /// The package of the update under way.
    pub fn meta(&self) -> Option<&PackageMeta> {
        match self {
            Phase::Setup(p) => Some(p.meta()),
            Phase::Quarantine(q) => Some(&q.plan.meta),
            Phase::Probation(p) => Some(&p.plan.meta),
            _ => None,
        }
    }
}
