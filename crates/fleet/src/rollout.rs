//! The rollout itself: a state machine over the [`Record`], moved on by what the [`View`] says
//! of each PLC and by the clock, that answers with the commands to send. It sends nothing
//! itself and touches no file, so the same machine runs in `cetratus rollout` and in the
//! dashboard, and is tested without a broker.
//!
//! Each PLC of a stage goes through the gates of docs/fleet.md: its load (bound to its base
//! program, which is checked first), the least time in quarantine with no divergence beyond
//! what the package declares, the verdict when the plan requires one, the substitution, the
//! least time in probation, and the accept. The first failure halts the rollout and applies the
//! plan's `on_failure`; nothing goes on to the next stage.

mod gates;

pub(crate) use gates::window_too_short;

use std::time::{Duration, Instant};

use cetratus_proto::{Status, Verb};

use crate::record::{Outcome, PlcRecord, Record, Step};
use crate::view::{Seen, View};
use crate::{OnFailure, Plan};

/// A command the rollout wants sent to one PLC.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Order {
    /// The PLC.
    pub plc: String,
    /// The verb: `load` carries the plan's package, `substitute` its defaults.
    pub verb: Verb,
}

/// What an operator asks of a running rollout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// Take no PLC further until resumed.
    Pause,
    /// Carry on.
    Resume,
    /// Remove or revert the PLCs mid-update and end; done PLCs stay.
    Abort,
}

/// How long a command may go unanswered before it is sent again (only the ones that are safe
/// to repeat: a remove, an abort or a revert the PLC refused while its update still stood).
const RESEND_AFTER: Duration = Duration::from_secs(1);

/// A rollout under way: its plan and its record.
#[derive(Debug)]
pub struct Rollout {
    /// The plan it follows.
    pub plan: Plan,
    /// Where it stands; the caller saves it when [`Rollout::tick`] says it changed.
    pub record: Record,
    /// A line per change, for the rollout's log and the live view; the caller drains it.
    pub log: Vec<String>,
    /// When this process took the rollout up: a PLC never heard is as quiet as this is old.
    began: Instant,
}

impl Rollout {
    /// The rollout of `plan` as `record` has it.
    pub fn new(plan: Plan, record: Record) -> Rollout {
        Rollout {
            plan,
            record,
            log: Vec::new(),
            began: Instant::now(),
        }
    }

    /// Applies an operator's request.
    pub fn request(&mut self, r: Request) {
        if self.record.outcome.ended() && r != Request::Abort {
            return;
        }
        match r {
            Request::Pause => {
                self.record.paused = true;
                self.note_rollout("paused: no PLC is taken further until `resume`");
            }
            Request::Resume => {
                self.record.paused = false;
                self.note_rollout("resumed");
            }
            Request::Abort => {
                if self.record.outcome == Outcome::Done {
                    return;
                }
                self.record.reason = Some("aborted by an operator".into());
                self.record.outcome = Outcome::Stopping { aborted: true };
                self.note_rollout("abort: the PLCs mid-update are removed or reverted");
            }
        }
    }

    /// Moves the rollout on by what `view` says at `now`; the commands to send, in order.
    pub fn tick(&mut self, view: &View, now: Instant) -> Vec<Order> {
        let mut orders = Vec::new();
        if matches!(self.record.outcome, Outcome::Done | Outcome::Aborted) {
            return orders;
        }
        let ids: Vec<String> = self.record.plcs.keys().cloned().collect();
        for id in &ids {
            orders.extend(self.advance(id, view, now));
        }
        if self.record.outcome == Outcome::Running && !self.record.paused {
            self.start_more(view, now, &mut orders);
        }
        if let Outcome::Stopping { aborted } = self.record.outcome {
            for id in &ids {
                let step = self.record.plcs.get(id).map(|p| (p.step, p.lost));
                let (Some((step, false)), Some(seen)) = (step, view.get(id)) else {
                    continue;
                };
                if step.mid_update() && !matches!(step, Step::Removing | Step::Reverting) {
                    orders.extend(self.take_back(id, seen));
                }
            }
            if self.record.in_flight() == 0 {
                self.record.outcome = if aborted {
                    Outcome::Aborted
                } else {
                    Outcome::Halted
                };
                self.note_rollout(self.record.outcome.as_str());
            }
        }
        orders
    }

    /// Moves one PLC on; the command it needs, if any. While the rollout stops, only the
    /// commands that take PLCs back are followed here; [`Rollout::take_back`] sends them.
    fn advance(&mut self, id: &str, view: &View, now: Instant) -> Option<Order> {
        let p = self.record.plcs.get(id)?.clone();
        if !p.step.mid_update() || p.lost || self.silent(id, &p, view.get(id), now) {
            return None;
        }
        let seen = view.get(id)?;
        if let Some(why) = self.unanswered(seen, now) {
            self.give_up(id, &p, why);
            return None;
        }
        let stopping = matches!(self.record.outcome, Outcome::Stopping { .. });
        if stopping && !matches!(p.step, Step::Removing | Step::Reverting) {
            return None;
        }
        let go = !self.record.paused && self.record.outcome == Outcome::Running;
        gates::advance(self, id, &p, seen, now, go)
    }

    /// A PLC not heard for the plan's `silent` time fails the rollout (while it is only quiet,
    /// the rollout waits for it); one that goes silent while the rollout stops is left as it
    /// was, and said so. Whether it was silent.
    fn silent(&mut self, id: &str, p: &PlcRecord, seen: Option<&Seen>, now: Instant) -> bool {
        let quiet = now.saturating_duration_since(seen.map_or(self.began, |s| s.heard));
        if quiet < Duration::from_micros(self.plan.silent_us) {
            return false;
        }
        let secs = quiet.as_secs();
        let why = match seen {
            Some(s) if !s.online => format!("offline for {secs} s, past the plan's `silent`"),
            Some(_) => format!("silent for {secs} s, past the plan's `silent`"),
            None => format!("not heard on the broker for {secs} s, past the plan's `silent`"),
        };
        self.give_up(id, p, why);
        true
    }

    /// Why the rollout's last command to the PLC counts as lost: no reply within the plan's
    /// `silent` time, though the PLC is heard (a broker whose ACL drops the command, a PLC too
    /// busy to read it).
    fn unanswered(&self, seen: &Seen, now: Instant) -> Option<String> {
        let p = seen.pending.as_ref().filter(|p| p.reply.is_none())?;
        let waited = now.saturating_duration_since(p.at);
        (waited >= Duration::from_micros(self.plan.silent_us)).then(|| {
            format!(
                "its {} had no reply for {} s, past the plan's `silent`; check that the broker \
                 lets the rollout's account command it (its ACL)",
                p.verb,
                waited.as_secs()
            )
        })
    }

    /// A PLC the rollout cannot go on with: a failure, or, while the rollout stops, a PLC left
    /// as it was, and said so, that the stop no longer waits for.
    fn give_up(&mut self, id: &str, p: &PlcRecord, why: String) {
        if matches!(self.record.outcome, Outcome::Stopping { .. }) {
            let left = format!("{why}; left {} as it was", p.step.as_str());
            self.set(id, p.step, Some(left), None);
            if let Some(r) = self.record.plcs.get_mut(id) {
                r.lost = true;
            }
        } else {
            self.fail(id, p.step, why);
        }
    }

    /// Starts the next PLCs of the stage under way, up to `max_parallel` mid-update; moves to
    /// the next stage once every PLC of this one passed.
    fn start_more(&mut self, view: &View, now: Instant, orders: &mut Vec<Order>) {
        loop {
            let k = self.record.stage;
            let Some(members) = self.record.stages.get(k - 1).cloned() else {
                return;
            };
            for id in &members {
                if self.record.outcome != Outcome::Running
                    || self.record.in_flight() >= self.plan.max_parallel
                {
                    return;
                }
                let step = self.record.plcs.get(id).map(|p| p.step);
                if step == Some(Step::Untouched) {
                    if let Some(o) = gates::start(self, id, view.get(id), now) {
                        orders.push(o);
                    }
                }
            }
            let passed = (members.iter())
                .all(|id| self.record.plcs.get(id).is_some_and(|p| p.step.passed()));
            if !passed || self.record.outcome != Outcome::Running {
                return;
            }
            self.record.stage += 1;
            if self.record.stage > self.record.stages.len() {
                self.record.outcome = Outcome::Done;
                self.note_rollout("done: every stage passed");
                return;
            }
            let n = self.record.stages.len();
            self.note_rollout(&format!("stage {}/{n} begins", self.record.stage));
        }
    }

    /// The command that takes a PLC mid-update back: a remove from quarantine (an abort before
    /// the install), a revert in probation.
    fn take_back(&mut self, id: &str, seen: &Seen) -> Option<Order> {
        let status = seen.state.as_ref().map(|s| s.status);
        let (step, verb) = match status {
            Some(Status::Quarantine) => (Step::Removing, Verb::Remove),
            Some(Status::Setup) => (Step::Removing, Verb::Abort),
            Some(Status::Probation) => (Step::Reverting, Verb::Revert),
            // Idle or in fault: nothing of the update stands to take back.
            _ => {
                let step = self.record.plcs.get(id).map_or(Step::Loading, |p| p.step);
                let last = gates::settled(self, seen, step);
                self.set(id, last, None, None);
                return None;
            }
        };
        self.set(id, step, None, None);
        Some(Order {
            plc: id.into(),
            verb,
        })
    }

    /// The first failure: halts the rollout by the plan's `on_failure`. `step` is the PLC's
    /// step from now on.
    pub(crate) fn fail(&mut self, id: &str, step: Step, why: String) {
        self.set(id, step, Some(why.clone()), None);
        if self.record.outcome != Outcome::Running {
            return;
        }
        self.record.reason = Some(format!("{id}: {why}"));
        match self.plan.on_failure {
            OnFailure::Stop => {
                self.record.outcome = Outcome::Stopping { aborted: false };
                self.note_rollout(&format!(
                    "halted at {id}: {why}; the PLCs mid-update are removed or reverted"
                ));
            }
            OnFailure::Hold => {
                self.record.outcome = Outcome::Halted;
                self.record.alarm = true;
                self.note_rollout(&format!(
                    "ALARM: halted at {id}: {why}; the PLCs mid-update are held as they are"
                ));
            }
        }
    }

    /// Sets a PLC's step (and its note and wait, when given), and logs the change.
    pub(crate) fn set(
        &mut self,
        id: &str,
        step: Step,
        note: Option<String>,
        since_ms: Option<u64>,
    ) {
        let Some(p) = self.record.plcs.get_mut(id) else {
            return;
        };
        let changed = p.step != step || (note.is_some() && note != p.note);
        p.step = step;
        if note.is_some() {
            p.note = note;
        }
        if since_ms.is_some() || !step.mid_update() {
            p.since_ms = since_ms;
        }
        if changed {
            let line = match &p.note {
                Some(n) if !step.mid_update() || step == Step::Quarantine => {
                    format!("{id}: {} ({n})", step.as_str())
                }
                _ => format!("{id}: {}", step.as_str()),
            };
            self.log.push(line);
        }
    }

    fn note_rollout(&mut self, what: &str) {
        self.log.push(format!("rollout {}: {what}", self.record.id));
    }
}

#[cfg(test)]
mod tests;
