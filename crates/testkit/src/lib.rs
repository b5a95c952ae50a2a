//! What the test suites of the workspace share: a real stopwatch, the counting allocator, the
//! browser and MQTT helpers, and the Vernadat net. A dev-dependency only; nothing ships it.

use cetratus_runtime::Stopwatch;

/// The machine's stopwatch, as a PLC node uses it: tests of the watchdog and the candidate's
/// budget need real durations.
pub fn stopwatch() -> Box<dyn Stopwatch> {
    cetratus_node::clock::MonotonicStopwatch::boxed()
}
