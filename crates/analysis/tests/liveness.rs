//! Liveness and reversibility of the packed explorer (backward search from M0, then Tarjan over
//! the table's slots) against a naive reference on explicit graphs, on random small nets.

mod common;

use std::collections::{HashMap, VecDeque};

use cetratus_analysis::invariants::DEFAULT_MAX_ROWS;
use cetratus_analysis::reach::{explore, structural_packing, ReachOptions};
use cetratus_net::{Net, TransIdx};
use proptest::prelude::*;

/// Edges `(transition, target)` of each state.
type Edges = Vec<Vec<(usize, usize)>>;

/// The reachability graph as explicit adjacency lists (at most `limit` states).
fn graph(net: &Net, limit: usize) -> Option<(Vec<Vec<u32>>, Edges)> {
    let m0: Vec<u32> = net.initial_marking().as_slice().to_vec();
    let mut ids: HashMap<Vec<u32>, usize> = HashMap::from([(m0.clone(), 0)]);
    let mut states = vec![m0];
    let mut succ: Vec<Vec<(usize, usize)>> = Vec::new();
    let mut cur = 0;
    while cur < states.len() {
        let m = states[cur].clone();
        let mut out = Vec::new();
        for t in 0..net.num_transitions() {
            let ti = TransIdx(t as u32);
            if net.pre(ti).iter().all(|&(p, w)| m[p.index()] >= w) {
                let mut n = m.clone();
                for &(p, d) in net.delta(ti) {
                    n[p.index()] = (i64::from(n[p.index()]) + d) as u32;
                }
                let next = ids.len();
                let id = *ids.entry(n.clone()).or_insert_with(|| {
                    states.push(n);
                    next
                });
                out.push((t, id));
            }
        }
        succ.push(out);
        cur += 1;
        if states.len() > limit {
            return None;
        }
    }
    Some((states, succ))
}

fn reach_from(succ: &[Vec<(usize, usize)>], s: usize) -> Vec<bool> {
    let mut seen = vec![false; succ.len()];
    seen[s] = true;
    let mut q = VecDeque::from([s]);
    while let Some(u) = q.pop_front() {
        for &(_, v) in &succ[u] {
            if !seen[v] {
                seen[v] = true;
                q.push_back(v);
            }
        }
    }
    seen
}

/// (live, reversible, non-live transitions) by definition: a state is in a terminal SCC when
/// every state it reaches reaches it back.
fn reference(net: &Net, succ: &[Vec<(usize, usize)>]) -> (bool, bool, Vec<usize>) {
    let n = succ.len();
    let reach: Vec<Vec<bool>> = (0..n).map(|s| reach_from(succ, s)).collect();
    let reversible = (0..n).all(|s| reach[s][0]);
    let mut missing = vec![false; net.num_transitions()];
    for (s, from_s) in reach.iter().enumerate() {
        let terminal = (0..n).all(|v| !from_s[v] || reach[v][s]);
        if terminal {
            let mut occurs = vec![false; net.num_transitions()];
            for v in (0..n).filter(|&v| from_s[v]) {
                for &(t, _) in &succ[v] {
                    occurs[t] = true;
                }
            }
            for (m, o) in missing.iter_mut().zip(occurs) {
                *m |= !o;
            }
        }
    }
    let non_live: Vec<usize> = (0..missing.len()).filter(|&t| missing[t]).collect();
    (non_live.is_empty(), reversible, non_live)
}

fn small_net() -> impl Strategy<Value = Net> {
    (1usize..=4, 1usize..=5).prop_flat_map(|(np, nt)| {
        (
            proptest::collection::vec(proptest::collection::vec(0u32..=1, nt), np),
            proptest::collection::vec(proptest::collection::vec(0u32..=1, nt), np),
            proptest::collection::vec(0u32..=2, np),
        )
            .prop_map(|(pre, post, m0)| common::from_matrices(&pre, &post, &m0))
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn liveness_and_reversibility_agree_with_the_definitions(net in small_net(), threads in 1usize..=2) {
        let Ok(Some(packing)) = structural_packing(&net, DEFAULT_MAX_ROWS) else {
            return Ok(());
        };
        let Some((states, succ)) = graph(&net, 400) else {
            return Ok(());
        };
        let opts = ReachOptions { liveness: true, threads, ..ReachOptions::default() };
        let r = explore(&net, &packing, &opts).expect("fits");
        prop_assert_eq!(r.states as usize, states.len());
        let l = r.liveness.expect("liveness computed");
        let (live, reversible, non_live) = reference(&net, &succ);
        prop_assert_eq!(l.reversible, reversible);
        prop_assert_eq!(l.live, live);
        let got: Vec<usize> = l.non_live.iter().map(|t| t.index()).collect();
        prop_assert_eq!(got, non_live);
    }
}
