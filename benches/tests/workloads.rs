//! The workloads are the nets the rest of the project knows: the bare Vernadat net built in code
//! is the example cell's net, so a bench and a test that name "the Vernadat net" mean one net.

use cetratus_bench::workloads;
use cetratus_net::{Net, TransIdx};

/// Everything that makes a net's behaviour, by id: places with their initial marking, then per
/// transition (in declaration order) its Pre, Post and inhibitor arcs with their weights.
fn shape(net: &Net) -> (Vec<(String, u32)>, Vec<String>) {
    let places = net
        .places()
        .iter()
        .map(|p| (p.id.clone(), p.initial))
        .collect();
    let named = |arcs: &[(cetratus_net::PlaceIdx, u32)]| {
        let mut v: Vec<String> = arcs
            .iter()
            .map(|&(p, w)| format!("{}*{w}", net.place(p).id))
            .collect();
        v.sort();
        v.join(",")
    };
    let transitions = (0..net.num_transitions())
        .map(|t| {
            let t = TransIdx(t as u32);
            format!(
                "{}: pre [{}] post [{}] inhibitors [{}]",
                net.transition(t).id,
                named(net.pre(t)),
                named(net.post(t)),
                named(net.inhibitors(t)),
            )
        })
        .collect();
    (places, transitions)
}

#[test]
fn the_vernadat_workload_is_the_net_of_the_vernadat_example() {
    assert_eq!(
        shape(&workloads::vernadat()),
        shape(&cetratus_testkit::nets::vernadat())
    );
}

#[test]
fn the_stubborn_set_figures_count_the_reduced_space_beside_the_full_one() {
    for family in ["Kanban", "FMS"] {
        let r = cetratus_bench::analysis::reduction(family, 3);
        let full =
            cetratus_bench::analysis::explore_once(&cetratus_bench::analysis::family(family, 3));
        assert_eq!(r.full_states, full.states, "{family}");
        assert!(!r.deadlock, "{family}(3) has no deadlock");
        assert!(
            r.reduced_states >= 1 && r.reduced_states < r.full_states,
            "{family}(3): {} reduced states for {} in full",
            r.reduced_states,
            r.full_states
        );
    }
}
