//! Nets the benches run: the bare Vernadat net and the scale rings.

use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition};

/// The Vernadat cell of docs/design.md §6 as a bare net (13 places, H first; 10 transitions).
///
/// The workspace's only builder of it: `cetratus bench` ships it, so it cannot live in the
/// dev-only testkit. Tests read the same net from the example, and `tests/workloads.rs` checks
/// that the two agree.
pub fn vernadat() -> Net {
    let places = [
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
    ];
    let transitions: [(&str, &[&str], &[&str]); 10] = [
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
    ];
    let mut b = NetBuilder::new("vernadat");
    for (id, m) in places {
        b.add_place(Place::new(id, m)).expect("unique ids");
    }
    for (id, _, _) in transitions {
        b.add_transition(Transition::new(id)).expect("unique ids");
    }
    for (t, pre, post) in transitions {
        for p in pre {
            b.add_arc(&format!("{p}_{t}"), p, t, 1, ArcKind::Normal)
                .expect("declared nodes");
        }
        for p in post {
            b.add_arc(&format!("{t}_{p}"), t, p, 1, ArcKind::Normal)
                .expect("declared nodes");
        }
    }
    b.build().expect("the Vernadat net is well-formed")
}

/// Ten rings of `n / 10` places and `n / 10` transitions each, one token per ring, indices
/// contiguous within a ring: every step fires exactly ten transitions.
pub fn rings(n: usize) -> Net {
    let per = (n / 10).max(1);
    let mut b = NetBuilder::new(format!("rings-{n}"));
    for r in 0..10 {
        for i in 0..per {
            b.add_place(Place::new(format!("p{r}_{i}"), u32::from(i == 0)))
                .expect("unique ids");
        }
    }
    for r in 0..10 {
        for i in 0..per {
            b.add_transition(Transition::new(format!("t{r}_{i}")))
                .expect("unique ids");
        }
    }
    for r in 0..10 {
        for i in 0..per {
            let t = format!("t{r}_{i}");
            b.add_arc(
                &format!("i{r}_{i}"),
                &format!("p{r}_{i}"),
                &t,
                1,
                ArcKind::Normal,
            )
            .expect("declared nodes");
            let next = (i + 1) % per;
            b.add_arc(
                &format!("o{r}_{i}"),
                &t,
                &format!("p{r}_{next}"),
                1,
                ArcKind::Normal,
            )
            .expect("declared nodes");
        }
    }
    b.build().expect("ring nets are well-formed")
}
