//! Liveness and reversibility once the exploration is complete, over the finished hash tables.
//!
//! The tables no longer move, so a state's slot is its id ([`Visited`]): no id is stored
//! anywhere, and the packed states and BFS parents of the exploration are already freed. After a
//! parallel exploration the owners' tables are read as they are, an id naming the table and the
//! slot in it, so nothing is rebuilt.
//!
//! First a backward search from M0 over the implicit graph: predecessors are recomputed by undoing
//! each transition (a range test per field it changes, then the forward enabling test, evaluated
//! without a branch per test) and looked up in the table. On one thread the predecessors of many
//! queued states are generated together and looked up in turn, each lookup starting the load of
//! the home slot of the one [`AHEAD`] places further on (a prefetch), so that the cache misses
//! overlap instead of waiting one after the other; the keys of the queued states load the same
//! way. With more threads the search goes by layers over one queue, each thread taking a part
//! of the layer the same way and claiming the states it finds with one atomic bit each
//! ([`Graph::reaches_root_layered`]). If every state reaches M0, the graph is one strongly
//! connected component: the net is reversible, and live exactly when every transition is enabled
//! somewhere. This is the common
//! case of a plant model, and it costs one lookup per edge, stopping as soon as every state is
//! found. Otherwise an iterative Tarjan (explicit frames, no recursion) finds the terminal
//! components.
//!
//! Memory, all counted: the table, a bit per slot, a queue of 4 bytes per state and, per
//! thread, a batch of [`BATCH`] predecessors for the backward search; for Tarjan two `u32` per
//! slot, two bits per slot, and its stacks.

use super::par::{Crew, Padded};
use super::{hash, prefetch, Compiled, Liveness, ReachOptions, Stop, Table};
use cetratus_net::TransIdx;
use std::sync::atomic::{AtomicU32, AtomicU64, AtomicUsize, Ordering::Relaxed};

/// The finished set of states, read by id: a slot of a table.
pub(super) trait Visited<const W: usize>: Sync {
    /// The number of ids: every id is below it (empty slots included).
    fn ids(&self) -> usize;
    /// The id of `key`, whose hash is `h`, if it was found.
    fn id_of(&self, key: &[u64; W], h: u64) -> Option<usize>;
    /// The key with id `id`.
    fn key(&self, id: usize) -> [u64; W];
    /// Starts loading the first slot that a lookup of hash `h` reads (see [`Table::touch`]).
    fn touch(&self, h: u64);
    /// Starts loading the slot of `id`.
    fn touch_id(&self, id: usize);
    /// The bytes held by the tables.
    fn bytes(&self) -> usize;
}

impl<const W: usize> Visited<W> for Table<W> {
    fn ids(&self) -> usize {
        self.slots.len()
    }
    #[inline(always)]
    fn id_of(&self, key: &[u64; W], h: u64) -> Option<usize> {
        self.slot_of(key, h)
    }
    #[inline(always)]
    fn key(&self, id: usize) -> [u64; W] {
        self.slots[id]
    }
    #[inline(always)]
    fn touch(&self, h: u64) {
        Table::touch(self, h)
    }
    #[inline(always)]
    fn touch_id(&self, id: usize) {
        prefetch(&self.slots[id]);
    }
    fn bytes(&self) -> usize {
        Table::bytes(self)
    }
}

const NONE: u32 = u32::MAX;

/// Predecessors looked up together by the backward search on one thread, at most.
const BATCH: usize = 1 << 16;

/// How many loads ahead the backward search starts loading a slot: enough to cover a miss.
const AHEAD: usize = 64;

/// Bit `i` of the bit set `v`.
#[inline(always)]
pub(super) fn bit(v: &[u64], i: usize) -> bool {
    v[i >> 6] >> (i & 63) & 1 == 1
}

/// Sets bit `i` of the bit set `v`.
#[inline(always)]
pub(super) fn set(v: &mut [u64], i: usize) {
    v[i >> 6] |= 1 << (i & 63);
}

/// Liveness and reversibility, why they were not decided, and the bytes held at the peak.
pub(super) fn liveness<const W: usize>(
    code: &Compiled<W>,
    table: &impl Visited<W>,
    k0: &[u64; W],
    states: usize,
    never_enabled: &[TransIdx],
    opts: &ReachOptions,
) -> (Option<Liveness>, Option<Stop>, usize) {
    let Some(root) = table.id_of(k0, hash(k0)) else {
        return (None, None, 0);
    };
    let graph = Graph { code, table, opts };
    match graph.reaches_root(root, states) {
        Err((s, bytes)) => (None, Some(s), bytes),
        Ok((true, bytes)) => (
            Some(Liveness {
                sccs: 1,
                terminal_sccs: 1,
                live: never_enabled.is_empty(),
                non_live: never_enabled.to_vec(),
                reversible: true,
            }),
            None,
            bytes,
        ),
        Ok((false, bytes)) => match graph.tarjan(root) {
            Ok((l, b)) => (Some(l), None, bytes.max(b)),
            Err((s, b)) => (None, Some(s), bytes.max(b)),
        },
    }
}

type Counted<T> = Result<(T, usize), (Stop, usize)>;

/// The reachability graph over the finished set of states, implicit: a node is an id of
/// `table`, and `code` computes its successors and predecessors. Searched within `opts`.
struct Graph<'a, const W: usize, V> {
    code: &'a Compiled<W>,
    table: &'a V,
    opts: &'a ReachOptions,
}

/// How many of `states` queued states the backward search takes at a time, and the
/// predecessors they may have (a slot per transition each).
fn batch_sizes(nt: usize, states: usize) -> (usize, usize) {
    let per_batch = (BATCH / nt.max(1)).clamp(1, states.max(1));
    (per_batch, per_batch * nt.max(1))
}

/// The keys of the first `n` of `slots` into `keys` (cleared), the slots loading [`AHEAD`]
/// places ahead (`slots` may run past `n` so that the last ones load ahead too).
fn gather<const W: usize>(
    table: &impl Visited<W>,
    slots: &[u32],
    n: usize,
    keys: &mut Vec<[u64; W]>,
) {
    keys.clear();
    for (i, &s) in slots[..n].iter().enumerate() {
        if let Some(&next) = slots.get(i + AHEAD) {
            table.touch_id(next as usize);
        }
        keys.push(table.key(s as usize));
    }
}

/// Layers of a frontier below this size are searched on the calling thread.
const PARALLEL_LAYER: usize = 8_192;

/// What one thread of the layered search keeps from layer to layer.
struct Scratch<const W: usize> {
    ids: Vec<u32>,
    keys: Vec<[u64; W]>,
    batch: Vec<[u64; W]>,
    /// The states this thread found in its current batch, before they join the queue.
    found: Vec<u32>,
}

/// Sets bit `i` of `seen` unless it is set; true when this call set it. A plain load first: most
/// predecessors were found long before, and those cost no atomic write.
#[inline(always)]
fn claim(seen: &[AtomicU64], i: usize) -> bool {
    let (w, m) = (&seen[i >> 6], 1u64 << (i & 63));
    w.load(Relaxed) & m == 0 && w.fetch_or(m, Relaxed) & m == 0
}

/// The layer `queue[..end]` being searched: its states are taken in chunks from `next` on, by
/// whichever thread is free, so that no thread waits for another at the layer's end longer than
/// a chunk.
struct Layer<'a> {
    queue: &'a [AtomicU32],
    next: AtomicUsize,
    end: usize,
    chunk: usize,
    /// Where the states found are appended.
    tail: &'a AtomicUsize,
}

impl<const W: usize, V: Visited<W>> Graph<'_, W, V> {
    /// Whether every one of the `states` states reaches the state in slot `root`.
    fn reaches_root(&self, root: usize, states: usize) -> Counted<bool> {
        if self.opts.threads >= 2 {
            return self.reaches_root_layered(root, states);
        }
        let table = self.table;
        let cap = table.ids();
        let (per_batch, batch_cap) = batch_sizes(self.code.transitions(), states);
        let bytes = table.bytes()
            + cap.div_ceil(64) * 8
            + (states + 1) * 4
            + (batch_cap + per_batch) * 8 * W;
        self.opts.within_memory(bytes).map_err(|s| (s, bytes))?;
        let mut seen = vec![0u64; cap.div_ceil(64)];
        // Every state once, and one place past the last for the write that keeps nothing.
        let mut queue: Vec<u32> = vec![0; states + 1];
        // At its full length; `n` says how much of it a round holds, so that a predecessor is
        // written whether or not it exists and kept only when it does, without a branch.
        let mut batch: Vec<[u64; W]> = vec![[0; W]; batch_cap];
        let mut keys: Vec<[u64; W]> = Vec::with_capacity(per_batch);
        set(&mut seen, root);
        queue[0] = root as u32;
        let mut found = 1;
        let mut head = 0;
        while head < found && found < states {
            if let Some(s) = self.opts.interrupted() {
                return Err((s, bytes));
            }
            let end = found.min(head + per_batch);
            gather(
                table,
                &queue[head..found.min(end + AHEAD)],
                end - head,
                &mut keys,
            );
            head = end;
            self.each_predecessor(&keys, &mut batch, |s| {
                // Without a branch on `seen`, whose outcome is random: the slot is written past
                // the queue's end and kept only when it is new.
                let new = !bit(&seen, s);
                set(&mut seen, s);
                queue[found] = s as u32;
                found += new as usize;
            });
        }
        Ok((found == states, bytes))
    }

    /// Calls `found` with the slot of every predecessor of every key in `keys` (with repeats),
    /// in turn: the predecessors are generated into `batch` (which holds `keys.len()` times the
    /// transitions), then looked up, each lookup starting the load of the home slot [`AHEAD`]
    /// lookups further on.
    fn each_predecessor(
        &self,
        keys: &[[u64; W]],
        batch: &mut [[u64; W]],
        mut found: impl FnMut(usize),
    ) {
        let nt = self.code.transitions();
        // Written whether or not the predecessor exists, kept only when it does: no branch.
        let mut n = 0;
        for key in keys {
            for t in 0..nt {
                let (u, ok) = self.code.unfire_unchecked(key, t);
                batch[n] = u;
                n += ok as usize;
            }
        }
        let batch = &batch[..n];
        for (i, u) in batch.iter().enumerate() {
            if let Some(v) = batch.get(i + AHEAD) {
                self.table.touch(hash(v));
            }
            if let Some(s) = self.table.id_of(u, hash(u)) {
                found(s);
            }
        }
    }

    /// One thread's share of the search of `layer`: the predecessors that no thread has found
    /// yet are claimed in `seen` and appended to the queue. Stops early once the queue holds
    /// every one of the `states` states.
    fn search_part(&self, layer: &Layer, seen: &[AtomicU64], states: usize, sc: &mut Scratch<W>) {
        let (queue, tail) = (layer.queue, layer.tail);
        while tail.load(Relaxed) < states {
            let head = layer.next.fetch_add(layer.chunk, Relaxed);
            if head >= layer.end {
                break;
            }
            let end = layer.end.min(head + layer.chunk);
            sc.ids.clear();
            sc.ids.extend(
                queue[head..layer.end.min(end + AHEAD)]
                    .iter()
                    .map(|x| x.load(Relaxed)),
            );
            gather(self.table, &sc.ids, end - head, &mut sc.keys);
            let found = &mut sc.found;
            found.clear();
            self.each_predecessor(&sc.keys, &mut sc.batch, |s| {
                if claim(seen, s) {
                    found.push(s as u32);
                }
            });
            let at = tail.fetch_add(found.len(), Relaxed);
            for (q, &s) in queue[at..].iter().zip(found.iter()) {
                q.store(s, Relaxed);
            }
        }
    }

    /// [`Graph::reaches_root`] on `opts.threads` threads: a breadth-first search by layers over
    /// one queue. The threads split each layer and look up its predecessors (they only read the
    /// tables); a new state is claimed with one atomic bit in `seen` (tested with a plain load
    /// first, so only the first finding of each state writes), and appended to the queue by the
    /// thread that claimed it. The layer's end is where the threads meet, so the queue's order
    /// within a layer may differ from run to run, but its contents, the answer and the memory
    /// held do not.
    fn reaches_root_layered(&self, root: usize, states: usize) -> Counted<bool> {
        let (table, opts) = (self.table, self.opts);
        let threads = opts.threads.max(1);
        let (per_batch, batch_cap) = batch_sizes(self.code.transitions(), states);
        // The tables, the seen bits, the queue (every state once) and each thread's ids, keys,
        // predecessors and finds.
        let bytes = table.bytes()
            + table.ids().div_ceil(64) * 8
            + states * 4
            + threads * ((per_batch + AHEAD) * 4 + (per_batch + batch_cap) * (8 * W + 4));
        opts.within_memory(bytes).map_err(|s| (s, bytes))?;
        let seen: Vec<AtomicU64> = (0..table.ids().div_ceil(64))
            .map(|_| AtomicU64::new(0))
            .collect();
        let queue: Vec<AtomicU32> = (0..states).map(|_| AtomicU32::new(0)).collect();
        claim(&seen, root);
        queue[0].store(root as u32, Relaxed);
        let tail = AtomicUsize::new(1);
        let mut scratch: Vec<Padded<Scratch<W>>> = (0..threads)
            .map(|_| {
                Padded(Scratch {
                    ids: Vec::with_capacity(per_batch + AHEAD),
                    keys: Vec::with_capacity(per_batch),
                    batch: vec![[0; W]; batch_cap],
                    found: Vec::with_capacity(batch_cap),
                })
            })
            .collect();
        let crew = Crew::new(threads);
        let mut head = 0;
        loop {
            let end = tail.load(Relaxed);
            if head == end || end >= states {
                break;
            }
            if let Some(s) = opts.interrupted() {
                return Err((s, bytes));
            }
            let size = end - head;
            let layer = Layer {
                queue: &queue,
                next: AtomicUsize::new(head),
                end,
                // A batch of predecessors at most, and a few chunks per thread.
                chunk: per_batch.min(size.div_ceil(4 * threads)).max(1),
                tail: &tail,
            };
            let seen = &seen;
            crew.each(&mut scratch, size >= PARALLEL_LAYER, |_, sc| {
                self.search_part(&layer, seen, states, sc);
            });
            head = end;
        }
        Ok((tail.load(Relaxed) >= states, bytes))
    }

    /// Iterative Tarjan over the graph from `root`, recording the terminal SCCs and which
    /// transitions occur inside each.
    fn tarjan(&self, root: usize) -> Counted<Liveness> {
        let n = self.table.ids();
        let fixed = self.table.bytes() + n * 8 + n.div_ceil(64) * 16;
        self.opts.within_memory(fixed).map_err(|s| (s, fixed))?;
        let mut tj = Tarjan::new(n, self.code.transitions(), root);
        let mut peak = fixed;
        tj.enter(root);
        let mut steps = 0u64;
        while let Some(&(v, t0)) = tj.frames.last() {
            steps += 1;
            if steps & 0x3FFF == 0 {
                // The stacks grow with the search's depth: counted here, before they grow
                // further.
                let bytes = fixed + tj.stack_bytes();
                peak = peak.max(bytes);
                if let Err(s) = self.opts.within_memory(bytes * 2 - fixed) {
                    return Err((s, peak));
                }
                if let Some(s) = self.opts.interrupted() {
                    return Err((s, peak));
                }
            }
            if !tj.descend(self, v as usize, t0 as usize) {
                tj.leave(self, v as usize);
            }
        }
        peak = peak.max(fixed + tj.stack_bytes());
        Ok((tj.into_liveness(), peak))
    }
}

/// Where the iterative Tarjan search stands, and what it has found.
struct Tarjan {
    root: usize,
    /// Per id: the visiting order ([`NONE`]: not visited yet) and the lowlink.
    index: Vec<u32>,
    low: Vec<u32>,
    /// Bits per id: on the Tarjan stack; an edge leaves its SCC.
    on_stack: Vec<u64>,
    exits: Vec<u64>,
    stack: Vec<u32>,
    /// The path of the depth-first search: each node with the next transition to follow.
    frames: Vec<(u32, u32)>,
    next_index: u32,
    sccs: u64,
    terminal: u64,
    /// Transitions missing from some terminal SCC.
    missing: Vec<bool>,
    root_terminal: bool,
    /// The transitions occurring in the SCC being closed.
    occurs: Vec<bool>,
}

impl Tarjan {
    /// A search from `root` over `n` ids and `nt` transitions, nothing visited yet.
    fn new(n: usize, nt: usize, root: usize) -> Tarjan {
        Tarjan {
            root,
            index: vec![NONE; n],
            low: vec![0u32; n],
            on_stack: vec![0u64; n.div_ceil(64)],
            exits: vec![0u64; n.div_ceil(64)],
            stack: Vec::new(),
            frames: Vec::new(),
            next_index: 0,
            sccs: 0,
            terminal: 0,
            missing: vec![false; nt],
            root_terminal: false,
            occurs: vec![false; nt],
        }
    }

    /// The bytes of the stacks, which grow with the search's depth.
    fn stack_bytes(&self) -> usize {
        self.stack.capacity() * 4 + self.frames.capacity() * 8
    }

    /// Visits `v` and descends to it.
    #[inline]
    fn enter(&mut self, v: usize) {
        self.index[v] = self.next_index;
        self.low[v] = self.next_index;
        self.next_index += 1;
        set(&mut self.on_stack, v);
        self.stack.push(v as u32);
        self.frames.push((v as u32, 0));
    }

    /// Follows the edges of `v` from transition `t` on: true when it descended to a successor
    /// not visited yet; the other successors lower `v`'s lowlink or mark an exit of its SCC.
    #[inline]
    fn descend<const W: usize, V: Visited<W>>(
        &mut self,
        g: &Graph<'_, W, V>,
        v: usize,
        t: usize,
    ) -> bool {
        let key = g.table.key(v);
        for t in t..self.missing.len() {
            if !g.code.enabled(&key, t) {
                continue;
            }
            let succ = g.code.fire(&key, t);
            let w = g.table.id_of(&succ, hash(&succ)).unwrap_or(self.root);
            if self.index[w] == NONE {
                if let Some(f) = self.frames.last_mut() {
                    f.1 = t as u32 + 1;
                }
                self.enter(w);
                return true;
            } else if bit(&self.on_stack, w) {
                self.low[v] = self.low[v].min(self.index[w]);
            } else {
                // w belongs to an SCC already completed, so this edge leaves v's SCC.
                set(&mut self.exits, v);
            }
        }
        false
    }

    /// Leaves `v`, whose edges are all followed: closes its SCC if `v` is the SCC's root, else
    /// passes its lowlink to its parent.
    #[inline]
    fn leave<const W: usize, V: Visited<W>>(&mut self, g: &Graph<'_, W, V>, v: usize) {
        self.frames.pop();
        if self.low[v] == self.index[v] {
            self.close_scc(g, v);
            if let Some(&(u, _)) = self.frames.last() {
                // v's SCC is finished and differs from u's: the tree edge u → v leaves u's SCC.
                set(&mut self.exits, u as usize);
            }
        } else if let Some(&(u, _)) = self.frames.last() {
            let u = u as usize;
            self.low[u] = self.low[u].min(self.low[v]);
        }
    }

    /// Takes the SCC of `v` (the stack down to `v`) off the stack and counts it; when no edge
    /// leaves it, it is terminal, and the transitions that never occur inside are not live.
    fn close_scc<const W: usize, V: Visited<W>>(&mut self, g: &Graph<'_, W, V>, v: usize) {
        self.sccs += 1;
        let start = self
            .stack
            .iter()
            .rposition(|&x| x as usize == v)
            .unwrap_or(0);
        let is_terminal = self.stack[start..]
            .iter()
            .all(|&x| !bit(&self.exits, x as usize));
        self.occurs.iter_mut().for_each(|o| *o = false);
        for &x in &self.stack[start..] {
            let x = x as usize;
            self.on_stack[x >> 6] &= !(1 << (x & 63));
            if is_terminal {
                let k = g.table.key(x);
                for (t, o) in self.occurs.iter_mut().enumerate() {
                    *o |= g.code.enabled(&k, t);
                }
            }
        }
        self.stack.truncate(start);
        if is_terminal {
            self.terminal += 1;
            for (m, o) in self.missing.iter_mut().zip(&self.occurs) {
                *m |= !o;
            }
            if v == self.root {
                self.root_terminal = true;
            }
        }
    }

    /// What the terminal SCCs say, once the search is complete.
    fn into_liveness(self) -> Liveness {
        let non_live: Vec<TransIdx> = (0..self.missing.len())
            .filter(|&t| self.missing[t])
            .map(|t| TransIdx(t as u32))
            .collect();
        Liveness {
            sccs: self.sccs,
            terminal_sccs: self.terminal,
            live: non_live.is_empty(),
            non_live,
            reversible: self.root_terminal && self.terminal == 1,
        }
    }
}
