//! The one error type of the analysis crate.

/// Everything that can stop an analysis from giving an answer.
#[derive(Debug, thiserror::Error)]
pub enum AnalysisError {
    /// An integer computation left the range of `i64`; the answer would have been wrong.
    #[error("arithmetic overflow while computing {what}; the weights are too large for exact 64-bit arithmetic, so no result is given")]
    Overflow {
        /// What was being computed.
        what: &'static str,
    },
    /// A computation grew past its configured limit and was abandoned.
    #[error("{what} exceeded the limit of {limit}; raise the limit or analyse a smaller net")]
    Limit {
        /// What was being computed.
        what: &'static str,
        /// The limit that was hit.
        limit: usize,
    },
    /// The time budget ran out, or the run was cancelled, during a structural computation.
    #[error("{what} stopped when the time budget ran out or Ctrl-C was pressed")]
    Interrupted {
        /// What was being computed.
        what: &'static str,
    },
    /// A state of the net does not fit the packed encoding.
    #[error("the state vector of this net needs {bits} bits, more than the {max} the packed explorer supports")]
    StateTooWide {
        /// Bits needed.
        bits: usize,
        /// Bits supported.
        max: usize,
    },
    /// A size given on the command line could not be read.
    #[error("cannot read the size {text:?}: {why} (e.g. 4GiB, 512MiB or 1000000)")]
    BadSize {
        /// The text given.
        text: String,
        /// What is wrong with it.
        why: String,
    },
    /// A generated net could not be built.
    #[error(transparent)]
    Net(#[from] cetratus_net::NetError),
}
