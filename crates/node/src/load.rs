//! The one path by which a package file becomes a load, however it comes (a command over MQTT, a
//! scripted `--at`, the demo): verified against the trusted keys, resolved against the running
//! program and built ([`LoadPolicy::build`]), then gated by the analysis ([`LoadPolicy::gate`]),
//! whose verdict the update carries from then on. Both steps run on the thread of whoever
//! prepares, never on the scan thread, which only installs what comes out.

use cetratus_program::{OtherBase, TrustStore, Unsigned};
use cetratus_runtime::{PrepareError, PreparedUpdate, UpdateContext};

use crate::gate::{self, GatePolicy};

/// What a load accepts, from the local configuration: the keys packages are signed with, whether
/// an unsigned one may load, and the analysis gate. The default trusts no key, refuses unsigned
/// packages and gates with the default policy.
#[derive(Clone, Debug, Default)]
pub struct LoadPolicy {
    /// The package keys.
    pub trust: TrustStore,
    /// Whether an unsigned package may load (`allow_unsigned`).
    pub unsigned: Unsigned,
    /// The analysis gate.
    pub gate: GatePolicy,
}

/// Why a package does not load.
#[derive(Debug, thiserror::Error)]
pub enum LoadRefusal {
    /// The package could not be verified, resolved or built.
    #[error(transparent)]
    Package(#[from] PrepareError),
    /// The analysis gate refused the candidate; the text names the findings.
    #[error("{0}")]
    Gate(String),
    /// The package file could not be read.
    #[error("cannot read the package file: {source}")]
    Unreadable {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

impl LoadPolicy {
    /// Verifies `bytes`, resolves them against the running program of `ctx` and builds the
    /// candidate: everything but the gate.
    pub fn build(&self, ctx: &UpdateContext, bytes: &[u8]) -> Result<PreparedUpdate, LoadRefusal> {
        Ok(ctx.prepare_package(bytes, &self.trust, self.unsigned, OtherBase::Refused)?)
    }

    /// Runs the analysis gate on `update` from the primary's marking in `ctx`: refused, or the
    /// update with the gate's verdict attached.
    pub fn gate(
        &self,
        ctx: &UpdateContext,
        mut update: PreparedUpdate,
    ) -> Result<PreparedUpdate, LoadRefusal> {
        let outcome = gate::run(ctx, &update, &self.gate);
        if let Some(refusal) = outcome.refusal {
            return Err(LoadRefusal::Gate(refusal));
        }
        update.add_verdict(outcome.verdict);
        Ok(update)
    }

    /// Reads the package file `path`, then [`LoadPolicy::prepare`]s it.
    pub fn prepare_file(
        &self,
        ctx: &UpdateContext,
        path: &std::path::Path,
    ) -> Result<PreparedUpdate, LoadRefusal> {
        let bytes = std::fs::read(path).map_err(|source| LoadRefusal::Unreadable {
            path: path.display().to_string(),
            source,
        })?;
        self.prepare(ctx, &bytes)
    }

    /// [`LoadPolicy::build`], then [`LoadPolicy::gate`], against the same context.
    pub fn prepare(
        &self,
        ctx: &UpdateContext,
        bytes: &[u8],
    ) -> Result<PreparedUpdate, LoadRefusal> {
        self.gate(ctx, self.build(ctx, bytes)?)
    }
}
