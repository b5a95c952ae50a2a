//! The one error type of the SFC crate.

use cetratus_net::SourcePos;

/// Why a PLCopen file could not be imported.
#[derive(Debug, thiserror::Error)]
pub enum SfcError {
    /// The file is not well-formed XML, or not PLCopen TC6 XML.
    #[error("{pos}: {message}")]
    Malformed {
        /// Where.
        pos: SourcePos,
        /// What is wrong and what to do.
        message: String,
    },
    /// The file goes over a limit of the importer.
    #[error("{pos}: {message}")]
    TooLarge {
        /// Where.
        pos: SourcePos,
        /// Which limit, and what to do.
        message: String,
    },
    /// The chart breaks a rule of IEC 61131-3 SFC (two initial steps in a network, a transition
    /// with no target, an unknown jump target, …).
    #[error("{pos}: in POU `{pou}`: {message}")]
    Chart {
        /// Where.
        pos: SourcePos,
        /// The POU.
        pou: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A construct outside what Cetratus imports (an FBD condition, a macro step, ST outside the
    /// subset of docs/sfc.md, …).
    #[error("{pos}: in POU `{pou}`: {construct} is not supported: {message}")]
    Unsupported {
        /// Where.
        pos: SourcePos,
        /// The POU.
        pou: String,
        /// The construct, as a PLC engineer names it.
        construct: String,
        /// Why, and what to do instead.
        message: String,
    },
    /// Structured Text that does not parse or type-check.
    #[error("{pos}: in POU `{pou}`: {message}")]
    St {
        /// Where.
        pos: SourcePos,
        /// The POU.
        pou: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// The file holds no SFC POU of the name asked for, or several and no name was given.
    #[error("{file}: {message}")]
    Pou {
        /// The file.
        file: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// The generated program was refused by the program loader (a bug of the importer).
    #[error("{file}: the imported program does not load: {source}")]
    Program {
        /// The PLCopen file.
        file: String,
        /// The loader's error.
        source: cetratus_program::ProgramError,
    },
    /// The generated net could not be built (a bug of the importer).
    #[error("{file}: the imported net is not well-formed: {source}")]
    Net {
        /// The PLCopen file.
        file: String,
        /// The builder's error.
        source: cetratus_net::NetError,
    },
}

impl SfcError {
    /// Where in the file the error is, when it has a position.
    pub fn pos(&self) -> Option<&SourcePos> {
        match self {
            SfcError::Malformed { pos, .. }
            | SfcError::TooLarge { pos, .. }
            | SfcError::Chart { pos, .. }
            | SfcError::Unsupported { pos, .. }
            | SfcError::St { pos, .. } => Some(pos),
            _ => None,
        }
    }
}
