//! What happened in the PLC, for the event stream and the audit log.

use serde::Serialize;

use crate::updater::SubstituteMode;

pub use cetratus_vocab::EventKind;

/// Why a probation ended in a revert.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RevertReason {
    /// The new primary faulted (guard error, overflow, watchdog).
    Fault,
    /// The new primary stalled (a watched place held too long, or no firing for too long).
    Stall,
    /// The new primary broke an invariant its program declares.
    Invariant,
    /// A validation of the new primary failed.
    Verdict,
    /// The operator reverted.
    Operator,
}

impl RevertReason {
    /// The snake_case name.
    pub fn name(self) -> &'static str {
        match self {
            RevertReason::Fault => "fault",
            RevertReason::Stall => "stall",
            RevertReason::Invariant => "invariant",
            RevertReason::Verdict => "verdict",
            RevertReason::Operator => "operator",
        }
    }
}

/// Where the old program's marking came from at a revert.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RevertMarking {
    /// The projection of the new primary's marking, `Π·M + Π_base`.
    Projection,
    /// The shadow's own marking: the projected one was refused (it broke an invariant of the
    /// old program), or it did not agree with the plant and the shadow's did.
    Shadow,
}

/// Figures that go with an event.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum EventDetail {
    /// An install and its budget (stateTransTimeout).
    Install {
        /// What the install took, ns.
        install_ns: u64,
        /// stateTransTimeout, ns.
        budget_ns: u64,
    },
    /// A substitution: the drift at the switch and the mode used.
    Substitution {
        /// ‖Π·M_cand + Π_base − M_primary‖₁ at the switch.
        drift: u64,
        /// Retransform or keep.
        mode: SubstituteMode,
    },
    /// A revert: why, the cycle the cause was seen in, and where the marking came from.
    Revert {
        /// Fault, stall, invariant, verdict or operator.
        reason: RevertReason,
        /// The cycle in which the cause was seen; the revert's own cycle is the event's.
        detected_cycle: u64,
        /// Projection or shadow.
        marking: RevertMarking,
        /// ‖Π·M_new + Π_base − M_old‖₁ of the marking taken over: 0 for the projection.
        drift: u64,
        /// The outputs that changed at the revert because no marking of the old program
        /// agreed with the plant: 0 unless an automatic revert had to accept it.
        outputs_differing: u32,
    },
    /// A verdict: which validation and its result.
    Verdict {
        /// Analysis or twin.
        kind: crate::monitor::VerdictKind,
        /// Pass, warn or fail.
        result: crate::monitor::VerdictResult,
    },
    /// A stall: how long the place has been marked, or how long nothing fired, µs.
    Stall {
        /// The dwell or the time without a firing.
        waited_us: u64,
    },
    /// A probation window opened: when it ends if nothing reverts it.
    Probation {
        /// Program time at which the update becomes final, µs.
        ends_us: u64,
    },
    /// A drift that refused a substitution.
    Drift {
        /// The drift.
        drift: u64,
    },
}

/// Something that happened, for the event stream and the audit log.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Event {
    /// Cycle index at which it happened.
    pub cycle: u64,
    /// Program time in microseconds.
    pub time_us: u64,
    /// What.
    pub kind: EventKind,
    /// In words: what, why, and what to do.
    pub message: String,
    /// Figures that go with it (drift, install time, mode).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<EventDetail>,
}

/// The events of the PLC not yet drained, stamped with the current cycle and program time.
pub(crate) struct EventLog {
    events: Vec<Event>,
    pub cycle: u64,
    pub now_us: u64,
}

impl EventLog {
    pub fn new(now_us: u64) -> Self {
        EventLog {
            events: Vec::with_capacity(64),
            cycle: 0,
            now_us,
        }
    }

    pub fn push(&mut self, kind: EventKind, message: String, detail: Option<EventDetail>) {
        self.events.push(Event {
            cycle: self.cycle,
            time_us: self.now_us,
            kind,
            message,
            detail,
        });
    }

    pub fn drain(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    pub fn pending(&self) -> &[Event] {
        &self.events
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_event_serializes_as_the_events_topic_has_always_carried_it() {
        let e = Event {
            cycle: 7,
            time_us: 70_000,
            kind: EventKind::Substituted,
            message: "PRIMARY = B".into(),
            detail: Some(EventDetail::Substitution {
                drift: 0,
                mode: SubstituteMode::Retransform,
            }),
        };
        assert_eq!(
            serde_json::to_value(&e).unwrap(),
            serde_json::json!({"cycle": 7, "time_us": 70000, "kind": "substituted",
                "message": "PRIMARY = B", "detail": {"drift": 0, "mode": "retransform"}})
        );
        let plain = Event {
            detail: None,
            kind: EventKind::StateTransTimeout,
            ..e
        };
        let v = serde_json::to_value(&plain).unwrap();
        assert_eq!(v["kind"], "state_trans_timeout");
        assert!(v.get("detail").is_none());
    }

    #[test]
    fn every_kind_name_is_its_serde_name() {
        for k in EventKind::ALL {
            assert_eq!(serde_json::to_value(k).unwrap(), k.as_str());
        }
    }
}
