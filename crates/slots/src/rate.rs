//! How often a server does something for its clients: token buckets for the password checks of
//! the embedded broker, the dashboard and the OPC UA server, the broker's bytes and commands, and
//! the connections and logins of one address (docs/security.md).

use std::collections::HashMap;
use std::net::IpAddr;
use std::time::Instant;

/// Addresses a [`PerAddress`] tracks; past it, the table starts again (a limit for all clients
/// together, which every server keeps beside it, still holds).
pub const TRACKED_ADDRESSES: usize = 1024;

/// So many units a second, and how many may come at once above it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rate {
    /// Units a second.
    pub per_s: f64,
    /// Units saved up at the most: the burst allowed above the rate.
    pub burst: f64,
}

/// A token bucket: [`Rate::per_s`] units a second, at most [`Rate::burst`] saved up.
#[derive(Clone, Copy, Debug)]
pub struct TokenBucket {
    tokens: f64,
    at: Instant,
    rate: Rate,
}

impl TokenBucket {
    /// A full bucket at `now`.
    pub fn new(rate: Rate, now: Instant) -> Self {
        TokenBucket {
            tokens: rate.burst,
            at: now,
            rate,
        }
    }

    /// Takes `amount` at `now`, or refuses (and takes nothing). A `now` before the last one
    /// refills nothing.
    pub fn take(&mut self, amount: f64, now: Instant) -> bool {
        let dt = now.saturating_duration_since(self.at).as_secs_f64();
        self.tokens = (self.tokens + dt * self.rate.per_s).min(self.rate.burst);
        self.at = now;
        if amount <= self.tokens {
            self.tokens -= amount;
            true
        } else {
            false
        }
    }
}

/// One [`TokenBucket`] per client address, for at most [`TRACKED_ADDRESSES`] of them.
#[derive(Debug)]
pub struct PerAddress {
    rate: Rate,
    buckets: HashMap<IpAddr, TokenBucket>,
}

impl PerAddress {
    /// `rate` for each address.
    pub fn new(rate: Rate) -> Self {
        PerAddress {
            rate,
            buckets: HashMap::new(),
        }
    }

    /// Whether one more from `from` at `now` is within its address's rate; takes its token.
    pub fn admit(&mut self, from: IpAddr, now: Instant) -> bool {
        if self.buckets.len() >= TRACKED_ADDRESSES && !self.buckets.contains_key(&from) {
            self.buckets.clear();
        }
        let rate = self.rate;
        self.buckets
            .entry(from)
            .or_insert_with(|| TokenBucket::new(rate, now))
            .take(1.0, now)
    }
}

/// Whether `n` is worth a log line: the 1st, 2nd, 4th, 8th… occurrence, so that a flood is
/// reported with its size without writing one line per refusal.
pub fn worth_logging(n: u64) -> bool {
    n.is_power_of_two()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn the_bucket_passes_a_burst_then_its_rate() {
        let t0 = Instant::now();
        let rate = Rate {
            per_s: 100.0,
            burst: 300.0,
        };
        let mut b = TokenBucket::new(rate, t0);
        assert!(b.take(300.0, t0), "the burst");
        assert!(!b.take(1.0, t0), "nothing left");
        assert!(
            !b.take(60.0, t0 + Duration::from_millis(500)),
            "50 came back, not 60"
        );
        assert!(b.take(100.0, t0 + Duration::from_secs(1)));
        // Saved up to the burst, not beyond.
        assert!(!b.take(301.0, t0 + Duration::from_secs(100)));
        assert!(b.take(300.0, t0 + Duration::from_secs(100)));
    }

    #[test]
    fn each_address_has_its_own_bucket_and_the_table_stays_bounded() {
        let t0 = Instant::now();
        let mut p = PerAddress::new(Rate {
            per_s: 4.0,
            burst: 16.0,
        });
        let (a, c): (IpAddr, IpAddr) = ("10.0.0.1".parse().unwrap(), "10.0.0.2".parse().unwrap());
        assert_eq!((0..40).filter(|_| p.admit(a, t0)).count(), 16);
        assert!(p.admit(c, t0), "another address has its own budget");
        for i in 0..3 * TRACKED_ADDRESSES as u32 {
            p.admit(IpAddr::from(i.to_be_bytes()), t0);
        }
        assert!(p.buckets.len() <= TRACKED_ADDRESSES);
    }

    #[test]
    fn logging_thins_out_as_a_flood_goes_on() {
        let logged: Vec<u64> = (1..=100).filter(|&n| worth_logging(n)).collect();
        assert_eq!(logged, [1, 2, 4, 8, 16, 32, 64]);
    }
}
