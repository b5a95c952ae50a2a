//! `check`: every analysis of the crate, gathered into one [`Report`].

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use cetratus_net::{Net, PlaceIdx, TransIdx};

use crate::budget::{
    Clock, Deadline, PartialReason, DEFAULT_MAX_MEMORY, DEFAULT_MAX_STATES, DEFAULT_TIMEOUT,
};
use crate::classify::classify;
use crate::coverability::{karp_miller, OMEGA};
use crate::invariants::{
    p_semiflows_within, structural_bounds_within, t_semiflows_within, Semiflow, DEFAULT_MAX_ROWS,
};
use crate::reach::{explore, Packing, ReachOptions, ReachResult, SpareCoreFn, Stop};
use crate::report::{Bound, Named, Report, Timings};
use crate::siphons::{
    holds_marked_trap, minimal_siphons_until, minimal_traps_until, MinimalSets, SetLimits,
};
use crate::{AnalysisError, Incidence};

/// How far an exploration has got.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// States discovered.
    pub states: u64,
    /// Edges counted.
    pub edges: u64,
    /// States expanded (the BFS cursor).
    pub expanded: u64,
    /// Bytes the state space holds, as counted for `max_memory`.
    pub bytes: u64,
}

/// A progress callback, called from the exploring thread every few thousand states.
pub type ProgressFn = Arc<dyn Fn(Progress) + Send + Sync>;

/// The states a default run explores on one thread before it goes on with two
/// ([`CheckOptions::parallel_from`]), if a core stayed idle meanwhile
/// ([`CheckOptions::spare_core`]): measured on an idle 2-core machine, two threads gained
/// nothing at 50,000–60,000 states (Kanban 3, FMS 3) and were faster from 450,000 up (Kanban 4,
/// FMS 4: 1.4×); docs/analysis.md, "The default thread count".
pub const PARALLEL_FROM: u64 = 200_000;

/// Options of [`check`].
#[derive(Clone)]
pub struct CheckOptions {
    /// Stop exploring after this many states; the report is then partial (`max_states`).
    pub max_states: Option<u64>,
    /// Stop before the state space would hold more than this many bytes (`max_memory`).
    pub max_memory: Option<u64>,
    /// Stop when this much time has passed on `clock` (`timeout`); needs a clock.
    pub timeout: Option<Duration>,
    /// The clock of the time budget and of the report's timings. The analysis reads no clock
    /// of its own: without one, there is no time budget and every timing is 0.
    pub clock: Option<Arc<dyn Clock>>,
    /// Threads to use. With 2 or more, the invariants, siphons and traps are computed beside the
    /// state-space exploration, and the exploration itself runs on this many threads (same
    /// states, ids, counts and witness as on one thread).
    pub threads: usize,
    /// With 2 or more `threads`: the states the exploration finds on one thread before it goes
    /// on with `threads` (0: with `threads` from the start). See [`PARALLEL_FROM`].
    pub parallel_from: u64,
    /// Asked at `parallel_from` states whether to go on with `threads` (see
    /// [`ReachOptions::spare_core`]).
    pub spare_core: Option<SpareCoreFn>,
    /// Set to true (e.g. by Ctrl-C) to stop with a partial report.
    pub cancel: Option<Arc<AtomicBool>>,
    /// Called while the state space grows.
    pub progress: Option<ProgressFn>,
    /// Row limit of the Farkas tableau.
    pub farkas_max_rows: usize,
    /// Limits of the siphon and trap enumeration.
    pub set_limits: SetLimits,
    /// Explore the state space (false: structure only).
    pub behaviour: bool,
    /// Property mode: use stubborn sets for `deadlock`, `reach` and `always`.
    pub reduction: bool,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            max_states: Some(DEFAULT_MAX_STATES),
            max_memory: Some(DEFAULT_MAX_MEMORY),
            timeout: Some(DEFAULT_TIMEOUT),
            clock: None,
            threads: 1,
            parallel_from: 0,
            spare_core: None,
            cancel: None,
            progress: None,
            farkas_max_rows: DEFAULT_MAX_ROWS,
            set_limits: SetLimits::default(),
            behaviour: true,
            reduction: true,
        }
    }
}

/// Milliseconds on the options' clock since `since` (0 without a clock).
pub(crate) fn ms(opts: &CheckOptions, since: Duration) -> f64 {
    now(opts).saturating_sub(since).as_secs_f64() * 1e3
}

/// The Farkas tableaux share the memory budget with the state space.
pub(crate) fn tableau_bytes(opts: &CheckOptions) -> usize {
    opts.max_memory
        .map_or(usize::MAX, |m| usize::try_from(m).unwrap_or(usize::MAX))
}

pub(crate) fn now(opts: &CheckOptions) -> Duration {
    opts.clock.as_ref().map_or(Duration::ZERO, |c| c.elapsed())
}

struct Structural {
    p: Result<Vec<Semiflow>, AnalysisError>,
    t: Result<Vec<Semiflow>, AnalysisError>,
    siphons: MinimalSets,
    traps: MinimalSets,
    invariants_ms: f64,
    siphons_ms: f64,
}

/// The deadline of the whole run: `timeout` after now on the options' clock.
pub(crate) fn deadline(opts: &CheckOptions) -> Option<Deadline> {
    match (&opts.clock, opts.timeout) {
        (Some(c), Some(t)) => Some(Deadline::after(c.clone(), t)),
        _ => None,
    }
}

/// Why the run must stop now, if it must: Ctrl-C or the time budget.
pub(crate) fn interrupted(
    opts: &CheckOptions,
    deadline: &Option<Deadline>,
) -> Option<PartialReason> {
    if opts
        .cancel
        .as_ref()
        .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed))
    {
        return Some(PartialReason::Cancelled);
    }
    deadline
        .as_ref()
        .is_some_and(Deadline::passed)
        .then_some(PartialReason::Timeout)
}

fn structural(net: &Net, opts: &CheckOptions, deadline: &Option<Deadline>) -> Structural {
    let stop = || interrupted(opts, deadline).is_some();
    let t0 = now(opts);
    let p = p_semiflows_within(net, opts.farkas_max_rows, tableau_bytes(opts), &stop);
    let t = t_semiflows_within(net, opts.farkas_max_rows, tableau_bytes(opts), &stop);
    let invariants_ms = ms(opts, t0);
    let t1 = now(opts);
    let siphons = minimal_siphons_until(net, opts.set_limits, &stop);
    let traps = minimal_traps_until(net, opts.set_limits, &stop);
    Structural {
        p,
        t,
        siphons,
        traps,
        invariants_ms,
        siphons_ms: ms(opts, t1),
    }
}

/// What the behavioural phase found.
enum Behaviour {
    None(String),
    Reach(ReachResult),
    Cover(crate::coverability::Coverability),
}

fn behaviour(
    net: &Net,
    known: &[Option<u64>],
    opts: &CheckOptions,
    deadline: &Option<Deadline>,
    notes: &mut Vec<String>,
) -> Behaviour {
    let deadline = deadline.clone();
    let ropts = ReachOptions {
        max_states: opts.max_states,
        max_memory: opts.max_memory,
        deadline,
        cancel: opts.cancel.clone(),
        progress: opts.progress.clone(),
        liveness: true,
        threads: opts.threads,
        parallel_from: opts.parallel_from,
        spare_core: opts.spare_core.clone(),
    };
    let bounds: Vec<u64> = if known.iter().all(Option::is_some) {
        notes.push(
            "every place has a structural bound or a capacity, so the states are packed with \
             those widths from the start"
                .into(),
        );
        known.iter().map(|b| b.unwrap_or(0)).collect()
    } else {
        let km = karp_miller(net, &ropts);
        if !km.unbounded.is_empty() || km.stopped.is_some() {
            return Behaviour::Cover(km);
        }
        notes.push(
            "some place has no structural bound; a Karp–Miller graph found the net bounded, and \
             its exact place bounds size the packed states"
                .into(),
        );
        km.max_tokens
    };
    let packing = Packing::new(&bounds);
    match explore(net, &packing, &ropts) {
        Ok(r) => Behaviour::Reach(r),
        Err(e) => Behaviour::None(e.to_string()),
    }
}

fn named_flow(net: &Net, s: &Semiflow, places: bool) -> Named<i64> {
    Named(
        s.0.iter()
            .map(|&(i, w)| {
                let id = if places {
                    net.places()[i].id.clone()
                } else {
                    net.transitions()[i].id.clone()
                };
                (id, w)
            })
            .collect(),
    )
}

/// Per place, a proven bound: the structural bound (from `sb`) or the capacity, the smaller of
/// the two when both exist.
pub(crate) fn known_bounds(
    net: &Net,
    sb: &Result<Vec<Option<u64>>, AnalysisError>,
    notes: &mut Vec<String>,
) -> Vec<Option<u64>> {
    match sb {
        Ok(b) => b
            .iter()
            .enumerate()
            .map(|(p, s)| {
                let cap = net.capacity(PlaceIdx(p as u32)).map(u64::from);
                match (s, cap) {
                    (Some(a), Some(c)) => Some((*a).min(c)),
                    (a, c) => a.or(c),
                }
            })
            .collect(),
        Err(e) => {
            notes.push(format!("structural boundedness not decided: {e}"));
            net.places()
                .iter()
                .map(|p| p.capacity.map(u64::from))
                .collect()
        }
    }
}

/// Runs every analysis on `net` and reports. Never fails: what could not be computed is `null` in
/// the report and explained in its notes.
pub fn check(net: &Net, opts: &CheckOptions) -> Report {
    let t0 = now(opts);
    let np = net.num_places();
    let nt = net.num_transitions();
    let pid = |p: usize| net.places()[p].id.clone();
    let tid = |t: TransIdx| net.transitions()[t.index()].id.clone();
    let mut notes: Vec<String> = Vec::new();
    let mut warnings: Vec<String> = Vec::new();
    let classification = classify(net);
    let incidence = (np * nt <= 10_000).then(|| Incidence::of(net));
    let deadline = deadline(opts);
    let stop = || interrupted(opts, &deadline).is_some();
    let sb = structural_bounds_within(net, opts.farkas_max_rows, tableau_bytes(opts), &stop);
    let known = known_bounds(net, &sb, &mut notes);
    let structurally_bounded = sb.as_ref().ok().map(|b| b.iter().all(Option::is_some));
    let structure_ms = ms(opts, t0);

    let tb = now(opts);
    let (st, beh, behaviour_ms) = if opts.threads >= 2 && opts.behaviour {
        std::thread::scope(|s| {
            let h = s.spawn(|| structural(net, opts, &deadline));
            let mut n = Vec::new();
            let b = behaviour(net, &known, opts, &deadline, &mut n);
            let bms = ms(opts, tb);
            // A panic in the structural thread is a bug; surface it rather than hide it.
            let st = match h.join() {
                Ok(st) => st,
                Err(p) => std::panic::resume_unwind(p),
            };
            notes.extend(n);
            (st, b, bms)
        })
    } else {
        let st = structural(net, opts, &deadline);
        let tb = now(opts);
        let b = if opts.behaviour {
            behaviour(net, &known, opts, &deadline, &mut notes)
        } else {
            Behaviour::None("behaviour not requested".into())
        };
        (st, b, ms(opts, tb))
    };

    let p_invariants = match &st.p {
        Ok(v) => Some(
            v.iter()
                .map(|s| named_flow(net, s, true))
                .collect::<Vec<_>>(),
        ),
        Err(e) => {
            notes.push(format!("P-invariants: {e}"));
            None
        }
    };
    let m0 = net.initial_marking();
    let p_invariant_constants = st.p.as_ref().ok().and_then(|v| {
        v.iter()
            .map(|s| s.dot(m0.as_slice()))
            .collect::<Option<Vec<_>>>()
    });
    let t_invariants = match &st.t {
        Ok(v) => Some(
            v.iter()
                .map(|s| named_flow(net, s, false))
                .collect::<Vec<_>>(),
        ),
        Err(e) => {
            notes.push(format!("T-invariants: {e}"));
            None
        }
    };
    let conservative = st.p.as_ref().ok().map(|v| {
        let mut covered = vec![false; np];
        for s in v {
            for &(p, _) in &s.0 {
                covered[p] = true;
            }
        }
        covered.iter().all(|&c| c)
    });
    let set_names = |m: &MinimalSets| -> Vec<Vec<String>> {
        m.sets
            .iter()
            .map(|s| s.iter().map(|&p| pid(p)).collect())
            .collect()
    };
    let unguarded: Vec<Vec<String>> = st
        .siphons
        .sets
        .iter()
        .filter(|s| !holds_marked_trap(net, s))
        .map(|s| s.iter().map(|&p| pid(p)).collect())
        .collect();
    if let Some(first) = unguarded.first() {
        warnings.push(format!(
            "{} minimal siphon(s) hold no initially marked trap, e.g. {{{}}}: once such a siphon \
             is emptied it stays empty and its output transitions are dead (Commoner: a \
             free-choice net is live iff every siphon holds a marked trap); see \
             `siphons_without_marked_trap`",
            unguarded.len(),
            first.join(", ")
        ));
    }
    if st.siphons.truncated {
        notes.push(format!(
            "siphon enumeration stopped at its limit ({} search nodes or {} sets)",
            opts.set_limits.max_nodes, opts.set_limits.max_sets
        ));
    }
    if st.traps.truncated {
        notes.push("trap enumeration stopped at its limit".into());
    }
    if classification.inhibitor_arcs {
        notes.push(
            "inhibitor arcs are honoured in the state space but ignored by invariants, siphons, \
             traps and net classes"
                .into(),
        );
    }

    let mut report = Report {
        net: net.id().to_string(),
        places: np,
        transitions: nt,
        arcs: net.arcs().len(),
        graph: "none",
        states: 0,
        edges: 0,
        deadlocks: 0,
        deadlock_witness: None,
        bounded: structurally_bounded.filter(|&b| b),
        safe: None,
        unbounded_places: Vec::new(),
        max_tokens: Named(
            (0..np)
                .map(|p| (pid(p), known[p].map_or(Bound::Unknown, Bound::Tokens)))
                .collect(),
        ),
        live: None,
        non_live_transitions: Vec::new(),
        dead_transitions: Vec::new(),
        reversible: None,
        p_invariants,
        p_invariant_constants,
        t_invariants,
        conservative,
        structurally_bounded,
        classification,
        siphons: set_names(&st.siphons),
        siphons_truncated: st.siphons.truncated,
        siphons_without_marked_trap: unguarded,
        traps: set_names(&st.traps),
        traps_truncated: st.traps.truncated,
        warnings,
        notes,
        partial: false,
        partial_reason: None,
        bits_per_state: None,
        bytes_per_state: None,
        store_bytes: None,
        incidence,
        property: None,
        holds: None,
        witness: None,
        witness_shortest: None,
        reduction: None,
        timings: Timings {
            structure_ms,
            invariants_ms: st.invariants_ms,
            siphons_ms: st.siphons_ms,
            behaviour_ms,
        },
        sfc: None,
    };
    let stop_note = |s: &Stop| {
        let what = match s {
            Stop::MaxStates(n) => format!("stopped after {n} states (raise --max-states)"),
            Stop::MaxMemory(b) => format!(
                "stopped before the state space would hold more than {b} bytes (raise \
                 --max-memory)"
            ),
            Stop::Timeout => "stopped when the time budget ran out (raise --timeout)".into(),
            Stop::Cancelled => "cancelled (Ctrl-C)".into(),
        };
        format!(
            "{what}; counts are lower bounds and liveness, reversibility and exact bounds are \
             not decided"
        )
    };
    match beh {
        Behaviour::None(why) => {
            if opts.behaviour {
                report.partial = true;
                report.partial_reason = Some(PartialReason::NotExplored);
                report
                    .notes
                    .push(format!("the state space was not explored: {why}"));
            }
        }
        Behaviour::Reach(r) => {
            report.graph = "reachability";
            report.states = r.states;
            report.edges = r.edges;
            report.deadlocks = r.deadlocks;
            report.deadlock_witness = r
                .deadlock_witness
                .as_ref()
                .map(|w| w.iter().map(|&t| tid(t)).collect());
            report.bits_per_state = Some(r.bits_per_state);
            report.bytes_per_state = Some(r.peak_bytes as f64 / r.states.max(1) as f64);
            report.store_bytes = Some(r.peak_bytes);
            report.max_tokens = Named(
                (0..np)
                    .map(|p| (pid(p), Bound::Tokens(u64::from(r.max_tokens[p]))))
                    .collect(),
            );
            report.dead_transitions = r.never_enabled.iter().map(|&t| tid(t)).collect();
            // Packing widths come from proven bounds, so even a partial run knows boundedness.
            report.bounded = Some(true);
            match &r.stopped {
                Some(s) => {
                    report.partial = true;
                    report.partial_reason = Some(s.reason());
                    report.notes.push(stop_note(s));
                }
                None => {
                    report.safe = Some(r.max_tokens.iter().all(|&m| m <= 1));
                    if let Some(s) = &r.liveness_stopped {
                        report.partial = true;
                        report.partial_reason = Some(s.reason());
                        report.notes.push(format!(
                            "every state was explored, but the liveness pass {}",
                            match s {
                                Stop::MaxMemory(b) => format!(
                                    "would have held more than {b} bytes (raise --max-memory)"
                                ),
                                Stop::Timeout => "ran out of time (raise --timeout)".into(),
                                _ => "was stopped".into(),
                            }
                        ));
                    }
                    if let Some(l) = &r.liveness {
                        report.live = Some(l.live);
                        report.non_live_transitions = l.non_live.iter().map(|&t| tid(t)).collect();
                        report.reversible = Some(l.reversible);
                    }
                }
            }
            if r.deadlocks > 0 {
                report.warnings.push(format!(
                    "{} dead state(s): no transition is enabled there{}",
                    r.deadlocks,
                    report
                        .deadlock_witness
                        .as_ref()
                        .map(|w| format!("; shortest firing sequence to one: {}", w.join(" ")))
                        .unwrap_or_default()
                ));
            }
        }
        Behaviour::Cover(km) => {
            report.graph = "coverability";
            report.states = km.nodes;
            report.edges = km.edges;
            report.deadlocks = km.dead;
            report.deadlock_witness = km
                .dead_witness
                .as_ref()
                .map(|w| w.iter().map(|&t| tid(t)).collect());
            report.unbounded_places = km.unbounded.iter().map(|p| pid(p.index())).collect();
            report.max_tokens = Named(
                (0..np)
                    .map(|p| {
                        let m = km.max_tokens[p];
                        (
                            pid(p),
                            if m == OMEGA {
                                Bound::Omega
                            } else {
                                Bound::Tokens(m)
                            },
                        )
                    })
                    .collect(),
            );
            if !km.unbounded.is_empty() {
                report.bounded = Some(false);
                report.safe = Some(false);
                report.warnings.push(format!(
                    "the net is unbounded: {} can grow without limit; the figures are those of \
                     the Karp–Miller coverability graph, and liveness and reversibility are not \
                     decided",
                    report.unbounded_places.join(", ")
                ));
                if classification_has_extras(&report) {
                    report.notes.push(
                        "with inhibitor arcs or capacities the coverability graph is an \
                         approximation"
                            .into(),
                    );
                }
            }
            if let Some(s) = &km.stopped {
                report.partial = true;
                report.partial_reason = Some(s.reason());
                report.notes.push(stop_note(s));
            }
        }
    }
    // The structural phase honours the same time budget and Ctrl-C as the exploration.
    let cut = |r: Option<&AnalysisError>| matches!(r, Some(AnalysisError::Interrupted { .. }));
    if !report.partial
        && (cut(sb.as_ref().err())
            || cut(st.p.as_ref().err())
            || cut(st.t.as_ref().err())
            || st.siphons.truncated
            || st.traps.truncated)
    {
        if let Some(why) = interrupted(opts, &deadline) {
            report.partial = true;
            report.partial_reason = Some(why);
            report.notes.push(format!(
                "the structural analyses were cut short ({why}); what they could not finish is                  null or truncated"
            ));
        }
    }
    report
}

fn classification_has_extras(r: &Report) -> bool {
    r.classification.inhibitor_arcs || r.classification.capacities
}
