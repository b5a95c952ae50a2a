//! Persistence of the PLC's state: the state directory and the writer thread that fills it.
//!
//! A state directory holds everything a warm start needs (docs/design.md §4), in files that a crash at any
//! instant leaves consistent:
//!
//! ```text
//! DIR/state.json              the last committed PlcSnapshot: PRIMARY, STATUS, markings, timers,
//!                             retained variables and latches; replaced atomically (write a
//!                             temporary file, fsync, rename, fsync the directory)
//! DIR/programs/<hash>.toml    every program a snapshot refers to, content-addressed by
//! DIR/programs/<hash>.pnml    Program::hash_hex; written before any snapshot that names it
//! DIR/audit.jsonl             append-only log of update operations, one JSON object a line
//! DIR/lock                    held (flock) by the one process that writes the directory
//! ```
//!
//! [`StateStore`] is the directory. [`Persister`] owns one on a writer thread fed through bounded
//! channels: the scan thread offers a snapshot every few cycles with `try_send` and never waits
//! for the disk. `docs/persistence.md` derives how many scans a crash can lose.

mod audit;
mod exposure;
mod inspect;
mod sample;
mod store;
mod writer;

use std::path::Path;
use std::sync::Arc;
use std::time::SystemTime;

use cetratus_program::Program;
use cetratus_runtime::{Plc, Stopwatch, WallClock};

pub use audit::{rfc3339_utc, AuditLog, AuditRecord};
pub use exposure::{exposure, Exposure};
pub use inspect::{ContainerReport, Inspection, StoredProgram};
pub use sample::{REFUSAL_BURST, REFUSAL_EVERY_US};
pub use store::{is_program_hash, PersistFigures, StateFile, StateStore};
pub use writer::{PersistConfig, PersistStats, Persister, DEFAULT_INTERVAL_US};

/// The `format` of `state.json` this version writes and reads.
pub const STATE_FORMAT: &str = "cetratus-state/1";
pub(crate) const STATE_FILE: &str = "state.json";
pub(crate) const AUDIT_FILE: &str = "audit.jsonl";
pub(crate) const PROGRAMS_DIR: &str = "programs";
pub(crate) const LOCK_FILE: &str = "lock";

/// The largest commit number, cycle count or program time (µs) a state file may hold: 2⁵³ − 1,
/// the largest integer every JSON reader keeps exact. In program time that is 285 years; at a
/// 1 ms period as many years of cycles times a thousand. A larger one was not written by a PLC,
/// and counting on from it would wrap.
pub const MAX_COUNTER: u64 = (1 << 53) - 1;

/// Most bytes a `state.json` may have. The largest state a program can have (2²⁰ slots and
/// 4 MiB of strings of Structured Text, its markings and variables) is tens of megabytes in
/// JSON; a larger file was not written by a PLC and is refused before it is read.
pub const MAX_STATE_BYTES: u64 = 256 << 20;

/// Everything that can go wrong with a state directory (this module's own error type: the
/// scan engine's `RuntimeError` never meets a disk).
#[derive(Debug, thiserror::Error)]
pub enum PersistError {
    /// A file or directory could not be read, written or synced.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// Another process holds the state directory.
    #[error("{dir} is in use by another cetratus process (its lock file is held); stop that process, or give this one another --state-dir")]
    Locked {
        /// The directory.
        dir: String,
    },
    /// `state.json` is not valid JSON of the right shape.
    #[error("{path}: not a Cetratus state file: {reason}; start with --cold to replace it (the programs and the audit log are kept)")]
    Malformed {
        /// The file.
        path: String,
        /// What serde said.
        reason: String,
    },
    /// `state.json` is in a format this version does not read.
    #[error("{path}: state format `{found}`, but this version reads `{STATE_FORMAT}`; start with --cold to replace it")]
    Format {
        /// The file.
        path: String,
        /// The format the file gives.
        found: String,
    },
    /// A program hash is not 64 lowercase hex digits (so it cannot name a file here).
    #[error("`{hash}` is not a program hash (64 lowercase hex digits); the state file was edited or damaged")]
    BadHash {
        /// The text given.
        hash: String,
    },
    /// A program the state refers to is not in the directory.
    #[error("program {hash} is not in {dir}/programs; the state directory lost a file; start with --cold")]
    ProgramMissing {
        /// Its hash.
        hash: String,
        /// The state directory.
        dir: String,
    },
    /// A stored program does not load.
    #[error("{path}: the stored program does not load: {reason}")]
    Program {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// The saved state does not fit the program given on the command line (the I/O map).
    #[error("{dir}: cannot warm start: {reason}; start with --cold to replace the saved state")]
    WarmStart {
        /// The state directory.
        dir: String,
        /// Why.
        reason: String,
    },
    /// A counter of `state.json` is past [`MAX_COUNTER`]: counting on from it would wrap.
    #[error("{path}: {field} = {value} is past the largest value a PLC writes ({MAX_COUNTER}); the state file was edited or damaged; start with --cold to replace it (the programs and the audit log are kept)")]
    Counter {
        /// The file.
        path: String,
        /// `seq`, `cycle` or `time_us`.
        field: &'static str,
        /// What it holds.
        value: u64,
    },
    /// The state directory could be changed by someone other than the PLC's user: a snapshot
    /// written there by another would be warm-started as PRIMARY.
    #[error("{path} {why}, so another user of this machine could put a program of their own into the saved state; {fix}")]
    NotPrivate {
        /// The directory or file.
        path: String,
        /// What is wrong with it.
        why: String,
        /// What to run.
        fix: String,
    },
    /// A stored program loads, but to another hash than its name: the files were altered.
    #[error("program file {path} loads to hash {got}, not the {hash} its name says; it was altered; start with --cold")]
    ProgramMismatch {
        /// The hash its name gives.
        hash: String,
        /// The hash it loads to.
        got: String,
        /// The file.
        path: String,
    },
}

pub(crate) fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> PersistError + '_ {
    move |source| PersistError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// The machine's wall clock: the audit log is for people, in wall time.
#[derive(Clone, Copy, Debug, Default)]
pub struct SystemWallClock;

impl WallClock for SystemWallClock {
    fn now(&self) -> SystemTime {
        SystemTime::now()
    }
}

/// Starts a PLC from a state directory: a warm start from its snapshot when it has one and `cold`
/// is false, otherwise a cold start with `program`. The start-up events are left in the PLC's
/// event queue, and a cold start that replaces a saved state adds one saying so.
pub fn start(
    store: &StateStore,
    program: Arc<Program>,
    cold: bool,
    stopwatch: Box<dyn Stopwatch>,
) -> Result<Plc, PersistError> {
    let saved = if cold {
        None
    } else {
        store.load_state()?.map(|s| s.snapshot)
    };
    let Some(snap) = saved else {
        return Ok(Plc::new(program, 0, stopwatch));
    };
    // Loaded first so that a missing or altered program is reported as such, not as "absent".
    let mut found: Vec<Arc<Program>> = Vec::new();
    if let Some(p) = snap.primary {
        if let Some(cs) = &snap.containers[p.index()] {
            found.push(store.load_program(&cs.program_hash)?);
        }
    }
    Plc::warm_start(
        &snap,
        |h| found.iter().find(|p| p.hash_hex() == h).cloned(),
        program,
        stopwatch,
    )
    .map_err(|reason| PersistError::WarmStart {
        dir: store.dir().display().to_string(),
        reason: reason.to_string(),
    })
}

#[cfg(test)]
mod tests;
