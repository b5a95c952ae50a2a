//! A marking: tokens per place, in declaration order.

use crate::{PlaceIdx, Tokens};

/// Tokens per place, indexed by [`PlaceIdx`] (declaration order).
#[derive(Clone, Debug, PartialEq, Eq, Hash, Default)]
pub struct Marking(pub Vec<Tokens>);

impl Marking {
    /// A marking of `n` empty places.
    pub fn zeros(n: usize) -> Self {
        Marking(vec![0; n])
    }

    /// Tokens in place `p`.
    #[inline]
    pub fn get(&self, p: PlaceIdx) -> Tokens {
        self.0[p.index()]
    }

    /// The number of places.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// True for a marking of no places.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The tokens as a slice, in place order.
    pub fn as_slice(&self) -> &[Tokens] {
        &self.0
    }

    /// The total number of tokens.
    pub fn total(&self) -> u64 {
        self.0.iter().map(|&t| u64::from(t)).sum()
    }
}

impl From<Vec<Tokens>> for Marking {
    fn from(v: Vec<Tokens>) -> Self {
        Marking(v)
    }
}
