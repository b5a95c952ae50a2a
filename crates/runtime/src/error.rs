//! The one error type of the runtime crate.

/// What can go wrong while running a program.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    /// A guard could not be evaluated; the scan was rolled back.
    #[error("guard of transition `{transition}` failed: {message}")]
    Guard {
        /// The transition id.
        transition: String,
        /// The evaluation error.
        message: String,
    },
    /// A firing would overflow a token count; the scan was rolled back.
    #[error("firing transition `{transition}` would overflow the token count of place `{place}`")]
    Overflow {
        /// The transition id.
        transition: String,
        /// The place id.
        place: String,
    },
    /// A primary scan ran past the watchdog.
    #[error("the scan took {took_us} µs, past the watchdog of {limit_us} µs")]
    Watchdog {
        /// How long it took.
        took_us: u64,
        /// The watchdog time.
        limit_us: u64,
    },
    /// A fault injected on purpose by a test (feature `fault-injection`).
    #[error("injected fault: {0}")]
    Injected(String),
    /// The input image does not match the program's inputs.
    #[error("the input image has {got} signals but the program declares {expected}")]
    InputImage {
        /// Declared inputs.
        expected: usize,
        /// Signals given.
        got: usize,
    },
}
