//! The Karp–Miller coverability graph, for nets that may be unbounded.
//!
//! Nodes are ω-markings, explored breadth-first and merged when equal. A successor that strictly
//! covers one of its ancestors on the BFS tree gets ω in every place that grew. When no ω appears,
//! the graph is the reachability graph and its maxima are the exact place bounds.
//!
//! Inhibitor arcs and capacities make coverability undecidable in general. Here places with a
//! capacity or an inhibitor arc are never accelerated (so a place that an inhibitor keeps small is
//! explored exactly, not declared ω), and an ω place fails every inhibitor test. With either
//! feature the unbounded places reported are a best effort, and the report says so.

use std::ops::ControlFlow;

use cetratus_net::{Net, PlaceIdx, TransIdx};

use crate::reach::{ReachOptions, Stop};
use crate::Progress;

/// ω, "as many tokens as you like".
pub const OMEGA: u64 = u64::MAX;

/// The coverability graph's figures.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Coverability {
    /// Nodes (ω-markings).
    pub nodes: u64,
    /// Edges from expanded nodes.
    pub edges: u64,
    /// Expanded nodes with no enabled transition.
    pub dead: u64,
    /// A shortest firing sequence to a dead node.
    pub dead_witness: Option<Vec<TransIdx>>,
    /// Places that reach ω.
    pub unbounded: Vec<PlaceIdx>,
    /// Largest count per place, [`OMEGA`] for unbounded places.
    pub max_tokens: Vec<u64>,
    /// Why it stopped early, if it did.
    pub stopped: Option<Stop>,
    /// The firing sequence to the first node that got an ω: it reaches a marking that strictly
    /// covers an earlier marking on the same path, so the sequence between them can repeat.
    pub first_omega: Option<Vec<TransIdx>>,
}

fn enabled(net: &Net, t: TransIdx, m: &[u64]) -> bool {
    net.pre(t)
        .iter()
        .all(|&(p, w)| m[p.index()] >= u64::from(w))
        && net
            .inhibitors(t)
            .iter()
            .all(|&(p, w)| m[p.index()] < u64::from(w))
        && net.delta(t).iter().all(|&(p, d)| match net.capacity(p) {
            Some(cap) if d > 0 => m[p.index()].saturating_add(d as u64) <= u64::from(cap),
            _ => true,
        })
}

fn fire(net: &Net, t: TransIdx, m: &[u64]) -> Vec<u64> {
    let mut out = m.to_vec();
    for &(p, d) in net.delta(t) {
        let v = &mut out[p.index()];
        if *v != OMEGA {
            // A count past the token type's range is as good as unbounded.
            *v = (i128::from(*v) + i128::from(d))
                .try_into()
                .ok()
                .filter(|&x: &u64| x <= u64::from(u32::MAX))
                .unwrap_or(OMEGA);
        }
    }
    out
}

/// Nodes in chunks that never move (no reallocation peak), each row the node's counts followed by
/// its parent and the transition that made it, packed into one `u64`.
struct Nodes {
    width: usize,
    chunks: Vec<Vec<u64>>,
    len: usize,
}

const NODE_CHUNK: usize = 4096;
const NO_PARENT: u64 = u64::MAX;

impl Nodes {
    fn row(&self, i: usize) -> &[u64] {
        let c = &self.chunks[i / NODE_CHUNK];
        let o = (i % NODE_CHUNK) * self.width;
        &c[o..o + self.width]
    }
    fn marking(&self, i: usize) -> &[u64] {
        let r = self.row(i);
        &r[..r.len() - 1]
    }
    /// `(parent, transition)`, `None` for the root.
    fn parent(&self, i: usize) -> Option<(usize, u32)> {
        let link = self.row(i)[self.width - 1];
        (link != NO_PARENT).then_some(((link >> 32) as usize, link as u32))
    }
    fn push(&mut self, m: &[u64], link: u64) {
        if self.len.is_multiple_of(NODE_CHUNK) {
            self.chunks
                .push(Vec::with_capacity(NODE_CHUNK * self.width));
        }
        if let Some(c) = self.chunks.last_mut() {
            c.extend_from_slice(m);
            c.push(link);
        }
        self.len += 1;
    }
    fn bytes(&self) -> usize {
        self.chunks.len() * NODE_CHUNK * self.width * 8
    }
    /// The firing sequence along the BFS tree from the root to node `d`.
    fn path_to(&self, d: usize) -> Vec<TransIdx> {
        let mut path = Vec::new();
        let mut v = d;
        while let Some((p, t)) = self.parent(v) {
            path.push(TransIdx(t));
            v = p;
        }
        path.reverse();
        path
    }
}

fn hash_marking(m: &[u64]) -> u64 {
    let mut h = 0x243F_6A88_85A3_08D3u64;
    for &w in m {
        h = (h ^ w).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        h ^= h >> 32;
    }
    h
}

/// Open addressing over node ids (`u32::MAX` empty), load at most 3/4.
struct Seen {
    slots: Vec<u32>,
    len: usize,
}

impl Seen {
    fn find(&self, nodes: &Nodes, m: &[u64]) -> Result<u32, usize> {
        let mask = self.slots.len() - 1;
        let mut i = hash_marking(m) as usize & mask;
        loop {
            match self.slots[i] {
                u32::MAX => return Err(i),
                id if nodes.marking(id as usize) == m => return Ok(id),
                _ => i = (i + 1) & mask,
            }
        }
    }
    /// Bytes held while growing for one more id (old and new slots), or now.
    fn bytes_to_fit_one(&self) -> usize {
        if (self.len + 1) * 4 > self.slots.len() * 3 {
            self.slots.len() * 3 * 4
        } else {
            self.slots.len() * 4
        }
    }
    fn insert(&mut self, nodes: &Nodes, id: u32) {
        if (self.len + 1) * 4 > self.slots.len() * 3 {
            let cap = self.slots.len() * 2;
            let old = std::mem::replace(&mut self.slots, vec![u32::MAX; cap]);
            for x in old.into_iter().filter(|&x| x != u32::MAX) {
                if let Err(i) = self.find(nodes, nodes.marking(x as usize)) {
                    self.slots[i] = x;
                }
            }
        }
        if let Err(i) = self.find(nodes, nodes.marking(id as usize)) {
            self.slots[i] = id;
            self.len += 1;
        }
    }
}

/// Builds the Karp–Miller graph of `net`, within the options' states, bytes and time.
pub fn karp_miller(net: &Net, opts: &ReachOptions) -> Coverability {
    build(net, opts, false)
}

/// Like [`karp_miller`], but stops at the first ω (`first_omega` then holds its path): enough to
/// show that the net is unbounded.
pub fn karp_miller_until_omega(net: &Net, opts: &ReachOptions) -> Coverability {
    build(net, opts, true)
}

/// The Karp–Miller graph, expanded breadth-first until it is complete, a budget runs out, or
/// (with `stop_at_omega`) the first ω appears.
fn build(net: &Net, opts: &ReachOptions, stop_at_omega: bool) -> Coverability {
    let mut km = KarpMiller::new(net, opts, stop_at_omega);
    let mut m: Vec<u64> = Vec::with_capacity(net.num_places());
    while km.cur < km.nodes.len {
        if let Some(s) = km.checkpoint() {
            km.stopped = Some(s);
            break;
        }
        m.clear();
        m.extend_from_slice(km.nodes.marking(km.cur));
        if km.expand(&m).is_break() {
            break;
        }
        km.cur += 1;
    }
    km.finish()
}

/// A Karp–Miller graph under construction, breadth-first.
struct KarpMiller<'a> {
    net: &'a Net,
    opts: &'a ReachOptions,
    stop_at_omega: bool,
    /// Places never accelerated: those with a capacity or an inhibitor arc.
    frozen: Vec<bool>,
    /// Some place is not frozen.
    accelerable: bool,
    nodes: Nodes,
    seen: Seen,
    max_states: u64,
    /// The node being expanded.
    cur: usize,
    edges: u64,
    dead: u64,
    first_dead: Option<usize>,
    /// The first node to get an ω, as its parent and the transition from there.
    first_omega: Option<(usize, u32)>,
    stopped: Option<Stop>,
}

impl<'a> KarpMiller<'a> {
    /// The graph holding the root, M0, alone.
    fn new(net: &'a Net, opts: &'a ReachOptions, stop_at_omega: bool) -> Self {
        let np = net.num_places();
        let m0: Vec<u64> = net
            .initial_marking()
            .as_slice()
            .iter()
            .map(|&v| u64::from(v))
            .collect();
        let frozen: Vec<bool> = (0..np)
            .map(|p| {
                let p = PlaceIdx(p as u32);
                net.capacity(p).is_some() || !net.inhibited(p).is_empty()
            })
            .collect();
        let mut nodes = Nodes {
            width: np + 1,
            chunks: Vec::new(),
            len: 0,
        };
        nodes.push(&m0, NO_PARENT);
        let mut seen = Seen {
            slots: vec![u32::MAX; 1 << 10],
            len: 0,
        };
        seen.insert(&nodes, 0);
        KarpMiller {
            net,
            opts,
            stop_at_omega,
            accelerable: frozen.iter().any(|f| !f),
            frozen,
            nodes,
            seen,
            max_states: opts.state_limit(),
            cur: 0,
            edges: 0,
            dead: 0,
            first_dead: None,
            first_omega: None,
            stopped: None,
        }
    }

    /// Every 256 nodes (acceleration walks the ancestors, so a node can cost its depth): why
    /// to stop (the deadline, Ctrl-C), or else a progress report.
    fn checkpoint(&self) -> Option<Stop> {
        if self.cur & 0xFF != 0 || self.cur == 0 {
            return None;
        }
        if let Some(s) = self.opts.interrupted() {
            return Some(s);
        }
        if let Some(p) = &self.opts.progress {
            p(Progress {
                states: self.nodes.len as u64,
                edges: self.edges,
                expanded: self.cur as u64,
                bytes: (self.nodes.bytes() + self.seen.slots.len() * 4) as u64,
            });
        }
        None
    }

    /// Expands the current node, whose marking is `m`. Breaks when the construction ends here.
    fn expand(&mut self, m: &[u64]) -> ControlFlow<()> {
        let net = self.net;
        let mut any = false;
        for ti in 0..net.num_transitions() {
            let t = TransIdx(ti as u32);
            if !enabled(net, t, m) {
                continue;
            }
            any = true;
            self.edges += 1;
            let mut succ = fire(net, t, m);
            self.accelerate(&mut succ);
            if self.first_omega.is_none() && succ.contains(&OMEGA) {
                self.first_omega = Some((self.cur, ti as u32));
                if self.stop_at_omega {
                    return ControlFlow::Break(());
                }
            }
            self.add(&succ, ti as u32)?;
        }
        if !any {
            self.dead += 1;
            self.first_dead.get_or_insert(self.cur);
        }
        ControlFlow::Continue(())
    }

    /// Puts ω in every place, not frozen, in which `succ` strictly exceeds an ancestor that it
    /// covers. With no place to accelerate, the walk is skipped (it would make a long chain of
    /// states cost its length squared).
    fn accelerate(&self, succ: &mut [u64]) {
        let mut a = self.accelerable.then_some(self.cur);
        while let Some(ai) = a {
            let anc = self.nodes.marking(ai);
            if anc.iter().zip(&*succ).all(|(x, y)| x <= y) && anc != &*succ {
                for p in 0..succ.len() {
                    if anc[p] < succ[p] && !self.frozen[p] {
                        succ[p] = OMEGA;
                    }
                }
            }
            a = self.nodes.parent(ai).map(|(p, _)| p);
        }
    }

    /// Adds `succ`, reached from the current node by transition `t`, unless it is known.
    /// Breaks when the states or bytes budget would be exceeded.
    fn add(&mut self, succ: &[u64], t: u32) -> ControlFlow<()> {
        if self.seen.find(&self.nodes, succ).is_ok() {
            return ControlFlow::Continue(());
        }
        if self.nodes.len as u64 >= self.max_states {
            self.stopped = Some(Stop::MaxStates(self.max_states));
            return ControlFlow::Break(());
        }
        let chunk = if self.nodes.len.is_multiple_of(NODE_CHUNK) {
            NODE_CHUNK * self.nodes.width * 8
        } else {
            0
        };
        let bytes = self.nodes.bytes() + chunk + self.seen.bytes_to_fit_one();
        if let Err(s) = self.opts.within_memory(bytes) {
            self.stopped = Some(s);
            return ControlFlow::Break(());
        }
        self.nodes
            .push(succ, (self.cur as u64) << 32 | u64::from(t));
        self.seen.insert(&self.nodes, self.nodes.len as u32 - 1);
        ControlFlow::Continue(())
    }

    /// The graph's figures, with the paths to its first dead node and its first ω.
    fn finish(self) -> Coverability {
        let np = self.frozen.len();
        let nodes = &self.nodes;
        let mut max_tokens = vec![0u64; np];
        for i in 0..nodes.len {
            for (x, &v) in max_tokens.iter_mut().zip(nodes.marking(i)) {
                *x = (*x).max(v);
            }
        }
        let first_omega = self.first_omega.map(|(v, t)| {
            let mut p = nodes.path_to(v);
            p.push(TransIdx(t));
            p
        });
        Coverability {
            nodes: nodes.len as u64,
            edges: self.edges,
            dead: self.dead,
            dead_witness: self.first_dead.map(|d| nodes.path_to(d)),
            unbounded: (0..np)
                .filter(|&p| max_tokens[p] == OMEGA)
                .map(|p| PlaceIdx(p as u32))
                .collect(),
            max_tokens,
            stopped: self.stopped,
            first_omega,
        }
    }
}
