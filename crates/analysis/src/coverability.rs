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

use std::collections::HashMap;
use std::sync::atomic::Ordering;

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

/// Builds the Karp–Miller graph of `net`, within `opts.max_states` nodes.
pub fn karp_miller(net: &Net, opts: &ReachOptions) -> Coverability {
    let np = net.num_places();
    let nt = net.num_transitions();
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
    let mut nodes: Vec<Vec<u64>> = vec![m0.clone()];
    let mut parent: Vec<(u32, u32)> = vec![(u32::MAX, 0)];
    let mut seen: HashMap<Vec<u64>, u32> = HashMap::new();
    seen.insert(m0, 0);
    let max_states = opts.max_states.unwrap_or(u64::from(u32::MAX - 1));
    let (mut edges, mut dead) = (0u64, 0u64);
    let mut first_dead = None;
    let mut stopped = None;
    let mut cur = 0usize;
    'bfs: while cur < nodes.len() {
        if cur & 0xFFF == 0 && cur > 0 {
            if opts
                .cancel
                .as_ref()
                .is_some_and(|c| c.load(Ordering::Relaxed))
            {
                stopped = Some(Stop::Cancelled);
                break;
            }
            if let Some(p) = &opts.progress {
                p(Progress {
                    states: nodes.len() as u64,
                    edges,
                    expanded: cur as u64,
                });
            }
        }
        let mut any = false;
        for ti in 0..nt {
            let t = TransIdx(ti as u32);
            if !enabled(net, t, &nodes[cur]) {
                continue;
            }
            any = true;
            edges += 1;
            let mut succ = fire(net, t, &nodes[cur]);
            let mut a = cur as u32;
            while a != u32::MAX {
                let anc = &nodes[a as usize];
                if anc.iter().zip(&succ).all(|(x, y)| x <= y) && *anc != succ {
                    for p in 0..np {
                        if anc[p] < succ[p] && !frozen[p] {
                            succ[p] = OMEGA;
                        }
                    }
                }
                a = parent[a as usize].0;
            }
            if !seen.contains_key(&succ) {
                if nodes.len() as u64 >= max_states {
                    stopped = Some(Stop::MaxStates(max_states));
                    break 'bfs;
                }
                seen.insert(succ.clone(), nodes.len() as u32);
                nodes.push(succ);
                parent.push((cur as u32, ti as u32));
            }
        }
        if !any {
            dead += 1;
            first_dead.get_or_insert(cur);
        }
        cur += 1;
    }
    let mut max_tokens = vec![0u64; np];
    for m in &nodes {
        for (x, &v) in max_tokens.iter_mut().zip(m) {
            *x = (*x).max(v);
        }
    }
    let dead_witness = first_dead.map(|d| {
        let mut path = Vec::new();
        let mut v = d;
        while parent[v].0 != u32::MAX {
            path.push(TransIdx(parent[v].1));
            v = parent[v].0 as usize;
        }
        path.reverse();
        path
    });
    Coverability {
        nodes: nodes.len() as u64,
        edges,
        dead,
        dead_witness,
        unbounded: (0..np)
            .filter(|&p| max_tokens[p] == OMEGA)
            .map(|p| PlaceIdx(p as u32))
            .collect(),
        max_tokens,
        stopped,
    }
}
