//! Refused commands in the audit log: a burst of [`REFUSAL_BURST`] logged one by one, then one
//! every [`REFUSAL_EVERY_US`] of program time; the rest are counted and said in one record when
//! logging resumes, or when the writer stops. A client that sends refused commands as fast as
//! the broker lets it cannot grow the log faster than that (docs/persistence.md, *Audit log*).

/// Refusals logged one by one before the rate applies.
pub const REFUSAL_BURST: u64 = 20;

/// Program time per refusal logged one by one once the burst is spent.
pub const REFUSAL_EVERY_US: u64 = 1_000_000;

/// A token bucket in program time: no clock of its own, so that a run in virtual time logs
/// the same records every time.
#[derive(Debug)]
pub(crate) struct RefusalSampler {
    /// Program time earned and not spent, at most the burst's.
    credit_us: u64,
    /// Program time of the last refusal seen.
    last_us: u64,
    /// Refusals counted since the last one logged.
    unlogged: u64,
    /// Refusals counted in all.
    total_unlogged: u64,
}

impl Default for RefusalSampler {
    fn default() -> Self {
        RefusalSampler {
            credit_us: REFUSAL_BURST * REFUSAL_EVERY_US,
            last_us: 0,
            unlogged: 0,
            total_unlogged: 0,
        }
    }
}

impl RefusalSampler {
    /// A refusal at program time `time_us`: `Some(n)` when it is logged, `n` being the
    /// refusals counted but not logged just before it; `None` when it is only counted.
    pub(crate) fn admit(&mut self, time_us: u64) -> Option<u64> {
        let earned = time_us.saturating_sub(self.last_us);
        self.last_us = self.last_us.max(time_us);
        self.credit_us =
            (self.credit_us.saturating_add(earned)).min(REFUSAL_BURST * REFUSAL_EVERY_US);
        if self.credit_us < REFUSAL_EVERY_US {
            self.unlogged += 1;
            self.total_unlogged += 1;
            return None;
        }
        self.credit_us -= REFUSAL_EVERY_US;
        Some(std::mem::take(&mut self.unlogged))
    }

    /// The refusals counted and not said yet, now said.
    pub(crate) fn take_unlogged(&mut self) -> u64 {
        std::mem::take(&mut self.unlogged)
    }

    /// Every refusal that was counted instead of logged.
    pub(crate) fn total_unlogged(&self) -> u64 {
        self.total_unlogged
    }
}

/// The record that says how many refusals were counted rather than logged.
pub(crate) fn unlogged_record(
    n: u64,
    cycle: u64,
    time_us: u64,
    wall: std::time::SystemTime,
) -> crate::AuditRecord {
    crate::AuditRecord {
        utc: crate::rfc3339_utc(wall),
        cycle,
        time_us,
        who: "plc".into(),
        what: "refusals_not_logged".into(),
        message: format!(
            "{n} refused commands were counted, not logged one by one (more than {REFUSAL_BURST} at once, or more than one a second of program time)"
        ),
        detail: serde_json::json!({ "count": n }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_burst_is_logged_then_one_a_second_and_the_rest_is_counted() {
        let mut s = RefusalSampler::default();
        let logged: Vec<Option<u64>> = (0..25).map(|_| s.admit(0)).collect();
        assert!(logged[..20].iter().all(|&l| l == Some(0)), "{logged:?}");
        assert!(logged[20..].iter().all(|&l| l.is_none()), "{logged:?}");
        // A second later one more is logged, and says the five before it.
        assert_eq!(s.admit(1_000_000), Some(5));
        assert_eq!(s.admit(1_000_000), None);
        assert_eq!(s.total_unlogged(), 6);
        assert_eq!(s.take_unlogged(), 1);
        assert_eq!(s.take_unlogged(), 0);
    }

    #[test]
    fn a_quiet_minute_earns_back_the_whole_burst_and_no_more() {
        let mut s = RefusalSampler::default();
        (0..30).for_each(|_| {
            s.admit(0);
        });
        let logged = (0..30).filter(|_| s.admit(60_000_000).is_some()).count();
        assert_eq!(logged as u64, REFUSAL_BURST);
    }
}
