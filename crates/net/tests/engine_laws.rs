//! The laws of the token game, checked on random nets against a naive reference written from the
//! definitions in docs/design.md §3 (it reads the declared arcs, not the engine's derived tables).

use std::sync::Arc as Shared;

use cetratus_net::{
    ArcKind, Engine, FireError, NetBuilder, NodeRef, Place, Policy, SingleRule, Tokens, TransIdx,
    Transition,
};
use proptest::prelude::*;

#[derive(Clone, Debug)]
struct Spec {
    marking: Vec<Tokens>,
    capacity: Vec<Option<Tokens>>,
    priority: Vec<i32>,
    // (place, transition, weight, kind, place_to_transition)
    arcs: Vec<(usize, usize, Tokens, ArcKind, bool)>,
}

fn spec(max_p: usize, max_t: usize) -> impl Strategy<Value = Spec> {
    (1..=max_p, 1..=max_t).prop_flat_map(|(np, nt)| {
        (
            prop::collection::vec(0u32..4, np),
            prop::collection::vec(prop::option::weighted(0.2, 3u32..8), np),
            prop::collection::vec(0i32..3, nt),
            prop::collection::vec(
                (
                    0..np,
                    0..nt,
                    1u32..4,
                    prop::bool::weighted(0.15),
                    any::<bool>(),
                ),
                0..(3 * (np + nt)),
            ),
        )
            .prop_map(|(marking, capacity, priority, raw)| {
                let marking = marking
                    .iter()
                    .zip(&capacity)
                    .map(|(&m, c): (&u32, &Option<u32>)| c.map_or(m, |c| m.min(c)))
                    .collect();
                let arcs = raw
                    .into_iter()
                    .map(|(p, t, w, inh, pt)| {
                        if inh {
                            (p, t, w, ArcKind::Inhibitor, true)
                        } else {
                            (p, t, w, ArcKind::Normal, pt)
                        }
                    })
                    .collect();
                Spec {
                    marking,
                    capacity,
                    priority,
                    arcs,
                }
            })
    })
}

fn build(s: &Spec) -> cetratus_net::Net {
    let mut b = NetBuilder::new("random");
    for (i, (&m, &c)) in s.marking.iter().zip(&s.capacity).enumerate() {
        let mut p = Place::new(format!("p{i}"), m);
        p.capacity = c;
        b.add_place(p).expect("fresh id");
    }
    for (i, &prio) in s.priority.iter().enumerate() {
        let mut t = Transition::new(format!("t{i}"));
        t.priority = prio;
        b.add_transition(t).expect("fresh id");
    }
    for (k, &(p, t, w, kind, pt)) in s.arcs.iter().enumerate() {
        let (src, dst) = if pt {
            (format!("p{p}"), format!("t{t}"))
        } else {
            (format!("t{t}"), format!("p{p}"))
        };
        b.add_arc(&format!("a{k}"), &src, &dst, w, kind)
            .expect("arc ends are valid");
    }
    b.build().expect("random nets are well-formed")
}

/// Pre, Post and inhibitor thresholds read straight off the declared arcs.
struct Reference {
    pre: Vec<Vec<i64>>,
    post: Vec<Vec<i64>>,
    inhib: Vec<Vec<Option<i64>>>,
    cap: Vec<Option<i64>>,
    prio: Vec<i32>,
}

impl Reference {
    fn new(net: &cetratus_net::Net) -> Self {
        let (np, nt) = (net.num_places(), net.num_transitions());
        let mut r = Reference {
            pre: vec![vec![0; np]; nt],
            post: vec![vec![0; np]; nt],
            inhib: vec![vec![None; np]; nt],
            cap: net
                .places()
                .iter()
                .map(|p| p.capacity.map(i64::from))
                .collect(),
            prio: net.transitions().iter().map(|t| t.priority).collect(),
        };
        for a in net.arcs() {
            let w = i64::from(a.weight);
            match (a.source, a.target, a.kind) {
                (NodeRef::Place(p), NodeRef::Transition(t), ArcKind::Normal) => {
                    r.pre[t.index()][p.index()] += w
                }
                (NodeRef::Place(p), NodeRef::Transition(t), ArcKind::Inhibitor) => {
                    let e = &mut r.inhib[t.index()][p.index()];
                    *e = Some(e.map_or(w, |x| x.min(w)));
                }
                (NodeRef::Transition(t), NodeRef::Place(p), _) => r.post[t.index()][p.index()] += w,
                _ => unreachable!(),
            }
        }
        r
    }

    fn c(&self, t: usize, p: usize) -> i64 {
        self.post[t][p] - self.pre[t][p]
    }

    fn enabled(&self, t: usize, m: &[i64]) -> bool {
        (0..m.len()).all(|p| {
            m[p] >= self.pre[t][p]
                && self.inhib[t][p].is_none_or(|w| m[p] < w)
                && self.cap[p].is_none_or(|c| m[p] + self.c(t, p) <= c)
        })
    }

    fn order(&self) -> Vec<usize> {
        let mut v: Vec<usize> = (0..self.prio.len()).collect();
        v.sort_by_key(|&t| (std::cmp::Reverse(self.prio[t]), t));
        v
    }

    /// The greedy step exactly as docs/design.md §3 words it.
    fn step(&self, m: &[i64], guard: &dyn Fn(usize) -> bool) -> Vec<usize> {
        let mut avail = m.to_vec(); // M − Σ Pre[chosen]
        let mut cur = m.to_vec(); // M + Σ C[chosen]
        let mut chosen = Vec::new();
        for t in self.order() {
            let np = m.len();
            let ok = guard(t)
                && (0..np).all(|p| self.pre[t][p] <= avail[p])
                && (0..np).all(|p| self.inhib[t][p].is_none_or(|w| cur[p] < w))
                && (0..np).all(|p| self.cap[p].is_none_or(|c| cur[p] + self.c(t, p) <= c));
            if ok {
                for p in 0..np {
                    avail[p] -= self.pre[t][p];
                    cur[p] += self.c(t, p);
                }
                chosen.push(t);
            }
        }
        chosen
    }

    fn single(&self, m: &[i64], rule: SingleRule, guard: &dyn Fn(usize) -> bool) -> Vec<usize> {
        let firable: Vec<usize> = (0..self.prio.len())
            .filter(|&t| self.enabled(t, m) && guard(t))
            .collect();
        let pick = match rule {
            SingleRule::Last => firable.last().copied(),
            SingleRule::First => firable.first().copied(),
            SingleRule::Priority => self.order().into_iter().find(|t| firable.contains(t)),
        };
        pick.into_iter().collect()
    }
}

fn guard_of(seed: u64, scan: u64) -> impl Fn(usize) -> bool {
    move |t: usize| {
        let mut x = seed ^ (scan.wrapping_mul(0x9E37_79B9_7F4A_7C15)) ^ (t as u64 * 0xBF58_476D);
        x ^= x >> 31;
        x = x.wrapping_mul(0x94D0_49BB_1331_11EB);
        !x.is_multiple_of(4)
    }
}

fn policies() -> impl Strategy<Value = Policy> {
    prop_oneof![
        Just(Policy::Step),
        Just(Policy::Single(SingleRule::Last)),
        Just(Policy::Single(SingleRule::First)),
        Just(Policy::Single(SingleRule::Priority)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn every_scan_matches_the_reference_and_the_state_equation(
        s in spec(7, 7), policy in policies(), seed in any::<u64>()
    ) {
        let net = Shared::new(build(&s));
        let r = Reference::new(&net);
        let mut e = Engine::new(net.clone());
        for scan in 0..25u64 {
            let before: Vec<i64> = e.marking().iter().map(|&x| i64::from(x)).collect();
            let g = guard_of(seed, scan);
            let expected = match policy {
                Policy::Step => r.step(&before, &g),
                Policy::Single(rule) => r.single(&before, rule, &g),
            };
            let fired: Vec<usize> = e
                .scan(policy, |t: TransIdx| Ok::<bool, ()>(g(t.index())))
                .expect("no guard errors, no overflow")
                .iter()
                .map(|t| t.index())
                .collect();
            prop_assert_eq!(&fired, &expected);

            // State equation: M' = M + C·θ.
            let after: Vec<i64> = e.marking().iter().map(|&x| i64::from(x)).collect();
            for p in 0..before.len() {
                let sum: i64 = fired.iter().map(|&t| r.c(t, p)).sum();
                prop_assert_eq!(after[p], before[p] + sum);
            }

            // The step is a firing sequence in the order chosen.
            let mut m = before.clone();
            for &t in &fired {
                prop_assert!(r.enabled(t, &m), "t{} not enabled in sequence at {:?}", t, m);
                for (p, mp) in m.iter_mut().enumerate() {
                    *mp += r.c(t, p);
                }
            }

            // Incremental enabling equals a full recomputation from the arcs.
            let mut inc: Vec<usize> = e.enabled().iter().map(|t| t.index()).collect();
            inc.sort_unstable();
            let full: Vec<usize> = (0..net.num_transitions()).filter(|&t| r.enabled(t, &after)).collect();
            prop_assert_eq!(inc, full);
        }
    }

    #[test]
    fn a_failing_guard_leaves_marking_and_enabled_set_untouched(
        s in spec(6, 6), seed in any::<u64>(), fail_at in 0usize..6
    ) {
        let net = Shared::new(build(&s));
        let mut e = Engine::new(net.clone());
        for scan in 0..10u64 {
            let g = guard_of(seed, scan);
            let m0 = e.marking().to_vec();
            let mut en0 = e.enabled().to_vec();
            en0.sort_unstable();
            let res = e.scan(Policy::Step, |t: TransIdx| {
                if t.index() == fail_at { Err("boom") } else { Ok(g(t.index())) }
            });
            if let Err(err) = res {
                let hit = matches!(err, FireError::Guard { transition, .. } if transition.index() == fail_at);
                prop_assert!(hit, "the error names the failing transition");
                prop_assert_eq!(e.marking(), &m0[..]);
                let mut en1 = e.enabled().to_vec();
                en1.sort_unstable();
                prop_assert_eq!(en1, en0);
                break;
            }
        }
    }

    #[test]
    fn brute_force_p_invariants_stay_constant_on_conservative_nets(
        s in spec(5, 5), seed in any::<u64>()
    ) {
        // Make the net conservative: every transition gives back to a place as many tokens as it
        // takes in total, so the all-ones vector is an invariant besides whatever else is.
        let mut s = s;
        s.capacity = vec![None; s.marking.len()];
        s.arcs.retain(|a| a.3 == ArcKind::Normal);
        for t in 0..s.priority.len() {
            let takes: u32 = s.arcs.iter().filter(|a| a.1 == t && a.4).map(|a| a.2).sum();
            let gives: u32 = s.arcs.iter().filter(|a| a.1 == t && !a.4).map(|a| a.2).sum();
            if takes > gives {
                s.arcs.push((t % s.marking.len(), t, takes - gives, ArcKind::Normal, false));
            } else if gives > takes {
                s.arcs.push((t % s.marking.len(), t, gives - takes, ArcKind::Normal, true));
            }
        }
        let net = Shared::new(build(&s));
        let r = Reference::new(&net);
        let np = net.num_places();
        let nt = net.num_transitions();
        // Every y in {0,1,2}^P with y·C = 0.
        let mut invariants = Vec::new();
        for code in 1..3usize.pow(np as u32) {
            let y: Vec<i64> = (0..np).map(|i| ((code / 3usize.pow(i as u32)) % 3) as i64).collect();
            if (0..nt).all(|t| (0..np).map(|p| y[p] * r.c(t, p)).sum::<i64>() == 0) {
                invariants.push(y);
            }
        }
        prop_assert!(invariants.contains(&vec![1; np]));
        let dot = |y: &[i64], m: &[Tokens]| -> i64 { y.iter().zip(m).map(|(a, &b)| a * i64::from(b)).sum() };
        let start: Vec<i64> = invariants.iter().map(|y| dot(y, &s.marking)).collect();
        let mut e = Engine::new(net.clone());
        for scan in 0..30u64 {
            let g = guard_of(seed, scan);
            e.scan(Policy::Step, |t: TransIdx| Ok::<bool, ()>(g(t.index()))).expect("no errors");
            for (y, &v) in invariants.iter().zip(&start) {
                prop_assert_eq!(dot(y, e.marking()), v);
            }
        }
    }
}

#[test]
fn overflow_is_an_error_and_changes_nothing() {
    let mut b = NetBuilder::new("overflow");
    b.add_place(Place::new("full", Tokens::MAX)).unwrap();
    b.add_transition(Transition::new("t")).unwrap();
    b.add_arc("a", "t", "full", 1, ArcKind::Normal).unwrap();
    let net = Shared::new(b.build().unwrap());
    let mut e = Engine::new(net);
    let err = e.scan(Policy::Step, |_| Ok::<bool, ()>(true)).unwrap_err();
    assert!(matches!(err, FireError::Overflow { .. }));
    assert_eq!(e.marking(), &[Tokens::MAX]);
}

#[test]
fn tokens_produced_in_a_scan_are_usable_only_in_the_next() {
    // a -> t1 -> b -> t2 -> c: one scan moves the token one place.
    let mut b = NetBuilder::new("chain");
    for (id, m) in [("a", 1), ("b", 0), ("c", 0)] {
        b.add_place(Place::new(id, m)).unwrap();
    }
    for id in ["t1", "t2"] {
        b.add_transition(Transition::new(id)).unwrap();
    }
    b.add_arc("x1", "a", "t1", 1, ArcKind::Normal).unwrap();
    b.add_arc("x2", "t1", "b", 1, ArcKind::Normal).unwrap();
    b.add_arc("x3", "b", "t2", 1, ArcKind::Normal).unwrap();
    b.add_arc("x4", "t2", "c", 1, ArcKind::Normal).unwrap();
    let mut e = Engine::new(Shared::new(b.build().unwrap()));
    e.scan(Policy::Step, |_| Ok::<bool, ()>(true)).unwrap();
    assert_eq!(e.marking(), &[0, 1, 0]);
    e.scan(Policy::Step, |_| Ok::<bool, ()>(true)).unwrap();
    assert_eq!(e.marking(), &[0, 0, 1]);
}

#[test]
fn a_firing_that_empties_an_inhibitor_place_lets_a_later_transition_join_the_step() {
    // t1 takes the token from p; t2 is inhibited by p and becomes enabled within the same step.
    let mut b = NetBuilder::new("inhibit");
    b.add_place(Place::new("p", 1)).unwrap();
    b.add_place(Place::new("q", 0)).unwrap();
    b.add_transition(Transition::new("t1")).unwrap();
    b.add_transition(Transition::new("t2")).unwrap();
    b.add_arc("a1", "p", "t1", 1, ArcKind::Normal).unwrap();
    b.add_arc("a2", "p", "t2", 1, ArcKind::Inhibitor).unwrap();
    b.add_arc("a3", "t2", "q", 1, ArcKind::Normal).unwrap();
    let mut e = Engine::new(Shared::new(b.build().unwrap()));
    let fired: Vec<usize> = e
        .scan(Policy::Step, |_| Ok::<bool, ()>(true))
        .unwrap()
        .iter()
        .map(|t| t.index())
        .collect();
    assert_eq!(fired, vec![0, 1]);
    assert_eq!(e.marking(), &[0, 1]);
}
