//! The Monitor's ring of recent cycles for the timing diagram. Every cycle's signals are bit
//! masks as wide as the I/O map needs; the ring's storage is allocated once, when the PLC is
//! made, so recording a cycle never allocates.

use crate::mask::words_for;
use crate::{Slot, Status};

/// One cycle as the timing diagram needs it; signals as bit masks in I/O-map order (bit `i` of
/// word `i / 64` is signal `i`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CycleRecord<'a> {
    /// Cycle index.
    pub cycle: u64,
    /// Program time at the cycle's start.
    pub time_us: u64,
    /// PRIMARY during the cycle.
    pub primary: Slot,
    /// STATUS during the cycle.
    pub status: Status,
    /// Inputs.
    pub inputs: &'a [u64],
    /// Outputs of container A (`None` when empty).
    pub outputs_a: Option<&'a [u64]>,
    /// Outputs of container B (`None` when empty).
    pub outputs_b: Option<&'a [u64]>,
    /// What reached the Dispatcher.
    pub dispatched: &'a [u64],
}

#[derive(Clone, Copy, Debug)]
struct Head {
    cycle: u64,
    time_us: u64,
    primary: Slot,
    status: Status,
    a: bool,
    b: bool,
}

/// The last `capacity` cycles, oldest first.
#[derive(Clone, Debug)]
pub struct RecentCycles {
    heads: Vec<Head>,
    // Per record: inputs, outputs of A, outputs of B, dispatched.
    words: Vec<u64>,
    in_words: usize,
    out_words: usize,
    cap: usize,
    start: usize,
    len: usize,
}

impl RecentCycles {
    /// A ring of `capacity` cycles for an I/O map of `inputs` and `outputs` signals.
    pub fn new(capacity: usize, inputs: usize, outputs: usize) -> Self {
        let capacity = capacity.max(1);
        let (in_words, out_words) = (words_for(inputs), words_for(outputs));
        RecentCycles {
            heads: Vec::with_capacity(capacity),
            words: vec![0; capacity * (in_words + 3 * out_words)],
            in_words,
            out_words,
            cap: capacity,
            start: 0,
            len: 0,
        }
    }

    /// Makes room for an I/O map that grew to `inputs` and `outputs` signals, keeping the cycles
    /// held (their new signals read as off). Allocates only when a mask needs another word.
    pub(crate) fn widen(&mut self, inputs: usize, outputs: usize) {
        let (iw, ow) = (words_for(inputs), words_for(outputs));
        if iw <= self.in_words && ow <= self.out_words {
            return;
        }
        let mut wider = RecentCycles {
            heads: Vec::with_capacity(self.capacity()),
            words: vec![0; self.capacity() * (iw + 3 * ow)],
            in_words: iw,
            out_words: ow,
            cap: self.cap,
            start: 0,
            len: 0,
        };
        for r in self.iter() {
            wider.record(
                r.cycle,
                r.time_us,
                r.primary,
                r.status,
                r.inputs,
                r.outputs_a,
                r.outputs_b,
                r.dispatched,
            );
        }
        *self = wider;
    }

    fn capacity(&self) -> usize {
        self.cap
    }

    fn stride(&self) -> usize {
        self.in_words + 3 * self.out_words
    }

    /// Cycles held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// No cycle yet.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Appends a cycle, overwriting the oldest when full. Masks narrower than the ring's are
    /// zero-extended, wider ones cut.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn record(
        &mut self,
        cycle: u64,
        time_us: u64,
        primary: Slot,
        status: Status,
        inputs: &[u64],
        outputs_a: Option<&[u64]>,
        outputs_b: Option<&[u64]>,
        dispatched: &[u64],
    ) {
        let head = Head {
            cycle,
            time_us,
            primary,
            status,
            a: outputs_a.is_some(),
            b: outputs_b.is_some(),
        };
        let at = if self.len < self.capacity() {
            self.heads.push(head);
            self.len += 1;
            self.len - 1
        } else {
            let at = self.start;
            self.heads[at] = head;
            self.start = (self.start + 1) % self.capacity();
            at
        };
        let (iw, ow, stride) = (self.in_words, self.out_words, self.stride());
        let row = &mut self.words[at * stride..(at + 1) * stride];
        let (ins, rest) = row.split_at_mut(iw);
        let (a, rest) = rest.split_at_mut(ow);
        let (b, d) = rest.split_at_mut(ow);
        put(ins, inputs);
        put(a, outputs_a.unwrap_or(&[]));
        put(b, outputs_b.unwrap_or(&[]));
        put(d, dispatched);
    }

    /// The cycles, oldest first.
    pub fn iter(&self) -> impl Iterator<Item = CycleRecord<'_>> + '_ {
        (0..self.len).map(move |i| self.get(i))
    }

    /// The newest cycle.
    pub fn last(&self) -> Option<CycleRecord<'_>> {
        self.len.checked_sub(1).map(|i| self.get(i))
    }

    /// The `i`-th cycle held, oldest first (`i` below `len`).
    fn get(&self, i: usize) -> CycleRecord<'_> {
        {
            let at = (self.start + i) % self.capacity();
            let h = self.heads[at];
            let (iw, ow, stride) = (self.in_words, self.out_words, self.stride());
            let row = &self.words[at * stride..(at + 1) * stride];
            CycleRecord {
                cycle: h.cycle,
                time_us: h.time_us,
                primary: h.primary,
                status: h.status,
                inputs: &row[..iw],
                outputs_a: h.a.then(|| &row[iw..iw + ow]),
                outputs_b: h.b.then(|| &row[iw + ow..iw + 2 * ow]),
                dispatched: &row[iw + 2 * ow..],
            }
        }
    }
}

fn put(to: &mut [u64], from: &[u64]) {
    for (i, w) in to.iter_mut().enumerate() {
        *w = from.get(i).copied().unwrap_or(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ring_keeps_the_newest_cycles_with_wide_masks() {
        let mut r = RecentCycles::new(3, 130, 70);
        for c in 0..5u64 {
            let ins = [c, 0, 1 << 1];
            let outs = [0, c];
            r.record(
                c,
                c * 10,
                Slot::A,
                Status::Idle,
                &ins,
                Some(&outs),
                None,
                &outs,
            );
        }
        let got: Vec<_> = r.iter().collect();
        assert_eq!(got.len(), 3);
        assert_eq!(got[0].cycle, 2);
        assert_eq!(got[2].inputs, &[4, 0, 2]);
        assert_eq!(got[2].outputs_a, Some(&[0u64, 4][..]));
        assert_eq!(got[2].outputs_b, None);
        assert_eq!(got[2].dispatched, &[0, 4]);
    }
}
