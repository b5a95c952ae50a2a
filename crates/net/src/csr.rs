//! Compressed sparse rows: one contiguous buffer of entries and one offset per row.

/// A compressed sparse row table: `row(i)` is a slice, and all rows live in one allocation.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Csr<T> {
    offsets: Vec<u32>,
    items: Vec<T>,
}

impl<T: Clone> Csr<T> {
    /// Builds the table from `rows` rows of `(row, item)` pairs, keeping the pairs' order within a row.
    pub fn from_pairs(rows: usize, pairs: &[(u32, T)]) -> Self {
        let mut counts = vec![0u32; rows + 1];
        for (r, _) in pairs {
            counts[*r as usize + 1] += 1;
        }
        for i in 0..rows {
            counts[i + 1] += counts[i];
        }
        let offsets = counts.clone();
        let mut next = counts;
        let mut items: Vec<Option<T>> = vec![None; pairs.len()];
        for (r, item) in pairs {
            let slot = &mut next[*r as usize];
            items[*slot as usize] = Some(item.clone());
            *slot += 1;
        }
        Csr {
            offsets,
            items: items.into_iter().flatten().collect(),
        }
    }
}

impl<T> Csr<T> {
    /// The entries of row `i`.
    #[inline]
    pub fn row(&self, i: usize) -> &[T] {
        let a = self.offsets[i] as usize;
        let b = self.offsets[i + 1] as usize;
        &self.items[a..b]
    }

    /// The number of rows.
    pub fn rows(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// The number of entries over all rows.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// True when no row has an entry.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}
