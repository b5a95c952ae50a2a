//! Fleet operations across many PLCs (docs/fleet.md): a rollout plan ([`Plan`]), read from
//! `rollout.toml` and checked, and the PLCs each of its stages picks from the fleet.
//!
//! A plan names the package, the selector of the PLCs it may touch, and cumulative stages (a
//! canary first), with the least time each PLC must spend in quarantine and in probation, how
//! many may be mid-update at once, and what a failure does. Everything that arrives in a plan
//! file is checked before anything is sent: a plan that cannot be followed to the end is
//! refused whole, with what is wrong and what to write.

#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod plan;

pub use plan::{OnFailure, Plan, PlanError, Stage, MAX_PLAN_BYTES, MAX_STAGES};
