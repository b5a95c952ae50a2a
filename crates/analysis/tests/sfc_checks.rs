//! The chart checks of `cetratus check` for SFC programs: an unsafe chart, unreachable steps and
//! a parallel branch that never joins are each named; a well-formed chart with nested parallel
//! branches has no finding.

use cetratus_analysis::sfc::check_chart;
use cetratus_analysis::{check, CheckOptions};
use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition};

/// A chart as a net: `steps` (name, initial), `transitions` (name, from steps, to steps).
fn chart(steps: &[(&str, bool)], transitions: &[(&str, &[&str], &[&str])]) -> Net {
    let mut b = NetBuilder::new("chart");
    for (s, initial) in steps {
        b.add_place(Place::new(*s, u32::from(*initial)))
            .expect("a step");
    }
    for (t, from, to) in transitions {
        b.add_transition(Transition::new(*t)).expect("a transition");
        for s in *from {
            b.add_arc(&format!("{s}_{t}"), s, t, 1, ArcKind::Normal)
                .expect("an arc");
        }
        for s in *to {
            b.add_arc(&format!("{t}_{s}"), t, s, 1, ArcKind::Normal)
                .expect("an arc");
        }
    }
    b.build().expect("a well-formed net")
}

fn findings(net: &Net) -> cetratus_analysis::sfc::SfcFindings {
    check_chart(net, &check(net, &CheckOptions::default()))
}

#[test]
fn a_well_formed_chart_with_nested_parallel_branches_has_no_finding() {
    let net = chart(
        &[
            ("S0", true),
            ("A", false),
            ("A1", false),
            ("A2", false),
            ("A3", false),
            ("B", false),
            ("B2", false),
        ],
        &[
            ("Fork", &["S0"], &["A", "B"]),
            ("InnerFork", &["A"], &["A1", "A2"]),
            ("InnerJoin", &["A1", "A2"], &["A3"]),
            ("TB", &["B"], &["B2"]),
            ("Join", &["A3", "B2"], &["S0"]),
        ],
    );
    let f = findings(&net);
    assert!(f.is_clean(), "{f:?}");
    assert!(f.warnings().is_empty());
}

#[test]
fn a_step_activated_twice_through_parallel_branches_is_unsafe_and_the_branches_never_join() {
    // Both branches end in the same step through plain transitions: C is activated twice.
    let net = chart(
        &[("S0", true), ("A", false), ("B", false), ("C", false)],
        &[
            ("Fork", &["S0"], &["A", "B"]),
            ("TA", &["A"], &["C"]),
            ("TB", &["B"], &["C"]),
            ("Back", &["C"], &["S0"]),
        ],
    );
    let f = findings(&net);
    assert!(f.unsafe_steps.contains(&"C".to_string()), "{f:?}");
    assert_eq!(
        f.unjoined_branches,
        [
            ("Fork".to_string(), "A".to_string()),
            ("Fork".to_string(), "B".to_string())
        ]
    );
    let text = f.warnings().join("\n");
    assert!(text.contains("unsafe SFC: step"), "{text}");
    assert!(text.contains("never joins"), "{text}");
}

#[test]
fn a_step_no_transition_leads_to_is_unreachable() {
    let net = chart(
        &[("S0", true), ("S1", false), ("Lost", false)],
        &[
            ("T1", &["S0"], &["S1"]),
            ("T2", &["S1"], &["S0"]),
            ("T3", &["Lost"], &["S0"]),
        ],
    );
    let f = findings(&net);
    assert_eq!(f.unreachable_steps, ["Lost"]);
    assert!(f.unsafe_steps.is_empty() && f.unjoined_branches.is_empty());
    assert!(f.to_string().contains("unreachable steps: Lost"), "{f}");
}
