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

use std::ops::ControlFlow;

use cetratus_net::{Net, TransIdx};

use super::scc::{self, bit, set};
use super::stubborn::{Scratch, Stubborn};
use super::{hash, Added, Chunked, Compiled, Packing, ReachOptions, Stop, Store};
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
    let code = Compiled::<W>::new(net, pk);
    let (store, k0) = Store::<W>::seeded(net, pk);
    let mut bfs = Bfs {
        code: &code,
        pk,
        target,
        stubborn,
        opts,
        max_states: opts.state_limit(),
        store,
        en: Vec::with_capacity(nt),
        is_en: vec![false; nt],
        fire_set: Vec::with_capacity(nt),
        scratch: stubborn.map(Stubborn::scratch),
        marking: vec![0u64; net.num_places()],
        batch: Vec::with_capacity(nt),
        enabled_ever: vec![false; nt],
        edges: 0,
        reduced_states: 0,
        peak_bytes: 0,
        found: None,
        stopped: None,
    };
    bfs.found = bfs.goal(&k0).then_some(0);
    bfs.run();
    let Bfs {
        store,
        enabled_ever,
        edges,
        reduced_states,
        peak_bytes,
        found,
        stopped,
        ..
    } = bfs;
    let mut out = Outcome {
        states: store.states.len as u64,
        edges,
        found: found.map(|v| path_to(&code, &store.states, &store.parents, v, nt)),
        stopped,
        verdict: None,
        culprit: None,
        peak_bytes: peak_bytes.max(store.bytes()),
        bits_per_state: pk.bits,
        reduced_states,
    };
    if after == After::Nothing || out.stopped.is_some() || out.found.is_some() {
        return out;
    }
    decide_after(&code, &store, &k0, &enabled_ever, after, opts, &mut out);
    out
}

/// The forward search: its store, the buffers that every state reuses, and what it found.
struct Bfs<'a, const W: usize> {
    code: &'a Compiled<W>,
    pk: &'a Packing,
    target: &'a Target<'a>,
    stubborn: Option<&'a Stubborn>,
    opts: &'a ReachOptions,
    max_states: u64,
    store: Store<W>,
    /// The transitions enabled at the state being expanded, as a list and per transition.
    en: Vec<u32>,
    is_en: Vec<bool>,
    /// The stubborn set of the state being expanded (sorted), and its scratch space.
    fire_set: Vec<u32>,
    scratch: Option<Scratch>,
    /// The state being expanded, unpacked for the stubborn sets.
    marking: Vec<u64>,
    /// The successors of one round, with their hashes.
    batch: Vec<([u64; W], u64)>,
    enabled_ever: Vec<bool>,
    edges: u64,
    reduced_states: u64,
    peak_bytes: usize,
    /// The target state, once found.
    found: Option<usize>,
    stopped: Option<Stop>,
}

/// Which enabled transitions a round of a state's expansion fires.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Round {
    /// All of them (no reduction).
    All,
    /// The stubborn set.
    Stubborn,
    /// Those the stubborn set left out (the cycle proviso asked for a full expansion).
    Rest,
}

impl<const W: usize> Bfs<'_, W> {
    /// The marking `k` is a target marking.
    #[inline]
    fn goal(&self, k: &[u64; W]) -> bool {
        match self.target {
            Target::Marking(pred) => pred.holds(|p| self.pk.fields[p.index()].read(k)),
            _ => false,
        }
    }

    /// Expands the states in breadth-first order until the target is found, the state space
    /// is exhausted, or a budget stops the search.
    fn run(&mut self) {
        let mut cur = 0usize;
        while cur < self.store.states.len && self.found.is_none() {
            if let Some(s) = self.store.checkpoint(self.opts, cur, self.edges) {
                self.stopped = Some(s);
                break;
            }
            if self.expand(cur).is_break() {
                break;
            }
            cur += 1;
        }
    }

    /// Expands state `cur`: a dead state may be the target; otherwise its stubborn set is
    /// fired, or every enabled transition. Breaks when the search ends here.
    #[inline]
    fn expand(&mut self, cur: usize) -> ControlFlow<()> {
        let key = self.store.states.get(cur);
        self.enabled_at(&key);
        if self.en.is_empty() {
            let hit = match self.target {
                Target::Dead => true,
                Target::DeadNotInitial => cur != 0,
                _ => false,
            };
            if hit {
                self.found = Some(cur);
                return ControlFlow::Break(());
            }
            return ControlFlow::Continue(());
        }
        if !self.reduce(&key) {
            self.fire_round(&key, cur, Round::All)?;
            return ControlFlow::Continue(());
        }
        let old = self.fire_round(&key, cur, Round::Stubborn)?;
        // Cycle proviso: a reduced state that reaches a state seen before is expanded fully.
        if matches!(self.target, Target::Marking(_)) && old {
            self.fire_round(&key, cur, Round::Rest)?;
        } else {
            self.reduced_states += 1;
        }
        ControlFlow::Continue(())
    }

    /// Lists the transitions enabled at `key`, and marks them enabled somewhere.
    #[inline(always)]
    fn enabled_at(&mut self, key: &[u64; W]) {
        self.en.clear();
        for (t, ever) in self.enabled_ever.iter_mut().enumerate() {
            let e = self.code.enabled(key, t);
            self.is_en[t] = e;
            if e {
                *ever = true;
                self.en.push(t as u32);
            }
        }
    }

    /// Computes the stubborn set of `key` into `fire_set`; true when it leaves out an enabled
    /// transition.
    #[inline]
    fn reduce(&mut self, key: &[u64; W]) -> bool {
        let (Some(st), Some(sc)) = (self.stubborn, self.scratch.as_mut()) else {
            return false;
        };
        for (p, m) in self.marking.iter_mut().enumerate() {
            *m = self.pk.fields[p].read(key);
        }
        st.reduce(&self.marking, &self.en, &self.is_en, sc, &mut self.fire_set);
        self.fire_set.len() < self.en.len()
    }

    /// Fires the transitions of `round` at `key` (state `cur`) and adds the successors.
    /// Continues with whether one of them was seen before; breaks when the search ends.
    #[inline]
    fn fire_round(&mut self, key: &[u64; W], cur: usize, round: Round) -> ControlFlow<(), bool> {
        self.batch.clear();
        let set: &[u32] = if round == Round::Stubborn {
            &self.fire_set
        } else {
            &self.en
        };
        for &t in set {
            if round == Round::Rest && self.fire_set.binary_search(&t).is_ok() {
                continue;
            }
            let succ = self.code.fire(key, t as usize);
            self.batch.push((succ, hash(&succ)));
        }
        let need = self.store.bytes_to_add(self.batch.len());
        if let Err(s) = self.opts.within_memory(need) {
            self.stopped = Some(s);
            return ControlFlow::Break(());
        }
        self.peak_bytes = self.peak_bytes.max(need);
        self.edges += self.batch.len() as u64;
        self.store.table.reserve(self.batch.len());
        let mut old = false;
        for (succ, h) in &self.batch {
            match self.store.add(succ, *h, cur, self.max_states) {
                Added::New if self.goal(succ) => {
                    self.found = Some(self.store.states.len - 1);
                    return ControlFlow::Break(());
                }
                Added::New => {}
                Added::Known => old = true,
                Added::Full => {
                    self.stopped = Some(Stop::MaxStates(self.max_states));
                    return ControlFlow::Break(());
                }
            }
        }
        ControlFlow::Continue(old)
    }
}

/// Liveness or reversibility over the finished table and, when it fails, the counterexample: a
/// shortest path to the first state, in BFS order, from which the seeds of a backward search
/// cannot be reached (M0, or the states that enable a non-live transition).
fn decide_after<const W: usize>(
    code: &Compiled<W>,
    store: &Store<W>,
    k0: &[u64; W],
    enabled_ever: &[bool],
    after: After,
    opts: &ReachOptions,
    out: &mut Outcome,
) {
    let nt = enabled_ever.len();
    let never: Vec<TransIdx> = (0..nt)
        .filter(|&t| !enabled_ever[t])
        .map(|t| TransIdx(t as u32))
        .collect();
    let (states, parents) = (&store.states, &store.parents);
    let (l, ls, bytes) = scc::liveness(code, &store.table, k0, states.len, &never, opts);
    out.peak_bytes = out.peak_bytes.max(bytes + states.bytes() + parents.bytes());
    let Some(l) = l else {
        out.stopped = ls;
        return;
    };
    let holds = if after == After::Live {
        l.live
    } else {
        l.reversible
    };
    if holds {
        out.verdict = Some((true, None));
        return;
    }
    let seeds: Vec<usize> = if after == After::Reversible {
        vec![0]
    } else {
        let t = l.non_live.first().map_or(0, |t| t.index());
        out.culprit = Some(TransIdx(t as u32));
        (0..states.len)
            .filter(|&i| code.enabled(&states.get(i), t))
            .collect()
    };
    match first_not_reaching(code, store, &seeds, opts, &mut out.peak_bytes) {
        Ok(missed) => {
            let path = |v| path_to(code, states, parents, v, nt);
            out.verdict = Some((false, missed.map(path)));
        }
        Err(s) => out.stopped = Some(s),
    }
}

/// The first state, in BFS order, that cannot reach any of the states `seeds`: a backward
/// search from the seeds marks every state that can. Its bytes count into `peak_bytes`.
fn first_not_reaching<const W: usize>(
    code: &Compiled<W>,
    store: &Store<W>,
    seeds: &[usize],
    opts: &ReachOptions,
    peak_bytes: &mut usize,
) -> Result<Option<usize>, Stop> {
    let (table, states) = (&store.table, &store.states);
    let slot = |i: usize| {
        let k = states.get(i);
        table.slot_of(&k, hash(&k)).unwrap_or(0)
    };
    let cap = table.slots.len();
    let bytes = store.bytes() + cap.div_ceil(64) * 8 + states.len * 4;
    *peak_bytes = (*peak_bytes).max(bytes);
    opts.within_memory(bytes)?;
    let mut seen = vec![0u64; cap.div_ceil(64)];
    let mut queue: Vec<u32> = Vec::with_capacity(seeds.len());
    // Queues slot `s` unless it was seen.
    let visit = |seen: &mut [u64], queue: &mut Vec<u32>, s: usize| {
        if !bit(seen, s) {
            set(seen, s);
            queue.push(s as u32);
        }
    };
    for &i in seeds {
        visit(&mut seen, &mut queue, slot(i));
    }
    let mut head = 0;
    while head < queue.len() {
        if head & 0x3FFF == 0 && head > 0 {
            if let Some(s) = opts.interrupted() {
                return Err(s);
            }
        }
        let key = table.slots[queue[head] as usize];
        head += 1;
        for t in 0..code.transitions() {
            if let Some(u) = code.unfire(&key, t) {
                if let Some(s) = table.slot_of(&u, hash(&u)) {
                    visit(&mut seen, &mut queue, s);
                }
            }
        }
    }
    Ok((0..states.len).find(|&i| !bit(&seen, slot(i))))
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
