//! Stubborn sets (Valmari) for the property-directed search: at each state only the enabled
//! transitions of a stubborn set are fired, which keeps every deadlock and, with the visibility
//! and cycle provisos, every reachable marking that a predicate can tell apart.
//!
//! Closure rules, for a set S built from one enabled seed:
//!
//! * an **enabled** `t` in S brings in every transition that can disable it or that it can
//!   disable (then firing transitions outside S never disables `t`, and firing `t` first never
//!   disables them, so the two orders commute — condition D1; every enabled `t` in S is a key
//!   transition — D2). With inhibitor arcs and capacities, producing tokens can disable, so
//!   "can disable `t`" is: consumes from a place `t` takes from; produces into a place that
//!   inhibits `t`; produces into a place with a capacity into which `t` also produces.
//! * a **disabled** `t` in S names one reason it is disabled (a scapegoat place) and brings in
//!   every transition that could remove that reason: producers of a place with too few tokens;
//!   consumers of a place with too many for an inhibitor arc or for a capacity.
//! * **visibility** (reachability only): if S holds an enabled transition that changes a place
//!   the predicate reads, S holds every such transition.
//!
//! The cycle proviso lives in the search: a state whose reduced successors include one seen
//! before is expanded fully, so every cycle of the reduced graph holds a fully expanded state.
//!
//! Every arc relation is looked up per place at run time (no transition × transition table), so
//! memory stays linear in the net.

use cetratus_net::{Net, PlaceIdx, TransIdx};

/// What the closure needs of the net, per transition and per place.
pub(crate) struct Stubborn {
    pre: Vec<Vec<(u32, u32)>>,
    inh: Vec<Vec<(u32, u32)>>,
    delta: Vec<Vec<(u32, i64)>>,
    cap: Vec<Option<u64>>,
    /// Per place: transitions that add tokens to it, remove tokens from it, need tokens in it
    /// (Pre > 0), are inhibited by it.
    inc: Vec<Vec<u32>>,
    dec: Vec<Vec<u32>>,
    needs: Vec<Vec<u32>>,
    inhibited: Vec<Vec<u32>>,
    visible: Vec<bool>,
    visible_list: Vec<u32>,
    /// Seeds tried per state (the smallest set wins).
    pub(crate) seeds: usize,
}

/// Buffers of the closure, allocated once per search.
pub(crate) struct Scratch {
    stamp: Vec<u32>,
    gen: u32,
    work: Vec<u32>,
    members: Vec<u32>,
    best: Vec<u32>,
}

impl Stubborn {
    /// The closure data of `net`; `visible_places` flags the places a predicate reads.
    pub(crate) fn new(net: &Net, visible_places: Option<&[bool]>) -> Stubborn {
        let nt = net.num_transitions();
        let np = net.num_places();
        let t = |i: usize| TransIdx(i as u32);
        let mut inc = vec![Vec::new(); np];
        let mut dec = vec![Vec::new(); np];
        let mut needs = vec![Vec::new(); np];
        let mut inhibited = vec![Vec::new(); np];
        let mut visible = vec![false; nt];
        for (i, vis) in visible.iter_mut().enumerate() {
            for &(p, d) in net.delta(t(i)) {
                if d > 0 {
                    inc[p.index()].push(i as u32);
                } else if d < 0 {
                    dec[p.index()].push(i as u32);
                }
                if d != 0 && visible_places.is_some_and(|v| v[p.index()]) {
                    *vis = true;
                }
            }
            for &(p, _) in net.pre(t(i)) {
                needs[p.index()].push(i as u32);
            }
            for &(p, _) in net.inhibitors(t(i)) {
                inhibited[p.index()].push(i as u32);
            }
        }
        let pairs = |v: &[(PlaceIdx, u32)]| v.iter().map(|&(p, w)| (p.0, w)).collect::<Vec<_>>();
        Stubborn {
            pre: (0..nt).map(|i| pairs(net.pre(t(i)))).collect(),
            inh: (0..nt).map(|i| pairs(net.inhibitors(t(i)))).collect(),
            delta: (0..nt)
                .map(|i| net.delta(t(i)).iter().map(|&(p, d)| (p.0, d)).collect())
                .collect(),
            cap: (0..np)
                .map(|p| net.capacity(PlaceIdx(p as u32)).map(u64::from))
                .collect(),
            visible_list: (0..nt as u32).filter(|&i| visible[i as usize]).collect(),
            visible,
            inc,
            dec,
            needs,
            inhibited,
            seeds: 4,
        }
    }

    /// Fresh buffers for [`Stubborn::reduce`].
    pub(crate) fn scratch(&self) -> Scratch {
        Scratch {
            stamp: vec![0; self.pre.len()],
            gen: 0,
            work: Vec::new(),
            members: Vec::new(),
            best: Vec::new(),
        }
    }

    /// The enabled transitions of a stubborn set at marking `m`, written to `out` (a subset of
    /// `enabled`, never empty when `enabled` is not). `is_enabled[t]` flags `enabled`.
    pub(crate) fn reduce(
        &self,
        m: &[u64],
        enabled: &[u32],
        is_enabled: &[bool],
        s: &mut Scratch,
        out: &mut Vec<u32>,
    ) {
        out.clear();
        if enabled.len() <= 1 {
            out.extend_from_slice(enabled);
            return;
        }
        let mut best_len = usize::MAX;
        s.best.clear();
        for &seed in enabled.iter().take(self.seeds) {
            if let Some(n) = self.closure(seed, m, is_enabled, s, best_len) {
                if n < best_len {
                    best_len = n;
                    std::mem::swap(&mut s.best, &mut s.members);
                    if n == 1 {
                        break;
                    }
                }
            }
        }
        out.extend(s.best.iter().copied().filter(|&t| is_enabled[t as usize]));
        out.sort_unstable();
    }

    /// Closes `{seed}`; returns its number of enabled members, or `None` once it reaches `limit`.
    fn closure(
        &self,
        seed: u32,
        m: &[u64],
        is_enabled: &[bool],
        s: &mut Scratch,
        limit: usize,
    ) -> Option<usize> {
        s.gen = s.gen.wrapping_add(1);
        if s.gen == 0 {
            s.stamp.iter_mut().for_each(|x| *x = 0);
            s.gen = 1;
        }
        let gen = s.gen;
        s.work.clear();
        s.members.clear();
        let mut enabled_in = 0usize;
        let mut all_visible = false;
        let add = |t: u32, s: &mut Scratch| {
            if s.stamp[t as usize] != gen {
                s.stamp[t as usize] = gen;
                s.work.push(t);
                s.members.push(t);
            }
        };
        add(seed, s);
        while let Some(t) = s.work.pop() {
            let ti = t as usize;
            if is_enabled[ti] {
                enabled_in += 1;
                if enabled_in >= limit {
                    return None;
                }
                for &(p, _) in &self.pre[ti] {
                    self.dec[p as usize].iter().for_each(|&u| add(u, s));
                }
                for &(p, _) in &self.inh[ti] {
                    self.inc[p as usize].iter().for_each(|&u| add(u, s));
                }
                for &(p, d) in &self.delta[ti] {
                    let p = p as usize;
                    if d < 0 {
                        self.needs[p].iter().for_each(|&u| add(u, s));
                    } else if d > 0 {
                        self.inhibited[p].iter().for_each(|&u| add(u, s));
                        if self.cap[p].is_some() {
                            self.inc[p].iter().for_each(|&u| add(u, s));
                        }
                    }
                }
                if self.visible[ti] && !all_visible {
                    all_visible = true;
                    self.visible_list.iter().for_each(|&u| add(u, s));
                }
            } else {
                self.scapegoat(ti, m, s, gen);
            }
        }
        Some(enabled_in)
    }

    /// Adds the transitions that could remove one reason why `t` is disabled at `m`.
    fn scapegoat(&self, t: usize, m: &[u64], s: &mut Scratch, gen: u32) {
        let add_all = |list: &[u32], s: &mut Scratch| {
            for &u in list {
                if s.stamp[u as usize] != gen {
                    s.stamp[u as usize] = gen;
                    s.work.push(u);
                    s.members.push(u);
                }
            }
        };
        for &(p, w) in &self.pre[t] {
            if m[p as usize] < u64::from(w) {
                return add_all(&self.inc[p as usize], s);
            }
        }
        for &(p, w) in &self.inh[t] {
            if m[p as usize] >= u64::from(w) {
                return add_all(&self.dec[p as usize], s);
            }
        }
        for &(p, d) in &self.delta[t] {
            if let (Some(c), true) = (self.cap[p as usize], d > 0) {
                if m[p as usize] + d as u64 > c {
                    return add_all(&self.dec[p as usize], s);
                }
            }
        }
    }
}
