//! What the test suites of the workspace share: the counting allocator, free ports and child
//! processes, a Mosquitto broker and its command-line clients, the pymodbus and asyncua peers,
//! headless Chromium, the example nets and programs, and a real stopwatch. A dev-dependency only;
//! nothing ships it, and the architecture test checks that no crate depends on it otherwise.
//!
//! The parts that pull in heavy crates sit behind features (`nets`, `programs`, `stopwatch`,
//! `browser`), so that a suite compiles only what it uses.
//!
//! `matiec` runs batches of Structured Text programs through MATIEC, the compiler of OpenPLC and
//! Beremiz, as an independent second implementation of the language.
//! `stgen` writes random, well-typed, deterministic ST programs and input sequences for it.
//!
//! # Where the Vernadat net lives
//!
//! The bare Vernadat net is built in code exactly once, in `cetratus_bench::workloads::vernadat`:
//! `cetratus bench` ships it, and shipped code cannot depend on this dev-only crate. This crate
//! cannot depend on the bench crate either (only the binary may), so the tests get the same net
//! from the example the project already publishes, `examples/vernadat/vernadat.pnml`, through
//! `nets::vernadat`. A test of the bench crate checks that its builder and that file are the
//! same net, place for place and arc for arc, so the two cannot drift apart.

#[cfg(feature = "browser")]
pub mod browser;
pub mod counting;
pub mod http;
pub mod matiec;
pub mod modbus;
pub mod mqtt;
#[cfg(feature = "nets")]
pub mod nets;
pub mod opcua;
pub mod paths;
pub mod ports;
pub mod process;
#[cfg(feature = "programs")]
pub mod programs;
pub mod raw_mqtt;
pub mod stgen;

pub use counting::CountingAlloc;

/// The machine's stopwatch, as a PLC node uses it: tests of the watchdog and the candidate's
/// budget need real durations.
#[cfg(feature = "stopwatch")]
pub fn stopwatch() -> Box<dyn cetratus_runtime::Stopwatch> {
    cetratus_node::clock::MonotonicStopwatch::boxed()
}
