//! Signal images as bit masks of any width: bit `i` of word `i / 64` is signal `i`. A mask is
//! sized once for its I/O map, and refilling it never allocates.

use cetratus_program::Value;

/// A bit per signal: set when the signal is true or a nonzero integer.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct Mask {
    words: Vec<u64>,
}

/// Words needed for `signals` bits (at least one, so that an empty map still has a mask).
pub fn words_for(signals: usize) -> usize {
    signals.div_ceil(64).max(1)
}

fn high(v: &Value) -> bool {
    matches!(v, Value::Bool(true)) || matches!(v, Value::Int(x) if *x != 0)
}

impl Mask {
    /// All clear, wide enough for `signals` signals.
    pub fn new(signals: usize) -> Self {
        Mask {
            words: vec![0; words_for(signals)],
        }
    }

    /// A mask of the given words, lowest signals first.
    pub fn from_words(words: Vec<u64>) -> Self {
        Mask { words }
    }

    /// The mask of `values`.
    pub fn of(values: &[Value]) -> Self {
        let mut m = Mask::new(values.len());
        m.set_from(values);
        m
    }

    /// Refills from `values`; the mask must be wide enough (it is, when sized for their map).
    pub fn set_from(&mut self, values: &[Value]) {
        fill(&mut self.words, values);
    }

    /// Copies `other`, which has the same width (no allocation then).
    pub fn copy_from(&mut self, other: &Mask) {
        self.words.clone_from(&other.words);
    }

    /// Signal `i`'s bit (false beyond the width).
    pub fn get(&self, i: usize) -> bool {
        self.words
            .get(i / 64)
            .is_some_and(|w| w & (1 << (i % 64)) != 0)
    }

    /// The words, lowest signals first.
    pub fn words(&self) -> &[u64] {
        &self.words
    }

    /// No bit set.
    pub fn is_clear(&self) -> bool {
        self.words.iter().all(|&w| w == 0)
    }
}

/// Fills `words` with the bits of `values` (words beyond the values are cleared).
pub(crate) fn fill(words: &mut [u64], values: &[Value]) {
    for (k, w) in words.iter_mut().enumerate() {
        let chunk = values.get(k * 64..).unwrap_or(&[]);
        *w = chunk
            .iter()
            .take(64)
            .enumerate()
            .fold(0, |acc, (i, v)| if high(v) { acc | (1 << i) } else { acc });
    }
}

/// Calls `f` with the index of every bit that differs between `a` and `b` (same width).
pub(crate) fn for_each_difference(a: &[u64], b: &[u64], mut f: impl FnMut(usize)) {
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        let mut diff = x ^ y;
        while diff != 0 {
            f(k * 64 + diff.trailing_zeros() as usize);
            diff &= diff - 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signal_200_has_its_own_bit() {
        let mut v = vec![Value::Bool(false); 200];
        v[0] = Value::Bool(true);
        v[64] = Value::Int(3);
        v[199] = Value::Bool(true);
        let m = Mask::of(&v);
        assert_eq!(m.words().len(), 4);
        assert!(m.get(0) && m.get(64) && m.get(199));
        assert!(!m.get(1) && !m.get(63) && !m.get(198) && !m.get(500));
        let mut seen = Vec::new();
        for_each_difference(m.words(), Mask::new(200).words(), |i| seen.push(i));
        assert_eq!(seen, vec![0, 64, 199]);
    }
}
