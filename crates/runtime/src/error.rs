//! The runtime's errors: what a scan can fail with, why a command or an update is refused, and
//! why a saved state cannot be resumed. Each message says what, where, and what to do.

use cetratus_vocab::Verb;

use crate::Status;

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
    /// A scan would have passed its work budget (instructions of guards and action bodies,
    /// and firings) and was stopped midway.
    #[error("the scan was stopped at {at}, which would have taken it past its work budget of {budget} units (instructions of guards, action bodies and Structured Text, and firings); the program does more work in one scan than the PLC allows: make its scans do less (a loop that never ends is stopped here), or raise `[updates] candidate_instruction_budget` (a candidate) or `primary_instruction_budget` (the running program)")]
    WorkBudget {
        /// The budget that ran out.
        budget: u64,
        /// What was next: ``transition `T3` `` or ``action body `B` ``.
        at: String,
    },
    /// An action body failed (overflow, division by zero); the scan's firings have happened,
    /// the body's assignments before the failing statement too.
    #[error("{0}; fix the body, e.g. bound the value before the operation")]
    Body(cetratus_program::BodyError),
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

/// Why the PLC refused a command. A refused command changes nothing.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// A load while the PLC is in fault.
    #[error("load refused: the PLC is in fault; reset it first")]
    LoadInFault,
    /// A load while another update is under way.
    #[error("load refused: an update is already under way (status {status}); substitute, remove or abort it first")]
    LoadBusy {
        /// STATUS.
        status: Status,
    },
    /// A load while the previous update is on probation.
    #[error("load refused: the last update is on probation; accept or revert it first")]
    LoadInProbation,
    /// A load prepared against a program that no longer runs.
    #[error(
        "load refused: the update was prepared against another running program; load it again"
    )]
    StalePreparation,
    /// Substitute or remove with no candidate.
    #[error("{verb} refused: no candidate in quarantine (status {status})")]
    NoCandidate {
        /// `substitute` or `remove`.
        verb: &'static str,
        /// STATUS.
        status: Status,
    },
    /// A second substitution while one waits.
    #[error("substitute refused: a substitution is already waiting; abort it first")]
    SubstitutionWaiting,
    /// Abort with no update under way.
    #[error("abort refused: no update under way (status {status})")]
    NothingToAbort {
        /// STATUS.
        status: Status,
    },
    /// A substitution without a passing twin verdict while the PLC requires one.
    #[error("substitute refused: this PLC requires a passing twin verdict on the candidate, and a passing quarantine verdict when the twin recorded how the candidate diverges ([updates] require_verdict), and has {have}; wait for the `verdict` event, or remove the candidate")]
    VerdictRequired {
        /// What it has instead.
        have: &'static str,
    },
    /// Revert or accept outside probation.
    #[error("{verb} refused: no update is on probation (status {status}); {verb} applies after a substitution, while the old program runs as a shadow")]
    NotInProbation {
        /// `revert` or `accept`.
        verb: &'static str,
        /// STATUS.
        status: Status,
    },
    /// Revert or accept when the end of probation is already decided.
    #[error("{verb} refused: probation already ends at the next cycle (a revert or accept is due); wait for its event")]
    ProbationEnding {
        /// `revert` or `accept`.
        verb: &'static str,
    },
    /// A query (`exec_info`) sent as a command: it changes nothing, and its answer is read
    /// from the PLC.
    #[error("{verb} is a query, not a command: read `program_exec_info` instead")]
    Query {
        /// The verb.
        verb: Verb,
    },
    /// Reset outside the fault state.
    #[error("reset refused: the PLC is not in fault (status {status})")]
    NotInFault {
        /// STATUS.
        status: Status,
    },
}

/// Why an update package could not be prepared against the running program.
#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    /// The package did not verify or does not fit the running program.
    #[error("package refused: {0}")]
    Package(#[from] cetratus_program::PackageError),
    /// A variable of the running program's Structured Text cannot carry into the candidate.
    #[error("package refused: Structured Text variable `{variable}`: {message}")]
    StState {
        /// The variable.
        variable: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// The candidate reads an input the I/O map lacks.
    #[error("package refused: the candidate reads input `{signal}`, which the running I/O map does not provide ({available}); keep the I/O map or restart with the new program")]
    MissingInput {
        /// The input.
        signal: String,
        /// The I/O map's inputs, comma-separated.
        available: String,
    },
    /// The candidate drives an output the I/O map lacks.
    #[error("package refused: the candidate drives output `{signal}`, which the running I/O map does not have ({available})")]
    MissingOutput {
        /// The output.
        signal: String,
        /// The I/O map's outputs, comma-separated.
        available: String,
    },
    /// The candidate uses signals the I/O map lacks, and the node's I/O cannot serve them.
    #[error("package refused: the candidate uses signals that the running I/O map does not have, and the node's I/O configuration cannot serve them: {0}")]
    NewSignals(crate::io::Inadmissible),
    /// A substitution condition does not compile against the primary.
    #[error("substitute refused: the condition `{}` does not compile: {source}", excerpt(.text))]
    Condition {
        /// The condition as written.
        text: String,
        /// Why.
        source: cetratus_program::ProgramError,
    },
}

/// Why a saved state cannot be resumed by a warm start.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WarmStartError {
    /// No PRIMARY in the snapshot.
    #[error("the saved state has no PRIMARY")]
    NoPrimary,
    /// The PRIMARY container is empty in the snapshot.
    #[error("the saved state has no program in the PRIMARY container")]
    NoPrimaryProgram,
    /// The program the snapshot names is not available.
    #[error("the saved state refers to program {hash} which the state directory does not hold")]
    MissingProgram {
        /// Its hash.
        hash: String,
    },
    /// The saved marking does not fit the program.
    #[error("the saved marking has {saved} places but program {program} has {places}")]
    Shape {
        /// Places saved.
        saved: usize,
        /// The program's name.
        program: String,
        /// Its places.
        places: usize,
    },
    /// The saved marking breaks a declared invariant.
    #[error("the saved marking breaks an invariant: {0}")]
    Invariant(String),
    /// The saved state does not fit the net.
    #[error("{0}")]
    Net(String),
    /// The saved program reads an input the I/O map lacks.
    #[error("the saved program reads input `{0}` which the I/O map lacks")]
    MissingInput(String),
}

/// The start of a text quoted in a message: a condition that came over the network may be
/// megabytes long, and the reply that refuses it need not carry it back.
fn excerpt(text: &str) -> std::borrow::Cow<'_, str> {
    const SHOWN: usize = 120;
    match text.char_indices().nth(SHOWN) {
        None => text.into(),
        Some((end, _)) => format!("{}… ({} bytes in all)", &text[..end], text.len()).into(),
    }
}
