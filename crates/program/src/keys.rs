//! Signing keys and the trust store: an operator or a build machine signs with a [`KeyPair`];
//! a PLC accepts what a key of its [`TrustStore`] signed. Key files are documented in
//! `docs/package-format.md`.
//!
//! Secrets do not outlive their use: `SigningKey` wipes itself when dropped (ed25519-dalek's
//! `zeroize` feature), and every buffer that holds a seed on its way to or from a file is wiped.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use base64::engine::general_purpose::STANDARD as B64;
use base64::Engine as _;
use ed25519_dalek::{Signature, Signer, SigningKey, VerifyingKey};
use sha2::{Digest, Sha256};
use zeroize::Zeroizing;

use crate::PackageError;

const SECRET_HEADER: &str = "cetratus-secret-key/1";
const PUBLIC_HEADER: &str = "cetratus-public-key/1";

/// Whether `path` names a public key file: its extension is `pub`, in any case (`OP.PUB` too,
/// as some tools and file systems write it).
pub fn is_key_file(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("pub"))
}

/// The trusted public keys, by key id.
#[derive(Clone, Debug, Default)]
pub struct TrustStore {
    pub(crate) keys: BTreeMap<String, VerifyingKey>,
}

impl TrustStore {
    /// A store that trusts nobody.
    pub fn empty() -> Self {
        Self::default()
    }

    /// Every key file ([`is_key_file`]) in a directory; a malformed one is an error, not
    /// skipped, since a key someone meant to trust would otherwise be silently ignored.
    pub fn load_dir(dir: &Path) -> Result<Self, PackageError> {
        let io = |source| PackageError::Io {
            path: dir.display().to_string(),
            source,
        };
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(io)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| is_key_file(p) && p.is_file())
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
pub(crate) fn key_id_of(key: &VerifyingKey) -> String {
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
        let (text, label) = read_key_file(path)?;
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
        // `read_to_string` sizes its buffer from the file's length, so the text is read into one
        // allocation, which is wiped on drop; the fields borrow from it rather than copy it.
        let (text, label) = read_key_file(path)?;
        let text = Zeroizing::new(text);
        let fields = key_fields(&text, &label, SECRET_HEADER)?;
        let seed = field_bytes::<32>(&fields, "ed25519-seed", &label)?;
        let key = SigningKey::from_bytes(&seed);
        check_key_id(&fields, &key_id_of(&key.verifying_key()), &label)?;
        Ok(KeyPair { key })
    }

    /// Signs bytes.
    pub(crate) fn sign(&self, bytes: &[u8]) -> Signature {
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

/// A key file's text and the path as errors name it.
fn read_key_file(path: &Path) -> Result<(String, String), PackageError> {
    let label = path.display().to_string();
    match std::fs::read_to_string(path) {
        Ok(text) => Ok((text, label)),
        Err(source) => Err(PackageError::Io {
            path: label,
            source,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
