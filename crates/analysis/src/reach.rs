//! The reachability graph over bit-packed markings.
//!
//! Encoding. Every place gets a fixed field of `⌈log2(bound+1)⌉` bits, where the bound is proven
//! before exploring (a structural bound from `y·C ≤ 0`, a capacity, or the exact bound of a finished
//! Karp–Miller graph). Fields never straddle a 64-bit word and each word uses at most 63 bits, so
//! bit 63 is free: it is set in the first word of every stored state (firing never carries into
//! it), and a slot whose first word is 0 is empty, so a new table is fresh zeroed memory that
//! needs no filling. A state is `[u64; W]` for a small `W` chosen at
//! run time (the explorer is monomorphised for W = 1, 2, 4, 8, 16, 32).
//!
//! Firing is word arithmetic: enabledness is a range test `lo ≤ field ≤ hi` per place the
//! transition reads (Pre, inhibitors and capacities merged into one test), and the successor is
//! `key − sub + add` per word, exact because the bounds keep every field inside its bits.
//!
//! Storage. States are numbered in breadth-first order: a state's id is its insertion index in a
//! chunked array (no reallocation peaks), and the queue is implicit (a cursor over that array).
//! A set of keys is an open-addressing, linear-probing hash table of the keys themselves (load at
//! most 3/4), so a lookup costs one cache miss. Each state also records its BFS parent (4 bytes)
//! for the shortest deadlock witness. For the liveness pass the table also keeps the id of every
//! slot (4 bytes per slot). At Kanban N=5 that is 8 (state) + 4 (parent) + ≈13 (table) bytes per
//! state at the end, 27 at the peak (while the table doubles, both tables are alive).
//!
//! With `threads ≥ 2` the exploration is split between threads (module `par`): the table is
//! sharded by hash, each batch of states is expanded in parallel, and the new states are numbered
//! exactly as the sequential explorer numbers them.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use cetratus_net::{Net, PlaceIdx, TransIdx};

use crate::budget::{Deadline, PartialReason};
use crate::{AnalysisError, Progress, ProgressFn};

mod par;
mod scc;
mod table;

use table::{hash, Chunked, Table, CHUNK_BITS, MARK};
pub(crate) mod search;
pub(crate) mod stubborn;

/// Bits a state may use at most in the packed explorer.
pub const MAX_BITS: usize = 32 * 63;

/// Where one place lives in a packed state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Field {
    /// Word index.
    pub word: u32,
    /// Bit offset in the word.
    pub shift: u32,
    /// Mask of the field's width, not shifted.
    pub mask: u64,
}

impl Field {
    /// This field's value in the packed state `key`.
    #[inline(always)]
    pub(crate) fn read(&self, key: &[u64]) -> u64 {
        (key[self.word as usize] >> self.shift) & self.mask
    }
}

/// Raises each of `max` to its field's value in the packed state `key` (the bounds seen).
#[inline(always)]
fn observe(max: &mut [u64], fields: &[Field], key: &[u64]) {
    for (m, f) in max.iter_mut().zip(fields) {
        *m = (*m).max(f.read(key));
    }
}

/// The layout of packed states: one field per place.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Packing {
    /// Fields in place order.
    pub fields: Vec<Field>,
    /// Words per state.
    pub words: usize,
    /// Bits used in total.
    pub bits: usize,
}

impl Packing {
    /// A layout for places whose token counts never exceed `bounds`.
    pub fn new(bounds: &[u64]) -> Packing {
        let mut fields = Vec::with_capacity(bounds.len());
        let (mut word, mut used, mut bits) = (0u32, 0u32, 0usize);
        for &b in bounds {
            let width = 64 - b.leading_zeros();
            if used + width > 63 {
                word += 1;
                used = 0;
            }
            let mask = if width == 0 {
                0
            } else {
                u64::MAX >> (64 - width)
            };
            fields.push(Field {
                word,
                shift: used,
                mask,
            });
            used += width;
            bits += width as usize;
        }
        Packing {
            fields,
            words: word as usize + 1,
            bits,
        }
    }

    /// Packs a marking.
    pub fn encode(&self, m: &[u32], out: &mut [u64]) {
        out.iter_mut().for_each(|w| *w = 0);
        for (f, &v) in self.fields.iter().zip(m) {
            out[f.word as usize] |= (u64::from(v) & f.mask) << f.shift;
        }
    }

    /// Unpacks a state.
    pub fn decode(&self, key: &[u64], out: &mut [u32]) {
        for (f, o) in self.fields.iter().zip(out.iter_mut()) {
            *o = f.read(key) as u32;
        }
    }
}

/// Why an exploration stopped before it was complete.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Stop {
    /// `max_states` states were discovered.
    MaxStates(u64),
    /// Going on would have held more than `max_memory` bytes.
    MaxMemory(u64),
    /// The deadline passed.
    Timeout,
    /// The cancel flag was set.
    Cancelled,
}

impl Stop {
    /// The report's name for this stop.
    pub fn reason(&self) -> PartialReason {
        match self {
            Stop::MaxStates(_) => PartialReason::MaxStates,
            Stop::MaxMemory(_) => PartialReason::MaxMemory,
            Stop::Timeout => PartialReason::Timeout,
            Stop::Cancelled => PartialReason::Cancelled,
        }
    }
}

/// Options of one exploration.
#[derive(Clone, Default)]
pub struct ReachOptions {
    /// Stop after discovering this many states (`None`: only the ids' range limits them).
    pub max_states: Option<u64>,
    /// Stop before the store would hold more than this many bytes (`None`: no limit).
    pub max_memory: Option<u64>,
    /// Stop once this deadline has passed (checked every few thousand states).
    pub deadline: Option<Deadline>,
    /// Stop when this flag becomes true (checked every few thousand states).
    pub cancel: Option<Arc<AtomicBool>>,
    /// Called every few thousand states with the counts so far.
    pub progress: Option<ProgressFn>,
    /// Compute terminal SCCs, liveness and reversibility after a complete exploration.
    pub liveness: bool,
    /// Threads of the exploration: 0 or 1 run the sequential explorer, 2 or more the parallel one
    /// (same states, ids, counts and witness; more memory per state).
    pub threads: usize,
    /// With 2 or more `threads`: the states found on one thread before the exploration goes on
    /// with `threads` (0: with `threads` from the start). Two threads pay only on large state
    /// spaces (docs/analysis.md, "The default thread count").
    pub parallel_from: u64,
    /// With `parallel_from` > 0: asked once, when the exploration reaches `parallel_from` states,
    /// whether to go on with `threads` (e.g. whether a core has stayed idle meanwhile); false
    /// goes on with one. `None`: always hand over.
    pub spare_core: Option<SpareCoreFn>,
}

/// Whether a core is free for more threads now (see [`ReachOptions::spare_core`]).
pub type SpareCoreFn = Arc<dyn Fn() -> bool + Send + Sync>;

impl ReachOptions {
    /// The number of states a search may discover: `max_states`, within the range of the
    /// 32-bit state ids.
    pub(crate) fn state_limit(&self) -> u64 {
        self.max_states
            .unwrap_or(u64::from(u32::MAX - 1))
            .min(u64::from(u32::MAX - 1))
    }

    /// Why to stop now: cancellation or time (states and bytes are checked where they grow).
    pub fn interrupted(&self) -> Option<Stop> {
        if self
            .cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
        {
            return Some(Stop::Cancelled);
        }
        if self.deadline.as_ref().is_some_and(Deadline::passed) {
            return Some(Stop::Timeout);
        }
        None
    }

    /// `Err` when holding `bytes` would break the memory budget.
    pub fn within_memory(&self, bytes: usize) -> Result<(), Stop> {
        match self.max_memory {
            Some(m) if bytes as u64 > m => Err(Stop::MaxMemory(m)),
            _ => Ok(()),
        }
    }
}

/// What the terminal strongly connected components say.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Liveness {
    /// Strongly connected components of the reachability graph.
    pub sccs: u64,
    /// Terminal ones (no edge leaves them).
    pub terminal_sccs: u64,
    /// Every transition occurs in every terminal SCC (for a bounded net: the net is live).
    pub live: bool,
    /// Transitions missing from some terminal SCC.
    pub non_live: Vec<TransIdx>,
    /// M0 is a home state: its SCC is the only terminal one.
    pub reversible: bool,
}

/// The result of a packed exploration.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReachResult {
    /// States discovered.
    pub states: u64,
    /// Edges from the expanded states (one per enabled transition per state).
    pub edges: u64,
    /// Expanded states with no enabled transition.
    pub deadlocks: u64,
    /// A shortest firing sequence from M0 to a dead state.
    pub deadlock_witness: Option<Vec<TransIdx>>,
    /// The largest count seen in each place.
    pub max_tokens: Vec<u32>,
    /// Transitions enabled in no expanded state.
    pub never_enabled: Vec<TransIdx>,
    /// Why it stopped early, if it did.
    pub stopped: Option<Stop>,
    /// SCC results, when asked for and the exploration was complete.
    pub liveness: Option<Liveness>,
    /// Why liveness and reversibility were not decided although the exploration was complete.
    pub liveness_stopped: Option<Stop>,
    /// Bytes held by the state store at its largest (states, parents, hash table).
    pub peak_bytes: usize,
    /// Bits per packed state.
    pub bits_per_state: usize,
}

#[derive(Clone, Copy, Debug)]
struct Test {
    word: u32,
    shift: u32,
    mask: u64,
    lo: u64,
    hi: u64,
}

struct Compiled<const W: usize> {
    tests: Vec<Test>,
    offsets: Vec<u32>,
    /// Per transition, the field ranges in which undoing it stays inside every field.
    rtests: Vec<Test>,
    roffsets: Vec<u32>,
    sub: Vec<[u64; W]>,
    add: Vec<[u64; W]>,
}

impl<const W: usize> Compiled<W> {
    fn new(net: &Net, pk: &Packing) -> Self {
        let nt = net.num_transitions();
        let mut tests = Vec::new();
        let mut offsets = vec![0u32];
        let (mut rtests, mut roffsets) = (Vec::new(), vec![0u32]);
        let mut sub = vec![[0u64; W]; nt];
        let mut add = vec![[0u64; W]; nt];
        for ti in 0..nt {
            let t = TransIdx(ti as u32);
            let mut per: Vec<(PlaceIdx, u64, u64)> = Vec::new();
            let mut bound = |p: PlaceIdx, lo: u64, hi: u64| match per.iter_mut().find(|e| e.0 == p)
            {
                Some(e) => {
                    e.1 = e.1.max(lo);
                    e.2 = e.2.min(hi);
                }
                None => per.push((p, lo, hi)),
            };
            for &(p, w) in net.pre(t) {
                bound(p, u64::from(w), u64::MAX);
            }
            for &(p, w) in net.inhibitors(t) {
                // M[p] < w; w ≥ 1 is guaranteed by the net.
                bound(p, 0, u64::from(w) - 1);
            }
            for &(p, d) in net.delta(t) {
                if let (Some(cap), true) = (net.capacity(p), d > 0) {
                    let hi = i64::from(cap) - d;
                    if hi < 0 {
                        bound(p, 1, 0);
                    } else {
                        bound(p, 0, hi as u64);
                    }
                }
                let f = pk.fields[p.index()];
                let (lo, hi) = if d > 0 {
                    (d as u64, f.mask)
                } else {
                    match f.mask.checked_sub(d.unsigned_abs()) {
                        Some(hi) => (0, hi),
                        None => (1, 0),
                    }
                };
                rtests.push(Test {
                    word: f.word,
                    shift: f.shift,
                    mask: f.mask,
                    lo,
                    hi,
                });
                let amount = (d.unsigned_abs()) << f.shift;
                if d > 0 {
                    add[ti][f.word as usize] += amount;
                } else {
                    sub[ti][f.word as usize] += amount;
                }
            }
            for (p, lo, hi) in per {
                let f = pk.fields[p.index()];
                tests.push(Test {
                    word: f.word,
                    shift: f.shift,
                    mask: f.mask,
                    lo,
                    hi,
                });
            }
            offsets.push(tests.len() as u32);
            roffsets.push(rtests.len() as u32);
        }
        Compiled {
            tests,
            offsets,
            rtests,
            roffsets,
            sub,
            add,
        }
    }

    /// The number of transitions.
    fn transitions(&self) -> usize {
        self.offsets.len() - 1
    }

    #[inline(always)]
    fn enabled(&self, key: &[u64; W], t: usize) -> bool {
        let a = self.offsets[t] as usize;
        let b = self.offsets[t + 1] as usize;
        self.tests[a..b].iter().all(|x| {
            let v = (key[x.word as usize] >> x.shift) & x.mask;
            v >= x.lo && v <= x.hi
        })
    }

    /// Whether `key` passes every test of `tests`, all of them evaluated (no branch per test,
    /// whose outcome would be random from one key to the next).
    #[inline(always)]
    fn passes(tests: &[Test], key: &[u64; W]) -> bool {
        tests.iter().fold(true, |ok, x| {
            let v = (key[x.word as usize] >> x.shift) & x.mask;
            ok & (v >= x.lo) & (v <= x.hi)
        })
    }

    /// [`Compiled::unfire`] without a branch on the outcome: the state from which firing `t`
    /// gives `key`, and whether it exists (when not, the state returned means nothing).
    #[inline(always)]
    fn unfire_unchecked(&self, key: &[u64; W], t: usize) -> ([u64; W], bool) {
        let (a, b) = (self.roffsets[t] as usize, self.roffsets[t + 1] as usize);
        let inside = Self::passes(&self.rtests[a..b], key);
        let mut out = *key;
        let (s, ad) = (&self.sub[t], &self.add[t]);
        for i in 0..W {
            out[i] = out[i].wrapping_sub(ad[i]).wrapping_add(s[i]);
        }
        let (a, b) = (self.offsets[t] as usize, self.offsets[t + 1] as usize);
        (out, inside & Self::passes(&self.tests[a..b], &out))
    }

    /// The state from which firing `t` gives `key`, if `t` is enabled there.
    #[inline(always)]
    fn unfire(&self, key: &[u64; W], t: usize) -> Option<[u64; W]> {
        let a = self.roffsets[t] as usize;
        let b = self.roffsets[t + 1] as usize;
        let inside = self.rtests[a..b].iter().all(|x| {
            let v = (key[x.word as usize] >> x.shift) & x.mask;
            v >= x.lo && v <= x.hi
        });
        if !inside {
            return None;
        }
        let mut out = *key;
        let (s, ad) = (&self.sub[t], &self.add[t]);
        for i in 0..W {
            out[i] = out[i].wrapping_sub(ad[i]).wrapping_add(s[i]);
        }
        self.enabled(&out, t).then_some(out)
    }

    #[inline(always)]
    fn fire(&self, key: &[u64; W], t: usize) -> [u64; W] {
        let mut out = *key;
        let (s, a) = (&self.sub[t], &self.add[t]);
        for i in 0..W {
            out[i] = out[i].wrapping_sub(s[i]).wrapping_add(a[i]);
        }
        out
    }
}

/// Asks the CPU to start loading the cache line of `p`, without waiting for it.
#[allow(unsafe_code)]
#[inline(always)]
pub(super) fn prefetch<T>(p: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint that never faults and changes nothing the program computes;
    // `p` is a valid reference besides.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>((p as *const T).cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    std::hint::black_box(p);
}

/// States whose successors the exploration generates and starts loading ahead of their turn.
const AHEAD: usize = 4;

/// Explores the reachability graph of `net` with states packed by `packing`, whose field widths
/// must hold every reachable marking (see the module documentation).
pub fn explore(
    net: &Net,
    packing: &Packing,
    opts: &ReachOptions,
) -> Result<ReachResult, AnalysisError> {
    match packing.words {
        1 => Ok(explore_w::<1>(net, packing, opts)),
        2 => Ok(explore_w::<2>(net, packing, opts)),
        3..=4 => Ok(explore_w::<4>(net, packing, opts)),
        5..=8 => Ok(explore_w::<8>(net, packing, opts)),
        9..=16 => Ok(explore_w::<16>(net, packing, opts)),
        17..=32 => Ok(explore_w::<32>(net, packing, opts)),
        _ => Err(AnalysisError::StateTooWide {
            bits: packing.bits,
            max: MAX_BITS,
        }),
    }
}

/// The property-directed search (module `search`) with states packed by `packing`.
pub(crate) fn search(
    net: &Net,
    packing: &Packing,
    target: &search::Target<'_>,
    stubborn: Option<&stubborn::Stubborn>,
    after: search::After,
    opts: &ReachOptions,
) -> Result<search::Outcome, AnalysisError> {
    let (t, s, a, o) = (target, stubborn, after, opts);
    match packing.words {
        1 => Ok(search::search::<1>(net, packing, t, s, a, o)),
        2 => Ok(search::search::<2>(net, packing, t, s, a, o)),
        3..=4 => Ok(search::search::<4>(net, packing, t, s, a, o)),
        5..=8 => Ok(search::search::<8>(net, packing, t, s, a, o)),
        9..=16 => Ok(search::search::<16>(net, packing, t, s, a, o)),
        17..=32 => Ok(search::search::<32>(net, packing, t, s, a, o)),
        _ => Err(AnalysisError::StateTooWide {
            bits: packing.bits,
            max: MAX_BITS,
        }),
    }
}

/// M0 alone, packed and marked as stored: the states by id and each state's BFS parent.
fn seed<const W: usize>(net: &Net, pk: &Packing) -> (Chunked<[u64; W]>, Chunked<u32>) {
    let mut states: Chunked<[u64; W]> = Chunked::new();
    let mut parents: Chunked<u32> = Chunked::new();
    let mut k0 = [0u64; W];
    pk.encode(net.initial_marking().as_slice(), &mut k0);
    k0[0] |= MARK;
    states.push(k0);
    parents.push(u32::MAX);
    (states, parents)
}

/// The states of a one-thread search: the set of keys, the states by id (breadth-first order)
/// and each state's BFS parent.
struct Store<const W: usize> {
    table: Table<W>,
    states: Chunked<[u64; W]>,
    parents: Chunked<u32>,
}

/// What [`Store::add`] did with a successor.
enum Added {
    /// It is a new state, numbered next.
    New,
    /// It was found before.
    Known,
    /// It is new, but the search may hold no more states.
    Full,
}

impl<const W: usize> Store<W> {
    /// A store holding M0 alone, and M0 packed.
    fn seeded(net: &Net, pk: &Packing) -> (Store<W>, [u64; W]) {
        let (states, parents) = seed::<W>(net, pk);
        let k0 = states.get(0);
        let mut table = Table::<W>::new();
        table.insert(&k0);
        let store = Store {
            table,
            states,
            parents,
        };
        (store, k0)
    }

    /// The bytes held now.
    fn bytes(&self) -> usize {
        self.table.bytes() + self.states.bytes() + self.parents.bytes()
    }

    /// The bytes held once `n` new states are added: the table (old and new while it doubles),
    /// the states and their parents, and the chunks that the new states may open.
    fn bytes_to_add(&self, n: usize) -> usize {
        let chunk_bytes = (1 << CHUNK_BITS) * (8 * W + 4);
        self.table.bytes_to_fit(n)
            + self.states.bytes()
            + self.parents.bytes()
            + if (self.states.len & ((1 << CHUNK_BITS) - 1)) + n >= 1 << CHUNK_BITS {
                chunk_bytes
            } else {
                0
            }
    }

    /// Adds `succ`, whose hash is `h`, as a successor of state `parent` unless it is known. A
    /// new state past `max_states` is not numbered: the run is partial from there. Call
    /// [`Table::reserve`] first.
    #[inline(always)]
    fn add(&mut self, succ: &[u64; W], h: u64, parent: usize, max_states: u64) -> Added {
        if !self.table.insert_hashed(succ, h) {
            return Added::Known;
        }
        if self.states.len as u64 >= max_states {
            return Added::Full;
        }
        self.states.push(*succ);
        self.parents.push(parent as u32);
        Added::New
    }

    /// Every 16,384 expanded states of a search: why it must stop (its deadline, Ctrl-C), or
    /// else a progress report.
    #[inline]
    fn checkpoint(&self, opts: &ReachOptions, expanded: usize, edges: u64) -> Option<Stop> {
        if expanded & 0x3FFF != 0 || expanded == 0 {
            return None;
        }
        if let Some(s) = opts.interrupted() {
            return Some(s);
        }
        if let Some(p) = &opts.progress {
            p(Progress {
                states: self.states.len as u64,
                edges,
                expanded: expanded as u64,
                bytes: self.bytes() as u64,
            });
        }
        None
    }
}

/// What the states expanded so far have shown.
struct Counts {
    edges: u64,
    deadlocks: u64,
    /// The first dead state, for the shortest deadlock witness.
    first_dead: Option<usize>,
    enabled_ever: Vec<bool>,
    /// The largest value of each field in the states found.
    max_fields: Vec<u64>,
    /// Bytes held at the peak.
    peak_bytes: usize,
}

impl Counts {
    /// The counts before any state is expanded, M0 (`k0`) found.
    fn new<const W: usize>(nt: usize, pk: &Packing, k0: &[u64; W]) -> Counts {
        let mut max_fields = vec![0; pk.fields.len()];
        observe(&mut max_fields, &pk.fields, k0);
        Counts {
            edges: 0,
            deadlocks: 0,
            first_dead: None,
            enabled_ever: vec![false; nt],
            max_fields,
            peak_bytes: 0,
        }
    }
}

/// Where an exploration stands: the states found so far with their parents, the next state to
/// expand, and the counts of the states expanded before it.
struct Progressed<const W: usize> {
    states: Chunked<[u64; W]>,
    parents: Chunked<u32>,
    cur: usize,
    counts: Counts,
}

impl<const W: usize> Progressed<W> {
    /// The result of the exploration that ended here (early when `stopped` says why), over the
    /// finished set of states `visited`. The states and parents are freed before the liveness
    /// pass, which runs when asked for and the exploration is complete.
    fn finish(
        self,
        code: &Compiled<W>,
        pk: &Packing,
        stopped: Option<Stop>,
        visited: &impl scc::Visited<W>,
        opts: &ReachOptions,
    ) -> ReachResult {
        let Progressed {
            states,
            parents,
            counts: c,
            ..
        } = self;
        let nt = c.enabled_ever.len();
        let peak_bytes = c
            .peak_bytes
            .max(visited.bytes() + states.bytes() + parents.bytes());
        let deadlock_witness = c
            .first_dead
            .map(|d| search::path_to(code, &states, &parents, d, nt));
        let (n, k0) = (states.len, states.get(0));
        drop((states, parents));
        let never_enabled: Vec<TransIdx> = (0..nt)
            .filter(|&t| !c.enabled_ever[t])
            .map(|t| TransIdx(t as u32))
            .collect();
        let (liveness, liveness_stopped, scc_bytes) = if opts.liveness && stopped.is_none() {
            scc::liveness(code, visited, &k0, n, &never_enabled, opts)
        } else {
            (None, None, 0)
        };
        ReachResult {
            states: n as u64,
            edges: c.edges,
            deadlocks: c.deadlocks,
            deadlock_witness,
            max_tokens: c.max_fields.iter().map(|&m| m as u32).collect(),
            never_enabled,
            stopped,
            liveness,
            liveness_stopped,
            peak_bytes: peak_bytes.max(scc_bytes),
            bits_per_state: pk.bits,
        }
    }
}

/// The successors of the states being expanded next, at most [`AHEAD`] of them, generated and
/// their slots loading before the current state's inserts wait for their own: the cache misses
/// of several states overlap.
struct Ahead<const W: usize> {
    ring: Vec<Vec<([u64; W], u64)>>,
    /// The states whose successors the ring holds: `cur..prepared`.
    prepared: usize,
}

impl<const W: usize> Ahead<W> {
    /// An empty ring, each slot with room for the successors of one state.
    fn new(nt: usize) -> Self {
        Ahead {
            ring: (0..AHEAD).map(|_| Vec::with_capacity(nt)).collect(),
            prepared: 0,
        }
    }

    /// The successors of state `cur`, with their hashes, once those of the states up to
    /// [`AHEAD`] further on are generated and loading; marks the transitions enabled there.
    #[inline(always)]
    fn successors_of(
        &mut self,
        cur: usize,
        code: &Compiled<W>,
        store: &Store<W>,
        enabled_ever: &mut [bool],
    ) -> &[([u64; W], u64)] {
        while self.prepared < store.states.len && self.prepared < cur + AHEAD {
            let out = &mut self.ring[self.prepared % AHEAD];
            successors(code, &store.states.get(self.prepared), enabled_ever, out);
            for &(_, h) in out.iter() {
                store.table.touch(h);
            }
            self.prepared += 1;
        }
        &self.ring[cur % AHEAD]
    }
}

/// The sequential explorer; with `threads ≥ 2` it hands over to the parallel one, at once or
/// once the state space has grown past `parallel_from` states.
fn explore_w<const W: usize>(net: &Net, pk: &Packing, opts: &ReachOptions) -> ReachResult {
    if opts.threads >= 2 && opts.parallel_from == 0 {
        return par::explore_par::<W>(net, pk, opts);
    }
    let nt = net.num_transitions();
    let code = Compiled::<W>::new(net, pk);
    let (mut store, k0) = Store::<W>::seeded(net, pk);
    let mut c = Counts::new(nt, pk, &k0);
    let max_states = opts.state_limit();
    let mut ahead = Ahead::<W>::new(nt);
    let mut stopped = None;
    let mut cur = 0usize;
    let mut hand_over = opts.threads >= 2;
    let mut handed = false;
    'bfs: while cur < store.states.len {
        if let Some(s) = store.checkpoint(opts, cur, c.edges) {
            stopped = Some(s);
            break;
        }
        if hand_over && cur & 0x3FFF == 0 && store.states.len as u64 >= opts.parallel_from {
            if opts.spare_core.as_ref().is_none_or(|spare| spare()) {
                handed = true;
                break;
            }
            hand_over = false;
        }
        let batch = ahead.successors_of(cur, &code, &store, &mut c.enabled_ever);
        // Counted before anything grows: the table (old and new while it doubles) and the
        // chunks that this state's successors may open.
        let need = store.bytes_to_add(batch.len());
        if let Err(s) = opts.within_memory(need) {
            stopped = Some(s);
            break;
        }
        c.peak_bytes = c.peak_bytes.max(need);
        c.edges += batch.len() as u64;
        store.table.reserve(batch.len());
        for (succ, h) in batch {
            match store.add(succ, *h, cur, max_states) {
                Added::New => observe(&mut c.max_fields, &pk.fields, succ),
                Added::Known => {}
                Added::Full => {
                    // One state too many: the run is partial; the expansion of this state stops.
                    stopped = Some(Stop::MaxStates(max_states));
                    break 'bfs;
                }
            }
        }
        if batch.is_empty() {
            c.deadlocks += 1;
            c.first_dead.get_or_insert(cur);
        }
        cur += 1;
    }
    c.peak_bytes = c.peak_bytes.max(store.bytes());
    let Store {
        table,
        states,
        parents,
    } = store;
    let done = Progressed {
        states,
        parents,
        cur,
        counts: c,
    };
    if handed {
        drop(table);
        return par::continue_par(net, pk, done, opts);
    }
    // Not handed over: the state space is small enough for one thread here too.
    let one = ReachOptions {
        threads: 1,
        ..opts.clone()
    };
    done.finish(&code, pk, stopped, &table, &one)
}

/// The successors of `key` with their hashes, into `out`; marks the transitions enabled there.
#[inline(always)]
fn successors<const W: usize>(
    code: &Compiled<W>,
    key: &[u64; W],
    enabled_ever: &mut [bool],
    out: &mut Vec<([u64; W], u64)>,
) {
    out.clear();
    for (t, ever) in enabled_ever.iter_mut().enumerate() {
        if code.enabled(key, t) {
            *ever = true;
            let succ = code.fire(key, t);
            out.push((succ, hash(&succ)));
        }
    }
}

/// A packing from the structural bounds and capacities alone, or `None` when some place has
/// neither (then [`crate::coverability::karp_miller`] must find the bounds first).
pub fn structural_packing(net: &Net, max_rows: usize) -> Result<Option<Packing>, AnalysisError> {
    let sb = crate::invariants::structural_bounds(net, max_rows)?;
    let bounds: Option<Vec<u64>> = sb
        .iter()
        .zip(net.places())
        .map(|(s, p)| match (*s, p.capacity.map(u64::from)) {
            (Some(a), Some(c)) => Some(a.min(c)),
            (a, c) => a.or(c),
        })
        .collect();
    Ok(bounds.map(|b| Packing::new(&b)))
}
