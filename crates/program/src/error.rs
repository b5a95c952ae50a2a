//! The one error type of the program crate.

use cetratus_net::{NetError, SourcePos};

/// Everything that can go wrong while loading a program.
#[derive(Debug, thiserror::Error)]
pub enum ProgramError {
    /// A problem in the program text, with its position (file:line:column) and what was expected.
    #[error("{pos}: {message}")]
    At {
        /// Where.
        pos: SourcePos,
        /// What is wrong and what to do.
        message: String,
    },
    /// A problem with a file as a whole (no position inside it applies).
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The net could not be read or built.
    #[error(transparent)]
    Net(#[from] NetError),
}
