//! The PLC node as a library: a [`Plc`](cetratus_runtime::Plc) on its I/O, driven in virtual
//! or real time, connected to MQTT and to its state directory.
//!
//! * [`NodeSpec`]: the one place a node is assembled, for `cetratus run`, `cetratus demo` and
//!   the benches: the plant ([`plant`]), MQTT and its companion ([`services`]), the state
//!   directory, then the node; [`NodeSpec::start`] returns it running.
//! * [`Node`]: the node loop, one cycle at a time ([`Node::step`]), the same for `cetratus run`
//!   and `cetratus demo`: commands (MQTT, scripted), the scan, the trace and invariant check,
//!   events to the audit log, to MQTT and to the operator, publication, persistence.
//! * [`link`]: the scan thread's side of MQTT, with the preparer thread (verifies and builds
//!   packages, compiles conditions) and the publisher thread.
//! * [`periodic`]: the real-time loop at absolute deadlines; [`rt`]: SCHED_FIFO and mlockall;
//!   [`overruns`]: a candidate that makes the primary overrun more than before its load is
//!   faulted.
//! * [`clock`]: the machine's clocks, injected into the runtime.
//! * [`gate`]: the analysis gate at load, run by the preparers; [`validate`]: twin validation
//!   of an update on forked or fresh twins, on a thread of its own.
//! * [`config`]: the local configuration; [`state`]: the state directory and the start from it.
//! * [`demo`]: the Vernadat experiment of the paper, embedded.

pub mod clock;
pub mod config;
pub mod demo;
pub mod dirs;
pub mod gate;
pub mod link;
pub mod load;
mod node;
pub mod overruns;
pub mod periodic;
pub mod plant;
pub mod rt;
pub mod script;
pub mod services;
pub mod spec;
pub mod state;
pub mod validate;
pub mod wire;

pub use node::{Echo, Node, NodeOptions, NodeReport};
pub use spec::{Finished, NodeSpec, Notice, RunningNode, SpecError, StateDir, TimeMode};
