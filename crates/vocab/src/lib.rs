//! The words that the runtime, the wire protocol, the control plane, the node, the command line
//! and the dashboard share, each defined once: a container ([`Slot`]), [`Status`], a container's
//! [`Role`], a verdict's [`VerdictKind`] and [`VerdictResult`], an input's [`Quality`] and its
//! device's [`LinkState`], the [`EventKind`]s, the [`SubstituteMode`]s, and the command
//! [`Verb`]s with their arguments ([`Command`]). An [`Open`] name keeps what a newer peer may
//! send and this build does not know.
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

/// A closed set of names, made by [`names!`]: each value has one spelling.
pub trait Name: Copy {
    /// The name, as written on the wire and in the docs.
    fn name(self) -> &'static str;
}

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

        impl $crate::Name for $name {
            fn name(self) -> &'static str {
                self.as_str()
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
    VerdictKind, "verdict kind", "analysis, twin or quarantine" {
        /// The analysis gate at load.
        Analysis = "analysis",
        /// A run on the digital twin.
        Twin = "twin",
        /// The quarantine on the plant, compared with the twin run's divergence signature.
        Quarantine = "quarantine",
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
         substituted, probation_started, accepted, reverted, stall_alarm, verdict, \
         command_received, command_rejected or id_taken_over" {
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
        /// The control plane accepted a command and handed it to the PLC.
        CommandReceived = "command_received",
        /// The control plane turned a command down before it reached the PLC.
        CommandRejected = "command_rejected",
        /// The broker dropped the PLC's connection because another client connected with its
        /// client id: two PLCs on one broker share an id.
        IdTakenOver = "id_taken_over",
        /// The state directory cannot be written (a full disk, a lost mount): the PLC runs on,
        /// but a restart would start from the last state saved. Every snapshot due tries again.
        PersistFailed = "persist_failed",
        /// The state directory can be written again, after a `persist_failed`.
        PersistRecovered = "persist_recovered",
    }
}

impl EventKind {
    /// Whether the event is an alarm that a run's summary counts as a fault.
    pub fn is_alarm(self) -> bool {
        matches!(
            self,
            EventKind::PrimaryFault
                | EventKind::DeadlockAlarm
                | EventKind::StallAlarm
                | EventKind::PersistFailed
        )
    }
}

names! {
    /// A command verb: the last topic level under `cmd/`, the `--at` verbs of a script, the
    /// buttons of the dashboard. Declared in the order error messages list them.
    Verb, "verb", "load, remove, substitute, abort, reset, exec_info, revert or accept" {
        /// Load an update package into the secondary container.
        Load = "load",
        /// Drop the candidate in quarantine.
        Remove = "remove",
        /// Make the candidate PRIMARY.
        Substitute = "substitute",
        /// Cancel the update under way.
        Abort = "abort",
        /// Leave the fault state.
        Reset = "reset",
        /// Reply with both containers' `program_exec_info`.
        ExecInfo = "exec_info",
        /// End probation by flipping PRIMARY back to the old program.
        Revert = "revert",
        /// End probation early: the update is final.
        Accept = "accept",
    }
}

impl Verb {
    /// Whether the verb takes arguments (`load` and `substitute`); the others take none.
    pub fn takes_arguments(self) -> bool {
        matches!(self, Verb::Load | Verb::Substitute)
    }
}

/// A command: a [`Verb`] with its arguments. Each layer carries what it has of a load (`L`: the
/// package in base64 on the wire, its bytes in the control plane, a file in a script, the
/// prepared update in the runtime) and of a substitution (`S`), and maps one into the next with
/// [`Command::try_map`]; the verbs without arguments pass through unchanged, so a new one is
/// added here and the compiler names every `match` that must answer it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command<L, S> {
    /// Load an update package into the secondary container.
    Load(L),
    /// Make the candidate PRIMARY.
    Substitute(S),
    /// Drop the candidate in quarantine.
    Remove,
    /// Cancel the update under way.
    Abort,
    /// Leave the fault state.
    Reset,
    /// Reply with both containers' `program_exec_info`.
    ExecInfo,
    /// End probation by flipping PRIMARY back to the old program.
    Revert,
    /// End probation early: the update is final.
    Accept,
}

impl<L, S> Command<L, S> {
    /// The verb.
    pub fn verb(&self) -> Verb {
        match self {
            Command::Load(_) => Verb::Load,
            Command::Substitute(_) => Verb::Substitute,
            Command::Remove => Verb::Remove,
            Command::Abort => Verb::Abort,
            Command::Reset => Verb::Reset,
            Command::ExecInfo => Verb::ExecInfo,
            Command::Revert => Verb::Revert,
            Command::Accept => Verb::Accept,
        }
    }

    /// The command of a verb that takes no arguments; `None` for `load` and `substitute`.
    pub fn bare(verb: Verb) -> Option<Self> {
        Some(match verb {
            Verb::Load | Verb::Substitute => return None,
            Verb::Remove => Command::Remove,
            Verb::Abort => Command::Abort,
            Verb::Reset => Command::Reset,
            Verb::ExecInfo => Command::ExecInfo,
            Verb::Revert => Command::Revert,
            Verb::Accept => Command::Accept,
        })
    }

    /// The same command, borrowing its arguments.
    pub fn as_ref(&self) -> Command<&L, &S> {
        match self {
            Command::Load(l) => Command::Load(l),
            Command::Substitute(s) => Command::Substitute(s),
            bare => bare.unchanged(),
        }
    }

    /// The same command with its arguments converted; the first conversion that fails is the
    /// error.
    pub fn try_map<L2, S2, E>(
        self,
        load: impl FnOnce(L) -> Result<L2, E>,
        substitute: impl FnOnce(S) -> Result<S2, E>,
    ) -> Result<Command<L2, S2>, E> {
        Ok(match self {
            Command::Load(l) => Command::Load(load(l)?),
            Command::Substitute(s) => Command::Substitute(substitute(s)?),
            bare => bare.unchanged(),
        })
    }

    /// A command without arguments as a command of any argument types. Only called on one:
    /// `exec_info` stands in for the two that have arguments, which the callers take first.
    fn unchanged<L2, S2>(&self) -> Command<L2, S2> {
        Command::bare(self.verb()).unwrap_or(Command::ExecInfo)
    }
}

/// A name of an open set: one this build knows, or another, kept as it was read. A PLC of a
/// newer version may publish an event kind an older dashboard has never heard of; the reader
/// shows it as it is instead of refusing the message, so that versions can share a fleet.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Open<T> {
    /// A name of the set this build knows.
    Known(T),
    /// Any other name, as read.
    Other(String),
}

impl<T: Name> Open<T> {
    /// The name as read.
    pub fn as_str(&self) -> &str {
        match self {
            Open::Known(t) => t.name(),
            Open::Other(s) => s,
        }
    }

    /// The known name, if it is one.
    pub fn known(&self) -> Option<T> {
        match self {
            Open::Known(t) => Some(*t),
            Open::Other(_) => None,
        }
    }
}

impl<T> From<T> for Open<T> {
    fn from(t: T) -> Self {
        Open::Known(t)
    }
}

impl<T: PartialEq> PartialEq<T> for Open<T> {
    fn eq(&self, other: &T) -> bool {
        matches!(self, Open::Known(t) if t == other)
    }
}

impl<T: Name> PartialEq<str> for Open<T> {
    fn eq(&self, other: &str) -> bool {
        self.as_str() == other
    }
}

impl<T: Name> PartialEq<&str> for Open<T> {
    fn eq(&self, other: &&str) -> bool {
        self.as_str() == *other
    }
}

impl<T: fmt::Display> fmt::Display for Open<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Open::Known(t) => t.fmt(f),
            Open::Other(s) => f.pad(s),
        }
    }
}

impl<T: fmt::Display> serde::Serialize for Open<T> {
    fn serialize<Ser: serde::Serializer>(&self, s: Ser) -> Result<Ser::Ok, Ser::Error> {
        s.collect_str(self)
    }
}

impl<'de, T: std::str::FromStr> serde::Deserialize<'de> for Open<T> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        Ok(s.parse().map_or(Open::Other(s), Open::Known))
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
        reads_back(Verb::ALL);
        assert_eq!(EventKind::ALL.len(), 27);
    }

    #[test]
    fn an_open_name_keeps_what_this_build_does_not_know() {
        let known: Open<EventKind> =
            serde_json::from_str("\"substituted\"").unwrap_or(Open::Other(String::new()));
        assert_eq!(known, EventKind::Substituted);
        let newer: Open<EventKind> =
            serde_json::from_str("\"teleported\"").unwrap_or(Open::Known(EventKind::Reset));
        assert_eq!(newer, Open::Other("teleported".into()));
        assert_eq!(
            serde_json::to_string(&newer).ok().as_deref(),
            Some("\"teleported\"")
        );
        assert_eq!(
            serde_json::to_string(&known).ok().as_deref(),
            Some("\"substituted\"")
        );
    }

    #[test]
    fn every_verb_without_arguments_has_its_bare_command() {
        for &v in Verb::ALL {
            let bare = Command::<(), ()>::bare(v);
            assert_eq!(bare.is_none(), v.takes_arguments(), "{v}");
            assert!(bare.is_none_or(|c| c.verb() == v), "{v}");
        }
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
