//! Property-directed checks (`cetratus check NET --property …`, `--reach P`, `--always P`), the
//! way LoLA is used: one question, answered as soon as it is known, with the firing sequence
//! that shows it.
//!
//! | property | `holds` means | the search stops at | witness |
//! |---|---|---|---|
//! | `deadlock` | some reachable marking is dead | the first dead state | path to it |
//! | `bounded` | every place is bounded | the first ω of a Karp–Miller graph | path to a marking covering an earlier one |
//! | `safe` | no reachable marking has 2 tokens in a place | the first such marking | path to it |
//! | `live` | every transition can always fire again | a dead state, else the end | path to a marking from which some transition never fires again |
//! | `reversible` | M0 is reachable from every reachable marking | a dead state ≠ M0, else the end | path to a marking from which M0 is unreachable |
//! | `reach P` | some reachable marking satisfies P | the first such marking | path to it |
//! | `always P` | every reachable marking satisfies P | the first marking violating P | path to it |
//!
//! `deadlock`, `reach` and `always` use stubborn sets (module `reach::stubborn`) unless
//! [`CheckOptions::reduction`] is off; their witness is then a real firing sequence, not
//! necessarily a shortest one (`witness_shortest: false`). Without reduction the search is
//! breadth-first and the witness is shortest.

use cetratus_net::{Net, TransIdx};

use crate::budget::PartialReason;
use crate::check::{deadline, ms, now, why_stopped, ProvenBounds};
use crate::coverability::{karp_miller, karp_miller_until_omega};
use crate::predicate::Predicate;
use crate::reach::search::{After, Outcome, Target};
use crate::reach::stubborn::Stubborn;
use crate::reach::{Packing, ReachOptions, Stop};
use crate::report::{transition_ids, Report};
use crate::CheckOptions;

/// One question about a net.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Property {
    /// Some reachable marking is dead.
    Deadlock,
    /// Every place is bounded.
    Bounded,
    /// Every place holds at most one token in every reachable marking.
    Safe,
    /// Every transition can fire again from every reachable marking.
    Live,
    /// M0 can be reached again from every reachable marking.
    Reversible,
    /// Some reachable marking satisfies the predicate.
    Reach(Predicate),
    /// Every reachable marking satisfies the predicate.
    Always(Predicate),
}

impl Property {
    /// The names `--property` accepts.
    pub const NAMES: [&'static str; 5] = ["deadlock", "bounded", "safe", "live", "reversible"];

    /// The property called `name` (one of [`Property::NAMES`]).
    pub fn named(name: &str) -> Option<Property> {
        Some(match name {
            "deadlock" => Property::Deadlock,
            "bounded" => Property::Bounded,
            "safe" => Property::Safe,
            "live" => Property::Live,
            "reversible" => Property::Reversible,
            _ => return None,
        })
    }

    /// How the report names it.
    pub fn label(&self) -> String {
        match self {
            Property::Deadlock => "deadlock".into(),
            Property::Bounded => "bounded".into(),
            Property::Safe => "safe".into(),
            Property::Live => "live".into(),
            Property::Reversible => "reversible".into(),
            Property::Reach(p) => format!("reach {}", p.text),
            Property::Always(p) => format!("always {}", p.text),
        }
    }
}

/// The report of property mode before the check: everything unknown, and a note saying that
/// only what the property needs is computed.
fn blank(net: &Net, property: &Property) -> Report {
    let mut r = Report::empty(net);
    r.notes.push(
        "property mode: only what the property needs is computed (no invariants, siphons or \
         traps; run without --property, --reach or --always for the full report)"
            .into(),
    );
    r.property = Some(property.label());
    r
}

/// The note of a check stopped early: what stopped it, and that the property stays open.
fn undecided_note(s: &Stop) -> String {
    format!("{}; the property is not decided", why_stopped(s, "holding"))
}

/// Checks one property of `net` within the budgets of `opts`. Never fails: what could not be
/// decided is `holds: null`, with the reason in `partial_reason` and the notes.
pub fn check_property(net: &Net, property: &Property, opts: &CheckOptions) -> Report {
    let t0 = now(opts);
    let mut r = blank(net, property);
    let deadline = deadline(opts);
    let bounds = ProvenBounds::prove(net, opts, &deadline, &mut r.notes);
    r.structurally_bounded = bounds.structurally_bounded();
    r.timings.structure_ms = ms(opts, t0);
    let tb = now(opts);
    // The search decides liveness itself, on one thread.
    let ropts = ReachOptions {
        liveness: false,
        threads: 1,
        parallel_from: 0,
        spare_core: None,
        ..opts.reach_options(deadline)
    };
    decide(net, property, opts, &bounds.known, &ropts, &mut r);
    r.timings.behaviour_ms = ms(opts, tb);
    r
}

/// How the search answers a property.
struct Plan<'a> {
    /// What the search looks for.
    target: Target<'a>,
    /// What it decides once the exploration is complete.
    after: After,
    /// Stubborn sets keep the answer (and the witness real).
    reducible: bool,
    /// The predicate whose places the stubborn sets must watch.
    pred: Option<&'a Predicate>,
}

impl<'a> Plan<'a> {
    /// The plan of `property`, whose unsafe-marking predicate and, for `always`, negated
    /// predicate the caller holds; `None` for `bounded`, which needs no search.
    fn of(
        net: &Net,
        property: &'a Property,
        unsafe_pred: &'a Predicate,
        negated: Option<&'a Predicate>,
    ) -> Option<Plan<'a>> {
        let plan = |target, after, reducible, pred| Plan {
            target,
            after,
            reducible,
            pred,
        };
        Some(match property {
            Property::Deadlock => plan(Target::Dead, After::Nothing, true, None),
            Property::Safe => plan(Target::Marking(unsafe_pred), After::Nothing, false, None),
            Property::Live if net.num_transitions() > 0 => {
                plan(Target::Dead, After::Live, false, None)
            }
            Property::Live => plan(Target::None, After::Nothing, false, None),
            Property::Reversible => plan(Target::DeadNotInitial, After::Reversible, false, None),
            Property::Reach(p) => plan(Target::Marking(p), After::Nothing, true, Some(p)),
            Property::Always(p) => plan(Target::Marking(negated?), After::Nothing, true, Some(p)),
            Property::Bounded => return None,
        })
    }
}

/// Decides `property`: `bounded` on a Karp–Miller graph, the others by a search over states
/// packed with proven widths.
fn decide(
    net: &Net,
    property: &Property,
    opts: &CheckOptions,
    known: &[Option<u64>],
    ropts: &ReachOptions,
    r: &mut Report,
) {
    if *property == Property::Bounded {
        return decide_bounded(net, known, ropts, r);
    }
    let Some(bounds) = packing_bounds(net, property, known, ropts, r) else {
        return;
    };
    let packing = Packing::new(&bounds);
    let unsafe_pred = Predicate::unsafe_marking(net);
    let negated = match property {
        Property::Always(p) => Some(p.negated()),
        _ => None,
    };
    let Some(plan) = Plan::of(net, property, &unsafe_pred, negated.as_ref()) else {
        return;
    };
    let stubborn = (plan.reducible && opts.reduction).then(|| {
        Stubborn::new(
            net,
            plan.pred.map(|p| p.support(net.num_places())).as_deref(),
        )
    });
    r.reduction = Some(if stubborn.is_some() {
        "stubborn"
    } else {
        "none"
    });
    let searched = crate::reach::search(
        net,
        &packing,
        &plan.target,
        stubborn.as_ref(),
        plan.after,
        ropts,
    );
    match searched {
        Ok(out) => report_search(net, property, &out, stubborn.is_some(), r),
        Err(e) => r.stopped_early(
            PartialReason::NotExplored,
            format!("the state space was not explored: {e}"),
        ),
    }
}

/// `bounded`: proven by the structural bounds and capacities, else decided by a Karp–Miller
/// graph that stops at the first ω.
fn decide_bounded(net: &Net, known: &[Option<u64>], ropts: &ReachOptions, r: &mut Report) {
    if known.iter().all(Option::is_some) {
        r.holds = Some(true);
        r.bounded = Some(true);
        r.notes.push(
            "every place has a structural bound or a capacity: bounded without exploring".into(),
        );
        return;
    }
    let km = karp_miller_until_omega(net, ropts);
    r.graph = "coverability";
    r.states = km.nodes;
    r.edges = km.edges;
    if let Some(w) = &km.first_omega {
        r.holds = Some(false);
        r.bounded = Some(false);
        r.witness = Some(transition_ids(net, w));
        r.witness_shortest = Some(false);
        r.notes.push(
            "the witness reaches a marking that strictly covers an earlier marking on its \
             path: the transitions between the two can fire again and again"
                .into(),
        );
    } else if let Some(s) = &km.stopped {
        r.stopped_early(s.reason(), undecided_note(s));
    } else {
        r.holds = Some(true);
        r.bounded = Some(true);
    }
}

/// The widths of the packed states' fields, or `None` when the search cannot run: the net is
/// unbounded, or the Karp–Miller graph that would find the widths was stopped.
fn packing_bounds(
    net: &Net,
    property: &Property,
    known: &[Option<u64>],
    ropts: &ReachOptions,
    r: &mut Report,
) -> Option<Vec<u64>> {
    if *property == Property::Safe {
        return Some(safe_widths(net, known));
    }
    if known.iter().all(Option::is_some) {
        return Some(known.iter().map(|b| b.unwrap_or(0)).collect());
    }
    let km = karp_miller(net, ropts);
    if let Some(s) = &km.stopped {
        r.graph = "coverability";
        r.states = km.nodes;
        r.stopped_early(s.reason(), undecided_note(s));
        return None;
    }
    if !km.unbounded.is_empty() {
        r.graph = "coverability";
        r.states = km.nodes;
        r.edges = km.edges;
        r.bounded = Some(false);
        r.stopped_early(
            PartialReason::NotExplored,
            format!(
                "the net is unbounded ({} can grow without limit): {} is decided on bounded nets \
                 only",
                km.unbounded
                    .iter()
                    .map(|p| net.places()[p.index()].id.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
                property.label()
            ),
        );
        return None;
    }
    Some(km.max_tokens)
}

/// Fields wide enough for one firing from a safe marking: the search for `safe` stops at the
/// first unsafe marking, so no field ever overflows, bounded net or not.
fn safe_widths(net: &Net, known: &[Option<u64>]) -> Vec<u64> {
    let m0 = net.initial_marking();
    (0..net.num_places())
        .map(|p| {
            let most_in = net
                .producers(cetratus_net::PlaceIdx(p as u32))
                .iter()
                .map(|&(_, w)| u64::from(w))
                .max()
                .unwrap_or(0);
            let wide = u64::from(m0.as_slice()[p]).max(1 + most_in);
            known[p].map_or(wide, |k| k.min(wide))
        })
        .collect()
}

/// The search's figures and, unless it was stopped, the answer it found.
fn report_search(net: &Net, property: &Property, out: &Outcome, reduced: bool, r: &mut Report) {
    r.graph = "reachability";
    r.states = out.states;
    r.edges = out.edges;
    r.bits_per_state = Some(out.bits_per_state);
    r.store_bytes = Some(out.peak_bytes);
    r.bytes_per_state = Some(out.peak_bytes as f64 / out.states.max(1) as f64);
    if reduced {
        r.notes.push(format!(
            "stubborn sets: {} of {} expanded states fired a reduced set of transitions",
            out.reduced_states, out.states
        ));
    }
    if let Some(w) = &out.found {
        return report_found(net, property, w, !reduced, r);
    }
    if let Some(s) = &out.stopped {
        return r.stopped_early(s.reason(), undecided_note(s));
    }
    match &out.verdict {
        Some((holds, w)) => {
            r.holds = Some(*holds);
            r.witness = w.as_deref().map(|w| transition_ids(net, w));
            r.witness_shortest = r.witness.as_ref().map(|_| true);
            if let Some(t) = out.culprit {
                let id = &net.transitions()[t.index()].id;
                r.non_live_transitions = vec![id.clone()];
                r.notes.push(format!(
                    "from the marking the witness reaches, {id} can never fire again"
                ));
            }
            if *property == Property::Live {
                r.live = Some(*holds);
            } else {
                r.reversible = Some(*holds);
            }
        }
        None => {
            // The search met no target and explored everything.
            r.holds = Some(!matches!(property, Property::Deadlock | Property::Reach(_)));
            match property {
                Property::Safe => r.safe = Some(true),
                Property::Live => r.live = Some(true),
                _ => {}
            }
        }
    }
}

/// The search reached its target along `path`: for deadlock, reach and safe it is the witness;
/// for always, live and reversible it is a counterexample.
fn report_found(net: &Net, property: &Property, path: &[TransIdx], shortest: bool, r: &mut Report) {
    r.holds = Some(matches!(property, Property::Deadlock | Property::Reach(_)));
    r.witness = Some(transition_ids(net, path));
    r.witness_shortest = Some(shortest);
    match property {
        Property::Deadlock => r.deadlocks = 1,
        Property::Safe => r.safe = Some(false),
        Property::Live => {
            r.live = Some(false);
            r.deadlocks = 1;
            r.notes
                .push("the witness reaches a dead marking: no transition fires again".into());
        }
        Property::Reversible => {
            r.reversible = Some(false);
            r.deadlocks = 1;
            r.notes.push(
                "the witness reaches a dead marking other than M0: M0 is unreachable from it"
                    .into(),
            );
        }
        _ => {}
    }
}
