//! Probation (docs/design.md §4): after a substitution the old program stays resident as a shadow, and
//! the Updater ends the window at a cycle boundary, by an accept (the window over, or the
//! operator's) or by a revert to the shadow, for a cause the cycle saw or the operator's.

use crate::event::{EventDetail, EventKind, RevertMarking, RevertReason};
use crate::phase::{Ending, Phase};
use crate::plc::Core;
use crate::updater::Updater;

impl Updater {
    /// Probation ends at the next cycle boundary by a revert, for `reason` seen in the current
    /// cycle; a revert or accept already decided stands. Outside probation, nothing.
    pub(crate) fn request_revert(&mut self, core: &Core, reason: RevertReason, why: String) {
        if let Phase::Probation(p) = &mut self.phase {
            if !matches!(p.ending, Some(Ending::Revert { .. })) {
                p.ending = Some(Ending::Revert {
                    reason,
                    detected_cycle: core.log.cycle,
                    why,
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

    /// Ends probation when it is due: an accept, the window over, or a revert. A revert flips
    /// PRIMARY back to the shadow, whose marking becomes the projection of the new primary's
    /// (consistent with the plant by construction), or stays its own when the projected one is
    /// not a marking of the old program. Allocates nothing but the event.
    pub(crate) fn end_probation(&mut self, core: &mut Core) {
        let now_us = core.log.now_us;
        let Phase::Probation(p) = &self.phase else {
            return;
        };
        let due = p.ending.is_some() || now_us >= p.ends_us;
        if !due {
            return;
        }
        let Phase::Probation(p) = std::mem::replace(&mut self.phase, Phase::Idle) else {
            unreachable!("matched above");
        };
        let mut p = *p;
        let name = format!("{} {}", p.plan.meta.name, p.plan.meta.version);
        let held = now_us.saturating_sub(p.started_us) as f64 / 1e6;
        let ending = p.ending.take();
        let Some(Ending::Revert {
            reason,
            detected_cycle,
            why,
        }) = ending
        else {
            let how = if ending.is_some() {
                "accepted by the operator"
            } else {
                "the probation window is over"
            };
            core.log.push(
                EventKind::Accepted,
                format!("{name} is final ({how}, after {held:.1} s); the shadow stops"),
                None,
            );
            core.retired.push(p.shadow);
            return;
        };
        let s = core.primary_slot.other();
        let primary = &core.primary;
        let plan = &mut p.plan;
        let projected = plan
            .projection
            .apply(
                primary.marking(),
                p.shadow.program(),
                &mut plan.back_marking,
            )
            .map_err(|e| e.to_string())
            .and_then(|()| {
                plan.projection.apply_timers(
                    primary.place_since_us(),
                    &plan.back_marking,
                    now_us,
                    &mut plan.back_since,
                );
                p.shadow
                    .set_state(&plan.back_marking, &plan.back_since)
                    .map_err(|e| e.to_string())
            });
        let (marking, source) = match projected {
            Ok(()) => {
                p.shadow
                    .carry_from(primary, &plan.back_latch_map, &plan.back_var_map);
                core.router.mark_stale(s.index());
                (
                    RevertMarking::Projection,
                    "its marking is the projection of the new primary's".to_string(),
                )
            }
            Err(e) => (
                RevertMarking::Shadow,
                format!("it keeps its own marking, because the projected one was refused: {e}"),
            ),
        };
        p.shadow
            .continue_edges_from(core.router.last_inputs_for(s.index()));
        core.router.drive_safe(s.index(), &mut plan.safe);
        let new_slot = core.primary_slot;
        core.primary_slot = s;
        let new_primary = std::mem::replace(&mut core.primary, p.shadow);
        core.retired.push(new_primary);
        core.log.push(
            EventKind::Reverted,
            format!(
                "PRIMARY = {}: reverted from {name} after {held:.1} s of probation because {why} ({}); the old program drives the outputs again and {source}; {} stops",
                s.as_str(),
                reason.name(),
                new_slot.as_str()
            ),
            Some(EventDetail::Revert {
                reason,
                detected_cycle,
                marking,
            }),
        );
    }
}
