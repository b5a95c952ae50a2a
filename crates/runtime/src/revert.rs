//! A revert in probation (docs/live-update.md, *Probation and rollback*): PRIMARY flips back to
//! the shadow, which takes over with one of two markings of the old program, the projection of
//! the new primary's (`Π·M + Π_base`) or its own. Each is rehearsed first: the outputs the old
//! program would drive from it, on the inputs just read, against the outputs being dispatched.
//! A marking whose outputs are those the plant is being driven with *agrees with the plant*: a
//! machine mid-move is not stopped, and no part is dropped.
//!
//! * An automatic revert (fault, stall, broken invariant, failing verdict) happens at the
//!   cycle boundary after its cause, as before: it takes a marking that agrees (the projection
//!   first), or else the one that changes the fewest outputs, and reports what changed.
//! * An operator's revert waits for a boundary at which one agrees, at most
//!   [`crate::Limits::revert_wait_us`] of program time; then it is refused with the reason,
//!   and the new program stays in control.

use std::fmt::Write;

use crate::container::Carry;
use crate::event::{EventDetail, EventKind, RevertMarking, RevertReason};
use crate::phase::{Ending, Phase, Probation};
use crate::plc::Core;
use crate::updater::Updater;

/// A revert asked for: why, and since when.
pub(crate) struct Ask {
    pub reason: RevertReason,
    pub detected_cycle: u64,
    pub why: String,
    pub asked_us: u64,
}

/// How a marking of the old program would meet the plant if it took over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Fit {
    marking: RevertMarking,
    /// ‖Π·M_new + Π_base − M‖₁: 0 for the projection itself.
    drift: u64,
    /// Outputs of the I/O map that would change at the switch.
    differing: u32,
}

/// Both markings, weighed at one boundary.
struct Weighed {
    /// The projection, or why it was refused.
    projected: Result<Fit, String>,
    own: Fit,
}

impl Weighed {
    /// The marking that agrees with the plant, the projection first.
    fn agreeing(&self) -> Option<Fit> {
        [self.projected.as_ref().ok(), Some(&self.own)]
            .into_iter()
            .flatten()
            .find(|f| f.differing == 0)
            .copied()
    }

    /// The marking that agrees, or else the one that changes the fewest outputs (the projection
    /// on a tie: it carries the new primary's progress).
    fn best(&self) -> Fit {
        match &self.projected {
            Ok(p) if p.differing <= self.own.differing => *p,
            _ => self.own,
        }
    }
}

/// Rehearses both markings against what is dispatched now. The projection is left in the
/// plan's `back_marking` and `back_since`. Allocates nothing unless the projection is refused or
/// a body fails.
fn weigh(core: &Core, p: &mut Probation, budget: u64) -> Weighed {
    let now_us = core.log.now_us;
    let s = core.primary_slot.other().index();
    let (plan, shadow, primary) = (&mut p.plan, &p.shadow, &core.primary);
    let projected = plan
        .projection
        .apply(primary.marking(), shadow.program(), &mut plan.back_marking)
        .map_err(|e| e.to_string())
        .and_then(|()| {
            plan.projection.apply_timers(
                primary.place_since_us(),
                &plan.back_marking,
                now_us,
                &mut plan.back_since,
            );
            let carried = Carry {
                from: primary,
                latch_map: &plan.back_latch_map,
                var_map: &plan.back_var_map,
                st: &plan.back_st_map,
            };
            shadow
                .rehearse(
                    &plan.back_marking,
                    &plan.back_since,
                    Some(carried),
                    now_us,
                    budget,
                    &mut plan.rehearsal,
                )
                .map_err(|e| e.to_string())?;
            Ok(Fit {
                marking: RevertMarking::Projection,
                drift: 0,
                differing: core.router.differing(s, &plan.rehearsal.outputs, |_| {}),
            })
        });
    // The shadow keeps its marking and its action state: its next scan goes on from its last,
    // whose outputs are what it would drive.
    let own = Fit {
        marking: RevertMarking::Shadow,
        drift: plan.projection.drift(primary.marking(), shadow.marking()),
        differing: core.router.differing(s, shadow.outputs(), |_| {}),
    };
    Weighed { projected, own }
}

impl Updater {
    /// Reverts to the shadow of `p` as `ask` says, or for an operator's revert with no marking
    /// that agrees with the plant, waits (the probation goes on, its window held open) or, past
    /// the wait, refuses.
    pub(crate) fn revert(&mut self, core: &mut Core, mut p: Box<Probation>, ask: Ask) {
        let weighed = weigh(core, &mut p, self.limits.candidate_instruction_budget);
        let fit = match (ask.reason, weighed.agreeing()) {
            (RevertReason::Operator, None) => {
                let waited = core.log.now_us.saturating_sub(ask.asked_us);
                if waited < self.limits.revert_wait_us {
                    p.ending = Some(ending(ask));
                } else {
                    refuse(core, &p, &weighed, waited);
                }
                self.phase = Phase::Probation(p);
                return;
            }
            (RevertReason::Operator, Some(fit)) => fit,
            (_, agreeing) => agreeing.unwrap_or_else(|| weighed.best()),
        };
        take_over(core, p, fit, &weighed, ask);
    }
}

fn ending(ask: Ask) -> Ending {
    Ending::Revert {
        reason: ask.reason,
        detected_cycle: ask.detected_cycle,
        why: ask.why,
        asked_us: ask.asked_us,
    }
}

/// The names of the outputs that `fit` would change, for a message.
fn changed_outputs(core: &Core, p: &Probation, fit: Fit) -> String {
    let s = core.primary_slot.other().index();
    let outputs = match fit.marking {
        RevertMarking::Projection => &p.plan.rehearsal.outputs[..],
        RevertMarking::Shadow => p.shadow.outputs(),
    };
    let names = core.router.io_outputs();
    let mut text = String::new();
    core.router.differing(s, outputs, |j| {
        let sep = if text.is_empty() { "" } else { ", " };
        let _ = write!(text, "{sep}{}", names[j]);
    });
    text
}

/// The operator's revert found no marking that agrees with the plant in its wait.
fn refuse(core: &mut Core, p: &Probation, weighed: &Weighed, waited_us: u64) {
    let projection = match &weighed.projected {
        Err(e) => format!("the projection of the new primary's marking is refused ({e})"),
        Ok(fit) => format!(
            "the projection of the new primary's marking would change {}",
            changed_outputs(core, p, *fit)
        ),
    };
    let own = changed_outputs(core, p, weighed.own);
    let message = format!(
        "revert refused: in {:.1} s no marking of {} agreed with the plant: {projection}, and the shadow's own would change {own} (drift {}); {} {} stays in control. Revert again when the cell is between moves, or accept",
        waited_us as f64 / 1e6,
        p.shadow.program().name(),
        weighed.own.drift,
        p.plan.meta.name,
        p.plan.meta.version,
    );
    core.log.push(
        EventKind::Refused,
        message,
        Some(EventDetail::Drift {
            drift: weighed.own.drift,
        }),
    );
}

/// PRIMARY flips back to the shadow, which takes over with `fit`'s marking.
fn take_over(core: &mut Core, mut p: Box<Probation>, fit: Fit, weighed: &Weighed, ask: Ask) {
    let now_us = core.log.now_us;
    let s = core.primary_slot.other();
    let name = format!("{} {}", p.plan.meta.name, p.plan.meta.version);
    let held = now_us.saturating_sub(p.started_us) as f64 / 1e6;
    let agreement = if fit.differing == 0 {
        "which agrees with the plant".to_string()
    } else {
        format!(
            "although no marking of the old program agreed with the plant: {} change (drift {})",
            changed_outputs(core, &p, fit),
            fit.drift
        )
    };
    let source = match fit.marking {
        RevertMarking::Projection => {
            format!("its marking is the projection of the new primary's, {agreement}")
        }
        RevertMarking::Shadow => {
            let projection = match &weighed.projected {
                Err(e) => format!("the projected one was refused: {e}"),
                Ok(_) => "the projected one did not agree with the plant".to_string(),
            };
            format!("it keeps its own marking, {agreement}, because {projection}")
        }
    };
    if fit.marking == RevertMarking::Projection {
        let plan = &p.plan;
        // Sized for the shadow's program when the update was prepared: cannot fail.
        let _ = p.shadow.set_state(&plan.back_marking, &plan.back_since);
        p.shadow.carry_from(
            &core.primary,
            &plan.back_latch_map,
            &plan.back_var_map,
            &plan.back_st_map,
        );
        core.router.mark_stale(s.index());
    }
    p.shadow
        .continue_edges_from(core.router.last_inputs_for(s.index()));
    core.router.drive_safe(s.index(), &mut p.plan.safe);
    let new_slot = core.primary_slot;
    core.primary_slot = s;
    let p = *p;
    let new_primary = std::mem::replace(&mut core.primary, p.shadow);
    core.retired.push(new_primary);
    core.log.push(
        EventKind::Reverted,
        format!(
            "PRIMARY = {}: reverted from {name} after {held:.1} s of probation because {} ({}); the old program drives the outputs again and {source}; {} stops",
            s.as_str(),
            ask.why,
            ask.reason.name(),
            new_slot.as_str()
        ),
        Some(EventDetail::Revert {
            reason: ask.reason,
            detected_cycle: ask.detected_cycle,
            marking: fit.marking,
            drift: fit.drift,
            outputs_differing: fit.differing,
        }),
    );
}
