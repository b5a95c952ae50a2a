//! The one error type of the net crate.

use std::fmt;

/// Where in a source file something is, 1-based.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SourcePos {
    /// The file, as the user named it (may be `<memory>`).
    pub file: String,
    /// Line, from 1.
    pub line: u32,
    /// Column, from 1.
    pub column: u32,
}

impl fmt::Display for SourcePos {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}", self.file, self.line, self.column)
    }
}

/// Everything that can go wrong while building, reading or writing a net.
#[derive(Debug, thiserror::Error)]
pub enum NetError {
    /// Two nodes share an id.
    #[error(
        "duplicate id `{id}`: every place, transition and arc needs its own id; rename one of them"
    )]
    DuplicateId {
        /// The id.
        id: String,
    },
    /// An arc names a node that does not exist.
    #[error("arc `{arc}` refers to unknown node `{node}`; declare it as a place or transition, or fix the arc")]
    UnknownNode {
        /// The arc.
        arc: String,
        /// The missing node id.
        node: String,
    },
    /// An arc joins two places or two transitions.
    #[error("arc `{arc}` joins {what}; an arc must join a place and a transition")]
    BadArcEnds {
        /// The arc.
        arc: String,
        /// "two places" or "two transitions".
        what: &'static str,
    },
    /// An inhibitor arc goes from a transition to a place.
    #[error("inhibitor arc `{arc}` goes from a transition to a place; inhibitor arcs go from a place to a transition")]
    InhibitorFromTransition {
        /// The arc.
        arc: String,
    },
    /// An arc has weight zero.
    #[error("arc `{arc}` has weight 0; use a weight of at least 1 or delete the arc")]
    ZeroWeight {
        /// The arc.
        arc: String,
    },
    /// An initial marking is above its place's capacity.
    #[error("place `{place}` starts with {tokens} tokens but its capacity is {capacity}; raise the capacity or lower the initial marking")]
    InitialOverCapacity {
        /// The place.
        place: String,
        /// Its initial tokens.
        tokens: u32,
        /// Its capacity.
        capacity: u32,
    },
    /// A marking of the wrong length was given to a net.
    #[error("a marking of {got} places was given to a net of {expected} places")]
    MarkingLength {
        /// Places in the net.
        expected: usize,
        /// Entries in the marking.
        got: usize,
    },
    /// A problem in a source file, with its position.
    #[error("{pos}: {message}")]
    Syntax {
        /// Where.
        pos: SourcePos,
        /// What is wrong and what to do.
        message: String,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
}

impl NetError {
    /// Puts a position in front of an error that came from the builder while reading a file.
    pub(crate) fn at(pos: SourcePos, err: NetError) -> NetError {
        match err {
            NetError::Syntax { .. } | NetError::Io { .. } => err,
            other => NetError::Syntax {
                pos,
                message: other.to_string(),
            },
        }
    }
}
