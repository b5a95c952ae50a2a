//! The paper's algorithm as a baseline: a dense incidence matrix, every transition checked against
//! its Pre column on every scan, and `M + C·θ` computed in full.
//!
//! Entries use the smallest integer type that fits the nets measured (weights of 1, so `i8`/`u8`).
//! The step rule is the same greedy rule as the engine's, so both compute the same markings.

use cetratus_net::{Net, TransIdx};

/// A net as dense matrices, column-major (one contiguous column per transition).
pub struct DenseNet {
    places: usize,
    transitions: usize,
    pre: Vec<u8>,
    c: Vec<i8>,
    /// The marking.
    pub m: Vec<i32>,
    avail: Vec<i32>,
    theta: Vec<u8>,
}

impl DenseNet {
    /// Converts a net whose weights fit in `u8` and whose `C` fits in `i8`.
    pub fn new(net: &Net) -> Self {
        let (np, nt) = (net.num_places(), net.num_transitions());
        let mut pre = vec![0u8; np * nt];
        let mut c = vec![0i8; np * nt];
        for t in 0..nt {
            let ti = TransIdx(t as u32);
            for &(p, w) in net.pre(ti) {
                pre[t * np + p.index()] = u8::try_from(w).expect("weights fit in u8");
            }
            for &(p, d) in net.delta(ti) {
                c[t * np + p.index()] = i8::try_from(d).expect("C fits in i8");
            }
        }
        DenseNet {
            places: np,
            transitions: nt,
            pre,
            c,
            m: net.initial_marking().0.iter().map(|&x| x as i32).collect(),
            avail: vec![0; np],
            theta: vec![0; nt],
        }
    }

    /// One scan: enabling over every transition, the greedy step, then `M += C·θ` in full.
    pub fn scan(&mut self) -> usize {
        let np = self.places;
        self.avail.copy_from_slice(&self.m);
        let mut fired = 0;
        for t in 0..self.transitions {
            let col = &self.pre[t * np..(t + 1) * np];
            let ok = col
                .iter()
                .zip(&self.avail)
                .all(|(&w, &a)| a >= i32::from(w));
            self.theta[t] = u8::from(ok);
            if ok {
                for (a, &w) in self.avail.iter_mut().zip(col) {
                    *a -= i32::from(w);
                }
                fired += 1;
            }
        }
        for t in 0..self.transitions {
            let th = i32::from(self.theta[t]);
            let col = &self.c[t * np..(t + 1) * np];
            for (m, &c) in self.m.iter_mut().zip(col) {
                *m += i32::from(c) * th;
            }
        }
        fired
    }
}
