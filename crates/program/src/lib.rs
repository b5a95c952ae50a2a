//! Cetratus PLC programs: a Petri net plus its interpretation.
//!
//! A [`Program`] is loaded from a TOML program file (which names a PNML net next to it), or from a
//! PNML file carrying the same TOML in a net-level `<toolspecific tool="cetratus">`. Loading resolves
//! every name, type-checks and compiles every guard, and checks the declared invariants at M0, so
//! a `Program` that exists is ready to run: [`Program::eval_guard`] and [`ActionState::apply`]
//! never allocate. The file format is documented in `docs/program-format.md`.
//!
//! Live updates: [`transform`] holds the state transformation `M_new = ST·M_old + ST_base` and the
//! projection used to measure drift; [`package`] holds the signed update package that carries a new
//! program and its transformation (`docs/package-format.md`).

#![warn(missing_docs)]

mod action;
pub mod body;
pub mod duration;
mod error;
pub mod guard;
mod invariant;
pub mod keys;
pub mod package;
mod program;
mod source;
pub mod st;
pub mod transform;
mod value;

use std::path::Path;

pub use action::{ActError, Action, ActionState, Qualifier, SoleBody, Target};
pub use body::{Body, BodyError, Statement};
pub use cetratus_st::Work;
pub use error::ProgramError;
pub use guard::{EvalCtx, EvalError, EvalErrorKind, Guard};
pub use invariant::{Invariant, InvariantViolation};
pub use package::{
    build_package, BuildReport, Changes, KeyPair, OtherBase, PackageError, PackageMeta,
    ProgramImporter, ResolvedUpdate, TransformSpec, TrustStore, Unsigned, UpdatePackage,
    VerifyingKeyFile,
};
pub use program::{Program, Watchdog, DEFAULT_SCAN_PERIOD, TOOL};
pub use source::{toml_text, NotUtf8};
pub use transform::{DenseMatrix, Derivation, Projection, StateTransform, TransformError};
pub use value::{Signal, Type, Value};

use cetratus_net::Net;

/// Reads a PNML net file (UTF-8 or ISO-8859-1, as the net crate accepts).
fn load_net(path: &Path) -> Result<Net, ProgramError> {
    match cetratus_net::pnml::read_file(path) {
        Ok(net) => Ok(net),
        // Kept apart so the caller can point at the `net =` line that named the file.
        Err(cetratus_net::NetError::Io { path, source }) => Err(ProgramError::Io { path, source }),
        Err(e) => Err(e.into()),
    }
}

/// Reads PNML text.
fn read_net_str(text: &str, label: &str) -> Result<Net, ProgramError> {
    Ok(cetratus_net::pnml::read_str(text, label)?)
}
