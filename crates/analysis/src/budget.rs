//! Budgets that keep a long analysis from taking the machine: states, bytes and time, whichever
//! is reached first. The defaults keep a 2-core, 24 GB machine responsive.
//!
//! Memory is counted, not estimated: every structure that grows with the state space (packed
//! states, parents, the hash table and, while it doubles, its old copy; the SCC pass's arrays; the
//! Karp–Miller nodes) reports the bytes it holds, and a structure that would grow past the budget
//! stops the run before it allocates.
//!
//! Time comes from a [`Clock`] the caller gives: the analysis reads no clock of its own, so a test
//! can run it against a clock that moves when told.

use std::fmt;
use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;

/// States explored at most by default.
pub const DEFAULT_MAX_STATES: u64 = 50_000_000;
/// Bytes the state space may hold at most by default (4 GiB).
pub const DEFAULT_MAX_MEMORY: u64 = 4 << 30;
/// Longest run by default.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(600);

/// A monotonic clock: the time elapsed since some fixed origin (e.g. the start of the run).
pub trait Clock: Send + Sync {
    /// Time elapsed since the clock's origin.
    fn elapsed(&self) -> Duration;
}

/// A point in time on a [`Clock`] after which the analysis stops.
#[derive(Clone)]
pub struct Deadline {
    clock: Arc<dyn Clock>,
    at: Duration,
}

impl Deadline {
    /// The moment `timeout` after the clock's current reading.
    pub fn after(clock: Arc<dyn Clock>, timeout: Duration) -> Deadline {
        let at = clock.elapsed().saturating_add(timeout);
        Deadline { clock, at }
    }

    /// The deadline has passed.
    pub fn passed(&self) -> bool {
        self.clock.elapsed() >= self.at
    }
}

impl fmt::Debug for Deadline {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Deadline").field("at", &self.at).finish()
    }
}

/// Why a report is partial.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PartialReason {
    /// The state budget (`--max-states`) was reached.
    MaxStates,
    /// The memory budget (`--max-memory`) was reached.
    MaxMemory,
    /// The time budget (`--timeout`) ran out.
    Timeout,
    /// The run was cancelled (Ctrl-C).
    Cancelled,
    /// The state space could not be explored at all (see the notes).
    NotExplored,
}

impl fmt::Display for PartialReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PartialReason::MaxStates => "max_states",
            PartialReason::MaxMemory => "max_memory",
            PartialReason::Timeout => "timeout",
            PartialReason::Cancelled => "cancelled",
            PartialReason::NotExplored => "not_explored",
        })
    }
}

/// Parses a size in bytes: a whole number with an optional unit `B`, `KiB`, `MiB`, `GiB`,
/// `TiB` (powers of 1024) or `kB`, `MB`, `GB`, `TB` (powers of 1000), e.g. `4GiB`, `512MiB`.
pub fn parse_bytes(text: &str) -> Result<u64, crate::AnalysisError> {
    let t = text.trim();
    let split = t.find(|c: char| !c.is_ascii_digit()).unwrap_or(t.len());
    let (digits, unit) = t.split_at(split);
    let bad = |why: &str| crate::AnalysisError::BadSize {
        text: text.to_string(),
        why: why.to_string(),
    };
    let n: u64 = digits
        .parse()
        .map_err(|_| bad("it must start with a whole number"))?;
    let factor: u64 = match unit.trim() {
        "" | "B" => 1,
        "KiB" => 1 << 10,
        "MiB" => 1 << 20,
        "GiB" => 1 << 30,
        "TiB" => 1 << 40,
        "kB" | "KB" => 1_000,
        "MB" => 1_000_000,
        "GB" => 1_000_000_000,
        "TB" => 1_000_000_000_000,
        _ => {
            return Err(bad(
                "the unit must be B, KiB, MiB, GiB, TiB, kB, MB, GB or TB",
            ))
        }
    };
    n.checked_mul(factor)
        .ok_or_else(|| bad("it does not fit in 64 bits"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_binary_and_decimal_units_and_refuse_the_rest() {
        assert_eq!(parse_bytes("4GiB").ok(), Some(4 << 30));
        assert_eq!(parse_bytes("512 MiB").ok(), Some(512 << 20));
        assert_eq!(parse_bytes("1000").ok(), Some(1000));
        assert_eq!(parse_bytes("2MB").ok(), Some(2_000_000));
        assert!(parse_bytes("four").is_err());
        assert!(parse_bytes("4Gb").is_err());
        assert!(parse_bytes("99999999999TiB").is_err());
    }

    struct Stepping(std::sync::atomic::AtomicU64);
    impl Clock for Stepping {
        fn elapsed(&self) -> Duration {
            let ms = self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            Duration::from_millis(ms)
        }
    }

    #[test]
    fn a_deadline_passes_when_its_clock_reaches_it_and_not_before() {
        let clock = Arc::new(Stepping(Default::default()));
        let d = Deadline::after(clock, Duration::from_millis(3));
        assert!(!d.passed());
        assert!(!d.passed());
        assert!(d.passed());
    }
}
