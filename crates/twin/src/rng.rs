//! The twins' pseudo-random numbers: SplitMix64, kept in this crate so that a seed gives the same
//! stream for as long as the crate exists, whatever happens to random-number crates.

/// SplitMix64 (Steele, Lea and Flood, 2014): tiny, fast, and good enough for timing jitter.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator whose stream is fixed by `seed`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A number in `0..bound` (0 when `bound` is 0), by multiply-shift rather than modulo to avoid bias
    /// towards small values.
    pub fn below(&mut self, bound: u64) -> u64 {
        if bound == 0 {
            return 0;
        }
        ((u128::from(self.next_u64()) * u128::from(bound)) >> 64) as u64
    }

    /// `base` plus a uniform extra in `0..=max_extra`; draws nothing when `max_extra` is 0, so that
    /// zero jitter leaves the stream untouched.
    pub fn jitter(&mut self, base: u64, max_extra: u64) -> u64 {
        if max_extra == 0 {
            return base;
        }
        base.saturating_add(self.below(max_extra.saturating_add(1)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix64_stream_for_seed_zero_matches_the_reference() {
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        assert_eq!(r.next_u64(), 0x06C4_5D18_8009_454F);
    }

    #[test]
    fn jitter_stays_within_its_bound() {
        let mut r = SplitMix64::new(42);
        for _ in 0..10_000 {
            let v = r.jitter(1_000, 50);
            assert!((1_000..=1_050).contains(&v));
        }
    }

    #[test]
    fn zero_jitter_draws_nothing() {
        let mut a = SplitMix64::new(7);
        let b = a.clone();
        assert_eq!(a.jitter(5, 0), 5);
        assert_eq!(a, b);
    }
}
