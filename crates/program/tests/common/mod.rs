//! A small net and program for the behaviour tests.

#![allow(dead_code)]

use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition};
use cetratus_program::Program;

/// Places A (1 token), B (0), C (2); transitions T1: A -> B, T2: B -> A, T3: C -> C.
pub fn net() -> Net {
    let mut b = NetBuilder::new("small");
    for (id, m) in [("A", 1), ("B", 0), ("C", 2)] {
        b.add_place(Place::new(id, m))
            .map(|_| ())
            .unwrap_or_else(|e| panic!("{e}"));
    }
    for id in ["T1", "T2", "T3"] {
        b.add_transition(Transition::new(id))
            .map(|_| ())
            .unwrap_or_else(|e| panic!("{e}"));
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
            .map(|_| ())
            .unwrap_or_else(|e| panic!("{e}"));
    }
    b.build().unwrap_or_else(|e| panic!("{e}"))
}

/// A program over [`net`] with inputs `x: bool`, `n: int`, `r: real`, variable `v: int`, and
/// whatever `rest` adds.
pub fn program(rest: &str) -> Program {
    let src = format!(
        "[program]\nname = \"small\"\nversion = \"1\"\n\
         [[input]]\nname = \"x\"\ntype = \"bool\"\n\
         [[input]]\nname = \"n\"\ntype = \"int\"\n\
         [[input]]\nname = \"r\"\ntype = \"real\"\n\
         [[variable]]\nname = \"v\"\ntype = \"int\"\ninitial = 5\n{rest}"
    );
    Program::from_sources(&src, "small.toml", net()).unwrap_or_else(|e| panic!("{e}"))
}
