//! The token game: incremental enabling and the firing policies of docs/design.md §3.
//!
//! The engine keeps the set of enabled transitions up to date after every change of the marking by
//! looking only at the transitions that depend on the places that changed. A scan therefore costs
//! what the activity costs (the enabled transitions, the ones that fire, and their neighbourhoods),
//! not what the size of the net costs. All buffers are sized when the engine is built, so a scan
//! never allocates.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::Arc;

use cetratus_vocab::UnknownName;

use crate::{Marking, Net, NetError, PlaceIdx, Tokens, TransIdx};

/// How one firing is chosen under the `single` policy.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SingleRule {
    /// The firable transition declared last (the rule of the semi-compiled algorithm).
    Last,
    /// The firable transition declared first.
    First,
    /// The firable transition of highest priority; ties go to the one declared first.
    Priority,
}

/// What fires in one scan.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Policy {
    /// A maximal greedy step: transitions visited by priority, then declaration order (docs/design.md §3).
    #[default]
    Step,
    /// One firing per scan, chosen by the rule.
    Single(SingleRule),
}

impl std::str::FromStr for Policy {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, UnknownName> {
        match s {
            "step" => Ok(Policy::Step),
            "single-last" | "single" => Ok(Policy::Single(SingleRule::Last)),
            "single-first" => Ok(Policy::Single(SingleRule::First)),
            "single-priority" => Ok(Policy::Single(SingleRule::Priority)),
            other => Err(UnknownName {
                what: "firing policy",
                value: other.chars().take(64).collect(),
                expected: "step, single-last, single-first or single-priority",
            }),
        }
    }
}

impl std::fmt::Display for Policy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Policy::Step => "step",
            Policy::Single(SingleRule::Last) => "single-last",
            Policy::Single(SingleRule::First) => "single-first",
            Policy::Single(SingleRule::Priority) => "single-priority",
        })
    }
}

/// Why a scan did not complete. The marking is then exactly what it was before the scan.
#[derive(Debug, PartialEq, Eq)]
pub enum FireError<E> {
    /// The guard of a transition failed to evaluate.
    Guard {
        /// The transition whose guard failed.
        transition: TransIdx,
        /// The guard's error.
        error: E,
    },
    /// Firing would take a token count past `Tokens::MAX`.
    Overflow {
        /// The transition that would fire.
        transition: TransIdx,
        /// The place that would overflow.
        place: PlaceIdx,
    },
}

impl<E: std::fmt::Display> std::fmt::Display for FireError<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FireError::Guard { transition, error } => {
                write!(f, "guard of transition #{} failed: {error}", transition.0)
            }
            FireError::Overflow { transition, place } => write!(
                f,
                "firing transition #{} would overflow the token count of place #{}",
                transition.0, place.0
            ),
        }
    }
}

impl<E: std::fmt::Debug + std::fmt::Display> std::error::Error for FireError<E> {}

const NONE: u32 = u32::MAX;

/// The running state of one net: its marking, the enabled set, and reusable scratch buffers.
#[derive(Clone, Debug)]
pub struct Engine {
    net: Arc<Net>,
    m: Vec<Tokens>,
    enabled: Vec<TransIdx>,
    enabled_pos: Vec<u32>,
    // Scratch, sized once.
    stamp: Vec<u32>,
    epoch: u32,
    heap: BinaryHeap<Reverse<u32>>,
    produced: Vec<Tokens>,
    produced_touched: Vec<PlaceIdx>,
    fired: Vec<TransIdx>,
    changed: Vec<(PlaceIdx, Tokens)>,
    place_stamp: Vec<u32>,
    place_epoch: u32,
}

impl Engine {
    /// An engine at the net's initial marking.
    pub fn new(net: Arc<Net>) -> Self {
        let m0 = net.initial_marking();
        Self::with_marking(net, m0).expect("the initial marking has the net's length")
    }

    /// An engine at a given marking.
    pub fn with_marking(net: Arc<Net>, marking: Marking) -> Result<Self, NetError> {
        let np = net.num_places();
        let nt = net.num_transitions();
        if marking.len() != np {
            return Err(NetError::MarkingLength {
                expected: np,
                got: marking.len(),
            });
        }
        let mut e = Engine {
            m: marking.0,
            enabled: Vec::with_capacity(nt),
            enabled_pos: vec![NONE; nt],
            stamp: vec![0; nt],
            epoch: 0,
            heap: BinaryHeap::with_capacity(nt),
            produced: vec![0; np],
            produced_touched: Vec::with_capacity(np),
            fired: Vec::with_capacity(nt),
            changed: Vec::with_capacity(np),
            place_stamp: vec![0; np],
            place_epoch: 0,
            net,
        };
        e.recompute_enabled();
        Ok(e)
    }

    /// The net.
    pub fn net(&self) -> &Arc<Net> {
        &self.net
    }

    /// The current marking, in place order.
    pub fn marking(&self) -> &[Tokens] {
        &self.m
    }

    /// Replaces the marking (same length) and recomputes the enabled set from scratch.
    pub fn set_marking(&mut self, marking: &[Tokens]) -> Result<(), NetError> {
        if marking.len() != self.m.len() {
            return Err(NetError::MarkingLength {
                expected: self.m.len(),
                got: marking.len(),
            });
        }
        self.m.copy_from_slice(marking);
        self.recompute_enabled();
        Ok(())
    }

    /// The enabled transitions, in no particular order.
    pub fn enabled(&self) -> &[TransIdx] {
        &self.enabled
    }

    /// True when the net has transitions and none is enabled: it can never fire again. A net
    /// without transitions (a program whose behaviour is its action bodies, such as an imported
    /// Structured Text POU) is never dead.
    pub fn deadlocked(&self) -> bool {
        self.enabled.is_empty() && self.net.num_transitions() > 0
    }

    /// True when t is enabled at the current marking.
    pub fn is_enabled(&self, t: TransIdx) -> bool {
        self.enabled_pos[t.index()] != NONE
    }

    /// The transitions fired by the last scan, in firing order.
    pub fn fired(&self) -> &[TransIdx] {
        &self.fired
    }

    /// The places whose count changed in the last scan, each with its count before the scan.
    pub fn changes(&self) -> &[(PlaceIdx, Tokens)] {
        &self.changed
    }

    /// The enabled set computed from scratch, sorted; for checking the incremental one.
    pub fn enabled_from_scratch(&self) -> Vec<TransIdx> {
        (0..self.net.num_transitions() as u32)
            .map(TransIdx)
            .filter(|&t| self.net.is_enabled(t, &self.m))
            .collect()
    }

    fn recompute_enabled(&mut self) {
        for &t in &self.enabled {
            self.enabled_pos[t.index()] = NONE;
        }
        self.enabled.clear();
        for i in 0..self.net.num_transitions() as u32 {
            let t = TransIdx(i);
            if self.net.is_enabled(t, &self.m) {
                self.enabled_pos[t.index()] = self.enabled.len() as u32;
                self.enabled.push(t);
            }
        }
    }

    #[inline]
    fn set_enabled(&mut self, t: TransIdx, on: bool) {
        let pos = self.enabled_pos[t.index()];
        if on && pos == NONE {
            self.enabled_pos[t.index()] = self.enabled.len() as u32;
            self.enabled.push(t);
        } else if !on && pos != NONE {
            let last = *self.enabled.last().expect("t is in the list");
            self.enabled.swap_remove(pos as usize);
            if last != t {
                self.enabled_pos[last.index()] = pos;
            }
            self.enabled_pos[t.index()] = NONE;
        }
    }

    fn next_epoch(&mut self) -> u32 {
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.epoch = 1;
        }
        self.epoch
    }

    fn begin_scan(&mut self) {
        self.fired.clear();
        self.changed.clear();
        self.place_epoch = self.place_epoch.wrapping_add(1);
        if self.place_epoch == 0 {
            self.place_stamp.iter_mut().for_each(|s| *s = 0);
            self.place_epoch = 1;
        }
    }

    /// Applies `C[·,t]` to the marking, recording changes; on overflow nothing is changed.
    fn apply(&mut self, t: TransIdx) -> Result<(), PlaceIdx> {
        let net = &*self.net;
        for &(p, d) in net.delta(t) {
            if d > 0 && i64::from(self.m[p.index()]) + d > i64::from(Tokens::MAX) {
                return Err(p);
            }
        }
        for &(p, d) in net.delta(t) {
            let i = p.index();
            if self.place_stamp[i] != self.place_epoch {
                self.place_stamp[i] = self.place_epoch;
                self.changed.push((p, self.m[i]));
            }
            // In range: checked above for growth, and a decrease never goes below Pre ≤ M.
            self.m[i] = (i64::from(self.m[i]) + d) as Tokens;
        }
        self.fired.push(t);
        Ok(())
    }

    fn rollback(&mut self) {
        let net = Arc::clone(&self.net);
        for &t in self.fired.iter().rev() {
            for &(p, d) in net.delta(t) {
                self.m[p.index()] = (i64::from(self.m[p.index()]) - d) as Tokens;
            }
        }
        self.fired.clear();
        self.changed.clear();
        self.clear_produced();
    }

    fn clear_produced(&mut self) {
        for &p in &self.produced_touched {
            self.produced[p.index()] = 0;
        }
        self.produced_touched.clear();
    }

    fn update_enabling(&mut self) {
        let epoch = self.next_epoch();
        let net = Arc::clone(&self.net);
        for k in 0..self.changed.len() {
            let p = self.changed[k].0;
            for &t in net.dependents(p) {
                if self.stamp[t.index()] != epoch {
                    self.stamp[t.index()] = epoch;
                    let on = net.is_enabled(t, &self.m);
                    self.set_enabled(t, on);
                }
            }
        }
    }

    /// Runs one scan under `policy`, asking `guard` whether each candidate's condition holds.
    ///
    /// Returns the transitions fired, in firing order. On error the marking and the enabled set
    /// are exactly as before the scan.
    pub fn scan<E>(
        &mut self,
        policy: Policy,
        guard: impl FnMut(TransIdx) -> Result<bool, E>,
    ) -> Result<&[TransIdx], FireError<E>> {
        self.begin_scan();
        let res = match policy {
            Policy::Step => self.step(guard),
            Policy::Single(rule) => self.single(rule, guard),
        };
        match res {
            Ok(()) => {
                self.update_enabling();
                Ok(&self.fired)
            }
            Err(e) => {
                self.rollback();
                Err(e)
            }
        }
    }

    /// Fires one transition if it is enabled; returns whether it fired.
    pub fn fire(&mut self, t: TransIdx) -> Result<bool, FireError<std::convert::Infallible>> {
        self.begin_scan();
        if !self.is_enabled(t) {
            return Ok(false);
        }
        self.apply(t).map_err(|place| FireError::Overflow {
            transition: t,
            place,
        })?;
        self.update_enabling();
        Ok(true)
    }

    fn step<E>(
        &mut self,
        mut guard: impl FnMut(TransIdx) -> Result<bool, E>,
    ) -> Result<(), FireError<E>> {
        let net = Arc::clone(&self.net);
        let epoch = self.next_epoch();
        self.heap.clear();
        for &t in &self.enabled {
            self.stamp[t.index()] = epoch;
            self.heap.push(Reverse(net.rank(t)));
        }
        let result = loop {
            let Some(Reverse(r)) = self.heap.pop() else {
                break Ok(());
            };
            let t = net.by_rank(r);
            // Pre against what was there at the start minus what the step already took; tokens
            // produced in this scan are only usable in the next one.
            let m = &self.m;
            let produced = &self.produced;
            let ok = net
                .pre(t)
                .iter()
                .all(|&(p, w)| m[p.index()] - produced[p.index()] >= w)
                && (!net.has_inhibitors()
                    || net.inhibitors(t).iter().all(|&(p, w)| m[p.index()] < w))
                && net.fits_capacity(t, m);
            if !ok {
                continue;
            }
            match guard(t) {
                Ok(true) => {}
                Ok(false) => continue,
                Err(error) => {
                    break Err(FireError::Guard {
                        transition: t,
                        error,
                    })
                }
            }
            if let Err(place) = self.apply(t) {
                break Err(FireError::Overflow {
                    transition: t,
                    place,
                });
            }
            for &(p, w) in net.post(t) {
                let i = p.index();
                if self.produced[i] == 0 {
                    self.produced_touched.push(p);
                }
                self.produced[i] += w;
            }
            // A firing that lowers a count can lift an inhibitor or make room under a capacity
            // for a transition visited later in this same step.
            if net.has_inhibitors() || net.has_capacities() {
                for &(p, d) in net.delta(t) {
                    if d >= 0 {
                        continue;
                    }
                    for &(u, _) in net.inhibited(p) {
                        self.push_later(u, r, epoch);
                    }
                    if net.capacity(p).is_some() {
                        for &(u, _) in net.producers(p) {
                            self.push_later(u, r, epoch);
                        }
                    }
                }
            }
        };
        self.clear_produced();
        result
    }

    #[inline]
    fn push_later(&mut self, u: TransIdx, current_rank: u32, epoch: u32) {
        let ru = self.net.rank(u);
        if ru > current_rank && self.stamp[u.index()] != epoch {
            self.stamp[u.index()] = epoch;
            self.heap.push(Reverse(ru));
        }
    }

    fn single<E>(
        &mut self,
        rule: SingleRule,
        mut guard: impl FnMut(TransIdx) -> Result<bool, E>,
    ) -> Result<(), FireError<E>> {
        let net = Arc::clone(&self.net);
        // Lower key wins.
        let key = |t: TransIdx| -> u32 {
            match rule {
                SingleRule::Last => u32::MAX - t.0,
                SingleRule::First => t.0,
                SingleRule::Priority => net.rank(t),
            }
        };
        let mut best: Option<(u32, TransIdx)> = None;
        for i in 0..self.enabled.len() {
            let t = self.enabled[i];
            let k = key(t);
            if best.is_some_and(|(bk, _)| bk <= k) {
                continue;
            }
            match guard(t) {
                Ok(true) => best = Some((k, t)),
                Ok(false) => {}
                Err(error) => {
                    return Err(FireError::Guard {
                        transition: t,
                        error,
                    })
                }
            }
        }
        if let Some((_, t)) = best {
            self.apply(t).map_err(|place| FireError::Overflow {
                transition: t,
                place,
            })?;
        }
        Ok(())
    }
}
