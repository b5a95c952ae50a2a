//! Structural analyses: invariants are invariant and minimal, classes and siphons are right.

mod common;

use cetratus_analysis::classify::classify;
use cetratus_analysis::invariants::{p_semiflows, t_semiflows, DEFAULT_MAX_ROWS};
use cetratus_analysis::siphons::{minimal_siphons, minimal_traps, SetLimits};
use cetratus_analysis::{check, CheckOptions, Incidence, Semiflow};
use cetratus_net::{Net, TransIdx};
use proptest::prelude::*;
use proptest::strategy::ValueTree;

fn is_p_invariant(inc: &Incidence, y: &[i64]) -> bool {
    let nt = inc.c.first().map_or(0, Vec::len);
    (0..nt).all(|t| inc.c.iter().zip(y).map(|(row, w)| row[t] * w).sum::<i64>() == 0)
}

fn is_t_invariant(inc: &Incidence, x: &[i64]) -> bool {
    inc.c
        .iter()
        .all(|row| row.iter().zip(x).map(|(c, w)| c * w).sum::<i64>() == 0)
}

/// All nonzero vectors in `{0..=k}^n`.
fn vectors(n: usize, k: i64) -> Vec<Vec<i64>> {
    let mut out = vec![vec![]];
    for _ in 0..n {
        out = out
            .into_iter()
            .flat_map(|v| {
                (0..=k).map(move |x| {
                    let mut w = v.clone();
                    w.push(x);
                    w
                })
            })
            .collect();
    }
    out.retain(|v| v.iter().any(|&x| x != 0));
    out
}

fn support(v: &[i64]) -> Vec<usize> {
    (0..v.len()).filter(|&i| v[i] != 0).collect()
}

fn strictly_inside(a: &[usize], b: &[usize]) -> bool {
    a.len() < b.len() && a.iter().all(|i| b.contains(i))
}

/// Checks minimality and completeness of `flows` against every solution in `{0..=3}^n`.
fn check_minimal(flows: &[Semiflow], n: usize, holds: impl Fn(&[i64]) -> bool) {
    let solutions: Vec<Vec<i64>> = vectors(n, 3).into_iter().filter(|v| holds(v)).collect();
    let supports: Vec<Vec<usize>> = flows.iter().map(|f| support(&f.dense(n))).collect();
    for s in &supports {
        assert!(
            !solutions.iter().any(|v| strictly_inside(&support(v), s)),
            "a reported semiflow with support {s:?} is not minimal"
        );
    }
    for v in &solutions {
        let sv = support(v);
        assert!(
            supports.iter().any(|s| s.iter().all(|i| sv.contains(i))),
            "the solution {v:?} contains no reported minimal semiflow"
        );
    }
}

fn small_net() -> impl Strategy<Value = Net> {
    (1usize..=4, 1usize..=4).prop_flat_map(|(np, nt)| {
        (
            proptest::collection::vec(proptest::collection::vec(0u32..=2, nt), np),
            proptest::collection::vec(proptest::collection::vec(0u32..=2, nt), np),
            proptest::collection::vec(0u32..=3, np),
        )
            .prop_map(|(pre, post, m0)| common::from_matrices(&pre, &post, &m0))
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn every_p_invariant_is_constant_along_random_firing_sequences(
        net in small_net(),
        choices in proptest::collection::vec(0usize..16, 0..40),
    ) {
        let inc = Incidence::of(&net);
        let flows = p_semiflows(&net, DEFAULT_MAX_ROWS).expect("small nets do not overflow");
        let mut m = net.initial_marking().0;
        let start: Vec<i128> = flows.iter().map(|y| y.dot(&m).expect("small")).collect();
        for y in &flows {
            prop_assert!(is_p_invariant(&inc, &y.dense(net.num_places())));
        }
        for c in choices {
            let enabled: Vec<TransIdx> = (0..net.num_transitions() as u32)
                .map(TransIdx)
                .filter(|&t| net.is_enabled(t, &m))
                .collect();
            if enabled.is_empty() {
                break;
            }
            let t = enabled[c % enabled.len()];
            for &(p, d) in net.delta(t) {
                m[p.index()] = (i64::from(m[p.index()]) + d) as u32;
            }
            let now: Vec<i128> = flows.iter().map(|y| y.dot(&m).expect("small")).collect();
            prop_assert_eq!(&now, &start);
        }
    }

    #[test]
    fn every_t_invariant_reproduces_the_marking(net in small_net()) {
        let inc = Incidence::of(&net);
        for x in t_semiflows(&net, DEFAULT_MAX_ROWS).expect("small nets do not overflow") {
            prop_assert!(is_t_invariant(&inc, &x.dense(net.num_transitions())));
        }
    }

    #[test]
    fn minimal_siphons_and_traps_agree_with_brute_force(net in small_net()) {
        let np = net.num_places();
        let nt = net.num_transitions();
        let ins = |t: usize| net.pre(TransIdx(t as u32)).iter().map(|&(p, _)| p.index()).collect::<Vec<_>>();
        let outs = |t: usize| net.post(TransIdx(t as u32)).iter().map(|&(p, _)| p.index()).collect::<Vec<_>>();
        let subsets: Vec<Vec<usize>> = (1u32..(1 << np))
            .map(|mask| (0..np).filter(|&p| mask >> p & 1 == 1).collect())
            .collect();
        let is_siphon = |s: &Vec<usize>| (0..nt).all(|t| {
            !outs(t).iter().any(|p| s.contains(p)) || ins(t).iter().any(|p| s.contains(p))
        });
        let is_trap = |s: &Vec<usize>| (0..nt).all(|t| {
            !ins(t).iter().any(|p| s.contains(p)) || outs(t).iter().any(|p| s.contains(p))
        });
        let minimal = |pred: &dyn Fn(&Vec<usize>) -> bool| {
            let all: Vec<&Vec<usize>> = subsets.iter().filter(|s| pred(s)).collect();
            let mut m: Vec<Vec<usize>> = all
                .iter()
                .filter(|s| !all.iter().any(|o| strictly_inside(o, s)))
                .map(|s| (*s).clone())
                .collect();
            m.sort();
            m
        };
        let siphons = minimal_siphons(&net, SetLimits::default());
        prop_assert!(!siphons.truncated);
        prop_assert_eq!(siphons.sets, minimal(&is_siphon));
        let traps = minimal_traps(&net, SetLimits::default());
        prop_assert_eq!(traps.sets, minimal(&is_trap));
    }
}

#[test]
fn p_semiflows_of_small_nets_are_minimal_and_complete() {
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    for _ in 0..100 {
        let net = small_net()
            .new_tree(&mut runner)
            .expect("strategy")
            .current();
        let inc = Incidence::of(&net);
        let p = p_semiflows(&net, DEFAULT_MAX_ROWS).expect("small");
        check_minimal(&p, net.num_places(), |y| is_p_invariant(&inc, y));
        let t = t_semiflows(&net, DEFAULT_MAX_ROWS).expect("small");
        check_minimal(&t, net.num_transitions(), |x| is_t_invariant(&inc, x));
    }
}

#[test]
fn vernadat_cell_has_the_four_p_invariants_of_the_design() {
    let net = cetratus_testkit::nets::vernadat();
    let r = check(&net, &CheckOptions::default());
    let invs = r.p_invariants.expect("computed");
    let consts = r.p_invariant_constants.expect("computed");
    let expect: [(&[&str], i128); 4] = [
        (&["R", "P11", "P14", "P22", "P24"], 1),
        (&["H", "B", "P14"], 7),
        (&["P10", "P11", "P12", "P13", "P14"], 1),
        (&["P20", "P21", "P22", "P23", "P24"], 1),
    ];
    for (places, k) in expect {
        let found = invs.iter().zip(&consts).find(|(inv, _)| {
            let mut ids: Vec<&str> = inv.0.iter().map(|(id, _)| id.as_str()).collect();
            ids.sort_unstable();
            let mut want = places.to_vec();
            want.sort_unstable();
            ids == want && inv.0.iter().all(|(_, w)| *w == 1)
        });
        let (_, c) = found.unwrap_or_else(|| panic!("invariant over {places:?} missing: {invs:?}"));
        assert_eq!(*c, k);
    }
    assert_eq!(r.conservative, Some(true));
    assert_eq!(r.structurally_bounded, Some(true));
    assert_eq!(r.deadlocks, 0);
    assert_eq!(r.live, Some(true));
}

#[test]
fn a_cycle_is_a_state_machine_and_a_marked_graph() {
    let net = common::simple(
        &[("a", 1), ("b", 0)],
        &[("t", &["a"], &["b"]), ("u", &["b"], &["a"])],
    );
    let c = classify(&net);
    assert!(c.ordinary && c.pure && c.state_machine && c.marked_graph);
    assert!(c.free_choice && c.extended_free_choice);
}

#[test]
fn a_shared_place_with_an_extra_input_is_not_free_choice() {
    // p feeds t and u, and u also needs q: the classic non-free-choice confusion.
    let net = common::simple(
        &[("p", 1), ("q", 1), ("r", 0)],
        &[
            ("t", &["p"], &["r"]),
            ("u", &["p", "q"], &["r"]),
            ("v", &["r"], &["p", "q"]),
        ],
    );
    let c = classify(&net);
    assert!(c.ordinary);
    assert!(!c.free_choice);
    assert!(!c.extended_free_choice);
    assert!(!c.state_machine);
}

#[test]
fn a_self_loop_makes_a_net_impure() {
    let net = common::simple(&[("p", 1)], &[("t", &["p"], &["p"])]);
    assert!(!classify(&net).pure);
}

#[test]
fn farkas_reports_overflow_instead_of_a_wrong_invariant() {
    // Weights near u32::MAX chained through several transitions need ever larger coefficients.
    let w = u32::MAX;
    let n = 6;
    let mut pre = vec![vec![0u32; n - 1]; n];
    let mut post = vec![vec![0u32; n - 1]; n];
    for t in 0..n - 1 {
        pre[t][t] = 1;
        post[t + 1][t] = w - t as u32;
    }
    let net = common::from_matrices(&pre, &post, &vec![0; n]);
    match p_semiflows(&net, DEFAULT_MAX_ROWS) {
        Err(cetratus_analysis::AnalysisError::Overflow { .. }) => {}
        other => panic!("expected an overflow error, got {other:?}"),
    }
}
