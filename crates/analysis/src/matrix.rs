//! The incidence matrices Pre, Post and C = Post − Pre, dense, places × transitions.

use cetratus_net::{Net, TransIdx};
use serde::Serialize;

/// Dense Pre, Post and C matrices of a net, rows are places and columns transitions, both in
/// declaration order. Inhibitor arcs are not part of them (they do not move tokens).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Incidence {
    /// `pre[p][t]`: tokens t takes from p.
    pub pre: Vec<Vec<i64>>,
    /// `post[p][t]`: tokens t puts into p.
    pub post: Vec<Vec<i64>>,
    /// `c[p][t] = post[p][t] − pre[p][t]`.
    pub c: Vec<Vec<i64>>,
}

impl Incidence {
    /// The matrices of `net`.
    pub fn of(net: &Net) -> Self {
        let np = net.num_places();
        let nt = net.num_transitions();
        let mut pre = vec![vec![0i64; nt]; np];
        let mut post = vec![vec![0i64; nt]; np];
        let mut c = vec![vec![0i64; nt]; np];
        for t in 0..nt {
            let ti = TransIdx(t as u32);
            for &(p, w) in net.pre(ti) {
                pre[p.index()][t] = i64::from(w);
            }
            for &(p, w) in net.post(ti) {
                post[p.index()][t] = i64::from(w);
            }
            for &(p, d) in net.delta(ti) {
                c[p.index()][t] = d;
            }
        }
        Incidence { pre, post, c }
    }

    /// Cᵀ: rows are transitions.
    pub fn c_transposed(&self) -> Vec<Vec<i64>> {
        let nt = self.c.first().map_or(0, Vec::len);
        (0..nt)
            .map(|t| self.c.iter().map(|row| row[t]).collect())
            .collect()
    }
}
