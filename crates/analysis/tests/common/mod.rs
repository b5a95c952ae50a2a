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

/// The 13-place Vernadat cell of DESIGN §6.
pub fn vernadat() -> Net {
    simple(
        &[
            ("H", 4),
            ("B", 3),
            ("R", 1),
            ("P10", 1),
            ("P11", 0),
            ("P12", 0),
            ("P13", 0),
            ("P14", 0),
            ("P20", 1),
            ("P21", 0),
            ("P22", 0),
            ("P23", 0),
            ("P24", 0),
        ],
        &[
            ("T10", &["P10", "R"], &["P11"]),
            ("T11", &["P11"], &["P12", "R"]),
            ("T12", &["P12"], &["P13"]),
            ("T13", &["P13", "R", "H"], &["P14"]),
            ("T20", &["P14"], &["P10", "R", "B"]),
            ("T14", &["P20", "R", "B"], &["P22", "H"]),
            ("T21", &["P22"], &["P21", "R"]),
            ("T22", &["P21"], &["P23"]),
            ("T24", &["P23", "R"], &["P24"]),
            ("T23", &["P24"], &["P20", "R"]),
        ],
    )
}
