//! Loading the example programs, with the file named in the panic when one does not load.

use std::path::Path;

use cetratus_program::Program;

/// The program of the file at `path`.
///
/// # Panics
///
/// When it does not load, naming the file and the error.
pub fn load(path: &Path) -> Program {
    Program::load(path).unwrap_or_else(|e| panic!("{} should load: {e}", path.display()))
}

/// The program of the file `rel` under `examples/`, e.g. `vernadat/u1.toml`.
pub fn example(rel: &str) -> Program {
    load(&crate::paths::example(rel))
}
