//! The gates one PLC passes, each a function of its step: what the PLC's state says moves it
//! on, fails the rollout, or calls for the next command. A gate that may not move forward (the
//! rollout is paused) still sees failures.

use std::time::Instant;

use cetratus_proto::{Ending, Role, Status, Verb, VerdictKind, VerdictResult};

use super::{Order, Rollout, RESEND_AFTER};
use crate::record::{PlcRecord, Step};
use crate::view::Seen;

fn order(plc: &str, verb: Verb) -> Option<Order> {
    Some(Order {
        plc: plc.into(),
        verb,
    })
}

/// The first twelve digits of a hash, for messages.
fn short(hash: &str) -> &str {
    hash.get(..12).unwrap_or(hash)
}

/// Takes an untouched PLC up: checks that it runs the package's base program and has no update
/// under way, and sends the load. One that already runs the new program counts as done.
pub(super) fn start(r: &mut Rollout, id: &str, seen: Option<&Seen>, now: Instant) -> Option<Order> {
    let p = r.record.plcs.get(id)?.clone();
    let seen = match seen {
        Some(s) if s.online && s.state.is_some() => s,
        other => {
            r.silent(id, &p, other, now);
            return None;
        }
    };
    let state = seen.state.as_ref()?;
    let t = &r.record.target;
    let primary = seen.primary_hash().unwrap_or("");
    if primary == t.program_hash {
        let note = "it already ran the package's program".to_string();
        match state.status {
            Status::Probation => r.set(id, Step::Probation, Some(note), Some(state.cycle.time_ms)),
            _ => r.set(id, Step::Done, Some(note), None),
        }
        return None;
    }
    if primary != t.base_hash {
        let (name, base) = (program_name(seen), short(&t.base_hash).to_string());
        let why = format!(
            "it runs {name} ({}), not the package's base {base}",
            short(primary)
        );
        r.set(id, Step::Skipped, Some(why), None);
        return None;
    }
    if state.status != Status::Idle {
        let why = format!(
            "an update is already under way on it (STATUS {}): another rollout or an operator holds it",
            state.status
        );
        r.fail(id, Step::Untouched, why);
        return None;
    }
    if let Some(why) = window_too_short(r.plan.probation_us, seen) {
        r.fail(id, Step::Untouched, why);
        return None;
    }
    r.set(id, Step::Loading, None, None);
    order(id, Verb::Load)
}

/// Why the PLC's own probation window cannot hold the plan's probation, if it cannot.
pub(crate) fn window_too_short(plan_probation_us: u64, seen: &Seen) -> Option<String> {
    let state = seen.state.as_ref()?;
    let plan_ms = plan_probation_us / 1000;
    match state.updates {
        None => Some(
            "it publishes no update policy (a PLC older than fleet rollouts); update it first"
                .into(),
        ),
        Some(u) if u.probation_ms < plan_ms => Some(format!(
            "its probation window is {} s, shorter than the plan's probation of {} s; \
             shorten the plan's `probation` or lengthen the PLC's [updates] probation",
            u.probation_ms / 1000,
            plan_ms / 1000
        )),
        Some(_) => None,
    }
}

fn program_name(seen: &Seen) -> String {
    let Some(s) = &seen.state else {
        return "no program".into();
    };
    s.programs
        .get(s.primary)
        .map_or("no program".into(), |p| format!("{} {}", p.name, p.version))
}

/// Moves a PLC mid-update on by its step; `go` is false while the rollout is paused, when only
/// failures and what the PLC did on its own are taken in.
pub(super) fn advance(
    r: &mut Rollout,
    id: &str,
    p: &PlcRecord,
    seen: &Seen,
    now: Instant,
    go: bool,
) -> Option<Order> {
    let state = seen.state.as_ref()?;
    let target = r.record.target.program_hash.clone();
    let primary_is_new = seen.primary_hash() == Some(target.as_str());
    let since = p.since_ms.unwrap_or(state.cycle.time_ms);
    let waited_ms = state.cycle.time_ms.saturating_sub(since);
    match p.step {
        Step::Loading => loading(r, id, seen, go),
        Step::Quarantine | Step::Substituting if primary_is_new => {
            flipped(r, id, state.status, state.cycle.time_ms);
            None
        }
        Step::Quarantine => quarantine(r, id, seen, waited_ms, go),
        Step::Substituting => substituting(r, id, seen, now),
        Step::Probation | Step::Accepting if !primary_is_new => {
            r.fail(
                id,
                Step::Reverted,
                ended_why(seen, "it reverted in probation"),
            );
            None
        }
        Step::Probation | Step::Accepting if state.status != Status::Probation => {
            r.set(id, Step::Done, None, None);
            None
        }
        Step::Probation if go && waited_ms >= r.plan.probation_us / 1000 => {
            r.set(id, Step::Accepting, None, None);
            order(id, Verb::Accept)
        }
        Step::Accepting => resend(seen, Verb::Accept, now).and_then(|v| order(id, v)),
        Step::Removing => removing(r, id, seen, now),
        Step::Reverting => reverting(r, id, seen, now, primary_is_new),
        _ => None,
    }
}

/// The candidate became primary (the substitution, or the PLC's own automatic one).
fn flipped(r: &mut Rollout, id: &str, status: Status, time_ms: u64) {
    match status {
        Status::Probation => r.set(id, Step::Probation, None, Some(time_ms)),
        _ => r.set(id, Step::Done, None, None),
    }
}

fn loading(r: &mut Rollout, id: &str, seen: &Seen, go: bool) -> Option<Order> {
    let state = seen.state.as_ref()?;
    let target = r.record.target.program_hash.as_str();
    if state.status == Status::Quarantine && seen.secondary_hash() == Some(target) {
        r.set(id, Step::Quarantine, None, Some(state.cycle.time_ms));
        return None;
    }
    if seen.primary_hash() == Some(target) {
        flipped(r, id, state.status, state.cycle.time_ms);
        return None;
    }
    match &seen.pending {
        Some(p) if p.verb == Verb::Load => {
            if let Some(reply) = p.reply.as_ref().filter(|r| !r.ok) {
                let msg = reply
                    .error
                    .as_ref()
                    .map_or("no reason given", |e| &e.message);
                r.fail(id, Step::Untouched, format!("its load was refused: {msg}"));
            } else if let Some((Ending::Failed, e)) = &p.ended {
                let why = format!(
                    "its load ended before quarantine: {}: {}",
                    e.kind, e.message
                );
                r.fail(id, Step::Untouched, why);
            }
            None
        }
        // Taken up again after a crash: a load that never came to an install is sent again
        // (the PLC is idle on its base, so it was never loaded); one under way is waited for.
        _ if go && state.status == Status::Idle => order(id, Verb::Load),
        _ => None,
    }
}

fn quarantine(r: &mut Rollout, id: &str, seen: &Seen, waited_ms: u64, go: bool) -> Option<Order> {
    let state = seen.state.as_ref()?;
    let target = r.record.target.program_hash.as_str();
    if state.status != Status::Quarantine || seen.secondary_hash() != Some(target) {
        let why = ended_why(seen, "its candidate ended in quarantine");
        r.fail(id, Step::Removed, why);
        return None;
    }
    let candidate = (seen.info.iter())
        .flat_map(|i| i.0.iter().flatten())
        .find(|c| c.role == Role::Candidate && c.program.hash == target);
    if let Some(c) = candidate {
        let undeclared = (c.divergence.iter())
            .find(|(out, n)| **n > 0 && !r.record.target.may_differ.contains(out));
        if let Some((out, n)) = undeclared {
            let cause = c
                .first_cause
                .as_deref()
                .map_or(String::new(), |c| format!(" ({c})"));
            let why = format!(
                "its candidate diverged on {out} in {n} cycles, which the package does not declare{cause}"
            );
            r.fail(id, Step::Quarantine, why);
            return None;
        }
        if let Some(v) = c.verdicts.iter().find(|v| v.result == VerdictResult::Fail) {
            let why = format!("a failing {} verdict: {}", v.kind, v.reasons.join("; "));
            r.fail(id, Step::Quarantine, why);
            return None;
        }
    }
    let verdict = !r.plan.require_verdict
        || candidate.is_some_and(|c| {
            (c.verdicts.iter())
                .any(|v| v.kind == VerdictKind::Twin && v.result != VerdictResult::Fail)
        });
    if go && verdict && waited_ms >= r.plan.quarantine_us / 1000 {
        r.set(id, Step::Substituting, None, None);
        return order(id, Verb::Substitute);
    }
    None
}

fn substituting(r: &mut Rollout, id: &str, seen: &Seen, now: Instant) -> Option<Order> {
    let state = seen.state.as_ref()?;
    if state.status != Status::Quarantine {
        let why = ended_why(seen, "its candidate ended before the substitution");
        r.fail(id, Step::Removed, why);
        return None;
    }
    if let Some(p) = seen.pending.as_ref().filter(|p| p.verb == Verb::Substitute) {
        if let Some(reply) = p.reply.as_ref().filter(|r| !r.ok) {
            let msg = reply
                .error
                .as_ref()
                .map_or("no reason given", |e| &e.message);
            r.fail(
                id,
                Step::Quarantine,
                format!("its substitution was refused: {msg}"),
            );
            return None;
        }
        if let Some((Ending::Failed, e)) = &p.ended {
            let why = format!("its substitution failed: {}: {}", e.kind, e.message);
            r.fail(id, Step::Quarantine, why);
            return None;
        }
    }
    resend(seen, Verb::Substitute, now).and_then(|v| order(id, v))
}

fn removing(r: &mut Rollout, id: &str, seen: &Seen, now: Instant) -> Option<Order> {
    let state = seen.state.as_ref()?;
    match state.status {
        Status::Quarantine => resend(seen, Verb::Remove, now).and_then(|v| order(id, v)),
        Status::Setup => resend(seen, Verb::Abort, now).and_then(|v| order(id, v)),
        _ => {
            let step = settled(r, seen, Step::Quarantine);
            r.set(id, step, None, None);
            None
        }
    }
}

fn reverting(r: &mut Rollout, id: &str, seen: &Seen, now: Instant, new: bool) -> Option<Order> {
    let state = seen.state.as_ref()?;
    if state.status == Status::Probation {
        return resend(seen, Verb::Revert, now).and_then(|v| order(id, v));
    }
    if new {
        let note = "the update became final before the revert came".to_string();
        r.set(id, Step::Done, Some(note), None);
    } else {
        r.set(id, Step::Reverted, None, None);
    }
    None
}

/// Whether to send `verb` (again): none of it was sent by this process (the rollout was taken
/// up after a crash), or the last one was refused or failed at least [`RESEND_AFTER`] ago.
fn resend(seen: &Seen, verb: Verb, now: Instant) -> Option<Verb> {
    let again = match &seen.pending {
        Some(p) if p.verb == verb => {
            let failed = p.reply.as_ref().is_some_and(|r| !r.ok)
                || matches!(p.ended, Some((Ending::Failed, _)));
            failed && now.saturating_duration_since(p.at) >= RESEND_AFTER
        }
        _ => true,
    };
    again.then_some(verb)
}

/// What a PLC whose update no longer stands comes to, from the step it was at.
pub(super) fn settled(r: &Rollout, seen: &Seen, step: Step) -> Step {
    let idle = seen
        .state
        .as_ref()
        .is_some_and(|s| s.status == Status::Idle);
    if idle && seen.primary_hash() == Some(r.record.target.program_hash.as_str()) {
        return Step::Done;
    }
    match step {
        Step::Loading => Step::Untouched,
        Step::Probation | Step::Accepting | Step::Reverting => Step::Reverted,
        _ => Step::Removed,
    }
}

/// The reason the PLC gave for the end of its update: its last such event, or `otherwise`.
fn ended_why(seen: &Seen, otherwise: &str) -> String {
    match &seen.last_event {
        Some(e) => format!("{otherwise}: {}: {}", e.kind, e.message),
        None => otherwise.to_string(),
    }
}
