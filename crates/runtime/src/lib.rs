//! The Cetratus scan engine: Provider → container → Dispatcher, once per cycle.
//!
//! Time is an argument everywhere (`now_us`, microseconds): a [`Clock`] supplies it, virtual in
//! tests and twins, real on a machine. The [`Container`] holds one running program; its
//! [`Container::scan`] reads an input image, runs the net as DESIGN §3 says, and leaves an output
//! image, without allocating. [`ScanCycle`] drives containers against drivers in virtual time or
//! in real time, where it sleeps to absolute deadlines and measures what the OpenPLC v4 runtime
//! measures: scan time, cycle time, latency and overruns.

mod clock;
mod container;
mod cycle;
mod error;
#[cfg(feature = "fault-injection")]
pub mod inject;
mod io;
pub mod monitor;
pub mod persist;
pub mod plc;
pub mod rt;
mod stats;
pub mod trace;

pub use clock::{Clock, RealClock, VirtualClock};
pub use container::{Blocker, Container, ScanOutcome};
pub use cycle::{run_periodic, CycleFigures, LoopTiming, ScanCycle};
pub use error::RuntimeError;
pub use io::{Dispatcher, Provider};
pub use monitor::{Slot, Status};
pub use plc::{
    Command, Event, Limits, Plc, PreparedUpdate, SubstituteMode, SubstituteRequest, UpdateContext,
};
pub use stats::{Summary, TimingStats};
