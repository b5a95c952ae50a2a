//! `check`: every analysis of the crate, gathered into one [`Report`].

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use cetratus_net::{Net, PlaceIdx};

use crate::budget::{
    Clock, Deadline, PartialReason, DEFAULT_MAX_MEMORY, DEFAULT_MAX_STATES, DEFAULT_TIMEOUT,
};
use crate::coverability::{karp_miller, Coverability, OMEGA};
use crate::invariants::{
    p_semiflows_within, structural_bounds_within, t_semiflows_within, Semiflow, DEFAULT_MAX_ROWS,
};
use crate::reach::{explore, Packing, ReachOptions, ReachResult, SpareCoreFn, Stop};
use crate::report::{place_id, transition_ids, Bound, Named, Report};
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

impl CheckOptions {
    /// The options of an exploration within this run's budgets and threads, ending at
    /// `deadline`.
    pub(crate) fn reach_options(&self, deadline: Option<Deadline>) -> ReachOptions {
        ReachOptions {
            max_states: self.max_states,
            max_memory: self.max_memory,
            deadline,
            cancel: self.cancel.clone(),
            progress: self.progress.clone(),
            liveness: true,
            threads: self.threads,
            parallel_from: self.parallel_from,
            spare_core: self.spare_core.clone(),
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

/// The time on the options' clock (0 without a clock).
pub(crate) fn now(opts: &CheckOptions) -> Duration {
    opts.clock.as_ref().map_or(Duration::ZERO, |c| c.elapsed())
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

/// What the structural analyses found, and the milliseconds they took.
struct Structural {
    p: Result<Vec<Semiflow>, AnalysisError>,
    t: Result<Vec<Semiflow>, AnalysisError>,
    siphons: MinimalSets,
    traps: MinimalSets,
    invariants_ms: f64,
    siphons_ms: f64,
}

impl Structural {
    /// The invariants for the report: the semiflows by id, the constants `y·M0` and
    /// conservativeness; what could not be computed stays null, with a note saying why.
    fn report_invariants(&self, net: &Net, report: &mut Report) {
        report.p_invariants = named_flows(net, &self.p, true, &mut report.notes);
        report.t_invariants = named_flows(net, &self.t, false, &mut report.notes);
        let m0 = net.initial_marking();
        report.p_invariant_constants = self.p.as_ref().ok().and_then(|v| {
            v.iter()
                .map(|s| s.dot(m0.as_slice()))
                .collect::<Option<Vec<_>>>()
        });
        report.conservative = self.p.as_ref().ok().map(|v| {
            let mut covered = vec![false; net.num_places()];
            for s in v {
                for &(p, _) in &s.0 {
                    covered[p] = true;
                }
            }
            covered.iter().all(|&c| c)
        });
    }

    /// The siphons and traps for the report, with Commoner's warning about the siphons that
    /// hold no initially marked trap, and a note for each enumeration that hit its limit.
    fn report_siphons(&self, net: &Net, limits: &SetLimits, report: &mut Report) {
        let names = |s: &Vec<usize>| s.iter().map(|&p| place_id(net, p)).collect::<Vec<_>>();
        let unguarded: Vec<Vec<String>> = self
            .siphons
            .sets
            .iter()
            .filter(|s| !holds_marked_trap(net, s))
            .map(names)
            .collect();
        if let Some(first) = unguarded.first() {
            report.warnings.push(format!(
                "{} minimal siphon(s) hold no initially marked trap, e.g. {{{}}}: once such a \
                 siphon is emptied it stays empty and its output transitions are dead (Commoner: \
                 a free-choice net is live iff every siphon holds a marked trap); see \
                 `siphons_without_marked_trap`",
                unguarded.len(),
                first.join(", ")
            ));
        }
        if self.siphons.truncated {
            report.notes.push(format!(
                "siphon enumeration stopped at its limit ({} search nodes or {} sets)",
                limits.max_nodes, limits.max_sets
            ));
        }
        if self.traps.truncated {
            report
                .notes
                .push("trap enumeration stopped at its limit".into());
        }
        report.siphons = self.siphons.sets.iter().map(names).collect();
        report.siphons_truncated = self.siphons.truncated;
        report.siphons_without_marked_trap = unguarded;
        report.traps = self.traps.sets.iter().map(names).collect();
        report.traps_truncated = self.traps.truncated;
    }

    /// Whether a structural analysis (the structural bounds `sb` included) stopped before its
    /// end: interrupted, or an enumeration truncated.
    fn cut_short(&self, sb: &Result<Vec<Option<u64>>, AnalysisError>) -> bool {
        let cut = |r: Option<&AnalysisError>| matches!(r, Some(AnalysisError::Interrupted { .. }));
        cut(sb.as_ref().err())
            || cut(self.p.as_ref().err())
            || cut(self.t.as_ref().err())
            || self.siphons.truncated
            || self.traps.truncated
    }
}

/// What the behavioural phase found.
enum Behaviour {
    None(String),
    Reach(ReachResult),
    Cover(Coverability),
}

/// One run of [`check`]: the net, the options, the deadline, and the bounds proven before
/// exploring.
struct Run<'a> {
    net: &'a Net,
    opts: &'a CheckOptions,
    deadline: &'a Option<Deadline>,
    known: &'a [Option<u64>],
}

impl Run<'_> {
    /// The invariants, siphons and traps, within the run's budgets.
    fn structural(&self) -> Structural {
        let (net, opts) = (self.net, self.opts);
        let stop = || interrupted(opts, self.deadline).is_some();
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

    /// The state space: the reachability graph over states packed with proven widths, or the
    /// Karp–Miller graph when the net is unbounded (or its exploration stopped). Its notes go
    /// to `notes`.
    fn behaviour(&self, notes: &mut Vec<String>) -> Behaviour {
        let (net, known) = (self.net, self.known);
        let ropts = self.opts.reach_options(self.deadline.clone());
        let bounds: Vec<u64> = if known.iter().all(Option::is_some) {
            notes.push(
                "every place has a structural bound or a capacity, so the states are packed \
                 with those widths from the start"
                    .into(),
            );
            known.iter().map(|b| b.unwrap_or(0)).collect()
        } else {
            let km = karp_miller(net, &ropts);
            if !km.unbounded.is_empty() || km.stopped.is_some() {
                return Behaviour::Cover(km);
            }
            notes.push(
                "some place has no structural bound; a Karp–Miller graph found the net bounded, \
                 and its exact place bounds size the packed states"
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

    /// The structural analyses and the behavioural phase, side by side when there are threads
    /// to spare, with the milliseconds the behavioural phase took. Its notes go to `notes`.
    fn phases(&self, notes: &mut Vec<String>) -> (Structural, Behaviour, f64) {
        let opts = self.opts;
        let tb = now(opts);
        if opts.threads >= 2 && opts.behaviour {
            std::thread::scope(|s| {
                let h = s.spawn(|| self.structural());
                let mut n = Vec::new();
                let b = self.behaviour(&mut n);
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
            let st = self.structural();
            let tb = now(opts);
            let b = if opts.behaviour {
                self.behaviour(notes)
            } else {
                Behaviour::None("behaviour not requested".into())
            };
            (st, b, ms(opts, tb))
        }
    }
}

/// Semiflows by id (`places`: P-semiflows, else T-semiflows), or `None` with a note when they
/// could not be computed.
fn named_flows(
    net: &Net,
    flows: &Result<Vec<Semiflow>, AnalysisError>,
    places: bool,
    notes: &mut Vec<String>,
) -> Option<Vec<Named<i64>>> {
    match flows {
        Ok(v) => Some(v.iter().map(|s| named_flow(net, s, places)).collect()),
        Err(e) => {
            let what = if places {
                "P-invariants"
            } else {
                "T-invariants"
            };
            notes.push(format!("{what}: {e}"));
            None
        }
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

/// Per place, the bounds proven before anything is explored.
pub(crate) struct ProvenBounds {
    /// The structural bounds (`y·C ≤ 0`), or why they are not known.
    pub(crate) structural: Result<Vec<Option<u64>>, AnalysisError>,
    /// Per place, the structural bound or the capacity (see [`known_bounds`]).
    pub(crate) known: Vec<Option<u64>>,
}

impl ProvenBounds {
    /// The bounds proven within the run's budgets; when the structural bounds could not be
    /// computed, `notes` says why.
    pub(crate) fn prove(
        net: &Net,
        opts: &CheckOptions,
        deadline: &Option<Deadline>,
        notes: &mut Vec<String>,
    ) -> ProvenBounds {
        let stop = || interrupted(opts, deadline).is_some();
        let structural =
            structural_bounds_within(net, opts.farkas_max_rows, tableau_bytes(opts), &stop);
        let known = known_bounds(net, &structural, notes);
        ProvenBounds { structural, known }
    }

    /// Every place has a structural bound (`None`: they could not be computed).
    pub(crate) fn structurally_bounded(&self) -> Option<bool> {
        self.structural
            .as_ref()
            .ok()
            .map(|b| b.iter().all(Option::is_some))
    }
}

/// Per place, a proven bound: the structural bound (from `sb`) or the capacity, the smaller of
/// the two when both exist.
fn known_bounds(
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
    let mut report = Report::empty(net);
    let np = net.num_places();
    report.incidence = (np * net.num_transitions() <= 10_000).then(|| Incidence::of(net));
    let deadline = deadline(opts);
    let bounds = ProvenBounds::prove(net, opts, &deadline, &mut report.notes);
    report.structurally_bounded = bounds.structurally_bounded();
    report.bounded = report.structurally_bounded.filter(|&b| b);
    report.max_tokens = Named(
        (0..np)
            .map(|p| {
                let b = bounds.known[p].map_or(Bound::Unknown, Bound::Tokens);
                (place_id(net, p), b)
            })
            .collect(),
    );
    report.timings.structure_ms = ms(opts, t0);

    let run = Run {
        net,
        opts,
        deadline: &deadline,
        known: &bounds.known,
    };
    let (st, beh, behaviour_ms) = run.phases(&mut report.notes);
    report.timings.invariants_ms = st.invariants_ms;
    report.timings.siphons_ms = st.siphons_ms;
    report.timings.behaviour_ms = behaviour_ms;
    st.report_invariants(net, &mut report);
    st.report_siphons(net, &opts.set_limits, &mut report);
    if report.classification.inhibitor_arcs {
        report.notes.push(
            "inhibitor arcs are honoured in the state space but ignored by invariants, siphons, \
             traps and net classes"
                .into(),
        );
    }
    match beh {
        Behaviour::None(why) => {
            if opts.behaviour {
                report.stopped_early(
                    PartialReason::NotExplored,
                    format!("the state space was not explored: {why}"),
                );
            }
        }
        Behaviour::Reach(r) => report_reachability(&mut report, net, &r),
        Behaviour::Cover(km) => report_coverability(&mut report, net, &km),
    }
    // The structural phase honours the same time budget and Ctrl-C as the exploration.
    if !report.partial && st.cut_short(&bounds.structural) {
        if let Some(why) = interrupted(opts, &deadline) {
            report.stopped_early(
                why,
                format!(
                "the structural analyses were cut short ({why}); what they could not finish is                  null or truncated"
                ),
            );
        }
    }
    report
}

/// Why a run stopped early and which budget to raise, for the notes; `memory` names what would
/// have outgrown `--max-memory`.
pub(crate) fn why_stopped(s: &Stop, memory: &str) -> String {
    match s {
        Stop::MaxStates(n) => format!("stopped after {n} states (raise --max-states)"),
        Stop::MaxMemory(b) => {
            format!("stopped before {memory} more than {b} bytes (raise --max-memory)")
        }
        Stop::Timeout => "stopped when the time budget ran out (raise --timeout)".into(),
        Stop::Cancelled => "cancelled (Ctrl-C)".into(),
    }
}

/// The note of an exploration stopped early: what stopped it, and what it leaves undecided.
fn stop_note(s: &Stop) -> String {
    format!(
        "{}; counts are lower bounds and liveness, reversibility and exact bounds are not \
         decided",
        why_stopped(s, "the state space would hold")
    )
}

/// The reachability graph's figures for the report, and its verdicts when it is complete.
fn report_reachability(report: &mut Report, net: &Net, r: &ReachResult) {
    report.graph = "reachability";
    report.states = r.states;
    report.edges = r.edges;
    report.deadlocks = r.deadlocks;
    report.deadlock_witness = r
        .deadlock_witness
        .as_deref()
        .map(|w| transition_ids(net, w));
    report.bits_per_state = Some(r.bits_per_state);
    report.bytes_per_state = Some(r.peak_bytes as f64 / r.states.max(1) as f64);
    report.store_bytes = Some(r.peak_bytes);
    report.max_tokens = Named(
        (0..net.num_places())
            .map(|p| (place_id(net, p), Bound::Tokens(u64::from(r.max_tokens[p]))))
            .collect(),
    );
    report.dead_transitions = transition_ids(net, &r.never_enabled);
    // Packing widths come from proven bounds, so even a partial run knows boundedness.
    report.bounded = Some(true);
    match &r.stopped {
        Some(s) => report.stopped_early(s.reason(), stop_note(s)),
        None => report_verdicts(report, net, r),
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

/// Safety, liveness and reversibility, which only a complete exploration decides.
fn report_verdicts(report: &mut Report, net: &Net, r: &ReachResult) {
    report.safe = Some(r.max_tokens.iter().all(|&m| m <= 1));
    if let Some(s) = &r.liveness_stopped {
        let how = match s {
            Stop::MaxMemory(b) => {
                format!("would have held more than {b} bytes (raise --max-memory)")
            }
            Stop::Timeout => "ran out of time (raise --timeout)".into(),
            _ => "was stopped".into(),
        };
        report.stopped_early(
            s.reason(),
            format!("every state was explored, but the liveness pass {how}"),
        );
    }
    if let Some(l) = &r.liveness {
        report.live = Some(l.live);
        report.non_live_transitions = transition_ids(net, &l.non_live);
        report.reversible = Some(l.reversible);
    }
}

/// The Karp–Miller graph's figures for the report, and the unbounded places it found.
fn report_coverability(report: &mut Report, net: &Net, km: &Coverability) {
    report.graph = "coverability";
    report.states = km.nodes;
    report.edges = km.edges;
    report.deadlocks = km.dead;
    report.deadlock_witness = km.dead_witness.as_deref().map(|w| transition_ids(net, w));
    report.unbounded_places = km
        .unbounded
        .iter()
        .map(|p| place_id(net, p.index()))
        .collect();
    report.max_tokens = Named(
        (0..net.num_places())
            .map(|p| {
                let m = km.max_tokens[p];
                let b = if m == OMEGA {
                    Bound::Omega
                } else {
                    Bound::Tokens(m)
                };
                (place_id(net, p), b)
            })
            .collect(),
    );
    if !km.unbounded.is_empty() {
        report.bounded = Some(false);
        report.safe = Some(false);
        report.warnings.push(format!(
            "the net is unbounded: {} can grow without limit; the figures are those of the \
             Karp–Miller coverability graph, and liveness and reversibility are not decided",
            report.unbounded_places.join(", ")
        ));
        if classification_has_extras(report) {
            report.notes.push(
                "with inhibitor arcs or capacities the coverability graph is an approximation"
                    .into(),
            );
        }
    }
    if let Some(s) = &km.stopped {
        report.stopped_early(s.reason(), stop_note(s));
    }
}

fn classification_has_extras(r: &Report) -> bool {
    r.classification.inhibitor_arcs || r.classification.capacities
}
