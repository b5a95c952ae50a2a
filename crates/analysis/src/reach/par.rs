//! The multi-threaded exploration (`threads ≥ 2`): the same breadth-first search, state ids and
//! counts as the sequential explorer, with the work of each batch of states split between
//! threads and no atomic operation on the hot path.
//!
//! Ownership. The visited set is split into one `Table` per thread by the top bits of the
//! hash: thread `o` alone reads and writes table `o`, so its tables are the sequential ones
//! (same layout, same growth, same bytes per state).
//!
//! A batch is a range of numbered states `[cur, cur + S)`, expanded in two phases:
//! 1. each thread expands a contiguous sub-range (thread 0 the first) and sorts the successors
//!    into one outbox per owner, tagged with their *discoverer* `parent << 32 | t`;
//! 2. each owner inserts the successors of its outboxes, those of thread 0 first, so it meets
//!    them in discoverer order, and lists the new ones (already in that order).
//!
//! Determinism. The sequential BFS numbers a new state by its first discovery, i.e. by the least
//! discoverer. An owner inserts in discoverer order, so the first insertion of a key is by its
//! least discoverer; the owners' lists, merged by discoverer, are the new states in sequential
//! order. States found in earlier batches have smaller discoverers than any in this batch, so the
//! batches compose.
//!
//! Limits. At `max_states`, the batch's new states are cut where the sequential explorer stops,
//! and the counts of the batch are recomputed up to that state's parent, so a partial result is
//! the sequential one too. The cancel flag and the progress callback are served between
//! batches. The liveness pass reads the owners' tables as they are ([`Shards`]).
//!
//! Memory: the tables hold the same bytes per state as the sequential one; the outboxes of one
//! batch come on top (at most `OUTBOX_BYTES`; ≈ 4 MB with their spare capacity at Kanban N=5).
//!
//! Speed. The threads are started once ([`Crew`]). A batch is small enough that its outboxes stay
//! in the caches between the two phases, and everything that one thread writes while the others
//! work (its outboxes, its counters, each owner's table and list) sits on cache lines of its own
//! ([`Padded`]): without it the threads passed the lines back and forth at every edge, and two
//! threads were barely faster than one.

use cetratus_net::Net;

use super::{
    hash, observe, prefetch, scc, seed, Chunked, Compiled, Counts, Field, Packing, Progressed,
    ReachOptions, ReachResult, Stop, Table, CHUNK_BITS,
};
use crate::Progress;

/// Largest batch: enough to keep the threads busy, and few enough states to check the cancel
/// flag often.
const MAX_BATCH: usize = 1 << 14;

/// Bytes the outboxes of one batch may take at most (the batch is shortened for wide nets).
const OUTBOX_BYTES: usize = 64 << 20;

/// Batches smaller than this are expanded on the calling thread: spawning would cost more.
const MIN_PARALLEL: usize = 1 << 11;

/// Successors handled ahead of the one being inserted, so that their cache misses overlap.
const AHEAD: usize = 32;

/// A new state with its discoverer.
type Found<const W: usize> = (u64, [u64; W]);

/// A successor on its way to its owner: discoverer, key, hash.
type Succ<const W: usize> = (u64, [u64; W], u64);

/// The owner of a key: the hash's top bits (the slot index uses the low ones).
#[inline(always)]
fn owner(h: u64, owners: usize) -> usize {
    ((h >> 32) as usize * owners) >> 32
}

/// The owners' finished tables, read by the liveness pass: the id of a slot is its table's
/// index times the largest table's slot count, plus the slot.
struct Shards<const W: usize> {
    tables: Vec<Table<W>>,
    /// log2 of the largest table's slot count.
    bits: u32,
}

impl<const W: usize> Shards<W> {
    fn new(tables: Vec<Table<W>>) -> Self {
        let bits = tables
            .iter()
            .map(|t| t.slots.len().trailing_zeros())
            .max()
            .unwrap_or(0);
        Shards { tables, bits }
    }
    #[inline(always)]
    fn slot(&self, id: usize) -> &[u64; W] {
        &self.tables[id >> self.bits].slots[id & ((1 << self.bits) - 1)]
    }
}

impl<const W: usize> scc::Visited<W> for Shards<W> {
    fn ids(&self) -> usize {
        self.tables.len() << self.bits
    }
    #[inline(always)]
    fn id_of(&self, key: &[u64; W], h: u64) -> Option<usize> {
        let o = owner(h, self.tables.len());
        self.tables[o].slot_of(key, h).map(|s| o << self.bits | s)
    }
    #[inline(always)]
    fn key(&self, id: usize) -> [u64; W] {
        *self.slot(id)
    }
    #[inline(always)]
    fn touch(&self, h: u64) {
        self.tables[owner(h, self.tables.len())].touch(h);
    }
    #[inline(always)]
    fn touch_id(&self, id: usize) {
        prefetch(self.slot(id));
    }
    fn bytes(&self) -> usize {
        self.tables.iter().map(Table::bytes).sum()
    }
}

/// What one thread found in its sub-range of a batch. Each thread's is padded, and so is each
/// outbox: the threads write them at every edge.
struct Expanded<const W: usize> {
    /// One outbox per owner, in discoverer order.
    outboxes: Vec<Padded<Vec<Succ<W>>>>,
    edges: u64,
    deadlocks: u64,
    first_dead: Option<usize>,
    enabled_ever: Vec<bool>,
}

impl<const W: usize> Expanded<W> {
    fn new(owners: usize, nt: usize) -> Self {
        Expanded {
            outboxes: vec![Padded::default(); owners],
            edges: 0,
            deadlocks: 0,
            first_dead: None,
            enabled_ever: vec![false; nt],
        }
    }
}

/// Phase 1: the successors of states `range`, sorted by owner into `ex`'s (cleared) outboxes.
/// With no outboxes, only counts (used to stop exactly where the sequential explorer stops at
/// `max_states`).
fn expand<const W: usize>(
    code: &Compiled<W>,
    states: &Chunked<[u64; W]>,
    range: std::ops::Range<usize>,
    ex: &mut Expanded<W>,
) {
    let owners = ex.outboxes.len();
    ex.outboxes.iter_mut().for_each(|b| b.clear());
    let (mut edges, mut deadlocks, mut first_dead) = (0, 0, None);
    // Allocated here, by the thread that writes it, away from the other threads' data.
    let mut enabled_ever = vec![false; ex.enabled_ever.len()];
    for s in range {
        let key = states.get(s);
        let mut any = false;
        for (t, ever) in enabled_ever.iter_mut().enumerate() {
            if code.enabled(&key, t) {
                *ever = true;
                any = true;
                edges += 1;
                if owners > 0 {
                    let succ = code.fire(&key, t);
                    let h = hash(&succ);
                    ex.outboxes[owner(h, owners)].push(((s as u64) << 32 | t as u64, succ, h));
                }
            }
        }
        if !any {
            deadlocks += 1;
            first_dead.get_or_insert(s);
        }
    }
    ex.edges = edges;
    ex.deadlocks = deadlocks;
    ex.first_dead = first_dead;
    ex.enabled_ever = enabled_ever;
}

/// What one owner holds: its table, and what it found in the current batch.
struct Owner<const W: usize> {
    table: Table<W>,
    /// The new keys with their discoverers, in discoverer order.
    new: Vec<Found<W>>,
    /// The largest value of each field among `new`.
    max: Vec<u64>,
}

/// Phase 2: owner `o` inserts what the threads sent it, thread 0's first, lists the new keys
/// with their discoverers (in discoverer order) and observes their fields.
fn insert<const W: usize>(
    own: &mut Owner<W>,
    expanded: &[Padded<Expanded<W>>],
    o: usize,
    fields: &[Field],
) {
    let Owner { table, new, max } = own;
    new.clear();
    max.iter_mut().for_each(|m| *m = 0);
    for ex in expanded {
        let inbox = &ex.outboxes[o];
        for (j, (disc, key, h)) in inbox.iter().enumerate() {
            if let Some(&(_, _, ha)) = inbox.get(j + AHEAD) {
                table.touch(ha);
            }
            table.reserve(1);
            if table.insert_hashed(key, *h) {
                new.push((*disc, *key));
                observe(max, fields, key);
            }
        }
    }
}

/// A value alone on its cache lines (two, as the prefetcher pulls lines in pairs), so that two
/// threads writing their own values do not pass a shared line back and forth.
#[repr(align(128))]
#[derive(Clone, Default)]
pub(super) struct Padded<T>(pub(super) T);

impl<T> std::ops::Deref for Padded<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.0
    }
}

impl<T> std::ops::DerefMut for Padded<T> {
    fn deref_mut(&mut self) -> &mut T {
        &mut self.0
    }
}

/// The threads of a parallel pass, started once and reused by every batch or layer (starting a
/// thread per batch cost more than the batch's work once batches fit in the caches).
pub(super) struct Crew {
    /// `threads - 1` workers; the calling thread is the first member. None on one thread, or
    /// when the workers could not be started (then the calling thread does all the work).
    pool: Option<rayon_core::ThreadPool>,
}

impl Crew {
    pub(super) fn new(threads: usize) -> Crew {
        let pool = (threads > 1)
            .then(|| {
                rayon_core::ThreadPoolBuilder::new()
                    .num_threads(threads - 1)
                    .thread_name(|i| format!("cetratus-check-{}", i + 1))
                    .build()
                    .ok()
            })
            .flatten();
        Crew { pool }
    }

    /// Runs `f(i, &mut items[i])` for every item, one member per item when `parallel` (the
    /// calling thread taking the first).
    pub(super) fn each<T: Send, F: Fn(usize, &mut T) + Sync>(
        &self,
        items: &mut [T],
        parallel: bool,
        f: F,
    ) {
        let Some(pool) = self.pool.as_ref().filter(|_| parallel) else {
            items.iter_mut().enumerate().for_each(|(i, x)| f(i, x));
            return;
        };
        let f = &f;
        // A panic in a worker is a bug in this module; the scope passes it on to the caller.
        pool.in_place_scope(|sc| {
            let mut it = items.iter_mut().enumerate();
            let first = it.next();
            for (i, x) in it {
                sc.spawn(move |_| f(i, x));
            }
            if let Some((i, x)) = first {
                f(i, x);
            }
        });
    }
}

/// Explores with `opts.threads` threads; the result equals the sequential one.
pub(super) fn explore_par<const W: usize>(
    net: &Net,
    pk: &Packing,
    opts: &ReachOptions,
) -> ReachResult {
    let (states, parents) = seed::<W>(net, pk);
    let counts = Counts::new(net.num_transitions(), pk, &states.get(0));
    let start = Progressed {
        states,
        parents,
        cur: 0,
        counts,
    };
    continue_par(net, pk, start, opts)
}

/// Goes on with `opts.threads` threads from where `start` stands (the sequential explorer hands
/// over once the state space has grown past [`ReachOptions::parallel_from`]): the owners' tables
/// are filled with the states found so far, in id order, and the search continues from
/// `start.cur`. The result equals the sequential one.
pub(super) fn continue_par<const W: usize>(
    net: &Net,
    pk: &Packing,
    start: Progressed<W>,
    opts: &ReachOptions,
) -> ReachResult {
    let max_states = opts.state_limit();
    let mut at = start;
    let mut work = Batches::<W>::new(net, pk, opts.threads.max(1), &at.states);
    let mut stopped = None;
    while at.cur < at.states.len {
        if let Some(s) = between_batches(opts, &at) {
            stopped = Some(s);
            break;
        }
        let size = (at.states.len - at.cur).min(work.max_batch);
        if let Err(s) = opts.within_memory(work.bytes_before(size, &at)) {
            stopped = Some(s);
            break;
        }
        let end = at.cur + size;
        let held = work.expand_and_insert(&at.states, at.cur..end, &pk.fields);
        let c = &mut at.counts;
        c.peak_bytes = c
            .peak_bytes
            .max(held + at.states.bytes() + at.parents.bytes());
        stopped = work.number_new(&mut at, &pk.fields, max_states);
        if stopped.is_some() {
            break;
        }
        at.cur = end;
    }
    let Batches { code, owners, .. } = work;
    let shards = Shards::new(owners.into_iter().map(|o| o.0.table).collect());
    at.finish(&code, pk, stopped, &shards, opts)
}

/// Between two batches (not before the first state): why to stop (Ctrl-C, the deadline), or
/// else a progress report.
fn between_batches<const W: usize>(opts: &ReachOptions, at: &Progressed<W>) -> Option<Stop> {
    if at.cur == 0 {
        return None;
    }
    if let Some(s) = opts.interrupted() {
        return Some(s);
    }
    if let Some(p) = &opts.progress {
        p(Progress {
            states: at.states.len as u64,
            edges: at.counts.edges,
            expanded: at.cur as u64,
            bytes: at.counts.peak_bytes as u64,
        });
    }
    None
}

/// What the parallel explorer keeps from batch to batch: the owners' tables, a buffer per
/// thread, and the threads.
struct Batches<const W: usize> {
    code: Compiled<W>,
    nt: usize,
    threads: usize,
    /// The most states a batch takes: [`MAX_BATCH`], fewer for wide nets so that the outboxes
    /// stay within [`OUTBOX_BYTES`].
    max_batch: usize,
    owners: Vec<Padded<Owner<W>>>,
    expanded: Vec<Padded<Expanded<W>>>,
    /// The counts of a batch cut at `max_states`, recomputed up to the cut.
    recount: Padded<Expanded<W>>,
    crew: Crew,
}

impl<const W: usize> Batches<W> {
    /// The working set of `threads` threads, the owners' tables filled with `states` in id
    /// order.
    fn new(net: &Net, pk: &Packing, threads: usize, states: &Chunked<[u64; W]>) -> Self {
        let nt = net.num_transitions();
        let mut owners: Vec<Padded<Owner<W>>> = (0..threads)
            .map(|_| {
                Padded(Owner {
                    table: Table::new(),
                    new: Vec::new(),
                    max: vec![0; pk.fields.len()],
                })
            })
            .collect();
        for i in 0..states.len {
            let k = states.get(i);
            let h = hash(&k);
            let t = &mut owners[owner(h, threads)].table;
            t.reserve(1);
            t.insert_hashed(&k, h);
        }
        Batches {
            code: Compiled::<W>::new(net, pk),
            nt,
            threads,
            max_batch: MAX_BATCH
                .min((OUTBOX_BYTES / (nt.max(1) * std::mem::size_of::<Succ<W>>())).max(1)),
            owners,
            // Buffers reused from batch to batch: one per thread, one per owner.
            expanded: (0..threads)
                .map(|_| Padded(Expanded::new(threads, nt)))
                .collect(),
            recount: Padded(Expanded::new(0, nt)),
            crew: Crew::new(threads),
        }
    }

    /// The bytes that a batch of `size` states from `at` may hold, counted before it runs:
    /// every table grown to take the whole batch's successors (old and new slots), full
    /// outboxes, and the chunks the new states may open.
    fn bytes_before(&self, size: usize, at: &Progressed<W>) -> usize {
        let worst = size * self.nt;
        self.owners
            .iter()
            .map(|o| o.table.bytes_to_fit(worst))
            .sum::<usize>()
            + OUTBOX_BYTES.min(worst * std::mem::size_of::<Succ<W>>())
            + at.states.bytes()
            + at.parents.bytes()
            + worst.div_ceil(1 << CHUNK_BITS).saturating_add(1) * (1 << CHUNK_BITS) * (8 * W + 4)
    }

    /// Both phases of the batch `range`: its states expanded by the threads, then their
    /// successors inserted by the owners. Returns the bytes the tables (old and new slots where
    /// one grew) and the outboxes held meanwhile.
    fn expand_and_insert(
        &mut self,
        states: &Chunked<[u64; W]>,
        range: std::ops::Range<usize>,
        fields: &[Field],
    ) -> usize {
        let (cur, end) = (range.start, range.end);
        let size = end - cur;
        let parallel = size >= MIN_PARALLEL;
        let step = size.div_ceil(self.threads);
        let code = &self.code;
        self.crew.each(&mut self.expanded, parallel, |i, ex| {
            let a = (cur + i * step).min(end);
            expand(code, states, a..(a + step).min(end), ex);
        });
        let grows: Vec<u32> = self.owners.iter().map(|o| o.table.grows).collect();
        let expanded = &self.expanded;
        self.crew.each(&mut self.owners, parallel, |o, own| {
            insert(own, expanded, o, fields)
        });
        let outbox_bytes: usize = expanded
            .iter()
            .flat_map(|e| &e.outboxes)
            .map(|b| b.capacity() * std::mem::size_of::<Succ<W>>())
            .sum();
        let table_bytes: usize = self
            .owners
            .iter()
            .map(|o| &o.table)
            .zip(&grows)
            .map(|(t, &g)| {
                if t.grows != g {
                    t.transient_bytes
                } else {
                    t.bytes()
                }
            })
            .sum();
        table_bytes + outbox_bytes
    }

    /// Numbers the batch's new states as the sequential explorer would and adds the batch's
    /// counts to `at`. Past `max_states`, the batch is cut where the sequential explorer stops,
    /// and the reason is returned.
    fn number_new(
        &mut self,
        at: &mut Progressed<W>,
        fields: &[Field],
        max_states: u64,
    ) -> Option<Stop> {
        let allowed = max_states.saturating_sub(at.states.len as u64) as usize;
        let found: usize = self.owners.iter().map(|o| o.new.len()).sum();
        let c = &mut at.counts;
        if found <= allowed {
            merge(&self.owners, |(disc, key)| {
                at.states.push(*key);
                at.parents.push((disc >> 32) as u32);
            });
            for own in &self.owners {
                for (m, &x) in c.max_fields.iter_mut().zip(&own.max) {
                    *m = (*m).max(x);
                }
            }
            self.expanded.iter().for_each(|ex| add_counts(c, ex));
            return None;
        }
        // The sequential explorer stops at the first new state beyond the limit, inside the
        // expansion of its parent: count exactly what it would have counted by then.
        let mut new: Vec<Found<W>> = Vec::new();
        merge(&self.owners, |f| new.push(*f));
        let parent = (new[allowed].0 >> 32) as usize;
        new.truncate(allowed);
        // (`parent` has a successor, so it is not dead and its dead check does not matter.)
        expand(
            &self.code,
            &at.states,
            at.cur..parent + 1,
            &mut self.recount,
        );
        for (disc, key) in &new {
            at.states.push(*key);
            at.parents.push((disc >> 32) as u32);
            observe(&mut c.max_fields, fields, key);
        }
        add_counts(c, &self.recount);
        Some(Stop::MaxStates(max_states))
    }
}

/// Adds what one thread counted in its part of a batch.
fn add_counts<const W: usize>(c: &mut Counts, ex: &Expanded<W>) {
    c.edges += ex.edges;
    c.deadlocks += ex.deadlocks;
    if c.first_dead.is_none() {
        c.first_dead = ex.first_dead;
    }
    for (e, &x) in c.enabled_ever.iter_mut().zip(&ex.enabled_ever) {
        *e |= x;
    }
}

/// Calls `f` on the owners' new keys in discoverer order (each owner's list is in that order).
fn merge<const W: usize>(owners: &[Padded<Owner<W>>], mut f: impl FnMut(&Found<W>)) {
    if let [a, b] = owners {
        let (a, b) = (&a.new, &b.new);
        let (mut i, mut j) = (0, 0);
        while i < a.len() && j < b.len() {
            if a[i].0 < b[j].0 {
                f(&a[i]);
                i += 1;
            } else {
                f(&b[j]);
                j += 1;
            }
        }
        a[i..].iter().chain(&b[j..]).for_each(f);
        return;
    }
    let mut heads = vec![0usize; owners.len()];
    loop {
        let mut best: Option<(usize, u64)> = None;
        for (l, own) in owners.iter().enumerate() {
            if let Some(e) = own.new.get(heads[l]) {
                if best.is_none_or(|(_, d)| e.0 < d) {
                    best = Some((l, e.0));
                }
            }
        }
        let Some((l, _)) = best else { break };
        f(&owners[l].new[heads[l]]);
        heads[l] += 1;
    }
}
