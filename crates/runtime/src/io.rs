//! The two faces of the I/O drivers: the Provider fills the input image, the Dispatcher takes the
//! output image. Simulated plants, fieldbus drivers and test benches all implement these.

use std::sync::Arc;

use cetratus_program::{Signal, Value};

/// Fills the input image at the start of a cycle.
pub trait Provider {
    /// Writes the current inputs, in the program's declared input order.
    fn read_inputs(&mut self, now_us: u64, inputs: &mut [Value]);

    /// The I/O map grew at an install: `inputs` and `outputs` are appended to it, in this order,
    /// for a candidate that uses signals the running program does not. Called on the scan thread
    /// at the cycle boundary of the install, before the cycle's inputs are read; a driver that
    /// admitted them ([`IoAdmission`]) starts serving them. The default serves nothing new.
    fn io_map_grew(&mut self, _inputs: &[Signal], _outputs: &[Signal]) {}
}

/// Whether the node's I/O can serve signals that the running I/O map lacks, asked away from the
/// scan thread while an update is prepared.
pub trait IoAdmission: Send + Sync {
    /// `Ok` when every signal of `inputs` and `outputs` (new to the I/O map) maps to a channel
    /// of the node's I/O configuration; otherwise why not, naming the signal.
    fn admit(&self, inputs: &[Signal], outputs: &[Signal]) -> Result<(), Inadmissible>;
}

/// Why the node's I/O cannot serve a signal that a candidate adds, as its driver says it,
/// naming the signal and the configuration that would serve it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Inadmissible(pub String);

/// A shared [`IoAdmission`].
pub type SharedAdmission = Arc<dyn IoAdmission>;

/// Takes the output image at the end of a cycle.
pub trait Dispatcher {
    /// Applies the outputs, in the program's declared output order.
    fn write_outputs(&mut self, now_us: u64, outputs: &[Value]);

    /// The outputs' safe values changed (the first cycle, a new primary, an install that grew
    /// the map): what the I/O sends when it goes to its safe state on its own (a stop, a device
    /// gone stale under a `fault` policy), in I/O-map order. Called on the scan thread at a cycle
    /// boundary, after [`Provider::io_map_grew`]; it must neither block nor allocate. The default
    /// ignores them.
    fn safe_outputs(&mut self, _safe: &[Value]) {}
}
