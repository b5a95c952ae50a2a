//! The rate limits of the OPC UA server (docs/security.md, *OPC UA*): password checks for all
//! clients together, and new connections per address. The same token buckets as the dashboard's
//! login limiter and the broker's.

use std::collections::HashMap;
use std::net::IpAddr;
use std::time::Instant;

/// Password checks a second for all clients together, and the burst allowed above it: as the
/// dashboard's logins.
pub(crate) const LOGINS_PER_S: f64 = 4.0;
pub(crate) const LOGIN_BURST: f64 = 8.0;

/// New connections a second from one address, and the burst allowed above it.
pub(crate) const CONNECTIONS_PER_S_PER_ADDR: f64 = 4.0;
pub(crate) const CONNECTION_BURST_PER_ADDR: f64 = 16.0;

/// Addresses whose connection rate is tracked; past it, the table starts again.
const MAX_TRACKED_ADDRS: usize = 1024;

/// `rate` units a second, at most `burst` saved up.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bucket {
    tokens: f64,
    at: Instant,
    rate: f64,
    burst: f64,
}

impl Bucket {
    /// A full bucket at `now`.
    pub fn new(rate: f64, burst: f64, now: Instant) -> Bucket {
        Bucket {
            tokens: burst,
            at: now,
            rate,
            burst,
        }
    }

    /// Takes one token at `now`, or refuses.
    pub fn take(&mut self, now: Instant) -> bool {
        let dt = now.saturating_duration_since(self.at).as_secs_f64();
        self.tokens = (self.tokens + dt * self.rate).min(self.burst);
        self.at = now;
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

/// New connections per address.
pub(crate) struct PerAddress {
    buckets: HashMap<IpAddr, Bucket>,
}

impl PerAddress {
    pub fn new() -> PerAddress {
        PerAddress {
            buckets: HashMap::new(),
        }
    }

    /// Whether a connection from `from` at `now` is within its address's rate; takes its token.
    pub fn admit(&mut self, from: IpAddr, now: Instant) -> bool {
        if self.buckets.len() >= MAX_TRACKED_ADDRS && !self.buckets.contains_key(&from) {
            self.buckets.clear();
        }
        self.buckets
            .entry(from)
            .or_insert_with(|| {
                Bucket::new(CONNECTIONS_PER_S_PER_ADDR, CONNECTION_BURST_PER_ADDR, now)
            })
            .take(now)
    }
}

/// Whether `n` is worth a log line: the 1st, 2nd, 4th, 8th… occurrence.
pub(crate) fn worth_logging(n: u64) -> bool {
    n.is_power_of_two()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_burst_is_let_in_then_the_rate_and_each_address_has_its_own() {
        let t0 = Instant::now();
        let mut b = Bucket::new(LOGINS_PER_S, LOGIN_BURST, t0);
        let first = (0..20).filter(|_| b.take(t0)).count();
        assert_eq!(first, 8);
        assert!(b.take(t0 + Duration::from_millis(250)));
        assert!(!b.take(t0 + Duration::from_millis(260)));
        let mut p = PerAddress::new();
        let (a, c): (IpAddr, IpAddr) = ("10.0.0.1".parse().unwrap(), "10.0.0.2".parse().unwrap());
        let n = (0..40).filter(|_| p.admit(a, t0)).count();
        assert_eq!(n, 16);
        assert!(p.admit(c, t0), "another address has its own budget");
    }
}
