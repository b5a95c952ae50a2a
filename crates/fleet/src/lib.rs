//! Fleet operations across many PLCs (docs/fleet.md): a rollout takes one update package across
//! the PLCs a selector picks, stage by stage, a canary first, each PLC proven in quarantine and
//! probation by its own live-update machinery, and halts at the first failure.
//!
//! * [`Plan`]: `rollout.toml`, read and checked whole before anything is sent.
//! * [`Rollout`]: the state machine. It is moved on by what the broker says of each PLC
//!   ([`View`]) and by the clock, and answers with the commands to send; it sends nothing
//!   itself, so the same machine runs in `cetratus rollout` and in the dashboard.
//! * [`Record`]: what the rollout keeps in its state file, enough to resume after a crash
//!   without loading a PLC twice; [`Journal`] holds the state directory.
//! * [`Link`] and [`run`]: the one broker connection, and the loop that drives a rollout.

#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod journal;
pub mod link;
mod plan;
pub mod record;
pub mod rollout;
pub mod run;
pub mod view;

pub use journal::Journal;
pub use link::{Link, LinkConfig};
pub use plan::{OnFailure, Plan, PlanError, Stage, DEFAULT_SILENT_US, MAX_PLAN_BYTES, MAX_STAGES};
pub use record::{Outcome, PlcRecord, Record, Step, Target};
pub use rollout::{Order, Request, Rollout};
pub use view::View;

/// Why a rollout cannot start, go on, or be acted on.
#[derive(Debug, thiserror::Error)]
pub enum FleetError {
    /// The plan is refused.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The plan does not hold for the fleet (a PLC's probation window, a base no PLC runs).
    #[error("the plan is refused: {0}")]
    Refused(String),
    /// The package cannot be read.
    #[error("{path}: not a package the rollout can take: {reason}")]
    Package {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// A file of the state directory cannot be read or written.
    #[error("{0}: {1}")]
    Io(String, std::io::Error),
    /// `rollout.json` is not a rollout's record.
    #[error("{path}: not a rollout record: {reason}")]
    Record {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// No rollout is recorded in the directory.
    #[error("no rollout is recorded in {0}; start one with `cetratus rollout start PLAN`, or give its --state-dir")]
    NoRollout(String),
    /// Another rollout holds what this one needs.
    #[error("{0}")]
    Busy(String),
    /// The broker refused or failed.
    #[error("the broker: {0}")]
    Broker(cetratus_mct::MctError),
    /// The broker did not answer.
    #[error(
        "no answer from the broker at {url} within {after:?}; check --broker and that it runs"
    )]
    NoBroker {
        /// The broker URL.
        url: String,
        /// How long the rollout waited.
        after: std::time::Duration,
    },
    /// The connection's reader ended.
    #[error("the connection to the broker ended")]
    LinkClosed,
    /// A PLC id or a payload the protocol refuses.
    #[error(transparent)]
    Proto(cetratus_proto::ProtoError),
    /// A record or a command could not be written as JSON.
    #[error("cannot encode: {0}")]
    Encode(String),
}
