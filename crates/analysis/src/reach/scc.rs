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
//! ([`reaches_root_layered`]). If every state reaches M0, the graph is one strongly connected
//! component: the net is reversible, and live exactly when every transition is enabled
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

fn bit(v: &[u64], i: usize) -> bool {
    v[i >> 6] >> (i & 63) & 1 == 1
}

fn set(v: &mut [u64], i: usize) {
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
    match reaches_root(code, table, root, states, opts) {
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
        Ok((false, bytes)) => match tarjan(code, table, root, opts) {
            Ok((l, b)) => (Some(l), None, bytes.max(b)),
            Err((s, b)) => (None, Some(s), bytes.max(b)),
        },
    }
}

type Counted<T> = Result<(T, usize), (Stop, usize)>;

/// Whether every one of the `states` states reaches the state in slot `root`.
fn reaches_root<const W: usize>(
    code: &Compiled<W>,
    table: &impl Visited<W>,
    root: usize,
    states: usize,
    opts: &ReachOptions,
) -> Counted<bool> {
    if opts.threads >= 2 {
        return reaches_root_layered(code, table, root, states, opts);
    }
    let cap = table.ids();
    let nt = code.offsets.len() - 1;
    let (per_batch, batch_cap) = batch_sizes(nt, states);
    let bytes =
        table.bytes() + cap.div_ceil(64) * 8 + (states + 1) * 4 + (batch_cap + per_batch) * 8 * W;
    opts.within_memory(bytes).map_err(|s| (s, bytes))?;
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
        if let Some(s) = opts.interrupted() {
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
        each_predecessor(code, table, &keys, &mut batch, |s| {
            // Without a branch on `seen`, whose outcome is random: the slot is written past the
            // queue's end and kept only when it is new.
            let new = !bit(&seen, s);
            set(&mut seen, s);
            queue[found] = s as u32;
            found += new as usize;
        });
    }
    Ok((found == states, bytes))
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

/// Calls `found` with the slot of every predecessor of every key in `keys` (with repeats), in
/// turn: the predecessors are generated into `batch` (which holds `keys.len()` times the
/// transitions), then looked up, each lookup starting the load of the home slot [`AHEAD`]
/// lookups further on.
fn each_predecessor<const W: usize>(
    code: &Compiled<W>,
    table: &impl Visited<W>,
    keys: &[[u64; W]],
    batch: &mut [[u64; W]],
    mut found: impl FnMut(usize),
) {
    let nt = code.offsets.len() - 1;
    // Written whether or not the predecessor exists, kept only when it does: no branch.
    let mut n = 0;
    for key in keys {
        for t in 0..nt {
            let (u, ok) = code.unfire_unchecked(key, t);
            batch[n] = u;
            n += ok as usize;
        }
    }
    let batch = &batch[..n];
    for (i, u) in batch.iter().enumerate() {
        if let Some(v) = batch.get(i + AHEAD) {
            table.touch(hash(v));
        }
        if let Some(s) = table.id_of(u, hash(u)) {
            found(s);
        }
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

/// One thread's share of the search of `layer`: the predecessors that no thread has found yet
/// are claimed in `seen` and appended to the queue. Stops early once the queue holds every one
/// of the `states` states.
fn search_part<const W: usize>(
    code: &Compiled<W>,
    table: &impl Visited<W>,
    layer: &Layer,
    seen: &[AtomicU64],
    states: usize,
    sc: &mut Scratch<W>,
) {
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
        gather(table, &sc.ids, end - head, &mut sc.keys);
        let found = &mut sc.found;
        found.clear();
        each_predecessor(code, table, &sc.keys, &mut sc.batch, |s| {
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

/// [`reaches_root`] on `opts.threads` threads: a breadth-first search by layers over one queue.
/// The threads split each layer and look up its predecessors (they only read the tables); a new
/// state is claimed with one atomic bit in `seen` (tested with a plain load first, so only the
/// first finding of each state writes), and appended to the queue by the thread that claimed it.
/// The layer's end is where the threads meet, so the queue's order within a layer may differ from
/// run to run, but its contents, the answer and the memory held do not.
fn reaches_root_layered<const W: usize>(
    code: &Compiled<W>,
    table: &impl Visited<W>,
    root: usize,
    states: usize,
    opts: &ReachOptions,
) -> Counted<bool> {
    let threads = opts.threads.max(1);
    let (per_batch, batch_cap) = batch_sizes(code.offsets.len() - 1, states);
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
            search_part(code, table, &layer, seen, states, sc);
        });
        head = end;
    }
    Ok((tail.load(Relaxed) >= states, bytes))
}

/// Iterative Tarjan over the implicit graph, nodes being table slots, recording terminal SCCs and
/// which transitions occur inside each.
fn tarjan<const W: usize>(
    code: &Compiled<W>,
    table: &impl Visited<W>,
    root: usize,
    opts: &ReachOptions,
) -> Counted<Liveness> {
    let n = table.ids();
    let nt = code.offsets.len() - 1;
    let fixed = table.bytes() + n * 8 + n.div_ceil(64) * 16;
    opts.within_memory(fixed).map_err(|s| (s, fixed))?;
    let mut index = vec![NONE; n];
    let mut low = vec![0u32; n];
    let mut on_stack = vec![0u64; n.div_ceil(64)];
    let mut exits = vec![0u64; n.div_ceil(64)];
    let mut stack: Vec<u32> = Vec::new();
    let mut frames: Vec<(u32, u32)> = Vec::new();
    let mut peak = fixed;
    let mut next_index = 0u32;
    let (mut sccs, mut terminal) = (0u64, 0u64);
    let mut missing = vec![false; nt];
    let mut root_terminal = false;
    let mut occurs = vec![false; nt];
    let mut visit = |v: usize,
                     index: &mut Vec<u32>,
                     low: &mut Vec<u32>,
                     on_stack: &mut Vec<u64>,
                     stack: &mut Vec<u32>| {
        index[v] = next_index;
        low[v] = next_index;
        next_index += 1;
        set(on_stack, v);
        stack.push(v as u32);
    };
    visit(root, &mut index, &mut low, &mut on_stack, &mut stack);
    frames.push((root as u32, 0));
    let mut steps = 0u64;
    while let Some(&(v, t0)) = frames.last() {
        steps += 1;
        if steps & 0x3FFF == 0 {
            // The stacks grow with the search's depth: counted here, before they grow further.
            let bytes = fixed + stack.capacity() * 4 + frames.capacity() * 8;
            peak = peak.max(bytes);
            if let Err(s) = opts.within_memory(bytes * 2 - fixed) {
                return Err((s, peak));
            }
            if let Some(s) = opts.interrupted() {
                return Err((s, peak));
            }
        }
        let v = v as usize;
        let key = table.key(v);
        let mut descended = false;
        let mut t = t0 as usize;
        while t < nt {
            if code.enabled(&key, t) {
                let succ = code.fire(&key, t);
                let w = table.id_of(&succ, hash(&succ)).unwrap_or(root);
                if index[w] == NONE {
                    if let Some(f) = frames.last_mut() {
                        f.1 = t as u32 + 1;
                    }
                    visit(w, &mut index, &mut low, &mut on_stack, &mut stack);
                    frames.push((w as u32, 0));
                    descended = true;
                    break;
                } else if bit(&on_stack, w) {
                    low[v] = low[v].min(index[w]);
                } else {
                    // w belongs to an SCC already completed, so this edge leaves v's SCC.
                    set(&mut exits, v);
                }
            }
            t += 1;
        }
        if descended {
            continue;
        }
        frames.pop();
        if low[v] == index[v] {
            sccs += 1;
            let start = stack.iter().rposition(|&x| x as usize == v).unwrap_or(0);
            let is_terminal = stack[start..].iter().all(|&x| !bit(&exits, x as usize));
            occurs.iter_mut().for_each(|o| *o = false);
            for &x in &stack[start..] {
                let x = x as usize;
                on_stack[x >> 6] &= !(1 << (x & 63));
                if is_terminal {
                    let k = table.key(x);
                    for (t, o) in occurs.iter_mut().enumerate() {
                        *o |= code.enabled(&k, t);
                    }
                }
            }
            stack.truncate(start);
            if is_terminal {
                terminal += 1;
                for (m, o) in missing.iter_mut().zip(&occurs) {
                    *m |= !o;
                }
                if v == root {
                    root_terminal = true;
                }
            }
            if let Some(&(u, _)) = frames.last() {
                // v's SCC is finished and differs from u's: the tree edge u → v leaves u's SCC.
                set(&mut exits, u as usize);
            }
        } else if let Some(&(u, _)) = frames.last() {
            let u = u as usize;
            low[u] = low[u].min(low[v]);
        }
    }
    peak = peak.max(fixed + stack.capacity() * 4 + frames.capacity() * 8);
    let non_live: Vec<TransIdx> = (0..nt)
        .filter(|&t| missing[t])
        .map(|t| TransIdx(t as u32))
        .collect();
    Ok((
        Liveness {
            sccs,
            terminal_sccs: terminal,
            live: non_live.is_empty(),
            non_live,
            reversible: root_terminal && terminal == 1,
        },
        peak,
    ))
}
