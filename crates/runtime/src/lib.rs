//! The Cetratus scan engine and the live update: the boxes of the paper's Figure 1.
//!
//! * [`Container`]: one running program (engine, place timers, action state, I/O images), whose
//!   [`Container::scan`] never allocates.
//! * [`MessageRouter`]: the same inputs to both containers, only PRIMARY's outputs to the
//!   Dispatcher, the safe values in fault.
//! * [`Updater`]: the live-update process; its phase ([`Status`]) is an enum that owns the
//!   secondary container (docs/design.md §4).
//! * [`Monitor`]: `program_exec_info`, divergence and its derived cause, drift, recent cycles.
//! * [`Plc`]: composes them and runs one cycle at a time.
//!
//! Time is injected three ways (module [`clock`]): program time is an argument (`now_us`),
//! measured durations come from a [`Stopwatch`], wall-clock timestamps from a [`WallClock`].
//! Nothing in this crate reads a clock, so the same code runs in virtual time (tests, twins,
//! validation) and in real time.

pub mod clock;
mod container;
mod cycle;
mod error;
mod event;
#[cfg(feature = "fault-injection")]
pub mod inject;
mod io;
pub mod mask;
pub mod monitor;
mod phase;
mod plc;
mod prepare;
mod probation;
mod recent;
mod revert;
mod router;
pub mod signature;
mod snapshot;
mod stats;
pub mod trace;
mod updater;
mod watchdog;

pub use cetratus_vocab::UnknownName;
pub use clock::{
    Clock, FixedWallClock, InstallTiming, ManualStopwatch, Stopwatch, VirtualClock, WallClock,
};
pub use container::{Blocker, Container, ScanOutcome, Slot};
pub use cycle::{CycleFigures, LoopTiming, ScanCycle};
pub use error::{CommandError, PrepareError, RuntimeError, WarmStartError};
pub use event::{Event, EventDetail, EventKind, RevertMarking, RevertReason};
pub use io::{Dispatcher, Inadmissible, IoAdmission, Provider, SharedAdmission};
pub use monitor::{ExecInfo, Monitor, Role, Verdict, VerdictKind, VerdictResult};
pub use phase::Status;
pub use plc::Plc;
pub use router::MessageRouter;
pub use snapshot::{ContainerSnapshot, PlcSnapshot};
pub use stats::{Summary, TimingStats};
pub use updater::{
    value_json, Command, Limits, PreparedUpdate, SubstituteMode, SubstituteRequest, UpdateContext,
    Updater, DEFAULT_QUARANTINE_CYCLES, DEFAULT_REVERT_WAIT_US, INSTRUCTIONS_PER_US,
    VIRTUAL_NS_PER_ENTRY,
};
