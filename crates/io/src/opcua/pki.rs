//! The trust lists of OPC UA certificates, as async-opcua reads them: a certificate is trusted
//! when `<pki>/trusted/` holds it under the name `<common name> [<SHA-1 thumbprint>].der`. An
//! administrator copies a certificate there under any name ending in `.der`; [`install_trusted`]
//! adds it under the name async-opcua looks for.

use std::path::Path;

use opcua::crypto::{CertificateStore, X509};

/// The name under which a trust list must hold `der` (a DER certificate), or why it is not one.
pub fn trusted_name(der: &[u8]) -> Result<String, String> {
    let cert = X509::from_der(der).map_err(|e| format!("not a DER certificate ({e:?})"))?;
    Ok(CertificateStore::cert_file_name(&cert))
}

/// Copies every `.der` of `<pki>/trusted/` that is not under its own name to that name (the
/// directory is made when missing). Returns the certificates found, or what is wrong with a file,
/// naming it.
pub fn install_trusted(pki: &Path) -> Result<usize, String> {
    let dir = pki.join("trusted");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let entries = std::fs::read_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut found = 0;
    for e in entries {
        let path = e.map_err(|e| format!("{}: {e}", dir.display()))?.path();
        if path.extension().and_then(|x| x.to_str()) != Some("der") {
            continue;
        }
        let der = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let name = trusted_name(&der).map_err(|e| {
            format!(
                "{}: {e}; a trust list holds the peers' certificates in DER (.der)",
                path.display()
            )
        })?;
        found += 1;
        let target = dir.join(&name);
        if target != path && !target.exists() {
            std::fs::write(&target, &der).map_err(|e| format!("{}: {e}", target.display()))?;
        }
    }
    Ok(found)
}
