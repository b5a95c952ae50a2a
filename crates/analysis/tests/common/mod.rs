//! Small nets built in code for the tests.

#![allow(dead_code)]

use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition};

/// Builds a net from dense Pre and Post matrices (rows are places) and M0.
pub fn from_matrices(pre: &[Vec<u32>], post: &[Vec<u32>], m0: &[u32]) -> Net {
    let np = m0.len();
    let nt = pre.first().map_or(0, Vec::len);
    let mut b = NetBuilder::new("random");
    for (p, &m) in m0.iter().enumerate() {
        b.add_place(Place::new(format!("p{p}"), m)).expect("place");
    }
    for t in 0..nt {
        b.add_transition(Transition::new(format!("t{t}")))
            .expect("transition");
    }
    for p in 0..np {
        for t in 0..nt {
            if pre[p][t] > 0 {
                b.add_arc(
                    &format!("a{p}_{t}"),
                    &format!("p{p}"),
                    &format!("t{t}"),
                    pre[p][t],
                    ArcKind::Normal,
                )
                .expect("arc");
            }
            if post[p][t] > 0 {
                b.add_arc(
                    &format!("b{t}_{p}"),
                    &format!("t{t}"),
                    &format!("p{p}"),
                    post[p][t],
                    ArcKind::Normal,
                )
                .expect("arc");
            }
        }
    }
    b.build().expect("net")
}

/// A net from `(inputs, outputs)` lists of place names per transition, all weights 1.
pub fn simple(places: &[(&str, u32)], transitions: &[(&str, &[&str], &[&str])]) -> Net {
    let mut b = NetBuilder::new("simple");
    for &(p, m) in places {
        b.add_place(Place::new(p, m)).expect("place");
    }
    for (t, _, _) in transitions {
        b.add_transition(Transition::new(*t)).expect("transition");
    }
    for (t, ins, outs) in transitions {
        // Repeated places are parallel arcs, which add up to a weight.
        for (i, p) in ins.iter().enumerate() {
            b.add_arc(&format!("{p}>{t}#{i}"), p, t, 1, ArcKind::Normal)
                .expect("arc");
        }
        for (i, p) in outs.iter().enumerate() {
            b.add_arc(&format!("{t}>{p}#{i}"), t, p, 1, ArcKind::Normal)
                .expect("arc");
        }
    }
    b.build().expect("net")
}
