//! The trust lists of OPC UA certificates, as async-opcua reads them: a certificate is trusted
//! when `<pki>/trusted/` holds it under the name `<common name> [<SHA-1 thumbprint>].der`. An
//! administrator copies a certificate there under any name ending in `.der`; [`install_trusted`]
//! adds it under the name async-opcua looks for.

use std::path::Path;

use opcua::crypto::{CertificateStore, X509};

use crate::IoError;

/// What a trust list's file or directory came to: its path and the reason.
fn pki_error(path: &Path, reason: impl std::fmt::Display) -> IoError {
    IoError::Pki {
        path: path.display().to_string(),
        reason: reason.to_string(),
    }
}

/// The name under which a trust list must hold `der` (a DER certificate), or why it is not one.
pub(crate) fn trusted_name(der: &[u8]) -> Result<String, String> {
    let cert = X509::from_der(der).map_err(|e| format!("not a DER certificate ({e:?})"))?;
    Ok(CertificateStore::cert_file_name(&cert))
}

/// Copies every `.der` of `<pki>/trusted/` that is not under its own name to that name (the
/// directory is made when missing). Returns the certificates found, or what is wrong with a file,
/// naming it.
pub fn install_trusted(pki: &Path) -> Result<usize, IoError> {
    let dir = pki.join("trusted");
    std::fs::create_dir_all(&dir).map_err(|e| pki_error(&dir, e))?;
    let entries = std::fs::read_dir(&dir).map_err(|e| pki_error(&dir, e))?;
    let mut found = 0;
    for e in entries {
        let path = e.map_err(|e| pki_error(&dir, e))?.path();
        if path.extension().and_then(|x| x.to_str()) != Some("der") {
            continue;
        }
        let der = std::fs::read(&path).map_err(|e| pki_error(&path, e))?;
        let name = trusted_name(&der).map_err(|e| {
            pki_error(
                &path,
                format!("{e}; a trust list holds the peers' certificates in DER (.der)"),
            )
        })?;
        found += 1;
        let target = dir.join(&name);
        if target != path && !target.exists() {
            std::fs::write(&target, &der).map_err(|e| pki_error(&target, e))?;
        }
    }
    Ok(found)
}
