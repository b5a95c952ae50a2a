//! Timing statistics without allocation: last, min, mean, p99 and max from a log-linear histogram.

use serde::Serialize;

const SUB: usize = 16; // buckets per power of two: p99 within ~6 %
const BUCKETS: usize = 64 * SUB;

/// Running statistics of a duration in nanoseconds.
#[derive(Clone, Debug)]
pub struct TimingStats {
    last: u64,
    min: u64,
    max: u64,
    sum: u128,
    count: u64,
    hist: Box<[u32; BUCKETS]>,
}

/// A snapshot of [`TimingStats`], in nanoseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Summary {
    /// Samples recorded.
    pub count: u64,
    /// The latest sample.
    pub last_ns: u64,
    /// The smallest sample.
    pub min_ns: u64,
    /// The mean.
    pub mean_ns: u64,
    /// The median (upper edge of its histogram bucket, capped at max).
    pub p50_ns: u64,
    /// The 99th percentile (upper edge of its histogram bucket, capped at max).
    pub p99_ns: u64,
    /// The largest sample.
    pub max_ns: u64,
}

fn bucket(v: u64) -> usize {
    if v < SUB as u64 {
        return v as usize;
    }
    let log = 63 - v.leading_zeros() as usize; // ≥ 4
    let shift = log - 4;
    let mantissa = ((v >> shift) as usize) & (SUB - 1);
    ((log - 3) * SUB + mantissa).min(BUCKETS - 1)
}

fn bucket_upper(b: usize) -> u64 {
    if b < SUB {
        return b as u64;
    }
    let log = b / SUB + 3;
    let mantissa = (b % SUB) as u64;
    let shift = log - 4;
    ((SUB as u64 + mantissa + 1) << shift) - 1
}

impl Default for TimingStats {
    fn default() -> Self {
        TimingStats {
            last: 0,
            min: u64::MAX,
            max: 0,
            sum: 0,
            count: 0,
            hist: Box::new([0; BUCKETS]),
        }
    }
}

impl TimingStats {
    /// Empty statistics.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records one sample.
    #[inline]
    pub fn record(&mut self, ns: u64) {
        self.last = ns;
        self.min = self.min.min(ns);
        self.max = self.max.max(ns);
        self.sum += u128::from(ns);
        self.count += 1;
        let b = &mut self.hist[bucket(ns)];
        *b = b.saturating_add(1);
    }

    /// Adds `other`'s samples to these, as if each had been recorded here (`last` becomes
    /// `other`'s last, when it has one).
    pub fn add(&mut self, other: &TimingStats) {
        if other.count == 0 {
            return;
        }
        self.last = other.last;
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
        self.sum += other.sum;
        self.count += other.count;
        for (b, &n) in self.hist.iter_mut().zip(other.hist.iter()) {
            *b = b.saturating_add(n);
        }
    }

    /// The value below which `q` (0..=1) of the samples fall.
    pub fn quantile(&self, q: f64) -> u64 {
        if self.count == 0 {
            return 0;
        }
        let target = ((self.count as f64) * q).ceil().max(1.0) as u64;
        let mut seen = 0u64;
        for (b, &n) in self.hist.iter().enumerate() {
            seen += u64::from(n);
            if seen >= target {
                return bucket_upper(b).min(self.max).max(self.min);
            }
        }
        self.max
    }

    /// The latest sample.
    #[inline]
    pub fn summary_last(&self) -> u64 {
        self.last
    }

    /// The summary of every sample so far.
    pub fn summary(&self) -> Summary {
        if self.count == 0 {
            return Summary::default();
        }
        Summary {
            count: self.count,
            last_ns: self.last,
            min_ns: self.min,
            mean_ns: (self.sum / u128::from(self.count)) as u64,
            p50_ns: self.quantile(0.5),
            p99_ns: self.quantile(0.99),
            max_ns: self.max,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_cover_their_values() {
        for v in [0u64, 1, 15, 16, 17, 100, 1_000, 123_456, 10_000_000_000] {
            let b = bucket(v);
            assert!(bucket_upper(b) >= v, "{v} in bucket {b}");
            if b > 0 {
                assert!(bucket_upper(b - 1) < v, "{v} in bucket {b}");
            }
        }
    }

    #[test]
    fn adding_two_halves_gives_the_summary_of_the_whole() {
        let (mut whole, mut a, mut b) =
            (TimingStats::new(), TimingStats::new(), TimingStats::new());
        for v in 1..=10_000u64 {
            let x = (v * 7_919) % 10_007 * 50;
            whole.record(x);
            if v % 3 == 0 {
                a.record(x)
            } else {
                b.record(x)
            }
        }
        a.add(&b);
        a.add(&TimingStats::new());
        assert_eq!(a.summary(), whole.summary());
    }

    #[test]
    fn p99_of_a_uniform_ramp_is_within_the_bucket_precision() {
        let mut s = TimingStats::new();
        for v in 1..=10_000u64 {
            s.record(v * 100);
        }
        let p99 = s.summary().p99_ns as f64;
        assert!((p99 - 990_000.0).abs() / 990_000.0 < 0.07, "p99 = {p99}");
        assert_eq!(s.summary().min_ns, 100);
        assert_eq!(s.summary().max_ns, 1_000_000);
        assert_eq!(s.summary().mean_ns, 500_050);
    }
}
