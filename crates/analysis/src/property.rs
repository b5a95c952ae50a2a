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
use crate::check::{deadline, interrupted, known_bounds, ms, now, tableau_bytes};
use crate::classify::classify;
use crate::coverability::{karp_miller, karp_miller_until_omega};
use crate::invariants::structural_bounds_within;
use crate::predicate::Predicate;
use crate::reach::search::{After, Target};
use crate::reach::stubborn::Stubborn;
use crate::reach::{Packing, ReachOptions, Stop};
use crate::report::{Named, Report, Timings};
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

fn blank(net: &Net, property: &Property) -> Report {
    Report {
        net: net.id().to_string(),
        places: net.num_places(),
        transitions: net.num_transitions(),
        arcs: net.arcs().len(),
        graph: "none",
        states: 0,
        edges: 0,
        deadlocks: 0,
        deadlock_witness: None,
        bounded: None,
        safe: None,
        unbounded_places: Vec::new(),
        max_tokens: Named(Vec::new()),
        live: None,
        non_live_transitions: Vec::new(),
        dead_transitions: Vec::new(),
        reversible: None,
        p_invariants: None,
        p_invariant_constants: None,
        t_invariants: None,
        conservative: None,
        structurally_bounded: None,
        classification: classify(net),
        siphons: Vec::new(),
        siphons_truncated: false,
        siphons_without_marked_trap: Vec::new(),
        traps: Vec::new(),
        traps_truncated: false,
        warnings: Vec::new(),
        notes: vec![
            "property mode: only what the property needs is computed (no invariants, siphons or \
             traps; run without --property, --reach or --always for the full report)"
                .into(),
        ],
        partial: false,
        partial_reason: None,
        bits_per_state: None,
        bytes_per_state: None,
        store_bytes: None,
        property: Some(property.label()),
        sfc: None,
        holds: None,
        witness: None,
        witness_shortest: None,
        reduction: None,
        incidence: None,
        timings: Timings::default(),
    }
}

fn stop_note(s: &Stop) -> String {
    let what = match s {
        Stop::MaxStates(n) => format!("stopped after {n} states (raise --max-states)"),
        Stop::MaxMemory(b) => {
            format!("stopped before holding more than {b} bytes (raise --max-memory)")
        }
        Stop::Timeout => "stopped when the time budget ran out (raise --timeout)".into(),
        Stop::Cancelled => "cancelled (Ctrl-C)".into(),
    };
    format!("{what}; the property is not decided")
}

fn names(net: &Net, path: &[TransIdx]) -> Vec<String> {
    path.iter()
        .map(|t| net.transitions()[t.index()].id.clone())
        .collect()
}

/// Checks one property of `net` within the budgets of `opts`. Never fails: what could not be
/// decided is `holds: null`, with the reason in `partial_reason` and the notes.
pub fn check_property(net: &Net, property: &Property, opts: &CheckOptions) -> Report {
    let t0 = now(opts);
    let mut r = blank(net, property);
    let deadline = deadline(opts);
    let stop = || interrupted(opts, &deadline).is_some();
    let sb = structural_bounds_within(net, opts.farkas_max_rows, tableau_bytes(opts), &stop);
    let known = known_bounds(net, &sb, &mut r.notes);
    r.structurally_bounded = sb.as_ref().ok().map(|b| b.iter().all(Option::is_some));
    r.timings.structure_ms = ms(opts, t0);
    let tb = now(opts);
    let ropts = ReachOptions {
        max_states: opts.max_states,
        max_memory: opts.max_memory,
        deadline,
        cancel: opts.cancel.clone(),
        progress: opts.progress.clone(),
        liveness: false,
        threads: 1,
        parallel_from: 0,
        spare_core: None,
    };
    decide(net, property, opts, &known, &ropts, &mut r);
    r.timings.behaviour_ms = ms(opts, tb);
    r
}

fn partial(r: &mut Report, s: &Stop) {
    r.partial = true;
    r.partial_reason = Some(s.reason());
    r.notes.push(stop_note(s));
}

fn decide(
    net: &Net,
    property: &Property,
    opts: &CheckOptions,
    known: &[Option<u64>],
    ropts: &ReachOptions,
    r: &mut Report,
) {
    let all_known = known.iter().all(Option::is_some);
    if *property == Property::Bounded {
        if all_known {
            r.holds = Some(true);
            r.bounded = Some(true);
            r.notes.push(
                "every place has a structural bound or a capacity: bounded without exploring"
                    .into(),
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
            r.witness = Some(names(net, w));
            r.witness_shortest = Some(false);
            r.notes.push(
                "the witness reaches a marking that strictly covers an earlier marking on its \
                 path: the transitions between the two can fire again and again"
                    .into(),
            );
        } else if let Some(s) = &km.stopped {
            partial(r, s);
        } else {
            r.holds = Some(true);
            r.bounded = Some(true);
        }
        return;
    }
    let m0 = net.initial_marking();
    let bounds: Vec<u64> = if *property == Property::Safe {
        // Fields wide enough for one firing from a safe marking: the search stops at the first
        // unsafe marking, so no field ever overflows, bounded net or not.
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
    } else if all_known {
        known.iter().map(|b| b.unwrap_or(0)).collect()
    } else {
        let km = karp_miller(net, ropts);
        if let Some(s) = &km.stopped {
            r.graph = "coverability";
            r.states = km.nodes;
            partial(r, s);
            return;
        }
        if !km.unbounded.is_empty() {
            r.graph = "coverability";
            r.states = km.nodes;
            r.edges = km.edges;
            r.bounded = Some(false);
            r.partial = true;
            r.partial_reason = Some(PartialReason::NotExplored);
            r.notes.push(format!(
                "the net is unbounded ({} can grow without limit): {} is decided on bounded nets \
                 only",
                km.unbounded
                    .iter()
                    .map(|p| net.places()[p.index()].id.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
                property.label()
            ));
            return;
        }
        km.max_tokens
    };
    let packing = Packing::new(&bounds);
    let unsafe_pred = Predicate::unsafe_marking(net);
    let negated;
    let (target, after, reducible, pred) = match property {
        Property::Deadlock => (Target::Dead, After::Nothing, true, None),
        Property::Safe => (Target::Marking(&unsafe_pred), After::Nothing, false, None),
        Property::Live if net.num_transitions() > 0 => (Target::Dead, After::Live, false, None),
        Property::Live => (Target::None, After::Nothing, false, None),
        Property::Reversible => (Target::DeadNotInitial, After::Reversible, false, None),
        Property::Reach(p) => (Target::Marking(p), After::Nothing, true, Some(p)),
        Property::Always(p) => {
            negated = p.negated();
            (Target::Marking(&negated), After::Nothing, true, Some(p))
        }
        Property::Bounded => return,
    };
    let stubborn = (reducible && opts.reduction)
        .then(|| Stubborn::new(net, pred.map(|p| p.support(net.num_places())).as_deref()));
    r.reduction = Some(if stubborn.is_some() {
        "stubborn"
    } else {
        "none"
    });
    let out = match crate::reach::search(net, &packing, &target, stubborn.as_ref(), after, ropts) {
        Ok(o) => o,
        Err(e) => {
            r.partial = true;
            r.partial_reason = Some(PartialReason::NotExplored);
            r.notes
                .push(format!("the state space was not explored: {e}"));
            return;
        }
    };
    r.graph = "reachability";
    r.states = out.states;
    r.edges = out.edges;
    r.bits_per_state = Some(out.bits_per_state);
    r.store_bytes = Some(out.peak_bytes);
    r.bytes_per_state = Some(out.peak_bytes as f64 / out.states.max(1) as f64);
    if stubborn.is_some() {
        r.notes.push(format!(
            "stubborn sets: {} of {} expanded states fired a reduced set of transitions",
            out.reduced_states, out.states
        ));
    }
    let shortest = stubborn.is_none();
    if let Some(w) = &out.found {
        // The target was reached: for deadlock, reach and safe it is the witness; for always,
        // live and reversible it is a counterexample.
        r.holds = Some(matches!(property, Property::Deadlock | Property::Reach(_)));
        r.witness = Some(names(net, w));
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
        return;
    }
    if let Some(s) = &out.stopped {
        partial(r, s);
        return;
    }
    match out.verdict {
        Some((holds, w)) => {
            r.holds = Some(holds);
            r.witness = w.map(|w| names(net, &w));
            r.witness_shortest = r.witness.as_ref().map(|_| true);
            if let Some(t) = out.culprit {
                r.non_live_transitions = vec![net.transitions()[t.index()].id.clone()];
                r.notes.push(format!(
                    "from the marking the witness reaches, {} can never fire again",
                    net.transitions()[t.index()].id
                ));
            }
            if *property == Property::Live {
                r.live = Some(holds);
            } else {
                r.reversible = Some(holds);
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
