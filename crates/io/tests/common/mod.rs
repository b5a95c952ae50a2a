//! Loading the example programs and connecting them to a twin, shared by the behaviour tests.

// Each test crate uses a different part of this module.
#![allow(dead_code)]

use std::path::Path;
use std::sync::Arc;

use cetratus_io::TwinDriver;
use cetratus_program::Program;
use cetratus_runtime::{Container, ScanCycle};
use cetratus_twin::{Plant, SECOND_US};

/// One virtual hour, in microseconds.
pub const HOUR_US: u64 = 3_600 * SECOND_US;

/// The Vernadat example program.
pub const VERNADAT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../examples/vernadat/vernadat.toml"
);

/// The Festo example program.
pub const FESTO: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../examples/festo/festo.toml"
);

/// The Vernadat program whose T13 no longer takes a free buffer slot.
pub const VERNADAT_BROKEN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../crates/program/tests/data/vernadat-broken.toml"
);

/// Loads a program file, naming it in the panic message if it does not load.
pub fn load(path: &str) -> Arc<Program> {
    Arc::new(cetratus_testkit::programs::load(Path::new(path)))
}

/// A scan cycle for `program` from its initial marking, and the twin wired to its signals by name.
pub fn connect<P: Plant>(program: &Arc<Program>, plant: P) -> (ScanCycle, TwinDriver<P>) {
    let io = TwinDriver::new(plant, program.inputs(), program.outputs())
        .expect("the example's signals are the twin's");
    (
        ScanCycle::new(
            Container::new(program.clone(), 0),
            cetratus_testkit::stopwatch(),
        ),
        io,
    )
}

/// The index of place `id` in `program`'s marking.
pub fn place(program: &Program, id: &str) -> usize {
    program
        .net()
        .place_by_id(id)
        .unwrap_or_else(|| panic!("the program has a place {id}"))
        .index()
}

/// The twin's counter `name`, which the twin must have.
pub fn counter<P: Plant>(plant: &P, name: &str) -> u64 {
    plant
        .counters()
        .get(name)
        .unwrap_or_else(|| panic!("the {} twin counts {name}", plant.name()))
}

/// Presses the Festo station's RESET at 100 ms (the table is brought to a position) and START at
/// 500 ms, as an operator does at power on.
pub fn start_festo<P: Plant>(station: &mut P) {
    station
        .press("RESET", 100_000)
        .expect("RESET is a button of the station");
    station
        .press("START", 500_000)
        .expect("START is a button of the station");
}
