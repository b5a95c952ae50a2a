//! Every shared fixture gives the states, edges and deadlocks listed in the fixtures README.

use cetratus_analysis::{check, CheckOptions, Report};
use cetratus_testkit::nets;

fn report(rel: &str) -> Report {
    check(&nets::fixture(rel), &CheckOptions::default())
}

fn counts(rel: &str) -> (u64, u64, u64) {
    let r = report(rel);
    assert!(!r.partial, "{rel}: {:?}", r.partial_reason);
    (r.states, r.edges, r.deadlocks)
}

#[test]
fn classic_gspn_has_6_states_9_edges_no_deadlock() {
    assert_eq!(counts("pipe/ClassicGSPN.xml"), (6, 9, 0));
}

#[test]
fn dining_philosophers_has_11_states_30_edges_no_deadlock() {
    assert_eq!(counts("pipe/DiningPhilosophers.xml"), (11, 30, 0));
}

#[test]
fn producer_consumer_has_36_states_66_edges_no_deadlock() {
    assert_eq!(counts("pipe/ProducerConsumer.xml"), (36, 66, 0));
}

#[test]
fn readers_writers_has_5_states_8_edges_no_deadlock() {
    assert_eq!(counts("pipe/ReadersWriters.xml"), (5, 8, 0));
}

#[test]
fn simple_net_has_3_states_2_edges_1_deadlock() {
    assert_eq!(counts("pipe5/simpleNet.xml"), (3, 2, 1));
}

#[test]
fn pipe5_petri_net_has_2_states_1_edge_1_deadlock() {
    assert_eq!(counts("pipe5/petriNet.xml"), (2, 1, 1));
}

#[test]
fn inhibitor_arc_net_has_1_state_1_edge_no_deadlock() {
    assert_eq!(counts("pipe5/inhibitorArc.xml"), (1, 1, 0));
}

#[test]
fn philosophers_5_has_243_states_945_edges_2_deadlocks() {
    assert_eq!(counts("mcc/Philosophers-PT-000005.pnml"), (243, 945, 2));
}

#[test]
fn token_ring_5_has_166_states_365_edges_no_deadlock() {
    assert_eq!(counts("mcc/TokenRing-PT-005.pnml"), (166, 365, 0));
}

#[test]
fn fms_2_has_3444_states_16311_edges_no_deadlock() {
    assert_eq!(counts("mcc/FMS-PT-00002.pnml"), (3_444, 16_311, 0));
}

#[test]
fn nested_pages_has_12_states_18_edges_no_deadlock() {
    assert_eq!(counts("crafted/nested-pages.pnml"), (12, 18, 0));
}

#[test]
fn philosophers_deadlock_witness_is_a_shortest_path_to_a_dead_state() {
    let r = report("mcc/Philosophers-PT-000005.pnml");
    let w = r.deadlock_witness.expect("Philosophers-5 deadlocks");
    // Every philosopher takes one fork: five firings, and no shorter way exists.
    assert_eq!(w.len(), 5);
    assert_eq!(r.live, Some(false));
}

#[test]
fn fms_fixture_matches_the_generated_fms_net() {
    let r = report("mcc/FMS-PT-00002.pnml");
    let g = check(
        &cetratus_analysis::families::fms(2).expect("FMS builds"),
        &CheckOptions::default(),
    );
    assert_eq!(r.p_invariants, g.p_invariants);
    assert_eq!(r.t_invariants, g.t_invariants);
    assert_eq!(r.live, Some(true));
}
