//! Nets the tests share: the Vernadat cell, the examples, the reference fixtures, and a small
//! three-place net.

use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition};

/// The 13-place Vernadat cell of docs/design.md §6 (H first, 10 transitions), read from the example.
///
/// The net built in code lives in `cetratus_bench::workloads::vernadat`; the crate doc says why
/// there is one builder and how it is kept equal to this file.
pub fn vernadat() -> Net {
    example("vernadat/vernadat.pnml")
}

/// The net of the PNML file `rel` under `examples/`, e.g. `vernadat/u1.pnml`.
///
/// # Panics
///
/// When the file does not read as a net, naming it.
pub fn example(rel: &str) -> Net {
    let path = crate::paths::example(rel);
    cetratus_net::pnml::read_file(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The reference net `rel` of the shared fixtures, e.g. `pipe/ClassicGSPN.xml`.
///
/// # Panics
///
/// When the file does not read as a net, naming it.
pub fn fixture(rel: &str) -> Net {
    let path = crate::paths::fixture(rel);
    cetratus_net::pnml::read_file(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Places A (1 token), B (0), C (2); transitions T1: A -> B, T2: B -> A, T3: C -> C.
pub fn small() -> Net {
    let mut b = NetBuilder::new("small");
    for (id, m) in [("A", 1), ("B", 0), ("C", 2)] {
        b.add_place(Place::new(id, m)).expect("unique place ids");
    }
    for id in ["T1", "T2", "T3"] {
        b.add_transition(Transition::new(id))
            .expect("unique transition ids");
    }
    for (id, s, t) in [
        ("a1", "A", "T1"),
        ("a2", "T1", "B"),
        ("a3", "B", "T2"),
        ("a4", "T2", "A"),
        ("a5", "C", "T3"),
        ("a6", "T3", "C"),
    ] {
        b.add_arc(id, s, t, 1, ArcKind::Normal)
            .expect("arcs between declared nodes");
    }
    b.build().expect("the small net is well-formed")
}

/// A net of `places` (id, initial tokens) and `transitions` (id, from, to), each taking one
/// token from its place and putting one into the next: the shape of a chart's sequence.
pub fn sequence(places: &[(&str, u32)], transitions: &[(&str, &str, &str)]) -> Net {
    let mut b = NetBuilder::new("sequence");
    for &(id, m) in places {
        b.add_place(Place::new(id, m)).expect("unique place ids");
    }
    for &(t, from, to) in transitions {
        b.add_transition(Transition::new(t))
            .expect("unique transition ids");
        b.add_arc(&format!("{from}-{t}"), from, t, 1, ArcKind::Normal)
            .expect("arcs between declared nodes");
        b.add_arc(&format!("{t}-{to}"), t, to, 1, ArcKind::Normal)
            .expect("arcs between declared nodes");
    }
    b.build().expect("the sequence is well-formed")
}
