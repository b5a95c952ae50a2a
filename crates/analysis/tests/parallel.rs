//! The parallel exploration (`threads ≥ 2`) finds exactly what the sequential one finds: the
//! same states, edges, dead states, deadlock witness, bounds, liveness, and the same stopping
//! point under `--max-states`.

mod common;

use cetratus_analysis::families::{fms, kanban};
use cetratus_analysis::invariants::DEFAULT_MAX_ROWS;
use cetratus_analysis::reach::{explore, structural_packing, ReachOptions, ReachResult};
use cetratus_analysis::SpareCoreFn;
use cetratus_analysis::{check, CheckOptions, Report};
use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition};
use cetratus_testkit::nets;
use proptest::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

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

/// The report without what legitimately differs between runs (time, memory).
fn behaviour(net: &Net, threads: usize, max_states: Option<u64>) -> Report {
    let mut r = check(
        net,
        &CheckOptions {
            threads,
            max_states,
            ..CheckOptions::default()
        },
    );
    r.timings = Default::default();
    r.bytes_per_state = None;
    r.store_bytes = None;
    r
}

/// The exploration result without the store's bytes (the parallel store is laid out differently).
fn explored(net: &Net, threads: usize, max_states: Option<u64>, liveness: bool) -> ReachResult {
    handed_over(net, threads, 0, max_states, liveness)
}

/// [`explored`] on one thread until `from` states are found, then on `threads`.
fn handed_over(
    net: &Net,
    threads: usize,
    from: u64,
    max_states: Option<u64>,
    liveness: bool,
) -> ReachResult {
    let packing = structural_packing(net, DEFAULT_MAX_ROWS)
        .expect("structural bounds")
        .expect("structurally bounded");
    let opts = ReachOptions {
        threads,
        max_states,
        liveness,
        parallel_from: from,
        ..ReachOptions::default()
    };
    let mut r = explore(net, &packing, &opts).expect("fits the packed explorer");
    r.peak_bytes = 0;
    r
}

#[test]
fn parallel_check_of_every_fixture_equals_the_sequential_one() {
    for rel in FIXTURES {
        let net = nets::fixture(rel);
        let one = behaviour(&net, 1, None);
        for threads in [2, 3] {
            assert_eq!(
                behaviour(&net, threads, None),
                one,
                "{rel}, {threads} threads"
            );
        }
    }
}

#[test]
fn parallel_witness_of_philosophers_is_the_sequential_shortest_one() {
    let net = nets::fixture("mcc/Philosophers-PT-000005.pnml");
    let one = behaviour(&net, 1, None);
    let two = behaviour(&net, 2, None);
    assert!(one.deadlock_witness.is_some());
    assert_eq!(two.deadlock_witness, one.deadlock_witness);
}

#[test]
fn parallel_exploration_of_fms_and_kanban_one_to_three_equals_the_sequential_one() {
    for n in 1..=3 {
        for net in [
            fms(n).expect("FMS builds"),
            kanban(n).expect("Kanban builds"),
        ] {
            let one = explored(&net, 1, None, true);
            assert!(one.liveness.is_some());
            for threads in [2, 3, 4] {
                assert_eq!(
                    explored(&net, threads, None, true),
                    one,
                    "N={n}, {threads} threads"
                );
            }
        }
    }
}

#[test]
#[cfg_attr(debug_assertions, ignore = "slow in debug; run with --release")]
fn parallel_exploration_of_fms_and_kanban_four_equals_the_sequential_one() {
    for net in [
        fms(4).expect("FMS builds"),
        kanban(4).expect("Kanban builds"),
    ] {
        let one = explored(&net, 1, None, false);
        assert_eq!(explored(&net, 2, None, false), one);
    }
}

#[test]
fn an_exploration_handed_over_to_more_threads_midway_equals_the_sequential_one() {
    // The hand-over happens between blocks of 16,384 expanded states: FMS 3 and Kanban 3 have
    // 48,590 and 58,400 states, so it happens once or twice over, or (past the last state) never.
    for net in [
        fms(3).expect("FMS builds"),
        kanban(3).expect("Kanban builds"),
    ] {
        let one = explored(&net, 1, None, true);
        for from in [1, 16_384, 30_000, 1_000_000] {
            for threads in [2, 3] {
                assert_eq!(
                    handed_over(&net, threads, from, None, true),
                    one,
                    "from {from}, {threads} threads"
                );
            }
        }
        for max in [20_000, 40_000] {
            assert_eq!(
                handed_over(&net, 2, 16_384, Some(max), true),
                explored(&net, 1, Some(max), true),
                "from 16,384, max_states {max}"
            );
        }
    }
}

#[test]
fn an_exploration_told_no_core_is_spare_stays_on_one_thread() {
    // Asked once, at the hand-over point: "no" keeps the sequential explorer, whose result,
    // memory included, is the one-thread result; "yes" hands over.
    let net = kanban(3).expect("Kanban builds");
    let packing = structural_packing(&net, DEFAULT_MAX_ROWS)
        .expect("structural bounds")
        .expect("structurally bounded");
    let run = |threads: usize, spare: Option<bool>| {
        let asked = Arc::new(AtomicUsize::new(0));
        let count = asked.clone();
        let opts = ReachOptions {
            threads,
            liveness: true,
            parallel_from: if threads > 1 { 16_384 } else { 0 },
            spare_core: spare.map(|spare| {
                Arc::new(move || {
                    count.fetch_add(1, Ordering::Relaxed);
                    spare
                }) as SpareCoreFn
            }),
            ..ReachOptions::default()
        };
        let r = explore(&net, &packing, &opts).expect("fits the packed explorer");
        (r, asked.load(Ordering::Relaxed))
    };
    let (one, _) = run(1, None);
    let (kept, asked) = run(2, Some(false));
    assert_eq!(asked, 1);
    assert_eq!(kept, one, "memory included");
    let (handed, asked) = run(2, Some(true));
    assert_eq!(asked, 1);
    assert_eq!(handed, run(2, None).0, "memory included");
    assert_eq!(
        ReachResult {
            peak_bytes: 0,
            ..handed
        },
        ReachResult {
            peak_bytes: 0,
            ..one
        }
    );
}

#[test]
fn parallel_exploration_stops_at_max_states_where_the_sequential_one_stops() {
    let net = fms(3).expect("FMS builds");
    for max in [
        0, 1, 2, 100, 3_000, 4_095, 4_096, 20_000, 48_589, 48_590, 48_591,
    ] {
        let one = explored(&net, 1, Some(max), true);
        for threads in [2, 3] {
            assert_eq!(
                explored(&net, threads, Some(max), true),
                one,
                "max_states {max}, {threads} threads"
            );
        }
    }
}

#[test]
fn parallel_check_under_max_states_equals_the_sequential_one() {
    let net = nets::fixture("mcc/Philosophers-PT-000005.pnml");
    for max in [0, 10, 100, 242, 243] {
        assert_eq!(
            behaviour(&net, 2, Some(max)),
            behaviour(&net, 1, Some(max)),
            "max_states {max}"
        );
    }
}

fn small_net() -> impl Strategy<Value = Net> {
    (1usize..=5, 1usize..=5).prop_flat_map(|(np, nt)| {
        (
            proptest::collection::vec(proptest::collection::vec(0u32..=2, nt), np),
            proptest::collection::vec(proptest::collection::vec(0u32..=2, nt), np),
            proptest::collection::vec(0u32..=3, np),
        )
            .prop_map(|(pre, post, m0)| common::from_matrices(&pre, &post, &m0))
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Random small nets (bounded or not), with a state limit so that none runs for long.
    #[test]
    fn parallel_check_of_a_random_net_equals_the_sequential_one(net in small_net()) {
        prop_assert_eq!(behaviour(&net, 2, Some(5_000)), behaviour(&net, 1, Some(5_000)));
    }
}

/// Sixteen switches that flip back and forth (2^16 states, one strongly connected component)
/// and a one-way latch that any state may close, after which the switches still flip: 2^17
/// states, of which only the first half reach M0. The backward search meets layers of up to
/// 12,870 states, large enough to be split between threads, and finds M0 unreachable from half
/// the states, so Tarjan runs after it.
fn switches_with_a_latch() -> Net {
    let mut b = NetBuilder::new("switches-with-a-latch");
    for i in 0..16 {
        b.add_place(Place::new(format!("off{i}"), 1))
            .expect("place");
        b.add_place(Place::new(format!("on{i}"), 0)).expect("place");
        for (t, from, to) in [("up", "off", "on"), ("down", "on", "off")] {
            b.add_transition(Transition::new(format!("{t}{i}")))
                .expect("transition");
            let (tr, a, z) = (format!("{t}{i}"), format!("{from}{i}"), format!("{to}{i}"));
            b.add_arc(&format!("{tr}a"), &a, &tr, 1, ArcKind::Normal)
                .expect("arc");
            b.add_arc(&format!("{tr}b"), &tr, &z, 1, ArcKind::Normal)
                .expect("arc");
        }
    }
    b.add_place(Place::new("open", 1)).expect("place");
    b.add_place(Place::new("closed", 0)).expect("place");
    b.add_transition(Transition::new("close"))
        .expect("transition");
    b.add_arc("ca", "open", "close", 1, ArcKind::Normal)
        .expect("arc");
    b.add_arc("cb", "close", "closed", 1, ArcKind::Normal)
        .expect("arc");
    b.build().expect("net")
}

#[test]
fn parallel_liveness_of_a_large_net_that_is_not_reversible_equals_the_sequential_one() {
    let net = switches_with_a_latch();
    let one = explored(&net, 1, None, true);
    assert_eq!(one.states, 1 << 17);
    let live = one.liveness.as_ref().expect("liveness decided");
    assert!(!live.reversible);
    assert!(!live.live);
    for threads in [2, 3] {
        assert_eq!(
            explored(&net, threads, None, true),
            one,
            "{threads} threads"
        );
    }
}
