//! Property-directed checks: each answer agrees with the full check, every witness replays on the
//! net to a marking that shows the answer, and stubborn sets never change an answer — on every
//! fixture and on random nets with inhibitor arcs and capacities.

mod common;

use cetratus_analysis::{check, check_property, CheckOptions, Predicate, Property, Report};
use cetratus_net::{ArcKind, Net, NetBuilder, Place, PlaceIdx, Transition};
use cetratus_testkit::nets;
use proptest::prelude::*;

const FIXTURES: [&str; 11] = [
    "pipe/ClassicGSPN.xml",
    "pipe/DiningPhilosophers.xml",
    "pipe/ProducerConsumer.xml",
    "pipe/ReadersWriters.xml",
    "pipe5/simpleNet.xml",
    "pipe5/petriNet.xml",
    "pipe5/inhibitorArc.xml",
    "mcc/Philosophers-PT-000005.pnml",
    "mcc/TokenRing-PT-005.pnml",
    "mcc/FMS-PT-00002.pnml",
    "crafted/nested-pages.pnml",
];

fn opts(reduction: bool) -> CheckOptions {
    CheckOptions {
        reduction,
        ..CheckOptions::default()
    }
}

/// The marking reached by firing `witness` from M0; panics if a transition is not enabled.
fn replay(net: &Net, witness: &[String]) -> Vec<u32> {
    let mut m = net.initial_marking().as_slice().to_vec();
    for id in witness {
        let t = net.transition_by_id(id).expect("a transition of the net");
        assert!(net.is_enabled(t, &m), "{id} is not enabled at {m:?}");
        for &(p, d) in net.delta(t) {
            m[p.index()] = (i64::from(m[p.index()]) + d) as u32;
        }
    }
    m
}

fn dead(net: &Net, m: &[u32]) -> bool {
    (0..net.num_transitions()).all(|t| !net.is_enabled(cetratus_net::TransIdx(t as u32), m))
}

fn prop(net: &Net, p: &Property, reduction: bool) -> Report {
    let r = check_property(net, p, &opts(reduction));
    assert!(
        !r.partial,
        "{}: {:?} {:?}",
        p.label(),
        r.partial_reason,
        r.notes
    );
    r
}

/// Every property against the full check, and every witness replayed.
fn agrees_with_the_full_check(net: &Net) {
    let full = check(net, &CheckOptions::default());
    assert!(!full.partial);
    for reduction in [true, false] {
        let d = prop(net, &Property::Deadlock, reduction);
        assert_eq!(d.holds, Some(full.deadlocks > 0), "{}", net.id());
        if let Some(w) = &d.witness {
            assert!(dead(net, &replay(net, w)));
            if !reduction {
                assert_eq!(Some(w), full.deadlock_witness.as_ref(), "shortest witness");
                assert_eq!(d.witness_shortest, Some(true));
            }
        }
    }
    let live = prop(net, &Property::Live, false);
    assert_eq!(live.holds, full.live, "live {}", net.id());
    let rev = prop(net, &Property::Reversible, false);
    assert_eq!(rev.holds, full.reversible, "reversible {}", net.id());
    if let Some(w) = &rev.witness {
        // M0 is not reachable from the end of the witness: check it on the full graph by a
        // second property run from there.
        let end = replay(net, w);
        let from = net
            .with_initial_marking(&cetratus_net::Marking::from(end))
            .expect("a marking of the net");
        let m0 = net.initial_marking();
        let text = (0..net.num_places())
            .map(|p| format!("\"{}\" == {}", net.places()[p].id, m0.as_slice()[p]))
            .collect::<Vec<_>>()
            .join(" && ");
        let back = Predicate::parse(&text, &from).expect("predicate");
        assert_eq!(
            prop(&from, &Property::Reach(back), false).holds,
            Some(false)
        );
    }
    let safe = prop(net, &Property::Safe, false);
    assert_eq!(safe.holds, full.safe, "safe {}", net.id());
    if let Some(w) = &safe.witness {
        assert!(replay(net, w).iter().any(|&x| x > 1));
    }
    assert_eq!(prop(net, &Property::Bounded, false).holds, Some(true));
}

#[test]
fn every_fixture_answers_each_property_as_the_full_check_does() {
    for f in FIXTURES {
        agrees_with_the_full_check(&nets::fixture(f));
    }
}

#[test]
fn on_every_fixture_each_place_bound_is_reached_with_stubborn_sets_and_never_exceeded() {
    for f in FIXTURES {
        let net = nets::fixture(f);
        let full = check(&net, &CheckOptions::default());
        for (p, b) in &full.max_tokens.0 {
            let cetratus_analysis::Bound::Tokens(b) = *b else {
                panic!("{f}: {p} has no bound");
            };
            let at = Predicate::parse(&format!("\"{p}\" >= {b}"), &net).expect("predicate");
            let over = Predicate::parse(&format!("\"{p}\" > {b}"), &net).expect("predicate");
            for reduction in [true, false] {
                let r = prop(&net, &Property::Reach(at.clone()), reduction);
                assert_eq!(r.holds, Some(true), "{f}: {p} >= {b}");
                let end = replay(&net, r.witness.as_ref().expect("witness"));
                let idx = net.place_by_id(p).expect("place").index();
                assert_eq!(u64::from(end[idx]), b, "{f}: {p}");
                let r = prop(&net, &Property::Always(over.negated()), reduction);
                assert_eq!(r.holds, Some(true), "{f}: never {p} > {b}");
            }
        }
    }
}

#[test]
fn the_philosophers_deadlock_witness_replays_to_a_dead_marking_with_and_without_reduction() {
    let net = nets::fixture("mcc/Philosophers-PT-000005.pnml");
    let reduced = prop(&net, &Property::Deadlock, true);
    let full = prop(&net, &Property::Deadlock, false);
    assert_eq!(reduced.holds, Some(true));
    assert_eq!(reduced.reduction, Some("stubborn"));
    assert_eq!(full.reduction, Some("none"));
    assert!(
        reduced.states <= full.states,
        "{} > {}",
        reduced.states,
        full.states
    );
    for r in [&reduced, &full] {
        assert!(dead(
            &net,
            &replay(&net, r.witness.as_ref().expect("witness"))
        ));
    }
}

/// A producer that fills `buf` without limit.
fn unbounded() -> Net {
    let mut b = NetBuilder::new("unbounded");
    b.add_place(Place::new("idle", 1)).expect("place");
    b.add_place(Place::new("buf", 0)).expect("place");
    b.add_transition(Transition::new("produce")).expect("t");
    b.add_arc("a", "idle", "produce", 1, ArcKind::Normal)
        .expect("arc");
    b.add_arc("b", "produce", "idle", 1, ArcKind::Normal)
        .expect("arc");
    b.add_arc("c", "produce", "buf", 1, ArcKind::Normal)
        .expect("arc");
    b.build().expect("net")
}

#[test]
fn an_unbounded_net_is_not_bounded_nor_safe_and_says_which_firing_sequence_shows_it() {
    let net = unbounded();
    let b = prop(&net, &Property::Bounded, false);
    assert_eq!(b.holds, Some(false));
    let w = b.witness.expect("witness");
    assert_eq!(w, vec!["produce".to_string()]);
    let s = prop(&net, &Property::Safe, false);
    assert_eq!(s.holds, Some(false));
    assert_eq!(s.witness, Some(vec!["produce".into(), "produce".into()]));
}

#[test]
fn reach_and_always_answer_with_the_marking_they_name() {
    let net = nets::fixture("mcc/FMS-PT-00002.pnml");
    let full = check(&net, &CheckOptions::default());
    let (p, bound) = full
        .max_tokens
        .0
        .iter()
        .find_map(|(p, b)| match b {
            cetratus_analysis::Bound::Tokens(n) if *n >= 2 => Some((p.clone(), *n)),
            _ => None,
        })
        .expect("a place with two tokens");
    for reduction in [true, false] {
        let at_max = Predicate::parse(&format!("{p} >= {bound}"), &net).expect("predicate");
        let r = prop(&net, &Property::Reach(at_max.clone()), reduction);
        assert_eq!(r.holds, Some(true));
        let end = replay(&net, r.witness.as_ref().expect("witness"));
        let idx = net.place_by_id(&p).expect("place").index();
        assert_eq!(u64::from(end[idx]), bound);
        let beyond = Predicate::parse(&format!("{p} > {bound}"), &net).expect("predicate");
        assert_eq!(
            prop(&net, &Property::Reach(beyond.clone()), reduction).holds,
            Some(false)
        );
        let always = prop(&net, &Property::Always(beyond.negated()), reduction);
        assert_eq!(always.holds, Some(true));
        let never_max = prop(&net, &Property::Always(at_max.negated()), reduction);
        assert_eq!(never_max.holds, Some(false));
        assert!(never_max.witness.is_some());
    }
}

/// A random net with inhibitor arcs and capacities: Pre, Post, inhibitor weights (0 = none),
/// capacities (0 = none), M0.
type Spec = (
    Vec<Vec<u32>>,
    Vec<Vec<u32>>,
    Vec<Vec<u32>>,
    Vec<u32>,
    Vec<u32>,
);

fn build(spec: &Spec) -> Net {
    let (pre, post, inh, caps, m0) = spec;
    let mut b = NetBuilder::new("random");
    for (p, &m) in m0.iter().enumerate() {
        let mut place = Place::new(format!("p{p}"), m);
        if caps[p] > 0 {
            place.capacity = Some(caps[p].max(m));
        }
        b.add_place(place).expect("place");
    }
    let nt = pre[0].len();
    for t in 0..nt {
        b.add_transition(Transition::new(format!("t{t}")))
            .expect("t");
    }
    for p in 0..m0.len() {
        for t in 0..nt {
            let (pp, tt) = (format!("p{p}"), format!("t{t}"));
            if pre[p][t] > 0 {
                b.add_arc(&format!("a{p}_{t}"), &pp, &tt, pre[p][t], ArcKind::Normal)
                    .expect("arc");
            }
            if post[p][t] > 0 {
                b.add_arc(&format!("b{t}_{p}"), &tt, &pp, post[p][t], ArcKind::Normal)
                    .expect("arc");
            }
            if inh[p][t] > 0 && pre[p][t] == 0 {
                b.add_arc(
                    &format!("i{p}_{t}"),
                    &pp,
                    &tt,
                    inh[p][t],
                    ArcKind::Inhibitor,
                )
                .expect("arc");
            }
        }
    }
    b.build().expect("net")
}

fn spec() -> impl Strategy<Value = Spec> {
    (2usize..6, 1usize..6).prop_flat_map(|(np, nt)| {
        let m = |hi: u32| proptest::collection::vec(proptest::collection::vec(0u32..=hi, nt), np);
        (
            m(2),
            m(2),
            proptest::collection::vec(
                proptest::collection::vec(prop_oneof![4 => Just(0u32), 1 => 1u32..=3], nt),
                np,
            ),
            proptest::collection::vec(prop_oneof![2 => Just(0u32), 1 => 1u32..=4], np),
            proptest::collection::vec(0u32..=3, np),
        )
    })
}

/// A random comparison over two places.
fn predicate(net: &Net, (a, b, k, op): (usize, usize, u32, usize)) -> Predicate {
    let n = net.num_places();
    let ops = ["<", "<=", "==", "!=", ">=", ">"];
    let text = format!(
        "p{} + 2*p{} {} {k} || p{} == 0 && !(p{} > {k})",
        a % n,
        b % n,
        ops[op],
        b % n,
        a % n
    );
    Predicate::parse(&text, net).expect("predicate")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn stubborn_sets_give_the_answers_of_the_full_search(
        spec in spec(),
        atom in (0usize..6, 0usize..6, 0u32..5, 0usize..6),
    ) {
        let net = build(&spec);
        let budget = CheckOptions { max_states: Some(3_000), ..opts(true) };
        let full = check(&net, &CheckOptions { max_states: Some(3_000), ..CheckOptions::default() });
        prop_assume!(!full.partial && full.graph == "reachability");
        let d = check_property(&net, &Property::Deadlock, &budget);
        prop_assert_eq!(d.holds, Some(full.deadlocks > 0));
        if let Some(w) = &d.witness {
            prop_assert!(dead(&net, &replay(&net, w)));
        }
        let pred = predicate(&net, atom);
        for p in [Property::Reach(pred.clone()), Property::Always(pred.clone())] {
            let reduced = check_property(&net, &p, &budget);
            let plain = check_property(&net, &p, &CheckOptions { reduction: false, ..budget.clone() });
            prop_assert_eq!(reduced.holds, plain.holds, "{}", p.label());
            prop_assert!(reduced.holds.is_some());
            if let Some(w) = &reduced.witness {
                let end = replay(&net, w);
                let sat = pred.holds(|q: PlaceIdx| u64::from(end[q.index()]));
                prop_assert_eq!(sat, matches!(p, Property::Reach(_)));
            }
        }
    }
}
