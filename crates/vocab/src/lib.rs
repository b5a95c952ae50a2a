//! The words that the runtime, the wire protocol, the control plane, the node, the command line
//! and the dashboard share, each defined once: a container ([`Slot`]), [`Status`], a container's
//! [`Role`], a verdict's [`VerdictKind`] and [`VerdictResult`], an input's [`Quality`] and its
//! device's [`LinkState`], the [`EventKind`]s and the [`SubstituteMode`]s.
//!
//! Each is a closed set of names with one spelling, the same in JSON (serde), in text
//! ([`std::fmt::Display`], [`std::str::FromStr`]) and in the docs. This crate depends on serde
//! only, so that every other crate may depend on it.

// Every public item carries a doc line (house style); the compiler keeps us honest.
#![warn(missing_docs)]

use std::fmt;

/// A name that is none of a set's: what was read, and what the set holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownName {
    /// What the name should have named (`container`, `status`, …).
    pub what: &'static str,
    /// The name read, cut to 64 characters.
    pub value: String,
    /// The names of the set, for the message.
    pub expected: &'static str,
}

impl fmt::Display for UnknownName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unknown {} `{}`; expected {}",
            self.what, self.value, self.expected
        )
    }
}

impl std::error::Error for UnknownName {}

/// Defines a closed set of names: an enum whose variants each have one spelling, with `ALL`,
/// `as_str`, `Display` (padded, so widths work), `FromStr` (its error an [`UnknownName`]) and
/// serde by that spelling.
#[macro_export]
macro_rules! names {
    (
        $(#[$meta:meta])*
        $name:ident, $what:literal, $expected:literal {
            $( $(#[$vmeta:meta])* $variant:ident = $text:literal ),+ $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
        pub enum $name {
            $( $(#[$vmeta])* #[serde(rename = $text)] $variant, )+
        }

        impl $name {
            /// Every value, in declaration order.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];

            /// The name, as written on the wire and in the docs.
            pub fn as_str(self) -> &'static str {
                match self {
                    $( $name::$variant => $text, )+
                }
            }
        }

        impl ::std::fmt::Display for $name {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.pad(self.as_str())
            }
        }

        impl ::std::str::FromStr for $name {
            type Err = $crate::UnknownName;
            fn from_str(s: &str) -> Result<Self, $crate::UnknownName> {
                match s {
                    $( $text => Ok($name::$variant), )+
                    other => Err($crate::UnknownName {
                        what: $what,
                        value: other.chars().take(64).collect(),
                        expected: $expected,
                    }),
                }
            }
        }
    };
}

names! {
    /// A program container, `"A"` or `"B"`; PRIMARY is one of them.
    Slot, "container", "A or B" {
        /// Container A (PRIMARY at boot).
        A = "A",
        /// Container B.
        B = "B",
    }
}

impl Slot {
    /// The other container.
    pub fn other(self) -> Slot {
        match self {
            Slot::A => Slot::B,
            Slot::B => Slot::A,
        }
    }

    /// 0 for A, 1 for B: the position in two-element lists such as `exec_info`.
    pub fn index(self) -> usize {
        match self {
            Slot::A => 0,
            Slot::B => 1,
        }
    }
}

names! {
    /// STATUS: whether an update is under way (docs/live-update.md), or the PLC is in fault.
    Status, "status", "idle, setup, quarantine, probation or fault" {
        /// No update under way.
        Idle = "idle",
        /// A package was accepted; the state transformation runs at the next cycle boundary.
        Setup = "setup",
        /// Both containers run; only PRIMARY's outputs are dispatched.
        Quarantine = "quarantine",
        /// The new primary runs; the old program stays resident as a shadow until the window
        /// ends.
        Probation = "probation",
        /// The primary faulted: safe outputs until an operator resets.
        Fault = "fault",
    }
}

names! {
    /// The role of a container in `program_exec_info`.
    Role, "role", "primary, candidate or shadow" {
        /// It drives the outputs.
        Primary = "primary",
        /// It runs in quarantine, its outputs withheld.
        Candidate = "candidate",
        /// The old program on probation after a substitution, its outputs withheld.
        Shadow = "shadow",
    }
}

names! {
    /// How `substitute` carries the state over.
    SubstituteMode, "substitution mode", "retransform or keep" {
        /// Recompute `ST·M_primary + ST_base` at the switch: consistent with the plant by
        /// construction (the default).
        Retransform = "retransform",
        /// Keep the candidate's own marking; only when drift is 0, unless forced.
        Keep = "keep",
    }
}

// `names!` owns the derives, and a derived `Default` needs them.
#[allow(clippy::derivable_impls)]
impl Default for SubstituteMode {
    fn default() -> Self {
        SubstituteMode::Retransform
    }
}

names! {
    /// Which validation a verdict comes from.
    VerdictKind, "verdict kind", "analysis or twin" {
        /// The analysis gate at load.
        Analysis = "analysis",
        /// A run on the digital twin.
        Twin = "twin",
    }
}

names! {
    /// What a validation verdict says.
    VerdictResult, "verdict result", "pass, fail or warn" {
        /// Passed.
        Pass = "pass",
        /// Failed.
        Fail = "fail",
        /// Passed with findings.
        Warn = "warn",
    }
}

names! {
    /// What a device's inputs are worth this cycle.
    Quality, "input quality", "initial, good, late or stale" {
        /// No complete read yet: the inputs are their safe values.
        Initial = "initial",
        /// Read in time.
        Good = "good",
        /// Missed cycles, fewer than the device's `stale_after`: the last values are used.
        Late = "late",
        /// `stale_after` cycles or more without a read: the device's stale policy applies.
        Stale = "stale",
    }
}

names! {
    /// How the connection to a device stands.
    LinkState, "link state", "connecting, up or down" {
        /// Not connected yet.
        Connecting = "connecting",
        /// Connected.
        Up = "up",
        /// Lost, or never made: retried with backoff.
        Down = "down",
    }
}

// `names!` owns the derives, and a derived `Default` needs them.
#[allow(clippy::derivable_impls)]
impl Default for LinkState {
    fn default() -> Self {
        LinkState::Connecting
    }
}

names! {
    /// What happened in the PLC: the `kind` of the `events` topic and the `what` of the audit
    /// log (docs/live-update.md lists them).
    EventKind, "event kind",
        "cold_start, warm_start, load_accepted, refused, substitute_accepted, removed, aborted, \
         reset, candidate_fault, primary_fault, update_discarded, deadlock_alarm, \
         transform_refused, state_trans_timeout, quarantine_started, substitute_timeout, \
         substituted, probation_started, accepted, reverted, stall_alarm or verdict" {
        /// A cold start: A runs the configured program from M0.
        ColdStart = "cold_start",
        /// A warm start from a saved state.
        WarmStart = "warm_start",
        /// A package was accepted; its install is due at the next cycle boundary.
        LoadAccepted = "load_accepted",
        /// A command, a transform or a substitution was refused; nothing changed.
        Refused = "refused",
        /// A substitution was accepted and waits for its cycle boundary or its condition.
        SubstituteAccepted = "substitute_accepted",
        /// The operator removed the candidate.
        Removed = "removed",
        /// The update under way was aborted.
        Aborted = "aborted",
        /// The operator left the fault state.
        Reset = "reset",
        /// The candidate faulted; the update is aborted.
        CandidateFault = "candidate_fault",
        /// The primary faulted; safe values are driven.
        PrimaryFault = "primary_fault",
        /// The update under way was discarded (primary fault, warm start).
        UpdateDiscarded = "update_discarded",
        /// The primary is deadlocked while its inputs change.
        DeadlockAlarm = "deadlock_alarm",
        /// The state transformation was refused at the install.
        TransformRefused = "transform_refused",
        /// The install took longer than stateTransTimeout.
        StateTransTimeout = "state_trans_timeout",
        /// The candidate was installed and runs in quarantine.
        QuarantineStarted = "quarantine_started",
        /// A waiting substitution was given up.
        SubstituteTimeout = "substitute_timeout",
        /// PRIMARY flipped to the candidate.
        Substituted = "substituted",
        /// The new primary runs with the old program as a shadow (probation).
        ProbationStarted = "probation_started",
        /// Probation ended; the update is final.
        Accepted = "accepted",
        /// Probation failed or was reverted; PRIMARY flipped back.
        Reverted = "reverted",
        /// The primary stalls: a watched place marked too long, or no firing too long.
        StallAlarm = "stall_alarm",
        /// A validation's verdict on an update (the analysis gate at load, a twin run).
        Verdict = "verdict",
    }
}

impl EventKind {
    /// Whether the event is an alarm that a run's summary counts as a fault.
    pub fn is_alarm(self) -> bool {
        matches!(
            self,
            EventKind::PrimaryFault | EventKind::DeadlockAlarm | EventKind::StallAlarm
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reads_back<T>(all: &[T])
    where
        T: Copy + PartialEq + std::fmt::Debug + std::fmt::Display,
        T: std::str::FromStr<Err = UnknownName> + serde::Serialize + serde::de::DeserializeOwned,
    {
        for v in all {
            let text = v.to_string();
            assert_eq!(text.parse::<T>().ok(), Some(*v));
            let json = serde_json::to_string(v).unwrap_or_default();
            assert_eq!(json, format!("\"{text}\""));
            assert_eq!(serde_json::from_str::<T>(&json).ok(), Some(*v));
        }
    }

    #[test]
    fn every_name_reads_back_as_itself_in_text_and_in_json() {
        reads_back(Slot::ALL);
        reads_back(Status::ALL);
        reads_back(Role::ALL);
        reads_back(SubstituteMode::ALL);
        reads_back(VerdictKind::ALL);
        reads_back(VerdictResult::ALL);
        reads_back(Quality::ALL);
        reads_back(LinkState::ALL);
        reads_back(EventKind::ALL);
        assert_eq!(EventKind::ALL.len(), 22);
    }

    #[test]
    fn an_unknown_name_says_what_it_should_have_been() {
        let e = "C".parse::<Slot>().err().map(|e| e.to_string());
        assert_eq!(e.as_deref(), Some("unknown container `C`; expected A or B"));
        assert!(
            format!("{:>8}", Status::Idle).ends_with("    idle"),
            "padded"
        );
    }
}
