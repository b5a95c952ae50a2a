//! The property-directed search of `cetratus check --property/--reach/--always`: the same
//! breadth-first exploration over packed states as [`super::explore`], which stops as soon as the
//! answer is known and returns the firing sequence that shows it.
//!
//! * A **target** (a dead state, a dead state other than M0, or a marking satisfying a predicate)
//!   is tested when a state is discovered, so without reduction the witness is a shortest path.
//! * With **stubborn sets** (module `stubborn`) a state fires only the enabled transitions of a
//!   stubborn set; with a predicate, the visibility proviso is in the set and the cycle proviso
//!   here (a state with an already-seen reduced successor is expanded fully). The witness is then
//!   a real firing sequence but not necessarily a shortest one.
//! * **After** a complete exploration without reduction, liveness and reversibility are decided
//!   over the finished table (module `scc`), and their counterexample is found by a backward
//!   search: from M0 (reversibility) or from every state enabling a non-live transition
//!   (liveness); the first state in BFS order that the backward search misses is the end of a
//!   shortest path to a marking from which M0, or that transition, can never be reached again.

use cetratus_net::{Net, TransIdx};

use super::stubborn::Stubborn;
use super::{hash, scc, Chunked, Compiled, Packing, ReachOptions, Stop};
use crate::predicate::Predicate;

/// What the search looks for.
pub(crate) enum Target<'a> {
    /// Nothing: explore everything (for `After`).
    None,
    /// A state where no transition is enabled.
    Dead,
    /// A dead state other than M0.
    DeadNotInitial,
    /// A marking where the predicate holds.
    Marking(&'a Predicate),
}

/// What to decide once the exploration is complete.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum After {
    Nothing,
    Live,
    Reversible,
}

/// The outcome of a property-directed search.
pub(crate) struct Outcome {
    pub states: u64,
    pub edges: u64,
    /// The firing sequence to the target, when one was found.
    pub found: Option<Vec<TransIdx>>,
    pub stopped: Option<Stop>,
    /// `Live`/`Reversible`: the verdict, and a counterexample path when it is false.
    pub verdict: Option<(bool, Option<Vec<TransIdx>>)>,
    /// For `Live`: the transition the counterexample is about.
    pub culprit: Option<TransIdx>,
    pub peak_bytes: usize,
    pub bits_per_state: usize,
    /// States expanded with a reduced set (stubborn sets on).
    pub reduced_states: u64,
}

/// Runs the search with states packed by `pk`.
pub(crate) fn search<const W: usize>(
    net: &Net,
    pk: &Packing,
    target: &Target<'_>,
    stubborn: Option<&Stubborn>,
    after: After,
    opts: &ReachOptions,
) -> Outcome {
    let nt = net.num_transitions();
    let np = net.num_places();
    let code = Compiled::<W>::new(net, pk);
    let (mut table, mut states, mut parents, k0) = super::seeded::<W>(net, pk);
    let max_states = opts.state_limit();
    let field = |k: &[u64; W], p: usize| pk.fields[p].read(k);
    let goal = |k: &[u64; W]| match target {
        Target::Marking(pred) => pred.holds(|p| field(k, p.index())),
        _ => false,
    };
    let proviso = matches!(target, Target::Marking(_));
    let mut found: Option<usize> = goal(&k0).then_some(0);
    let mut enabled_ever = vec![false; nt];
    let mut en: Vec<u32> = Vec::with_capacity(nt);
    let mut is_en = vec![false; nt];
    let mut fire_set: Vec<u32> = Vec::with_capacity(nt);
    let mut scratch = stubborn.map(Stubborn::scratch);
    let mut marking = vec![0u64; np];
    let mut batch: Vec<([u64; W], u64)> = Vec::with_capacity(nt);
    let mut edges = 0u64;
    let mut reduced_states = 0u64;
    let mut stopped = None;
    let mut peak_bytes = 0usize;
    let mut cur = 0usize;
    'bfs: while cur < states.len && found.is_none() {
        if let Some(s) = super::checkpoint(opts, cur, edges, &table, &states, &parents) {
            stopped = Some(s);
            break;
        }
        let key = states.get(cur);
        en.clear();
        for (t, ever) in enabled_ever.iter_mut().enumerate() {
            let e = code.enabled(&key, t);
            is_en[t] = e;
            if e {
                *ever = true;
                en.push(t as u32);
            }
        }
        if en.is_empty() {
            let hit = match target {
                Target::Dead => true,
                Target::DeadNotInitial => cur != 0,
                _ => false,
            };
            if hit {
                found = Some(cur);
                break;
            }
            cur += 1;
            continue;
        }
        let reduced = match (stubborn, scratch.as_mut()) {
            (Some(st), Some(sc)) => {
                for (p, m) in marking.iter_mut().enumerate() {
                    *m = field(&key, p);
                }
                st.reduce(&marking, &en, &is_en, sc, &mut fire_set);
                fire_set.len() < en.len()
            }
            _ => false,
        };
        let sets: [&[u32]; 2] = if reduced {
            [&fire_set, &en]
        } else {
            [&en, &[]]
        };
        for (round, set) in sets.into_iter().enumerate() {
            batch.clear();
            for &t in set {
                // The second round fires the transitions the reduced set left out.
                if round == 1 && fire_set.binary_search(&t).is_ok() {
                    continue;
                }
                let succ = code.fire(&key, t as usize);
                batch.push((succ, hash(&succ)));
            }
            let need = super::bytes_to_add(&table, &states, &parents, batch.len());
            if let Err(s) = opts.within_memory(need) {
                stopped = Some(s);
                break 'bfs;
            }
            peak_bytes = peak_bytes.max(need);
            edges += batch.len() as u64;
            table.reserve(batch.len());
            let mut old = false;
            for (succ, h) in &batch {
                if table.insert_hashed(succ, *h) {
                    if states.len as u64 >= max_states {
                        stopped = Some(Stop::MaxStates(max_states));
                        break 'bfs;
                    }
                    states.push(*succ);
                    parents.push(cur as u32);
                    if goal(succ) {
                        found = Some(states.len - 1);
                        break 'bfs;
                    }
                } else {
                    old = true;
                }
            }
            // Cycle proviso: a reduced state that reaches a state seen before is expanded fully.
            if round == 0 && !(reduced && proviso && old) {
                if reduced {
                    reduced_states += 1;
                }
                break;
            }
        }
        cur += 1;
    }
    let peak_bytes = peak_bytes.max(table.bytes() + states.bytes() + parents.bytes());
    let path = |v: usize| path_to(&code, &states, &parents, v, nt);
    let mut out = Outcome {
        states: states.len as u64,
        edges,
        found: found.map(path),
        stopped,
        verdict: None,
        culprit: None,
        peak_bytes,
        bits_per_state: pk.bits,
        reduced_states,
    };
    if after == After::Nothing || out.stopped.is_some() || out.found.is_some() {
        return out;
    }
    let never: Vec<TransIdx> = (0..nt)
        .filter(|&t| !enabled_ever[t])
        .map(|t| TransIdx(t as u32))
        .collect();
    let (l, ls, bytes) = scc::liveness(&code, &table, &k0, states.len, &never, opts);
    let base = table.bytes() + states.bytes() + parents.bytes();
    out.peak_bytes = out.peak_bytes.max(bytes + states.bytes() + parents.bytes());
    let Some(l) = l else {
        out.stopped = ls;
        return out;
    };
    let holds = if after == After::Live {
        l.live
    } else {
        l.reversible
    };
    if holds {
        out.verdict = Some((true, None));
        return out;
    }
    // The backward search from the seeds marks every state that can reach one of them.
    let seeds: Vec<usize> = if after == After::Reversible {
        vec![0]
    } else {
        let t = l.non_live.first().map_or(0, |t| t.index());
        out.culprit = Some(TransIdx(t as u32));
        (0..states.len)
            .filter(|&i| code.enabled(&states.get(i), t))
            .collect()
    };
    let slot = |i: usize| {
        let k = states.get(i);
        table.slot_of(&k, hash(&k)).unwrap_or(0)
    };
    let cap = table.slots.len();
    let bytes = base + cap.div_ceil(64) * 8 + states.len * 4;
    out.peak_bytes = out.peak_bytes.max(bytes);
    if let Err(s) = opts.within_memory(bytes) {
        out.stopped = Some(s);
        return out;
    }
    let mut seen = vec![0u64; cap.div_ceil(64)];
    let mut queue: Vec<u32> = Vec::with_capacity(seeds.len());
    for &i in &seeds {
        let s = slot(i);
        if seen[s >> 6] >> (s & 63) & 1 == 0 {
            seen[s >> 6] |= 1 << (s & 63);
            queue.push(s as u32);
        }
    }
    let mut head = 0;
    while head < queue.len() {
        if head & 0x3FFF == 0 && head > 0 {
            if let Some(s) = opts.interrupted() {
                out.stopped = Some(s);
                return out;
            }
        }
        let key = table.slots[queue[head] as usize];
        head += 1;
        for t in 0..nt {
            if let Some(u) = code.unfire(&key, t) {
                if let Some(s) = table.slot_of(&u, hash(&u)) {
                    if seen[s >> 6] >> (s & 63) & 1 == 0 {
                        seen[s >> 6] |= 1 << (s & 63);
                        queue.push(s as u32);
                    }
                }
            }
        }
    }
    let missed = (0..states.len).find(|&i| {
        let s = slot(i);
        seen[s >> 6] >> (s & 63) & 1 == 0
    });
    out.verdict = Some((false, missed.map(path)));
    out
}

/// The firing sequence along the BFS parents from M0 to state `v`.
pub(super) fn path_to<const W: usize>(
    code: &Compiled<W>,
    states: &Chunked<[u64; W]>,
    parents: &Chunked<u32>,
    v: usize,
    nt: usize,
) -> Vec<TransIdx> {
    let mut path = Vec::new();
    let mut v = v;
    while parents.get(v) != u32::MAX {
        let u = parents.get(v) as usize;
        let (ku, kv) = (states.get(u), states.get(v));
        if let Some(t) = (0..nt).find(|&t| code.enabled(&ku, t) && code.fire(&ku, t) == kv) {
            path.push(TransIdx(t as u32));
        }
        v = u;
    }
    path.reverse();
    path
}
