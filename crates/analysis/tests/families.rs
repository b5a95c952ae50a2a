//! The generated FMS and Kanban nets have the published state counts.

use cetratus_analysis::families::{fms, kanban};
use cetratus_analysis::{check, CheckOptions, Report};

fn run(net: &cetratus_net::Net) -> Report {
    check(net, &CheckOptions::default())
}

#[test]
fn fms_with_one_to_three_parts_has_the_published_state_counts() {
    for (n, states) in [(1, 120), (2, 3_444), (3, 48_590)] {
        let r = run(&fms(n).expect("FMS builds"));
        assert_eq!(r.states, states, "FMS({n})");
        assert!(!r.partial);
        assert_eq!(r.deadlocks, 0);
    }
}

#[test]
fn fms_with_two_parts_has_the_fixture_edge_count() {
    let r = run(&fms(2).expect("FMS builds"));
    assert_eq!((r.states, r.edges, r.deadlocks), (3_444, 16_311, 0));
    assert_eq!(r.live, Some(true));
    assert_eq!(r.reversible, Some(true));
}

#[test]
fn kanban_with_one_to_three_cards_has_the_published_state_counts() {
    for (n, states) in [(1, 160), (2, 4_600), (3, 58_400)] {
        let r = run(&kanban(n).expect("Kanban builds"));
        assert_eq!(r.states, states, "Kanban({n})");
        assert!(!r.partial);
        assert_eq!(r.deadlocks, 0);
        assert_eq!(r.live, Some(true));
        assert_eq!(r.reversible, Some(true));
    }
}

#[test]
#[cfg_attr(debug_assertions, ignore = "slow in debug; run with --release")]
fn fms_and_kanban_with_four_have_the_published_state_counts() {
    assert_eq!(run(&fms(4).expect("FMS builds")).states, 438_600);
    assert_eq!(run(&kanban(4).expect("Kanban builds")).states, 454_475);
}
