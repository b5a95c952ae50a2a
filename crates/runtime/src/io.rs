//! The two faces of the I/O drivers: the Provider fills the input image, the Dispatcher takes the
//! output image. Simulated plants, fieldbus drivers and test benches all implement these.

use cetratus_program::Value;

/// Fills the input image at the start of a cycle.
pub trait Provider {
    /// Writes the current inputs, in the program's declared input order.
    fn read_inputs(&mut self, now_us: u64, inputs: &mut [Value]);
}

/// Takes the output image at the end of a cycle.
pub trait Dispatcher {
    /// Applies the outputs, in the program's declared output order.
    fn write_outputs(&mut self, now_us: u64, outputs: &[Value]);
}
