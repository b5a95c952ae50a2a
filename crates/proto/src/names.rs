//! The closed sets of names that only the wire has: the error codes of a reply. The names the
//! wire shares with the runtime (containers, STATUS, roles, verdicts, input quality, event
//! kinds, substitution modes) are `cetratus-vocab`'s, re-exported here.

use cetratus_vocab::names;

pub use cetratus_vocab::{
    EventKind, LinkState, Open, Quality, Role, Slot, Status, SubstituteMode, UnknownName,
    VerdictKind, VerdictResult,
};

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
