//! Probation (docs/design.md §4): after a substitution the old program stays resident as a shadow, and
//! the Updater ends the window at a cycle boundary, by an accept (the window over, or the
//! operator's) or by a revert to the shadow, for a cause the cycle saw or the operator's.

use crate::event::{EventKind, RevertReason};
use crate::phase::{Ending, Phase};
use crate::plc::Core;
use crate::updater::Updater;

impl Updater {
    /// Probation ends at the next cycle boundary by a revert, for `reason` seen in the current
    /// cycle; a revert or accept already decided stands. Outside probation, nothing.
    /// An operator's revert still waiting for a marking that agrees with the plant gives way
    /// to an automatic one, which does not wait.
    pub(crate) fn request_revert(&mut self, core: &Core, reason: RevertReason, why: String) {
        if let Phase::Probation(p) = &mut self.phase {
            let decided = matches!(
                p.ending,
                Some(Ending::Revert { reason, .. }) if reason != RevertReason::Operator
            );
            if !decided {
                p.ending = Some(Ending::Revert {
                    reason,
                    detected_cycle: core.log.cycle,
                    why,
                    asked_us: core.log.now_us,
                });
            }
        }
    }

    /// The shadow faulted: it can no longer take over, so probation ends and the update is final.
    pub(crate) fn drop_shadow(&mut self, core: &mut Core, why: String) {
        if let Phase::Probation(p) = std::mem::replace(&mut self.phase, Phase::Idle) {
            core.retired.push(p.shadow);
        }
        core.log.push(
            EventKind::Accepted,
            format!("the shadow faulted ({why}) and stops; it cannot take over again, so the update is final"),
            None,
        );
    }

    /// Ends probation when it is due: an accept, the window over, or a revert
    /// ([`Updater::revert`], which an operator's revert may put off). Allocates nothing but the
    /// event.
    pub(crate) fn end_probation(&mut self, core: &mut Core) {
        let now_us = core.log.now_us;
        let Phase::Probation(p) = &self.phase else {
            return;
        };
        let due = p.ending.is_some() || now_us >= p.ends_us;
        if !due {
            return;
        }
        let Phase::Probation(mut p) = std::mem::replace(&mut self.phase, Phase::Idle) else {
            unreachable!("matched above");
        };
        let held = now_us.saturating_sub(p.started_us) as f64 / 1e6;
        match p.ending.take() {
            Some(Ending::Revert {
                reason,
                detected_cycle,
                why,
                asked_us,
            }) => {
                let ask = crate::revert::Ask {
                    reason,
                    detected_cycle,
                    why,
                    asked_us,
                };
                self.revert(core, p, ask);
            }
            ending => {
                let how = if ending.is_some() {
                    "accepted by the operator"
                } else {
                    "the probation window is over"
                };
                core.log.push(
                    EventKind::Accepted,
                    format!(
                        "{} {} is final ({how}, after {held:.1} s); the shadow stops",
                        p.plan.meta.name, p.plan.meta.version
                    ),
                    None,
                );
                core.retired.push(p.shadow);
            }
        }
    }
}
