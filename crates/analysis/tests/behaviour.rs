//! Behavioural analyses: coverability, partial runs, witnesses, liveness and reversibility.

mod common;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

use cetratus_analysis::families::kanban;
use cetratus_analysis::{check, Bound, CheckOptions, PartialReason, Report};
use cetratus_net::{ArcKind, NetBuilder, Place, Transition};

fn run(net: &cetratus_net::Net) -> Report {
    check(net, &CheckOptions::default())
}

#[test]
fn a_producer_without_consumer_is_unbounded_and_names_the_place() {
    let net = common::simple(
        &[("src", 1), ("sink", 0)],
        &[("t", &["src"], &["src", "sink"])],
    );
    let r = run(&net);
    assert_eq!(r.graph, "coverability");
    assert_eq!(r.bounded, Some(false));
    assert_eq!(r.unbounded_places, vec!["sink".to_string()]);
    assert_eq!(r.max_tokens.0[1].1, Bound::Omega);
    assert_eq!(r.max_tokens.0[0].1, Bound::Tokens(1));
    assert_eq!(r.structurally_bounded, Some(false));
    assert!(!r.partial);
    let json = serde_json_like(&r);
    assert!(json.contains("ω"));
}

fn serde_json_like(r: &Report) -> String {
    // The crate has no JSON dependency; the text rendering carries the same ω.
    r.to_string()
}

#[test]
fn an_inhibitor_that_caps_a_place_keeps_the_net_bounded() {
    // t adds a token to q while q < 3: bounded by behaviour, not by structure.
    let mut b = NetBuilder::new("capped");
    b.add_place(Place::new("p", 1)).expect("p");
    b.add_place(Place::new("q", 0)).expect("q");
    b.add_transition(Transition::new("t")).expect("t");
    b.add_arc("a", "p", "t", 1, ArcKind::Normal).expect("a");
    b.add_arc("b", "t", "p", 1, ArcKind::Normal).expect("b");
    b.add_arc("c", "t", "q", 1, ArcKind::Normal).expect("c");
    b.add_arc("i", "q", "t", 3, ArcKind::Inhibitor).expect("i");
    let r = run(&b.build().expect("net"));
    assert_eq!(r.graph, "reachability");
    assert_eq!((r.states, r.edges, r.deadlocks), (4, 3, 1));
    assert_eq!(r.bounded, Some(true));
    assert_eq!(r.safe, Some(false));
    assert_eq!(r.max_tokens.0[1].1, Bound::Tokens(3));
    assert_eq!(
        r.deadlock_witness,
        Some(vec!["t".into(), "t".into(), "t".into()])
    );
}

#[test]
fn capacities_are_enabling_conditions() {
    let mut b = NetBuilder::new("cap");
    b.add_place(Place::new("p", 1)).expect("p");
    let mut q = Place::new("q", 0);
    q.capacity = Some(2);
    b.add_place(q).expect("q");
    b.add_transition(Transition::new("t")).expect("t");
    b.add_arc("a", "p", "t", 1, ArcKind::Normal).expect("a");
    b.add_arc("b", "t", "p", 1, ArcKind::Normal).expect("b");
    b.add_arc("c", "t", "q", 1, ArcKind::Normal).expect("c");
    let r = run(&b.build().expect("net"));
    assert_eq!((r.states, r.edges, r.deadlocks), (3, 2, 1));
    assert_eq!(r.bounded, Some(true));
}

#[test]
fn max_states_stops_the_run_and_marks_the_report_partial() {
    let net = kanban(3).expect("Kanban builds");
    let opts = CheckOptions {
        max_states: Some(1_000),
        ..CheckOptions::default()
    };
    let r = check(&net, &opts);
    assert!(r.partial);
    assert_eq!(r.partial_reason, Some(PartialReason::MaxStates));
    assert_eq!(r.states, 1_000);
    assert_eq!(r.live, None);
    assert_eq!(r.reversible, None);
    assert!(r.to_string().contains("PARTIAL"));
}

#[test]
fn a_set_cancel_flag_stops_the_run_and_marks_the_report_partial() {
    let net = kanban(3).expect("Kanban builds");
    let opts = CheckOptions {
        cancel: Some(Arc::new(AtomicBool::new(true))),
        ..CheckOptions::default()
    };
    let r = check(&net, &opts);
    assert!(r.partial);
    assert!(r.states < 58_400);
}

#[test]
fn the_progress_callback_sees_the_state_space_grow() {
    let seen = Arc::new(AtomicU64::new(0));
    let s = seen.clone();
    let opts = CheckOptions {
        progress: Some(Arc::new(move |p| {
            s.fetch_max(p.states, Ordering::Relaxed);
        })),
        threads: 2,
        ..CheckOptions::default()
    };
    let r = check(&kanban(3).expect("Kanban builds"), &opts);
    assert_eq!(r.states, 58_400);
    assert!(seen.load(Ordering::Relaxed) > 0);
}

#[test]
fn two_threads_give_the_same_report_as_one() {
    let net = cetratus_testkit::nets::vernadat();
    let one = check(&net, &CheckOptions::default());
    let two = check(
        &net,
        &CheckOptions {
            threads: 2,
            ..CheckOptions::default()
        },
    );
    assert_eq!((one.states, one.edges), (two.states, two.edges));
    assert_eq!(one.p_invariants, two.p_invariants);
    assert_eq!(one.siphons, two.siphons);
}

#[test]
fn a_transient_initial_state_is_not_a_home_state() {
    let net = common::simple(
        &[("a", 1), ("b", 0), ("c", 0)],
        &[
            ("t0", &["a"], &["b"]),
            ("t1", &["b"], &["c"]),
            ("t2", &["c"], &["b"]),
        ],
    );
    let r = run(&net);
    assert_eq!(r.reversible, Some(false));
    assert_eq!(r.live, Some(false));
    assert_eq!(r.non_live_transitions, vec!["t0".to_string()]);
    assert!(r.dead_transitions.is_empty());
}

#[test]
fn a_marked_cycle_is_live_safe_and_reversible() {
    let net = common::simple(
        &[("a", 1), ("b", 0)],
        &[("t", &["a"], &["b"]), ("u", &["b"], &["a"])],
    );
    let r = run(&net);
    assert_eq!((r.states, r.edges, r.deadlocks), (2, 2, 0));
    assert_eq!(
        (r.live, r.safe, r.reversible),
        (Some(true), Some(true), Some(true))
    );
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
}

#[test]
fn an_unmarked_siphon_is_reported_with_commoner_warning() {
    // {a, b} is a siphon and a trap, but empty at M0: t and u are dead.
    let net = common::simple(
        &[("a", 0), ("b", 0), ("c", 1)],
        &[
            ("t", &["a"], &["b"]),
            ("u", &["b"], &["a"]),
            ("v", &["c"], &["c"]),
        ],
    );
    let r = run(&net);
    assert_eq!(
        r.siphons_without_marked_trap,
        vec![vec!["a".to_string(), "b".to_string()]]
    );
    assert!(r.warnings.iter().any(|w| w.contains("Commoner")));
    assert_eq!(r.dead_transitions, vec!["t".to_string(), "u".to_string()]);
}

#[test]
fn the_deadlock_witness_leads_from_m0_to_a_dead_marking() {
    let net = common::simple(
        &[("p", 2), ("q", 0), ("r", 0)],
        &[
            ("t", &["p"], &["q"]),
            ("u", &["q", "q"], &["r"]),
            ("v", &["p"], &["p"]),
        ],
    );
    // v keeps p alive while p > 0; once both tokens move, only u can fire, then nothing.
    let r = run(&net);
    let w = r.deadlock_witness.clone().expect("a deadlock exists");
    let mut m = net.initial_marking().0;
    for id in &w {
        let t = net.transition_by_id(id).expect("known id");
        assert!(net.is_enabled(t, &m));
        for &(p, d) in net.delta(t) {
            m[p.index()] = (i64::from(m[p.index()]) + d) as u32;
        }
    }
    assert!(
        (0..net.num_transitions() as u32).all(|t| !net.is_enabled(cetratus_net::TransIdx(t), &m))
    );
    assert_eq!(w.len(), 3);
}

/// A clock that moves one second each time it is read.
struct Jumps(AtomicU64);

impl cetratus_analysis::Clock for Jumps {
    fn elapsed(&self) -> std::time::Duration {
        std::time::Duration::from_secs(self.0.fetch_add(1, Ordering::Relaxed))
    }
}

#[test]
fn the_structural_phase_stops_at_the_timeout_and_the_report_says_so() {
    for threads in [1, 2] {
        let opts = CheckOptions {
            clock: Some(Arc::new(Jumps(AtomicU64::new(0)))),
            timeout: Some(std::time::Duration::from_secs(1)),
            threads,
            ..CheckOptions::default()
        };
        let r = check(&kanban(2).expect("Kanban builds"), &opts);
        assert!(r.partial);
        assert_eq!(r.partial_reason, Some(PartialReason::Timeout));
        assert_eq!(r.p_invariants, None, "{:?}", r.notes);
        assert_eq!(r.t_invariants, None);
        assert!(
            r.notes.iter().any(|n| n.contains("P-invariants")),
            "{:?}",
            r.notes
        );
    }
}

#[test]
fn a_set_cancel_flag_also_stops_the_invariants() {
    let opts = CheckOptions {
        cancel: Some(Arc::new(AtomicBool::new(true))),
        ..CheckOptions::default()
    };
    let r = check(&kanban(2).expect("Kanban builds"), &opts);
    assert_eq!(r.partial_reason, Some(PartialReason::Cancelled));
    assert_eq!(r.p_invariants, None);
}
