//! The small closed sets of names on the wire: containers, STATUS, roles, error codes, verdicts.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::ProtoError;

macro_rules! names {
    (
        $(#[$meta:meta])*
        $name:ident, $what:literal, $expected:literal {
            $( $(#[$vmeta:meta])* $variant:ident = $text:literal ),+ $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
        pub enum $name {
            $( $(#[$vmeta])* #[serde(rename = $text)] $variant, )+
        }

        impl $name {
            /// Every value, in declaration order.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];

            /// The name on the wire.
            pub fn as_str(self) -> &'static str {
                match self {
                    $( $name::$variant => $text, )+
                }
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.as_str())
            }
        }

        impl FromStr for $name {
            type Err = ProtoError;
            fn from_str(s: &str) -> Result<Self, ProtoError> {
                match s {
                    $( $text => Ok($name::$variant), )+
                    other => Err(ProtoError::UnknownName {
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

    /// 0 for A, 1 for B: the position in two-element payloads such as `exec_info`.
    pub fn index(self) -> usize {
        match self {
            Slot::A => 0,
            Slot::B => 1,
        }
    }
}

names! {
    /// STATUS: whether an update is under way, or the PLC is in fault.
    StatusName, "status", "idle, setup, quarantine, probation or fault" {
        /// No update under way.
        Idle = "idle",
        /// A package was accepted; the state transformation runs at the next cycle boundary.
        Setup = "setup",
        /// Both containers run; only PRIMARY's outputs are dispatched.
        Quarantine = "quarantine",
        /// The new program is PRIMARY and the old one is kept to fall back to (not published yet).
        Probation = "probation",
        /// The primary faulted: safe outputs until an operator resets.
        Fault = "fault",
    }
}

names! {
    /// A container's role in `exec_info`.
    Role, "role", "primary, candidate or shadow" {
        /// The container whose outputs are dispatched.
        Primary = "primary",
        /// The container in quarantine.
        Candidate = "candidate",
        /// The old program on probation after a substitution, its outputs withheld.
        Shadow = "shadow",
    }
}

names! {
    /// How `substitute` carries the state over.
    SubstituteMode, "substitution mode", "retransform or keep" {
        /// Map the primary's marking through the projection again (the default).
        Retransform = "retransform",
        /// Keep the candidate's marking.
        Keep = "keep",
    }
}

names! {
    /// Why a command failed: the `error.code` of a reply.
    ErrorCode, "error code",
        "malformed, too_large, unknown_verb, unauthorised, replayed, not_allowed, busy, refused or unavailable" {
        /// Not JSON, not an object, a field of the wrong type, an unknown field, bad base64.
        Malformed = "malformed",
        /// The payload is larger than [`crate::MAX_PAYLOAD`].
        TooLarge = "too_large",
        /// The topic names no known verb.
        UnknownVerb = "unknown_verb",
        /// Operator keys are configured and the command is unsigned or its signature is bad.
        Unauthorised = "unauthorised",
        /// A signed command's nonce was already used inside the replay window.
        Replayed = "replayed",
        /// The command asked for something only local configuration may grant (`allow_unsigned`).
        NotAllowed = "not_allowed",
        /// The scan thread's command queue is full; retry.
        Busy = "busy",
        /// The PLC refused the command (wrong state, bad package, ...); the message says why.
        Refused = "refused",
        /// The PLC did not answer (its scan loop is not running).
        Unavailable = "unavailable",
    }
}

names! {
    /// Where a validation verdict comes from.
    VerdictKind, "verdict kind", "analysis or twin" {
        /// Static analysis of the nets.
        Analysis = "analysis",
        /// A run against the digital twin.
        Twin = "twin",
    }
}

names! {
    /// What a validation verdict says.
    VerdictResult, "verdict result", "pass, fail or warn" {
        /// The check passed.
        Pass = "pass",
        /// The check failed.
        Fail = "fail",
        /// The check passed with reservations.
        Warn = "warn",
    }
}
