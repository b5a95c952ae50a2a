//! The unit in which the cost of a scan is counted, for a budget that a candidate in quarantine
//! may not pass (docs/live-update.md, *Timing isolation*).
//!
//! One unit is one instruction of compiled code: a guard or an action body costs the length of
//! its code. The code only jumps forward, so a run executes at most that many instructions, and
//! charging the length is never less than the work done. A transition without a guard costs one
//! unit to look at, and a firing one more. Counted, not timed: a virtual run decides the same on
//! every machine, and a program cannot make a unit dearer than the instructions it is made of.

/// Work done so far in one scan, against its budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Work {
    used: u64,
    budget: u64,
}

impl Work {
    /// No work done yet, `budget` units allowed.
    #[inline]
    pub fn within(budget: u64) -> Self {
        Work { used: 0, budget }
    }

    /// No limit (the primary's scan).
    pub fn unlimited() -> Self {
        Self::within(u64::MAX)
    }

    /// Charges `units` of work about to be done: false, and nothing charged, when they would
    /// pass the budget (the work must then not be done).
    #[inline]
    pub fn charge(&mut self, units: u64) -> bool {
        match self.used.checked_add(units) {
            Some(total) if total <= self.budget => {
                self.used = total;
                true
            }
            _ => false,
        }
    }

    /// Sets the units charged so far, as code that charged them without this value reports
    /// (`jit`): never past the budget.
    #[cfg(feature = "jit")]
    #[inline]
    pub(crate) fn set_used(&mut self, used: u64) {
        self.used = used.min(self.budget);
    }

    /// Units charged so far.
    #[inline]
    pub fn used(&self) -> u64 {
        self.used
    }

    /// Units allowed in all.
    #[inline]
    pub fn budget(&self) -> u64 {
        self.budget
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_is_charged_up_to_the_budget_and_what_would_pass_it_is_not_charged() {
        let mut w = Work::within(10);
        assert!(w.charge(4));
        assert!(w.charge(6));
        assert!(!w.charge(1));
        assert_eq!(w.used(), 10);
        let mut u = Work::unlimited();
        assert!(u.charge(u64::MAX));
        assert!(!u.charge(1));
    }
}
