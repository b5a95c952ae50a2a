//! Structural and behavioural analysis of place/transition nets: what engineers get from PIPE2,
//! faster.
//!
//! * Structure ([`structure`]): incidence matrices, net classes, minimal P- and T-semiflows by the
//!   Farkas algorithm with checked arithmetic, conservativeness and structural boundedness, minimal
//!   siphons and traps with Commoner's warning.
//! * Behaviour ([`reach`], [`coverability`]): the reachability graph over bit-packed markings, a
//!   Karp–Miller coverability graph when the net may be unbounded, deadlocks with a shortest
//!   witness, place bounds, liveness and reversibility from the terminal strongly connected
//!   components.
//! * Property-directed checks ([`check_property`]): one property (deadlock, bounded, safe, live,
//!   reversible, or a predicate reachable / always true), stopping as soon as it is decided, with
//!   stubborn-set reduction for deadlocks and predicates.
//! * [`check`] runs everything and returns a [`Report`] (serde-serialisable, with a text rendering).
//!
//! Semantics are the plain interleaving semantics of docs/design.md §3: every enabled transition at a state
//! is one edge, inhibitor arcs are honoured, capacities are enabling conditions, priorities are
//! ignored.

pub mod budget;
mod check;
pub mod classify;
pub mod coverability;
mod error;
pub mod families;
pub mod invariants;
pub mod matrix;
pub mod predicate;
mod property;
pub mod reach;
mod report;
pub mod sfc;
pub mod siphons;
pub mod spare;

pub use budget::{Clock, Deadline, PartialReason};
pub use check::{check, CheckOptions, Progress, ProgressFn, PARALLEL_FROM};
pub use classify::Classification;
pub use error::AnalysisError;
pub use invariants::Semiflow;
pub use matrix::Incidence;
pub use predicate::{Predicate, PredicateError};
pub use property::{check_property, Property};
pub use reach::SpareCoreFn;
pub use report::{Bound, Named, Report};

/// The structural analyses, gathered under one name for readers of the issue.
pub mod structure {
    pub use crate::classify::classify;
    pub use crate::invariants::{p_semiflows, structural_bounds, t_semiflows};
    pub use crate::matrix::Incidence;
    pub use crate::siphons::{minimal_siphons, minimal_traps};
}
