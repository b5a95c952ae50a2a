//! What a rollout keeps in its state file: the package it takes across the fleet, the PLCs of
//! each stage, where each PLC stands, and how the rollout stands. Everything a `resume` needs to
//! carry on without loading a PLC twice is here; what the broker says live is in
//! [`crate::view::View`].

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

cetratus_vocab::names! {
    /// Where one PLC stands in the rollout. The last step of each PLC is what the report shows.
    Step, "rollout step",
        "untouched, loading, quarantine, substituting, probation, accepting, done, skipped, \
         removing, removed, reverting or reverted" {
        /// Not reached yet, or its load was refused and nothing changed.
        Untouched = "untouched",
        /// The package was sent; waiting for it to run in quarantine.
        Loading = "loading",
        /// The candidate runs in quarantine; waiting out the least time (and the verdict).
        Quarantine = "quarantine",
        /// The substitution was sent; waiting for probation.
        Substituting = "substituting",
        /// The new program drives the outputs; waiting out the least time in probation.
        Probation = "probation",
        /// The accept was sent; waiting for the update to be final.
        Accepting = "accepting",
        /// The PLC runs the package's program, accepted: final (docs/live-update.md).
        Done = "done",
        /// Not updated: it runs another base program, or is otherwise not the package's to
        /// update.
        Skipped = "skipped",
        /// The remove (or abort) was sent; waiting for the candidate to be gone.
        Removing = "removing",
        /// Its candidate was removed from quarantine; it runs its old program.
        Removed = "removed",
        /// The revert was sent; waiting for the old program to be primary again.
        Reverting = "reverting",
        /// Reverted in probation; it runs its old program.
        Reverted = "reverted",
    }
}

impl Step {
    /// Whether the PLC is mid-update: a command of the rollout is under way on it, or its
    /// update waits for the rollout's next one.
    pub fn mid_update(self) -> bool {
        matches!(
            self,
            Step::Loading
                | Step::Quarantine
                | Step::Substituting
                | Step::Probation
                | Step::Accepting
                | Step::Removing
                | Step::Reverting
        )
    }

    /// Whether the PLC has passed its stage.
    pub fn passed(self) -> bool {
        matches!(self, Step::Done | Step::Skipped)
    }
}

/// How the rollout stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Under way (or paused).
    Running,
    /// A failure halted it with `on_failure = "stop"` (or an abort was asked): the PLCs
    /// mid-update are being removed or reverted; it ends [`Outcome::Halted`] (or
    /// [`Outcome::Aborted`]).
    Stopping {
        /// Whether an operator's abort caused it.
        aborted: bool,
    },
    /// Every stage passed.
    Done,
    /// Halted at a failure; nothing went on to the next stage.
    Halted,
    /// Aborted by an operator.
    Aborted,
}

impl Outcome {
    /// Whether the rollout has ended.
    pub fn ended(self) -> bool {
        matches!(self, Outcome::Done | Outcome::Halted | Outcome::Aborted)
    }

    /// The outcome as the report writes it.
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Running => "running",
            Outcome::Stopping { .. } => "stopping",
            Outcome::Done => "done",
            Outcome::Halted => "halted",
            Outcome::Aborted => "aborted",
        }
    }
}

/// What the rollout takes across the fleet, read from the package's manifest.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Target {
    /// The update's name and version, as its manifest gives them.
    pub update: String,
    /// The hash of the new program.
    pub program_hash: String,
    /// The hash of the program the package is bound to.
    pub base_hash: String,
    /// The outputs the package declares may differ from the old program's; divergence on any
    /// other is a failure.
    pub may_differ: Vec<String>,
    /// SHA-256 of the package file.
    pub file_sha256: String,
}

/// One PLC in the rollout.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlcRecord {
    /// Its stage, from 1.
    pub stage: usize,
    /// Where it stands.
    pub step: Step,
    /// Why, when the step alone does not say (a skip, a failure, a refusal).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
    /// The PLC's program time, ms, when its current wait began (quarantine, probation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub since_ms: Option<u64>,
    /// Went silent while the rollout stopped: left as it was, no longer waited for.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub lost: bool,
}

/// The state file's content: the whole rollout.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Record {
    /// The rollout's id: the plan's name and the start time.
    pub id: String,
    /// The plan file, as given.
    pub plan_file: String,
    /// The plan's text, so that a resume follows the plan it started with.
    pub plan_text: String,
    /// What it takes across the fleet.
    pub target: Target,
    /// The PLC ids each stage adds, in order.
    pub stages: Vec<Vec<String>>,
    /// Every PLC of the selection.
    pub plcs: BTreeMap<String, PlcRecord>,
    /// The stage under way, from 1; `stages.len() + 1` once all passed.
    pub stage: usize,
    /// How it stands.
    pub outcome: Outcome,
    /// Paused by an operator: no PLC is taken further until it is resumed.
    #[serde(default)]
    pub paused: bool,
    /// The failure that halted it, or the abort.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Raised when a failure halted it with `on_failure = "hold"`: PLCs were left mid-update.
    #[serde(default)]
    pub alarm: bool,
}

impl Record {
    /// A new rollout of `target` over `stages`, every PLC untouched, at the first stage.
    pub fn new(id: String, plan: (&str, &str), target: Target, stages: Vec<Vec<String>>) -> Record {
        let mut plcs = BTreeMap::new();
        for (k, ids) in stages.iter().enumerate() {
            for id in ids {
                plcs.insert(
                    id.clone(),
                    PlcRecord {
                        stage: k + 1,
                        step: Step::Untouched,
                        note: None,
                        since_ms: None,
                        lost: false,
                    },
                );
            }
        }
        Record {
            id,
            plan_file: plan.0.to_string(),
            plan_text: plan.1.to_string(),
            target,
            stages,
            plcs,
            stage: 1,
            outcome: Outcome::Running,
            paused: false,
            reason: None,
            alarm: false,
        }
    }

    /// How many PLCs are mid-update.
    pub fn in_flight(&self) -> usize {
        (self.plcs.values())
            .filter(|p| p.step.mid_update() && !p.lost)
            .count()
    }

    /// The report: the outcome, and for each PLC its stage, last step and note.
    pub fn report(&self) -> serde_json::Value {
        let plcs: serde_json::Map<String, serde_json::Value> = (self.plcs.iter())
            .map(|(id, p)| {
                let mut v = serde_json::json!({ "stage": p.stage, "step": p.step.as_str() });
                if let Some(n) = &p.note {
                    v["reason"] = n.as_str().into();
                }
                (id.clone(), v)
            })
            .collect();
        serde_json::json!({
            "rollout": self.id,
            "outcome": self.outcome.as_str(),
            "paused": self.paused,
            "reason": self.reason,
            "alarm": self.alarm,
            "update": self.target.update,
            "program_hash": self.target.program_hash,
            "stage": self.stage.min(self.stages.len()),
            "stages": self.stages.len(),
            "plcs": plcs,
        })
    }
}
