//! Login attempts within a rate, with a share kept for those who logged in before.
//!
//! Checking a password costs an argon2 hash, so the embedded broker and the dashboard take only
//! so many attempts a second from all clients together. A limit for all together is what keeps a
//! flood of guesses from taking the machine, but alone it lets the flood lock the real operators
//! out: every token goes to the flood. So a second, smaller bucket is kept for the pairs of
//! address and account that logged in successfully before (at most [`KNOWN_LOGINS`], the oldest
//! forgotten first): when the common bucket is empty, such a pair still gets in, up to
//! [`RETURNING`] a second.
//!
//! The trade-off (docs/security.md, *Logins under a flood*): a guesser who once logged in from an
//! address, with a real account, shares the reserve with its owner; an operator on a new machine
//! or with a new account waits with the flood until it ends. Source addresses of TCP
//! connections cannot be chosen by an attacker who does not see the replies, so the reserve is
//! not open to a flood from elsewhere.

use std::collections::hash_map::RandomState;
use std::collections::VecDeque;
use std::hash::BuildHasher;
use std::net::IpAddr;
use std::time::Instant;

use cetratus_slots::rate::{Rate, TokenBucket};

/// Pairs of address and account remembered as having logged in.
pub const KNOWN_LOGINS: usize = 64;

/// Attempts a second kept for pairs that logged in before, past the common rate, and how many
/// may come at once.
pub const RETURNING: Rate = Rate {
    per_s: 2.0,
    burst: 4.0,
};

/// The rate of login attempts, and who logged in before.
#[derive(Debug)]
pub struct LoginGate {
    all: TokenBucket,
    returning: TokenBucket,
    known: VecDeque<u64>,
    keys: RandomState,
}

impl LoginGate {
    /// `rate` for everyone together, plus the reserve.
    pub fn new(rate: Rate, now: Instant) -> Self {
        LoginGate {
            all: TokenBucket::new(rate, now),
            returning: TokenBucket::new(RETURNING, now),
            known: VecDeque::with_capacity(KNOWN_LOGINS),
            keys: RandomState::new(),
        }
    }

    fn key(&self, from: Option<IpAddr>, account: &str) -> u64 {
        self.keys
            .hash_one((from.map(|a| a.to_canonical()), account))
    }

    /// Whether an attempt of `account` from `from` at `now` may be checked; takes its token,
    /// from the reserve when the common rate is spent and the pair logged in before.
    pub fn admit(&mut self, from: Option<IpAddr>, account: &str, now: Instant) -> bool {
        if self.all.take(1.0, now) {
            return true;
        }
        let key = self.key(from, account);
        self.known.contains(&key) && self.returning.take(1.0, now)
    }

    /// `account` logged in from `from`: the pair is known from now on.
    pub fn succeeded(&mut self, from: Option<IpAddr>, account: &str) {
        let key = self.key(from, account);
        if self.known.contains(&key) {
            return;
        }
        if self.known.len() >= KNOWN_LOGINS {
            self.known.pop_front();
        }
        self.known.push_back(key);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_spends_the_common_rate_and_a_returning_operator_still_gets_in() {
        let t0 = Instant::now();
        let mut g = LoginGate::new(
            Rate {
                per_s: 8.0,
                burst: 16.0,
            },
            t0,
        );
        let ops: Option<IpAddr> = Some([10, 0, 0, 1].into());
        assert!(g.admit(ops, "ops", t0));
        g.succeeded(ops, "ops");
        let flood: Option<IpAddr> = Some([10, 0, 0, 9].into());
        while g.admit(flood, "ops", t0) {}
        assert!(!g.admit(flood, "ops", t0), "the flood is held back");
        assert!(!g.admit(ops, "root", t0), "another account is not known");
        for _ in 0..RETURNING.burst as usize {
            assert!(g.admit(ops, "ops", t0), "the reserve lets the operator in");
        }
        assert!(!g.admit(ops, "ops", t0), "and is bounded too");
    }

    #[test]
    fn at_most_known_logins_pairs_are_remembered() {
        let mut g = LoginGate::new(
            Rate {
                per_s: 0.0,
                burst: 0.0,
            },
            Instant::now(),
        );
        for k in 0..=KNOWN_LOGINS {
            g.succeeded(None, &format!("a{k}"));
        }
        assert_eq!(g.known.len(), KNOWN_LOGINS);
        assert!(
            !g.admit(None, "a0", Instant::now()),
            "the oldest is forgotten"
        );
    }
}
