//! Cetratus PLC programs: a Petri net plus its interpretation.
//!
//! A [`Program`] is loaded from a TOML program file (which names a PNML net next to it), or from a
//! PNML file carrying the same TOML in a net-level `<toolspecific tool="cetratus">`. Loading resolves
//! every name, type-checks and compiles every guard, and checks the declared invariants at M0, so
//! a `Program` that exists is ready to run: [`Program::eval_guard`] and [`ActionState::apply`]
//! never allocate. The file format is documented in `docs/program-format.md`.

mod action;
mod error;
pub mod guard;
mod invariant;
mod program;
mod source;
mod value;

use std::path::Path;

pub use action::{Action, ActionState, Qualifier, Target};
pub use error::ProgramError;
pub use guard::{EvalCtx, EvalError, EvalErrorKind, Guard};
pub use invariant::{Invariant, InvariantViolation};
pub use program::{Program, DEFAULT_SCAN_PERIOD, TOOL};
pub use value::{Signal, Type, Value};

use cetratus_net::Net;

/// Reads a PNML net file.
fn load_net(path: &Path) -> Result<Net, ProgramError> {
    let label = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| ProgramError::Io {
        path: label.clone(),
        source,
    })?;
    read_net_str(&text, &label)
}

/// Reads PNML text.
fn read_net_str(text: &str, label: &str) -> Result<Net, ProgramError> {
    Ok(cetratus_net::pnml::read_str(text, label)?)
}
