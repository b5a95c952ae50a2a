//! Signed update packages (DESIGN §1, §4): metadata + the new program + its state transformation
//! and projection, in one file signed with Ed25519.
//!
//! An [`UpdatePackage`] exists only once its signature has been checked against a [`TrustStore`]
//! and its program has loaded: the runtime never looks inside bytes it has not authenticated.
//! [`build_package`] makes one from a manifest; the formats are in `docs/package-format.md`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use base64::engine::general_purpose::STANDARD as B64;
use base64::Engine as _;
use cetratus_net::SourcePos;
use ed25519_dalek::{Signature, Signer, SigningKey, VerifyingKey};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use toml::Spanned;
use zeroize::Zeroizing;

use crate::source::{NetOnly, Origin};
use crate::transform::{DenseMatrix, Projection, StateTransform, TransformError};
use crate::{Program, ProgramError};

/// The `format` of a package file this version writes and reads.
pub const PACKAGE_FORMAT: &str = "cetratus-package/1";
/// The `format` of the signed payload inside a package.
const PAYLOAD_FORMAT: &str = "cetratus-payload/1";
const SECRET_HEADER: &str = "cetratus-secret-key/1";
const PUBLIC_HEADER: &str = "cetratus-public-key/1";

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
    #[error("{path}: in [{section}]: {source}")]
    ManifestTransform {
        /// The manifest.
        path: String,
        /// `transform` or `projection`.
        section: &'static str,
        /// Why (boxed: it is large, and this is a build-time error).
        source: Box<TransformError>,
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
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
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
}

/// A transformation or projection as the manifest declares it, before it meets the nets.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum TransformSpec {
    /// Generated from place ids (DESIGN §1, the paper's future work).
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

impl UpdatePackage {
    /// Parses a package file, checks its signature against the trusted keys (an unsigned package
    /// passes only when `allow_unsigned`), then loads its program.
    pub fn verify(
        bytes: &[u8],
        trust: &TrustStore,
        allow_unsigned: bool,
    ) -> Result<UpdatePackage, PackageError> {
        let (envelope, payload_bytes) = open(bytes)?;
        // The signature is checked before the payload is parsed: nothing unauthenticated is
        // interpreted beyond the envelope.
        let signer = match &envelope.signature {
            None if allow_unsigned => None,
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
    /// program unless `force`, then builds the state transform and the projection.
    pub fn resolve(&self, old: &Program, force: bool) -> Result<ResolvedUpdate, PackageError> {
        let running = old.hash_hex();
        if !force && self.meta.base_program_hash != running {
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
    let (on, nn) = (old.net().as_ref(), new.net().as_ref());
    match spec {
        TransformSpec::Generated { removed } => StateTransform::generated(old, new, removed),
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
            StateTransform::dense(on, nn, rows, cols, matrix, base)
        }
        TransformSpec::Sparse {
            entries,
            base,
            identity_on_kept,
        } => StateTransform::sparse(on, nn, &triples(entries, *identity_on_kept, nn, on), base),
    }
}

fn resolve_projection(
    spec: Option<&TransformSpec>,
    old: &Program,
    new: &Program,
) -> Result<Projection, TransformError> {
    let (on, nn) = (old.net().as_ref(), new.net().as_ref());
    match spec {
        None => Ok(Projection::generated(on, nn)),
        Some(TransformSpec::Generated { removed }) => match removed.keys().next() {
            None => Ok(Projection::generated(on, nn)),
            Some(id) => Err(TransformError::RemovedIsKept { id: id.clone() }),
        },
        Some(TransformSpec::Dense {
            rows,
            cols,
            matrix,
            base,
        }) => {
            let zeros;
            let base = match base {
                Some(b) => b.as_slice(),
                None => {
                    zeros = vec![0; rows.len()];
                    &zeros
                }
            };
            Projection::dense(on, nn, rows, cols, matrix, base)
        }
        Some(TransformSpec::Sparse {
            entries,
            base,
            identity_on_kept,
        }) => Projection::sparse(on, nn, &triples(entries, *identity_on_kept, on, nn), base),
    }
}

/// The entries as (row, column, coefficient), plus the identity on places both nets have.
fn triples(
    entries: &[SparseEntry],
    identity: bool,
    row_net: &cetratus_net::Net,
    col_net: &cetratus_net::Net,
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

/// The trusted public keys, by key id.
#[derive(Clone, Debug, Default)]
pub struct TrustStore {
    keys: BTreeMap<String, VerifyingKey>,
}

impl TrustStore {
    /// A store that trusts nobody.
    pub fn empty() -> Self {
        Self::default()
    }

    /// Every `*.pub` file in a directory; a malformed one is an error, not skipped, since a
    /// key someone meant to trust would otherwise be silently ignored.
    pub fn load_dir(dir: &Path) -> Result<Self, PackageError> {
        let io = |source| PackageError::Io {
            path: dir.display().to_string(),
            source,
        };
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(io)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "pub") && p.is_file())
            .collect();
        files.sort();
        let mut store = Self::empty();
        for f in files {
            store.add(VerifyingKeyFile::load(&f)?);
        }
        Ok(store)
    }

    /// Trusts one more key.
    pub fn add(&mut self, key: VerifyingKeyFile) {
        self.keys.insert(key.key_id, key.key);
    }

    /// Trusts every key `other` trusts as well.
    pub fn merge(&mut self, other: &TrustStore) {
        for (id, key) in &other.keys {
            self.keys.insert(id.clone(), *key);
        }
    }

    /// How many keys are trusted.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// True when no key is trusted.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// The trusted key ids, sorted.
    pub fn key_ids(&self) -> impl Iterator<Item = &str> {
        self.keys.keys().map(String::as_str)
    }
}

/// The key id of a public key: the first 8 bytes of its SHA-256, in hex.
fn key_id_of(key: &VerifyingKey) -> String {
    hex::encode(&Sha256::digest(key.as_bytes())[..8])
}

/// A public key file: key id and Ed25519 public key.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VerifyingKeyFile {
    key_id: String,
    key: VerifyingKey,
}

impl VerifyingKeyFile {
    /// The Ed25519 public key (also used for operator command keys).
    pub fn verifying_key(&self) -> &VerifyingKey {
        &self.key
    }

    /// Reads a public key file.
    pub fn load(path: &Path) -> Result<Self, PackageError> {
        let label = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| PackageError::Io {
            path: label.clone(),
            source,
        })?;
        Self::parse(&text, &label)
    }

    /// Parses the text of a public key file (`label` names it in messages).
    pub fn parse(text: &str, label: &str) -> Result<Self, PackageError> {
        let fields = key_fields(text, label, PUBLIC_HEADER)?;
        let raw = field_bytes::<32>(&fields, "ed25519", label)?;
        let key = VerifyingKey::from_bytes(&raw)
            .map_err(|_| key_err(label, "`ed25519` is not a valid Ed25519 public key"))?;
        let key_id = key_id_of(&key);
        check_key_id(&fields, &key_id, label)?;
        Ok(VerifyingKeyFile { key_id, key })
    }

    /// The key id.
    pub fn key_id(&self) -> &str {
        &self.key_id
    }

    /// The file's text.
    pub fn to_text(&self) -> String {
        format!(
            "# Cetratus public key: copy it into the trust directory of each PLC that should accept\n\
             # packages signed with the matching secret key.\n\
             {PUBLIC_HEADER}\nkey-id {}\ned25519 {}\n",
            self.key_id,
            B64.encode(self.key.as_bytes())
        )
    }
}

/// An Ed25519 signing key and its key id.
///
/// The secret does not outlive the value: `SigningKey` wipes itself when dropped (ed25519-dalek's
/// `zeroize` feature), and every buffer that holds the seed on the way to or from a key file
/// (`save`, `load`, `try_generate`) is wiped too.
pub struct KeyPair {
    key: SigningKey,
}

impl std::fmt::Debug for KeyPair {
    /// Shows the key id only: a secret does not belong in logs.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KeyPair")
            .field("key_id", &self.key_id())
            .finish_non_exhaustive()
    }
}

impl KeyPair {
    /// The Ed25519 signing key (also used to sign operator commands).
    pub fn signing_key(&self) -> &SigningKey {
        &self.key
    }

    /// A fresh key from the operating system's random source.
    ///
    /// # Panics
    /// When the OS has no random source to give, as `OsRng` does; [`KeyPair::try_generate`]
    /// returns that as an error instead.
    pub fn generate() -> Self {
        match Self::try_generate() {
            Ok(k) => k,
            Err(e) => panic!("{e}"),
        }
    }

    /// A fresh key from the operating system's random source, or why there is none.
    pub fn try_generate() -> Result<Self, PackageError> {
        // `Zeroizing` rather than a final `fill(0)`: the compiler may drop a store to memory that is
        // never read again, and an early return would skip it.
        let mut seed = Zeroizing::new([0u8; 32]);
        getrandom::fill(seed.as_mut()).map_err(|e| PackageError::Key {
            path: "<new key>".into(),
            message: format!("the operating system gave no random bytes ({e})"),
        })?;
        Ok(KeyPair {
            key: SigningKey::from_bytes(&seed),
        })
    }

    /// The key id: the first 8 bytes of SHA-256 of the public key, in hex.
    pub fn key_id(&self) -> String {
        key_id_of(&self.key.verifying_key())
    }

    /// The public half, as written to the `.pub` file.
    pub fn public(&self) -> VerifyingKeyFile {
        let key = self.key.verifying_key();
        VerifyingKeyFile {
            key_id: key_id_of(&key),
            key,
        }
    }

    /// The path of the public key file that goes with a secret key file: `path` + `.pub`.
    pub fn public_path(path: &Path) -> PathBuf {
        let mut s = path.as_os_str().to_owned();
        s.push(".pub");
        PathBuf::from(s)
    }

    /// Writes the secret key to `path` (mode 0600 on Unix) and the public key to `path.pub`;
    /// refuses to overwrite either, since losing a secret key strands every PLC that trusts it.
    pub fn save(&self, path: &Path) -> Result<(), PackageError> {
        let seed_b64 = Zeroizing::new(B64.encode(Zeroizing::new(self.key.to_bytes())));
        // One buffer large enough from the start (the file is under 200 bytes), so that no
        // reallocation leaves a copy of the seed behind; wiped when dropped.
        let mut secret = Zeroizing::new(String::with_capacity(256));
        let _ = write!(
            secret,
            "# Cetratus secret signing key: keep it private, never copy it to a PLC.\n\
             {SECRET_HEADER}\nkey-id {}\ned25519-seed {}\n",
            self.key_id(),
            seed_b64.as_str()
        );
        let public_path = Self::public_path(path);
        for p in [path, public_path.as_path()] {
            if p.exists() {
                return Err(key_err(
                    &p.display().to_string(),
                    "already exists; remove it or choose another path",
                ));
            }
        }
        write_new(path, secret.as_bytes(), true)?;
        write_new(&public_path, self.public().to_text().as_bytes(), false)
    }

    /// Reads a secret key file.
    pub fn load(path: &Path) -> Result<Self, PackageError> {
        let label = path.display().to_string();
        // `read_to_string` sizes its buffer from the file's length, so the text is read into one
        // allocation, which is wiped on drop; the fields borrow from it rather than copy it.
        let text = std::fs::read_to_string(path).map_err(|source| PackageError::Io {
            path: label.clone(),
            source,
        })?;
        let text = Zeroizing::new(text);
        let fields = key_fields(&text, &label, SECRET_HEADER)?;
        let seed = field_bytes::<32>(&fields, "ed25519-seed", &label)?;
        let key = SigningKey::from_bytes(&seed);
        check_key_id(&fields, &key_id_of(&key.verifying_key()), &label)?;
        Ok(KeyPair { key })
    }

    /// Signs bytes.
    fn sign(&self, bytes: &[u8]) -> Signature {
        self.key.sign(bytes)
    }
}

fn write_new(path: &Path, bytes: &[u8], secret: bool) -> Result<(), PackageError> {
    use std::io::Write;
    let io = |source| PackageError::Io {
        path: path.display().to_string(),
        source,
    };
    let mut opts = std::fs::OpenOptions::new();
    opts.write(true).create_new(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        opts.mode(if secret { 0o600 } else { 0o644 });
    }
    #[cfg(not(unix))]
    let _ = secret;
    let mut f = opts.open(path).map_err(io)?;
    f.write_all(bytes).map_err(io)
}

fn key_err(label: &str, message: impl Into<String>) -> PackageError {
    PackageError::Key {
        path: label.to_string(),
        message: message.into(),
    }
}

/// The `name value` lines of a key file after its header; `#` lines and blank lines are comments.
/// Borrowed from `text`, so that a secret key's seed is not copied out of its wiped buffer.
fn key_fields<'t>(
    text: &'t str,
    label: &str,
    header: &str,
) -> Result<BTreeMap<&'t str, &'t str>, PackageError> {
    let mut lines = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'));
    match lines.next() {
        Some(h) if h == header => {}
        Some(h) if h == SECRET_HEADER || h == PUBLIC_HEADER => {
            return Err(key_err(
                label,
                format!("this is a `{h}` file, expected a `{header}` file"),
            ))
        }
        _ => {
            return Err(key_err(
                label,
                format!("not a Cetratus key file: its first line should be `{header}`"),
            ))
        }
    }
    let mut fields = BTreeMap::new();
    for l in lines {
        let (k, v) = l.split_once(char::is_whitespace).unwrap_or((l, ""));
        fields.insert(k, v.trim());
    }
    Ok(fields)
}

/// The base64 field `name`, decoded to exactly `N` bytes, in buffers that are wiped on drop since
/// the field may be a secret seed.
fn field_bytes<const N: usize>(
    fields: &BTreeMap<&str, &str>,
    name: &str,
    label: &str,
) -> Result<Zeroizing<[u8; N]>, PackageError> {
    let v = fields
        .get(name)
        .ok_or_else(|| key_err(label, format!("no `{name}` line")))?;
    let raw = Zeroizing::new(
        B64.decode(v)
            .map_err(|_| key_err(label, format!("`{name}` is not base64")))?,
    );
    let mut out = Zeroizing::new([0u8; N]);
    if raw.len() != N {
        return Err(key_err(
            label,
            format!("`{name}` must be {N} bytes, found {}", raw.len()),
        ));
    }
    out.copy_from_slice(&raw);
    Ok(out)
}

fn check_key_id(
    fields: &BTreeMap<&str, &str>,
    actual: &str,
    label: &str,
) -> Result<(), PackageError> {
    match fields.get("key-id") {
        Some(&id) if id == actual => Ok(()),
        Some(id) => Err(key_err(
            label,
            format!(
                "`key-id {id}` does not match its key, whose id is {actual}; the file was edited"
            ),
        )),
        None => Err(key_err(label, "no `key-id` line")),
    }
}

/// The package manifest (`*.package.toml`).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    package: ManifestPackage,
    #[serde(default)]
    transform: TransformSpec,
    #[serde(default)]
    projection: Option<TransformSpec>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestPackage {
    name: Spanned<String>,
    version: Spanned<String>,
    #[serde(default)]
    author: String,
    #[serde(default)]
    description: String,
    program: Spanned<String>,
    base: Spanned<String>,
}

/// What [`build_package`] made, for printing.
#[derive(Clone, Debug)]
pub struct BuildReport {
    /// The metadata written.
    pub meta: PackageMeta,
    /// Name of the new program.
    pub program_name: String,
    /// Version of the new program.
    pub program_version: String,
    /// [`Program::hash_hex`] of the new program.
    pub program_hash: String,
    /// Name and version of the base program.
    pub base_program: String,
    /// `generated`, `dense` or `sparse`.
    pub transform_kind: &'static str,
    /// The transformation resolved against the base program (rows: new places; columns: old).
    pub transform: DenseMatrix,
    /// `generated` when the manifest declares none, else its kind.
    pub projection_kind: &'static str,
    /// The projection resolved against the base program (rows: old places; columns: new).
    pub projection: DenseMatrix,
    /// The key id that signed it, `None` when unsigned.
    pub signer: Option<String>,
    /// Things that do not stop the build but deserve a look.
    pub warnings: Vec<String>,
}

/// Builds a package from a manifest, signed with `key` (unsigned when `None`), stamped with the
/// current time.
pub fn build_package(
    manifest_path: &Path,
    key: Option<&KeyPair>,
) -> Result<(Vec<u8>, BuildReport), PackageError> {
    // The one clock read of this crate, on the tooling side: packages are built by people, not
    // by the scan engine, and the time only goes into `created`.
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    build_package_at(manifest_path, key, now)
}

/// [`build_package`] with `created` set from seconds since the Unix epoch, for reproducible
/// builds (e.g. from `SOURCE_DATE_EPOCH`).
pub fn build_package_at(
    manifest_path: &Path,
    key: Option<&KeyPair>,
    created_unix_secs: u64,
) -> Result<(Vec<u8>, BuildReport), PackageError> {
    let label = manifest_path.display().to_string();
    let text = std::fs::read_to_string(manifest_path).map_err(|source| PackageError::Io {
        path: label.clone(),
        source,
    })?;
    let o = Origin::new(&text, &label);
    let at = |offset: usize, message: String| PackageError::Manifest {
        pos: o.pos(offset),
        message,
    };
    let m: Manifest = toml::from_str(&text).map_err(|e| {
        at(
            e.span().map_or(0, |s| s.start),
            e.message().trim_end().to_string(),
        )
    })?;
    for (field, v) in [("name", &m.package.name), ("version", &m.package.version)] {
        if v.get_ref().trim().is_empty() {
            return Err(at(
                v.span().start,
                format!("the package {field} is empty; give one"),
            ));
        }
    }
    let dir = manifest_path.parent().unwrap_or_else(|| Path::new(""));
    let in_manifest = |e: PackageError, v: &Spanned<String>| match e {
        PackageError::Io { path, source } => at(
            v.span().start,
            format!("cannot read `{path}`: {source}; paths are relative to the manifest"),
        ),
        other => other,
    };
    let (program_toml, program_pnml) = program_sources(&dir.join(m.package.program.get_ref()))
        .map_err(|e| in_manifest(e, &m.package.program))?;
    let base_path = dir.join(m.package.base.get_ref());
    if !base_path.is_file() {
        return Err(at(
            m.package.base.span().start,
            format!(
                "cannot read the base program `{}`; paths are relative to the manifest",
                base_path.display()
            ),
        ));
    }
    let base = Program::load(&base_path)?;

    let meta = PackageMeta {
        name: m.package.name.get_ref().clone(),
        version: m.package.version.get_ref().clone(),
        author: m.package.author.clone(),
        description: m.package.description.clone(),
        created: rfc3339_utc(created_unix_secs),
        base_program_hash: base.hash_hex().to_string(),
    };
    let payload = Payload {
        format: PAYLOAD_FORMAT.to_string(),
        meta: meta.clone(),
        program_toml,
        program_pnml,
        transform: m.transform.clone(),
        projection: m.projection.clone(),
    };
    // The program is taken from the payload, as the PLC will load it, so that what is resolved
    // here is what runs there.
    let new = load_embedded(&payload)?;
    let manifest_err = |section, source| PackageError::ManifestTransform {
        path: label.clone(),
        section,
        source: Box::new(source),
    };
    let transform = resolve_transform(&payload.transform, &base, &new)
        .map_err(|e| manifest_err("transform", e))?;
    let projection = resolve_projection(payload.projection.as_ref(), &base, &new)
        .map_err(|e| manifest_err("projection", e))?;

    let mut warnings = Vec::new();
    let m0 = base.net().initial_marking();
    let mut out = vec![0; transform.rows()];
    if let Err(e) = transform.apply(m0.as_slice(), &new, &mut out) {
        warnings.push(format!(
            "applied to the initial marking of the base program, the transform is refused: {e}"
        ));
    }

    let payload_bytes = serde_json::to_vec(&payload).map_err(|e| PackageError::Malformed {
        reason: format!("cannot serialize the payload ({e})"),
    })?;
    let signature = key.map(|k| SignatureBlock {
        key_id: k.key_id(),
        ed25519: B64.encode(k.sign(&payload_bytes).to_bytes()),
    });
    let envelope = Envelope {
        format: PACKAGE_FORMAT.to_string(),
        payload: B64.encode(&payload_bytes),
        signature,
    };
    let mut bytes = serde_json::to_vec_pretty(&envelope).map_err(|e| PackageError::Malformed {
        reason: format!("cannot serialize the package ({e})"),
    })?;
    bytes.push(b'\n');

    let report = BuildReport {
        meta,
        program_name: new.name().to_string(),
        program_version: new.version().to_string(),
        program_hash: new.hash_hex().to_string(),
        base_program: format!("{} {}", base.name(), base.version()),
        transform_kind: payload.transform.kind(),
        transform: transform.to_dense(),
        projection_kind: payload
            .projection
            .as_ref()
            .map_or("generated", TransformSpec::kind),
        projection: projection.to_dense(),
        signer: key.map(KeyPair::key_id),
        warnings,
    };
    Ok((bytes, report))
}

/// The program TOML text and PNML text of a program file: a `.toml` naming its net, or a
/// `.pnml` carrying the program.
fn program_sources(path: &Path) -> Result<(String, String), PackageError> {
    let label = path.display().to_string();
    let read = |p: &Path| {
        std::fs::read_to_string(p).map_err(|source| PackageError::Io {
            path: p.display().to_string(),
            source,
        })
    };
    let text = read(path)?;
    let is_pnml = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("pnml") || e.eq_ignore_ascii_case("xml"));
    if is_pnml {
        let program = Program::from_pnml_text(&text, &label)?;
        return Ok((program.source().to_string(), text));
    }
    // Loading first reports any problem of the program with its own file positions.
    Program::load(path)?;
    let head: NetOnly = toml::from_str(&text).map_err(|e| ProgramError::File {
        path: label.clone(),
        message: e.message().to_string(),
    })?;
    let Some(net) = head.program.net else {
        return Err(ProgramError::File {
            path: label,
            message: "`[program]` has no `net = \"….pnml\"`".into(),
        }
        .into());
    };
    let net_path = path
        .parent()
        .unwrap_or_else(|| Path::new(""))
        .join(net.get_ref());
    Ok((text, read(&net_path)?))
}

/// `YYYY-MM-DDTHH:MM:SSZ` for seconds since the Unix epoch (proleptic Gregorian, UTC).
fn rfc3339_utc(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    // Howard Hinnant's days-to-civil algorithm.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    let mut s = String::with_capacity(20);
    let _ = write!(
        s,
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamps_are_rfc3339_utc() {
        assert_eq!(rfc3339_utc(0), "1970-01-01T00:00:00Z");
        assert_eq!(rfc3339_utc(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(rfc3339_utc(1_700_000_000), "2023-11-14T22:13:20Z");
    }

    #[test]
    fn a_key_survives_save_and_load_and_its_public_half_is_trusted() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let path = dir.path().join("k.key");
        let k = KeyPair::generate();
        k.save(&path).unwrap_or_else(|e| panic!("{e}"));
        let back = KeyPair::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(back.key_id(), k.key_id());
        assert_eq!(k.key_id().len(), 16);
        let store = TrustStore::load_dir(dir.path()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(store.key_ids().collect::<Vec<_>>(), [k.key_id().as_str()]);
        assert!(k.save(&path).is_err(), "refuses to overwrite a key");
        let len = std::fs::metadata(&path)
            .unwrap_or_else(|e| panic!("{e}"))
            .len();
        assert!(
            len < 256,
            "{len} bytes: `save` must reserve more for its wiped buffer"
        );
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path)
                .unwrap_or_else(|e| panic!("{e}"))
                .permissions()
                .mode();
            assert_eq!(mode & 0o777, 0o600);
        }
    }

    #[test]
    fn a_key_pair_wipes_its_secret_when_dropped() {
        // Compiles only while ed25519-dalek's `zeroize` feature is on: `SigningKey` is then
        // `ZeroizeOnDrop`, and `KeyPair` holds nothing else secret.
        fn wiped_on_drop<T: zeroize::ZeroizeOnDrop>() {}
        wiped_on_drop::<SigningKey>();
    }

    #[test]
    fn a_secret_key_of_the_wrong_length_is_refused_with_its_length() {
        let text = format!(
            "{SECRET_HEADER}\nkey-id 00\ned25519-seed {}\n",
            B64.encode([1u8; 31])
        );
        let fields = key_fields(&text, "x.key", SECRET_HEADER).unwrap_or_else(|e| panic!("{e}"));
        let err = field_bytes::<32>(&fields, "ed25519-seed", "x.key").unwrap_err();
        assert!(
            err.to_string().contains("must be 32 bytes, found 31"),
            "{err}"
        );
    }

    #[test]
    fn an_edited_key_id_is_refused() {
        let k = KeyPair::generate();
        let text = k
            .public()
            .to_text()
            .replace(&k.key_id(), "0000000000000000");
        let err = VerifyingKeyFile::parse(&text, "x.pub").unwrap_err();
        assert!(err.to_string().contains("does not match"), "{err}");
        let err = VerifyingKeyFile::parse("hello", "x.pub").unwrap_err();
        assert!(err.to_string().contains("first line"), "{err}");
    }
}
