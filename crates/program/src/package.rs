//! Signed update packages (docs/design.md §1, §4): metadata + the new program + its state transformation
//! and projection, in one file signed with Ed25519.
//!
//! An [`UpdatePackage`] exists only once its signature has been checked against a [`TrustStore`]
//! and its program has loaded: the runtime never looks inside bytes it has not authenticated.
//! [`build_package`] makes one from a manifest; the formats are in `docs/package-format.md`.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use base64::engine::general_purpose::STANDARD as B64;
use base64::Engine as _;
use cetratus_net::{Net, SourcePos};
use ed25519_dalek::Signature;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use toml::Spanned;

mod build;

pub use crate::keys::{KeyPair, TrustStore, VerifyingKeyFile};
pub use build::{
    build_package, build_package_with, BuildReport, ImportError, ProgramImporter, ProgramText,
};

use crate::source::{NetOnly, Origin};
use crate::transform::{Between, DenseMatrix, Linear, Projection, StateTransform, TransformError};
use crate::{Program, ProgramError};

/// The `format` of a package file this version writes and reads.
pub const PACKAGE_FORMAT: &str = "cetratus-package/1";
/// The `format` of the signed payload inside a package.
const PAYLOAD_FORMAT: &str = "cetratus-payload/1";

/// Everything that can go wrong while building, reading, verifying or resolving a package.
#[derive(Debug, thiserror::Error)]
pub enum PackageError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A problem in a manifest, with its position.
    #[error("{pos}: {message}")]
    Manifest {
        /// Where (file:line:column).
        pos: SourcePos,
        /// What is wrong and what to do.
        message: String,
    },
    /// The manifest's transform or projection does not resolve against its programs.
    #[error("{path}: in [{section}]: {reason}")]
    ManifestTransform {
        /// The manifest.
        path: String,
        /// `transform` or `projection`.
        section: &'static str,
        /// Why (boxed: it is large, and this is a build-time error). Not a `source`: the
        /// message says it already, and a reader of the chain would see it twice.
        reason: Box<TransformError>,
    },
    /// The manifest's `[changes]` declare something that cannot be.
    #[error("{path}: [changes]: {message}")]
    ManifestChanges {
        /// The manifest.
        path: String,
        /// What, and what to write instead.
        message: String,
    },
    /// The bytes are not a package (not JSON of the right shape, truncated, bad base64).
    #[error("not a Cetratus update package: {reason}; a package is the single JSON file `cetratus package build` writes (was it truncated or edited?)")]
    Malformed {
        /// What was wrong.
        reason: String,
    },
    /// The package is in a format this version does not read.
    #[error("unsupported package format `{found}`; this version reads `{PACKAGE_FORMAT}`, rebuild the package with this version of cetratus")]
    Format {
        /// The format the file gives.
        found: String,
    },
    /// The package carries no signature and unsigned packages are not allowed.
    #[error("the package is not signed; build it with `cetratus package build --key FILE`, or allow unsigned packages explicitly (--allow-unsigned) on a bench that is not a plant")]
    Unsigned,
    /// The package is signed by a key the trust store does not hold.
    #[error("the package is signed by key {key_id}, which is not trusted here; copy the signer's public key file (key-id {key_id}) into the trust directory")]
    UnknownSigner {
        /// The key id the package names.
        key_id: String,
    },
    /// The signature does not verify: the payload was altered after signing.
    #[error("the signature by key {key_id} does not match the package contents: the package was altered or damaged after signing; rebuild it, or copy it again")]
    BadSignature {
        /// The key id the package names.
        key_id: String,
    },
    /// The program inside the package does not load.
    #[error("the package's program does not load: {0}")]
    Program(#[from] ProgramError),
    /// The transform or projection of the package does not resolve, or refused.
    #[error(transparent)]
    Transform(#[from] TransformError),
    /// The package was built against another program than the one running.
    #[error("the package was built against program {package_base}, but the running program is {running_name} {running_version} with hash {running}; rebuild the package against the running program, or force the load if you know the transform still fits")]
    BaseMismatch {
        /// `base_program_hash` of the package.
        package_base: String,
        /// Hash of the running program.
        running: String,
        /// Name of the running program.
        running_name: String,
        /// Version of the running program.
        running_version: String,
    },
    /// A key file is malformed, or cannot be written.
    #[error("{path}: {message}")]
    Key {
        /// The key file.
        path: String,
        /// What is wrong and what to do.
        message: String,
    },
}

/// Who made a package, of what, and against which program.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PackageMeta {
    /// Name of the update, e.g. "U.2 lubrication".
    pub name: String,
    /// Version of the update, free form.
    pub version: String,
    /// Who made it.
    pub author: String,
    /// Free text for people.
    pub description: String,
    /// When it was built, RFC 3339 in UTC.
    pub created: String,
    /// [`Program::hash_hex`] of the program the package was built against.
    pub base_program_hash: String,
    /// The update changes the cell's throughput on purpose, with no share declared: the older
    /// form of [`Changes::throughput_share`] = 0 (a twin validation does not hold the
    /// candidate's throughput against the primary's). Read from older packages; a build writes
    /// [`PackageMeta::changes`] instead.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub changes_throughput: bool,
    /// What the update changes on purpose, signed with it (`[changes]` of the manifest).
    #[serde(default, skip_serializing_if = "Changes::is_empty")]
    pub changes: Changes,
}

/// The changes an update declares it makes on purpose (docs/package-format.md, *Declared
/// changes*): the one place where divergence from the program it replaces is allowed. Twin
/// validation judges the candidate against them; the fleet rollout reads them too.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Changes {
    /// Outputs whose values may differ from those the old program drives.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub outputs: Vec<String>,
    /// The least share of the old program's production the update may drop to, from 0 to 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub throughput_share: Option<f64>,
    /// Structured Text variables whose values do not carry over by name and type
    /// (docs/package-format.md, *Variables of Structured Text*): old name → new name (a rename,
    /// same type), or old name → `""` (not carried: the new program starts it from its initial
    /// value, and a RETAIN value is given up on purpose).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub variables: std::collections::BTreeMap<String, String>,
}

impl Changes {
    /// Whether nothing is declared.
    pub fn is_empty(&self) -> bool {
        self.outputs.is_empty() && self.throughput_share.is_none() && self.variables.is_empty()
    }
}

impl PackageMeta {
    /// The least share of the old program's production the update declares it may drop to:
    /// its `[changes] throughput_share`, or 0 for the older `changes_throughput = true`.
    pub fn declared_share(&self) -> Option<f64> {
        self.changes
            .throughput_share
            .or(self.changes_throughput.then_some(0.0))
    }

    /// What the update declares it changes on purpose, the older `changes_throughput` read as
    /// a share of 0; `None` when it declares nothing.
    pub fn declared_changes(&self) -> Option<Changes> {
        let changes = Changes {
            outputs: self.changes.outputs.clone(),
            throughput_share: self.declared_share(),
            variables: self.changes.variables.clone(),
        };
        (!changes.is_empty()).then_some(changes)
    }

    /// Whether the update declares that `output` may differ from the old program's.
    pub fn may_differ(&self, output: &str) -> bool {
        self.changes.outputs.iter().any(|o| o == output)
    }
}

/// A transformation or projection as the manifest declares it, before it meets the nets.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum TransformSpec {
    /// Generated from place ids (docs/design.md §1, the paper's future work).
    Generated {
        /// Transform only: removed old place id -> new place id that receives its tokens.
        #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
        removed: BTreeMap<String, String>,
    },
    /// A dense matrix naming its row and column place ids.
    Dense {
        /// Row place ids, in the row net's declaration order.
        rows: Vec<String>,
        /// Column place ids, in the column net's declaration order.
        cols: Vec<String>,
        /// `matrix[row][col]`.
        matrix: Vec<Vec<i64>>,
        /// One per row; absent means zeros.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        base: Option<Vec<i64>>,
    },
    /// Nonzero entries by place id.
    Sparse {
        /// `to` (row place) <- `coef` · `from` (column place).
        #[serde(default)]
        entries: Vec<SparseEntry>,
        /// Row place id -> base (absent rows are 0).
        #[serde(default)]
        base: BTreeMap<String, i64>,
        /// Adds `P <- 1·P` for every place both nets have, unless an entry already gives that pair.
        #[serde(default)]
        identity_on_kept: bool,
    },
}

impl Default for TransformSpec {
    fn default() -> Self {
        TransformSpec::Generated {
            removed: BTreeMap::new(),
        }
    }
}

impl TransformSpec {
    /// `generated`, `dense` or `sparse`.
    pub fn kind(&self) -> &'static str {
        match self {
            TransformSpec::Generated { .. } => "generated",
            TransformSpec::Dense { .. } => "dense",
            TransformSpec::Sparse { .. } => "sparse",
        }
    }
}

/// One nonzero coefficient of a sparse matrix.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SparseEntry {
    /// The row place id.
    pub to: String,
    /// The column place id.
    pub from: String,
    /// The coefficient; 1 when absent.
    #[serde(default = "one")]
    pub coef: i64,
}

fn one() -> i64 {
    1
}

/// The signed part of a package.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Payload {
    format: String,
    meta: PackageMeta,
    program_toml: String,
    program_pnml: String,
    transform: TransformSpec,
    #[serde(default)]
    projection: Option<TransformSpec>,
}

/// The file: the payload (base64, so its exact bytes survive) and a signature over them.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Envelope {
    format: String,
    payload: String,
    #[serde(default)]
    signature: Option<SignatureBlock>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SignatureBlock {
    key_id: String,
    ed25519: String,
}

/// A package whose signature has been verified and whose program has loaded.
#[derive(Clone, Debug)]
pub struct UpdatePackage {
    meta: PackageMeta,
    program: Arc<Program>,
    transform: TransformSpec,
    projection: Option<TransformSpec>,
    signer: Option<String>,
}

/// A package resolved against the running program: ready for the Updater.
#[derive(Clone, Debug)]
pub struct ResolvedUpdate {
    /// The new program.
    pub program: Arc<Program>,
    /// `M_new = ST·M_old + ST_base`.
    pub transform: StateTransform,
    /// `Π·M_cand + Π_base`, the candidate's marking seen in the running program's places.
    pub projection: Projection,
    /// The package's metadata.
    pub meta: PackageMeta,
}

/// Whether a package without a signature may load: only when the local configuration says so
/// (`allow_unsigned`), never by a command.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Unsigned {
    /// An unsigned package is refused.
    #[default]
    Refused,
    /// An unsigned package loads.
    Allowed,
}

impl Unsigned {
    /// [`Unsigned::Allowed`] when `allowed` (a configuration's `allow_unsigned`), else refused.
    pub fn allowed_if(allowed: bool) -> Self {
        if allowed {
            Unsigned::Allowed
        } else {
            Unsigned::Refused
        }
    }
}

/// Whether a package built against another program than the running one may load.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OtherBase {
    /// Refused: the package's `base_program_hash` must be the running program's.
    #[default]
    Refused,
    /// Resolved against the running program anyway (its transform must still fit both nets).
    Forced,
}

impl OtherBase {
    /// [`OtherBase::Forced`] when `forced` (a command line's `--force`), else refused.
    pub fn forced_if(forced: bool) -> Self {
        if forced {
            OtherBase::Forced
        } else {
            OtherBase::Refused
        }
    }
}

impl UpdatePackage {
    /// Parses a package file, checks its signature against the trusted keys (an unsigned package
    /// passes only when `unsigned` allows it), then loads its program.
    pub fn verify(
        bytes: &[u8],
        trust: &TrustStore,
        unsigned: Unsigned,
    ) -> Result<UpdatePackage, PackageError> {
        let (envelope, payload_bytes) = open(bytes)?;
        // The signature is checked before the payload is parsed: nothing unauthenticated is
        // interpreted beyond the envelope.
        let signer = match &envelope.signature {
            None if unsigned == Unsigned::Allowed => None,
            None => return Err(PackageError::Unsigned),
            Some(sig) => {
                let Some(key) = trust.keys.get(&sig.key_id) else {
                    return Err(PackageError::UnknownSigner {
                        key_id: sig.key_id.clone(),
                    });
                };
                let bad = || PackageError::BadSignature {
                    key_id: sig.key_id.clone(),
                };
                let raw = B64.decode(sig.ed25519.trim()).map_err(|_| bad())?;
                let raw: [u8; 64] = raw.as_slice().try_into().map_err(|_| bad())?;
                key.verify_strict(&payload_bytes, &Signature::from_bytes(&raw))
                    .map_err(|_| bad())?;
                Some(sig.key_id.clone())
            }
        };
        let payload = read_payload(&payload_bytes)?;
        let program = load_embedded(&payload)?;
        Ok(UpdatePackage {
            meta: payload.meta,
            program: Arc::new(program),
            transform: payload.transform,
            projection: payload.projection,
            signer,
        })
    }

    /// The metadata.
    pub fn meta(&self) -> &PackageMeta {
        &self.meta
    }
    /// The new program.
    pub fn program(&self) -> &Arc<Program> {
        &self.program
    }
    /// The key id that signed the package, `None` when it was unsigned and that was allowed.
    pub fn signer(&self) -> Option<&str> {
        self.signer.as_deref()
    }
    /// The transformation as declared.
    pub fn transform_spec(&self) -> &TransformSpec {
        &self.transform
    }
    /// The projection as declared, `None` when it is generated.
    pub fn projection_spec(&self) -> Option<&TransformSpec> {
        self.projection.as_ref()
    }
    /// SHA-256 of a package file, lowercase hex: its identity in listings and logs. Not kept in
    /// the verified package: the Updater never needs it, and hashing the whole file is a quarter
    /// of the cost of a setup.
    pub fn file_hash_hex(bytes: &[u8]) -> String {
        hex::encode(Sha256::digest(bytes))
    }

    /// Resolves the package against the running program: refuses one built against another
    /// program unless `base` forces it, then builds the state transform and the projection.
    pub fn resolve(&self, old: &Program, base: OtherBase) -> Result<ResolvedUpdate, PackageError> {
        let running = old.hash_hex();
        if base == OtherBase::Refused && self.meta.base_program_hash != running {
            return Err(PackageError::BaseMismatch {
                package_base: self.meta.base_program_hash.clone(),
                running: running.to_string(),
                running_name: old.name().to_string(),
                running_version: old.version().to_string(),
            });
        }
        let transform = resolve_transform(&self.transform, old, &self.program)?;
        let projection = resolve_projection(self.projection.as_ref(), old, &self.program)?;
        Ok(ResolvedUpdate {
            program: Arc::clone(&self.program),
            transform,
            projection,
            meta: self.meta.clone(),
        })
    }
}

/// What a package says about itself, read without checking its signature (for `inspect`).
#[derive(Clone, Debug)]
pub struct UnverifiedPackage {
    /// The metadata.
    pub meta: PackageMeta,
    /// The new program.
    pub program: Arc<Program>,
    /// The transformation as declared.
    pub transform: TransformSpec,
    /// The projection as declared, `None` when it is generated.
    pub projection: Option<TransformSpec>,
    /// The key id the signature claims (not checked), `None` when unsigned.
    pub claimed_signer: Option<String>,
    /// SHA-256 of the package file, lowercase hex.
    pub hash_hex: String,
}

impl UnverifiedPackage {
    /// The state transform and the projection the package declares, resolved against `old` as
    /// [`UpdatePackage::resolve`] would with [`OtherBase::Forced`]: for showing the matrices. The signature is
    /// not checked, so no [`ResolvedUpdate`] comes out of it: nothing here can be loaded.
    pub fn resolve_for_display(
        &self,
        old: &Program,
    ) -> Result<(StateTransform, Projection), PackageError> {
        Ok((
            resolve_transform(&self.transform, old, &self.program)?,
            resolve_projection(self.projection.as_ref(), old, &self.program)?,
        ))
    }
}

/// Reads a package without checking its signature: for showing what it claims, never for
/// loading it.
pub fn inspect(bytes: &[u8]) -> Result<UnverifiedPackage, PackageError> {
    let (envelope, payload_bytes) = open(bytes)?;
    let payload = read_payload(&payload_bytes)?;
    let program = load_embedded(&payload)?;
    Ok(UnverifiedPackage {
        meta: payload.meta,
        program: Arc::new(program),
        transform: payload.transform,
        projection: payload.projection,
        claimed_signer: envelope.signature.map(|s| s.key_id),
        hash_hex: hex::encode(Sha256::digest(bytes)),
    })
}

fn open(bytes: &[u8]) -> Result<(Envelope, Vec<u8>), PackageError> {
    let malformed = |reason: String| PackageError::Malformed { reason };
    let envelope: Envelope =
        serde_json::from_slice(bytes).map_err(|e| malformed(format!("{e}")))?;
    if envelope.format != PACKAGE_FORMAT {
        return Err(PackageError::Format {
            found: envelope.format,
        });
    }
    let payload = B64
        .decode(envelope.payload.trim())
        .map_err(|e| malformed(format!("the payload is not valid base64 ({e})")))?;
    Ok((envelope, payload))
}

fn read_payload(bytes: &[u8]) -> Result<Payload, PackageError> {
    let payload: Payload = serde_json::from_slice(bytes).map_err(|e| PackageError::Malformed {
        reason: format!("the payload is not readable ({e})"),
    })?;
    if payload.format != PAYLOAD_FORMAT {
        return Err(PackageError::Format {
            found: payload.format,
        });
    }
    Ok(payload)
}

/// Loads the program a payload carries, exactly as the PLC will.
fn load_embedded(p: &Payload) -> Result<Program, PackageError> {
    let net = crate::read_net_str(&p.program_pnml, "package:program.pnml")?;
    Ok(Program::from_sources(
        &p.program_toml,
        "package:program.toml",
        net,
    )?)
}

fn resolve_transform(
    spec: &TransformSpec,
    old: &Program,
    new: &Program,
) -> Result<StateTransform, TransformError> {
    resolve(spec, old.net(), new.net(), |removed| {
        StateTransform::generated(old, new, removed)
    })
}

fn resolve_projection(
    spec: Option<&TransformSpec>,
    old: &Program,
    new: &Program,
) -> Result<Projection, TransformError> {
    let (on, nn) = (old.net().as_ref(), new.net().as_ref());
    match spec {
        None => Projection::generated(on, nn),
        Some(spec) => resolve(spec, on, nn, |removed| match removed.keys().next() {
            None => Projection::generated(on, nn),
            Some(id) => Err(TransformError::RemovedIsKept { id: id.clone() }),
        }),
    }
}

/// A spec as a map of kind `M`: the explicit forms read alike for both kinds, the generated
/// form is each kind's own.
fn resolve<M: Between>(
    spec: &TransformSpec,
    on: &Net,
    nn: &Net,
    generated: impl FnOnce(&BTreeMap<String, String>) -> Result<M, TransformError>,
) -> Result<M, TransformError> {
    match spec {
        TransformSpec::Generated { removed } => generated(removed),
        TransformSpec::Dense {
            rows,
            cols,
            matrix,
            base,
        } => {
            let zeros;
            let base = match base {
                Some(b) => b.as_slice(),
                None => {
                    zeros = vec![0; rows.len()];
                    &zeros
                }
            };
            M::build(on, nn, |role, r, c| {
                Linear::dense(role, r, c, rows, cols, matrix, base)
            })
        }
        TransformSpec::Sparse {
            entries,
            base,
            identity_on_kept,
        } => M::build(on, nn, |role, r, c| {
            let entries = triples(entries, *identity_on_kept, r, c);
            Linear::sparse(role, r, c, &entries, base)
        }),
    }
}

/// The entries as (row, column, coefficient), plus the identity on places both nets have.
fn triples(
    entries: &[SparseEntry],
    identity: bool,
    row_net: &Net,
    col_net: &Net,
) -> Vec<(String, String, i64)> {
    let mut out: Vec<(String, String, i64)> = entries
        .iter()
        .map(|e| (e.to.clone(), e.from.clone(), e.coef))
        .collect();
    if identity {
        for p in row_net.places() {
            let given = entries.iter().any(|e| e.to == p.id && e.from == p.id);
            if !given && col_net.place_by_id(&p.id).is_some() {
                out.push((p.id.clone(), p.id.clone(), 1));
            }
        }
    }
    out
}
