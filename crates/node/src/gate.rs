//! The analysis gate at load (docs/live-update.md, *Analysis gate*): before a prepared update is
//! handed to the scan thread, the preparer explores the candidate's reachability graph from the
//! transformed marking (the package's state transformation applied to the primary's marking at
//! the cycle boundary the load is handled at, which is what an install there gives the
//! candidate), and the primary's from that marking, within a state and time budget, and reports:
//!
//! * deadlocks the candidate can reach, with a shortest witness;
//! * transitions (matched by id) that can fire in the primary's graph but in none of the
//!   candidate's;
//! * invariants the new net violates: the candidate's own declared invariants that a transition
//!   of its net changes, and the primary's declared invariants that still name places of the new
//!   net and that a transition of it changes.
//!
//! The exploration ignores guards and time, so it over-approximates what the program can do:
//! each kind of finding is a warning unless `[updates]` makes it refuse. Runs on the preparer
//! threads, never on the scan thread.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use cetratus_analysis::{check, CheckOptions, Report};
use cetratus_net::{Marking, Net};
use cetratus_program::Program;
use cetratus_runtime::{PreparedUpdate, UpdateContext, Verdict, VerdictKind, VerdictResult};

/// What a kind of finding does to the load.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Severity {
    /// The load goes on; the finding is in the verdict.
    #[default]
    Warn,
    /// The load is refused.
    Refuse,
}

impl std::str::FromStr for Severity {
    type Err = cetratus_vocab::UnknownName;
    fn from_str(s: &str) -> Result<Self, cetratus_vocab::UnknownName> {
        match s {
            "warn" => Ok(Severity::Warn),
            "refuse" => Ok(Severity::Refuse),
            o => Err(cetratus_vocab::UnknownName {
                what: "gate policy",
                value: o.chars().take(64).collect(),
                expected: "\"warn\" or \"refuse\"",
            }),
        }
    }
}

/// The gate's budget and what each kind of finding does (`[updates]` of the local configuration).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GatePolicy {
    /// States explored per net, at most.
    pub max_states: u64,
    /// Time for both explorations together.
    pub time: Duration,
    /// A reachable deadlock of the candidate.
    pub deadlock: Severity,
    /// A transition the primary can fire and the candidate cannot.
    pub lost_transitions: Severity,
    /// An invariant the new net breaks.
    pub broken_invariants: Severity,
}

impl Default for GatePolicy {
    fn default() -> Self {
        GatePolicy {
            max_states: 200_000,
            time: Duration::from_secs(2),
            deadlock: Severity::Warn,
            lost_transitions: Severity::Warn,
            broken_invariants: Severity::Warn,
        }
    }
}

/// What the gate said of a package: its verdict, and the refusal when the policy refuses.
#[derive(Clone, Debug)]
pub struct GateOutcome {
    /// Kind `analysis`: pass, warn or fail, with the findings as reasons.
    pub verdict: Verdict,
    /// Why the load is refused, when a finding's policy is `refuse`.
    pub refusal: Option<String>,
}

/// Explores `net` from `marking` within the budget that is left before `deadline`.
fn explore(net: &Net, marking: &[u32], policy: &GatePolicy, deadline: Instant) -> Report {
    let net = net
        .with_initial_marking(&Marking::from(marking.to_vec()))
        .unwrap_or_else(|_| net.clone());
    let cancel = Arc::new(AtomicBool::new(Instant::now() >= deadline));
    let flag = cancel.clone();
    let opts = CheckOptions {
        max_states: Some(policy.max_states),
        threads: 1,
        cancel: Some(cancel),
        progress: Some(Arc::new(move |_| {
            if Instant::now() >= deadline {
                flag.store(true, Ordering::Relaxed);
            }
        })),
        ..CheckOptions::default()
    };
    check(&net, &opts)
}

/// The invariants the candidate's net changes: its own, and the running program's carried over
/// to the new net.
fn broken_invariants(primary: &Program, candidate: &Program) -> Vec<String> {
    let cn = candidate.net();
    let mut broken = Vec::new();
    for inv in candidate.invariants() {
        if let Some((t, _)) = inv.first_breaking_transition(cn) {
            broken.push(format!(
                "the candidate's invariant `{}` is changed by {}",
                inv.expr(),
                cn.transition(t).id
            ));
        }
    }
    for inv in primary.invariants() {
        let Some(on_new) = inv.on_net(cn) else {
            continue;
        };
        if let Some((t, _)) = on_new.first_breaking_transition(cn) {
            broken.push(format!(
                "the running program's invariant `{}` is changed by {} in the new net",
                inv.expr(),
                cn.transition(t).id
            ));
        }
    }
    broken
}

/// Runs the gate on `update`, prepared against the primary of `ctx`.
pub fn run(ctx: &UpdateContext, update: &PreparedUpdate, policy: &GatePolicy) -> GateOutcome {
    let t0 = Instant::now();
    let deadline = t0 + policy.time;
    let primary: &Program = &ctx.primary;
    let candidate: &Program = update.program();
    let (pn, cn) = (primary.net(), candidate.net());
    let mut notes = Vec::new();
    let mut from = if ctx.primary_marking.len() == pn.num_places() {
        ctx.primary_marking.clone()
    } else {
        notes.push("the primary's marking was not known; the primary's M0 was used".to_string());
        pn.initial_marking().as_slice().to_vec()
    };
    let mut transformed = vec![0; cn.num_places()];
    if let Err(e) = update.transform().apply(&from, candidate, &mut transformed) {
        notes.push(format!(
            "the transform does not apply to the primary's marking of now ({e}); the candidate was explored from its M0"
        ));
        transformed = cn.initial_marking().as_slice().to_vec();
        from = pn.initial_marking().as_slice().to_vec();
    }
    let cand = explore(cn, &transformed, policy, deadline);
    let prim = explore(pn, &from, policy, deadline);

    let mut findings: Vec<(Severity, String)> = Vec::new();
    if cand.deadlocks > 0 {
        let witness = cand
            .deadlock_witness
            .as_ref()
            .map_or("none found".to_string(), |w| {
                if w.is_empty() {
                    "the transformed marking itself".to_string()
                } else {
                    w.join(" ")
                }
            });
        findings.push((
            policy.deadlock,
            format!(
                "deadlock: the candidate reaches {} dead marking(s); a shortest firing sequence to one: {witness}",
                cand.deadlocks
            ),
        ));
    }
    let lost: Vec<&str> = pn
        .transitions()
        .iter()
        .filter(|t| !prim.dead_transitions.contains(&t.id))
        .filter(|t| cn.transition_by_id(&t.id).is_none() || cand.dead_transitions.contains(&t.id))
        .map(|t| t.id.as_str())
        .collect();
    if !lost.is_empty() {
        findings.push((
            policy.lost_transitions,
            format!(
                "lost transitions: {} can fire in the primary's reachable graph but in none of the candidate's",
                lost.join(", ")
            ),
        ));
    }
    let broken = broken_invariants(primary, candidate);
    if !broken.is_empty() {
        findings.push((
            policy.broken_invariants,
            format!("broken invariants: {}", broken.join("; ")),
        ));
    }
    for (r, which) in [(&cand, "candidate's"), (&prim, "primary's")] {
        if r.partial {
            notes.push(format!(
                "the {which} exploration stopped early ({}) after {} states; the findings cover what was explored",
                r.partial_reason
                    .map_or_else(|| "budget".to_string(), |p| p.to_string()),
                r.states
            ));
        }
    }

    let refusing: Vec<&str> = findings
        .iter()
        .filter(|(s, _)| *s == Severity::Refuse)
        .map(|(_, r)| r.as_str())
        .collect();
    let result = if !refusing.is_empty() {
        VerdictResult::Fail
    } else if findings.is_empty() {
        VerdictResult::Pass
    } else {
        VerdictResult::Warn
    };
    let refusal = (!refusing.is_empty()).then(|| {
        format!(
            "package refused by the analysis gate: {}; fix the program, or set the finding's policy to \"warn\" in [updates] of the local configuration",
            refusing.join("; ")
        )
    });
    let mut figures = std::collections::BTreeMap::new();
    figures.insert("states_candidate".to_string(), cand.states as f64);
    figures.insert("states_primary".to_string(), prim.states as f64);
    figures.insert("deadlocks".to_string(), cand.deadlocks as f64);
    figures.insert("lost_transitions".to_string(), lost.len() as f64);
    figures.insert("broken_invariants".to_string(), broken.len() as f64);
    figures.insert("from_cycle".to_string(), ctx.cycle as f64);
    figures.insert("gate_ms".to_string(), t0.elapsed().as_secs_f64() * 1e3);
    let mut reasons: Vec<String> = findings.into_iter().map(|(_, r)| r).collect();
    reasons.extend(notes);
    GateOutcome {
        verdict: Verdict {
            kind: VerdictKind::Analysis,
            result,
            reasons,
            figures,
            signature: None,
        },
        refusal,
    }
}
