//! Budgets for the queues that other parties fill: a limit on what is queued, in bytes (or in
//! entries), shared by everything in the queue and given back when an entry is consumed.
//!
//! A queue bounded only in entries holds as many bytes as senders care to put in each entry: 256
//! commands of 1 MiB are 256 MiB that someone else decided to spend. A [`Budget`] is taken before
//! an entry is queued and travels with it as a [`Permit`]; dropping the permit (when the entry is
//! consumed) gives the bytes back. Lock-free, so the scan thread may use it.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;

#[derive(Debug)]
struct Inner {
    limit: usize,
    used: AtomicUsize,
    refused: AtomicU64,
}

/// A shared limit on what is queued; cheap to clone (all clones share the one count).
#[derive(Clone, Debug)]
pub struct Budget(Arc<Inner>);

/// A share of a [`Budget`], given back when dropped.
#[derive(Debug)]
pub struct Permit {
    budget: Arc<Inner>,
    amount: usize,
}

impl Budget {
    /// A budget of `limit` units (bytes, or entries when every entry weighs 1).
    pub fn new(limit: usize) -> Self {
        Budget(Arc::new(Inner {
            limit,
            used: AtomicUsize::new(0),
            refused: AtomicU64::new(0),
        }))
    }

    /// Takes `amount` units, or refuses (and counts the refusal) when that would pass the limit.
    pub fn try_take(&self, amount: usize) -> Option<Permit> {
        let inner = &self.0;
        let mut used = inner.used.load(Ordering::Relaxed);
        loop {
            let after = used.saturating_add(amount);
            if after > inner.limit {
                inner.refused.fetch_add(1, Ordering::Relaxed);
                return None;
            }
            match inner
                .used
                .compare_exchange_weak(used, after, Ordering::AcqRel, Ordering::Relaxed)
            {
                Ok(_) => {
                    return Some(Permit {
                        budget: self.0.clone(),
                        amount,
                    })
                }
                Err(now) => used = now,
            }
        }
    }

    /// Units taken now.
    pub fn used(&self) -> usize {
        self.0.used.load(Ordering::Acquire)
    }

    /// The limit.
    pub fn limit(&self) -> usize {
        self.0.limit
    }

    /// How many times [`Budget::try_take`] refused.
    pub fn refused(&self) -> u64 {
        self.0.refused.load(Ordering::Relaxed)
    }
}

impl Permit {
    /// Units held.
    pub fn amount(&self) -> usize {
        self.amount
    }
}

impl Drop for Permit {
    fn drop(&mut self) {
        self.budget.used.fetch_sub(self.amount, Ordering::AcqRel);
    }
}

pub use cetratus_slots::rate::worth_logging;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_budget_refuses_past_its_limit_and_gets_units_back_when_permits_drop() {
        let b = Budget::new(10);
        let p1 = b.try_take(6).expect("fits");
        assert!(b.try_take(5).is_none());
        assert_eq!(b.refused(), 1);
        let p2 = b.try_take(4).expect("fits exactly");
        assert_eq!(b.used(), 10);
        drop(p1);
        assert_eq!(b.used(), 4);
        assert!(b.try_take(6).is_some(), "the permit is dropped at once");
        drop(p2);
        assert_eq!(b.used(), 0);
    }

    #[test]
    fn an_amount_larger_than_the_limit_never_fits() {
        let b = Budget::new(10);
        assert!(b.try_take(11).is_none());
        assert!(b.try_take(usize::MAX).is_none());
        assert_eq!(b.used(), 0);
    }

    #[test]
    fn clones_share_one_count_across_threads() {
        let b = Budget::new(1000);
        let threads: Vec<_> = (0..4)
            .map(|_| {
                let b = b.clone();
                std::thread::spawn(move || {
                    (0..1000).filter_map(|_| b.try_take(1)).collect::<Vec<_>>()
                })
            })
            .collect();
        // Every permit is held until all threads are done, so no unit is handed out twice.
        let held: Vec<Vec<Permit>> = threads
            .into_iter()
            .map(|t| t.join().expect("joins"))
            .collect();
        assert_eq!(held.iter().map(Vec::len).sum::<usize>(), 1000);
        drop(held);
        assert_eq!(b.used(), 0, "every permit came back");
    }
}
