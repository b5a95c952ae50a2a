//! Who may change what the PLC trusts from its configuration: its directory, `config.toml`, the
//! key directories and files, and the TLS files must belong to the process's user (root aside),
//! and neither its group nor others may write them, nor read a TLS private key
//! (docs/configuration.md, *Who may change it*).

use std::path::Path;

use cetratus_persist::Exposure;

use super::ConfigError;

/// Refuses a configuration file or directory that another user owns, or that its group or others
/// may write: the local configuration decides which keys are trusted, so only its owner may
/// change it.
pub(super) fn check_not_writable_by_others(path: &Path) -> Result<(), ConfigError> {
    match std::fs::metadata(path) {
        Ok(meta) => check_meta(path, &meta),
        Err(_) => Ok(()),
    }
}

/// Refuses a TLS private key that its group or others may read (or change): whoever reads it
/// can pose as this PLC.
pub(super) fn check_private_key(path: &Path) -> Result<(), ConfigError> {
    use std::os::unix::fs::PermissionsExt;
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(());
    };
    check_meta(path, &meta)?;
    let mode = meta.permissions().mode() & 0o7777;
    if mode & 0o044 != 0 {
        return Err(ConfigError::KeyReadable {
            path: path.display().to_string(),
            mode,
        });
    }
    Ok(())
}

/// [`check_not_writable_by_others`] on metadata already read.
fn check_meta(path: &Path, meta: &std::fs::Metadata) -> Result<(), ConfigError> {
    let path = path.display().to_string();
    match cetratus_persist::exposure(meta) {
        None => Ok(()),
        Some(Exposure::OwnedByOther { owner, me }) => {
            Err(ConfigError::OwnedByOther { path, owner, me })
        }
        Some(Exposure::WritableByOthers { mode }) => {
            Err(ConfigError::WritableByOthers { path, mode })
        }
    }
}
