//! Who may change what the PLC trusts from its configuration: its directory, `config.toml`, the
//! key directories and files, and the TLS files must belong to the process's user (root aside),
//! and neither its group nor others may write them, nor read a TLS private key
//! (docs/configuration.md, *Who may change it*).

use std::path::Path;

use super::ConfigError;

/// Refuses a configuration file or directory that its group or others may write: the local
/// configuration decides which keys are trusted, so only its owner may change it.
pub(super) fn check_not_writable_by_others(path: &Path) -> Result<(), ConfigError> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(());
    };
    let me = nix::unistd::geteuid().as_raw();
    if meta.uid() != me && meta.uid() != 0 {
        return Err(ConfigError::OwnedByOther {
            path: path.display().to_string(),
            owner: meta.uid(),
            me,
        });
    }
    let mode = meta.permissions().mode() & 0o7777;
    // A sticky directory (like /tmp) still lets others write; it is no exception.
    if mode & 0o022 != 0 {
        return Err(ConfigError::WritableByOthers {
            path: path.display().to_string(),
            mode,
        });
    }
    Ok(())
}

/// Refuses a TLS private key that its group or others may read (or change): whoever reads it
/// can pose as this PLC.
pub(super) fn check_private_key(path: &Path) -> Result<(), ConfigError> {
    use std::os::unix::fs::PermissionsExt;
    check_not_writable_by_others(path)?;
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(());
    };
    let mode = meta.permissions().mode() & 0o7777;
    if mode & 0o044 != 0 {
        return Err(ConfigError::KeyReadable {
            path: path.display().to_string(),
            mode,
        });
    }
    Ok(())
}
