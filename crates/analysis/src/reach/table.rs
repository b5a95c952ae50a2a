//! The store of the states seen: packed markings in an open-addressing hash table over
//! append-only chunks, so that growing never copies and a lookup touches one cache line.

use super::prefetch;

/// A chunk holds 2^16 entries.
pub(crate) const CHUNK_BITS: u32 = 16;

/// An append-only array in fixed chunks, so that growing never copies (no reallocation peak).
pub(crate) struct Chunked<T: Copy> {
    pub(crate) chunks: Vec<Vec<T>>,
    pub(crate) len: usize,
}

impl<T: Copy> Chunked<T> {
    pub(crate) fn new() -> Self {
        Chunked {
            chunks: Vec::new(),
            len: 0,
        }
    }
    #[inline(always)]
    pub(crate) fn push(&mut self, v: T) {
        if self.len & ((1 << CHUNK_BITS) - 1) == 0 {
            self.chunks.push(Vec::with_capacity(1 << CHUNK_BITS));
        }
        if let Some(c) = self.chunks.last_mut() {
            c.push(v);
        }
        self.len += 1;
    }
    #[inline(always)]
    pub(crate) fn get(&self, i: usize) -> T {
        self.chunks[i >> CHUNK_BITS][i & ((1 << CHUNK_BITS) - 1)]
    }
    pub(crate) fn bytes(&self) -> usize {
        self.chunks.len() * (1 << CHUNK_BITS) * std::mem::size_of::<T>()
    }
}

#[inline(always)]
pub(crate) fn hash<const W: usize>(k: &[u64; W]) -> u64 {
    // A multiply-xorshift mix per word: cheap and good enough for structured keys.
    let mut h = 0x243F_6A88_85A3_08D3u64;
    for &w in k {
        h = (h ^ w).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        h ^= h >> 32;
    }
    h.wrapping_mul(0xD6E8_FEB8_6659_FD93) ^ (h >> 29)
}

/// The first word of an empty slot.
pub(crate) const EMPTY: u64 = 0;

/// Set in the first word of every stored state, so that no state is [`EMPTY`].
pub(crate) const MARK: u64 = 1 << 63;

/// Open addressing over the keys themselves. Once an exploration is complete the table no longer
/// moves, and a key's slot is its id for the liveness pass (module `scc`).
pub(crate) struct Table<const W: usize> {
    pub(crate) slots: Vec<[u64; W]>,
    pub(crate) len: usize,
    /// Bytes held during the last growth, when the old and the new slots coexist.
    pub(crate) transient_bytes: usize,
    pub(crate) grows: u32,
}

impl<const W: usize> Table<W> {
    pub(crate) fn new() -> Self {
        let cap = 1 << 12;
        Table {
            slots: vec![[EMPTY; W]; cap],
            len: 0,
            transient_bytes: 0,
            grows: 0,
        }
    }

    pub(crate) fn bytes(&self) -> usize {
        self.slots.len() * 8 * W
    }

    /// Bytes held while growing to fit `n` more keys (old and new slots), or the current bytes
    /// when no growth is needed.
    pub(crate) fn bytes_to_fit(&self, n: usize) -> usize {
        let mut cap = self.slots.len();
        while (self.len + n) * 4 > cap * 3 {
            cap *= 2;
        }
        if cap == self.slots.len() {
            self.bytes()
        } else {
            (self.slots.len() + cap) * 8 * W
        }
    }

    /// Makes room for `n` more keys, so that slot positions computed now stay valid.
    #[inline(always)]
    pub(crate) fn reserve(&mut self, n: usize) {
        while (self.len + n) * 4 > self.slots.len() * 3 {
            self.grow();
        }
    }

    /// Starts loading the first slot of a key's probe sequence (a prefetch: nothing waits for
    /// it), so that the cache misses of the lookups to come overlap.
    #[inline(always)]
    pub(crate) fn touch(&self, h: u64) {
        prefetch(&self.slots[h as usize & (self.slots.len() - 1)]);
    }

    /// Inserts the key whose hash is `h`; true when it was new. Call [`Table::reserve`] first.
    #[inline(always)]
    pub(crate) fn insert_hashed(&mut self, key: &[u64; W], h: u64) -> bool {
        let mask = self.slots.len() - 1;
        let mut i = h as usize & mask;
        loop {
            let s = &self.slots[i];
            if s[0] == EMPTY {
                self.slots[i] = *key;
                self.len += 1;
                return true;
            }
            if s == key {
                return false;
            }
            i = (i + 1) & mask;
        }
    }

    /// Inserts the key; true when it was new.
    pub(crate) fn insert(&mut self, key: &[u64; W]) -> bool {
        self.reserve(1);
        self.insert_hashed(key, hash(key))
    }

    /// The slot holding the key whose hash is `h`.
    #[inline(always)]
    pub(crate) fn slot_of(&self, key: &[u64; W], h: u64) -> Option<usize> {
        let mask = self.slots.len() - 1;
        let mut i = h as usize & mask;
        loop {
            let s = &self.slots[i];
            if s[0] == EMPTY {
                return None;
            }
            if s == key {
                return Some(i);
            }
            i = (i + 1) & mask;
        }
    }

    pub(crate) fn grow(&mut self) {
        let cap = self.slots.len() * 2;
        let old = std::mem::replace(&mut self.slots, vec![[EMPTY; W]; cap]);
        // Both tables are alive here: this is the peak of the table's memory.
        self.transient_bytes = (old.len() + cap) * 8 * W;
        self.grows += 1;
        let mask = cap - 1;
        for k in old.iter() {
            if k[0] == EMPTY {
                continue;
            }
            let mut i = hash(k) as usize & mask;
            while self.slots[i][0] != EMPTY {
                i = (i + 1) & mask;
            }
            self.slots[i] = *k;
        }
    }
}
