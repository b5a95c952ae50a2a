//! `cetratus twin serve … --opcua URL`: the twin as the OPC UA client of a PLC's server.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use anyhow::{bail, Context};
use cetratus_io::opcua::config::Policy;
use cetratus_io::opcua::twin_client::{prepare_pki, serve, ClientSecurity, PlcTarget};
use cetratus_twin::{Plant, Twin};

/// The environment variable that holds the password of `--user`.
pub const PASSWORD_ENV: &str = "CETRATUS_OPCUA_PASSWORD";

/// How `twin serve --opcua` reaches the PLC's server.
#[derive(clap::Args, Debug)]
pub struct SecurityArgs {
    /// `none` (a PLC serving on loopback) or `sign-and-encrypt`.
    #[arg(long, default_value = "none", value_parser = ["none", "sign-and-encrypt"], requires = "opcua")]
    security: String,
    /// The security policy with `--security sign-and-encrypt`: Basic256Sha256 (the default),
    /// Aes128_Sha256_RsaOaep or Aes256_Sha256_RsaPss.
    #[arg(long)]
    policy: Option<String>,
    /// The twin's PKI directory with `--security sign-and-encrypt`: its certificate and key
    /// (made on first use) and, in `trusted/`, the PLC certificates it trusts.
    #[arg(long)]
    pki: Option<PathBuf>,
    /// Log in as this user; the password comes from CETRATUS_OPCUA_PASSWORD or --password-file.
    #[arg(long)]
    user: Option<String>,
    /// A file whose first line is the password of `--user`.
    #[arg(long, requires = "user")]
    password_file: Option<PathBuf>,
}

impl SecurityArgs {
    /// Checks the options and reads the password; makes the PKI directory on first use.
    pub fn resolve(&self, opcua: bool) -> anyhow::Result<ClientSecurity> {
        if self.security == "none" {
            if self.policy.is_some() || self.pki.is_some() || self.user.is_some() {
                bail!("--policy, --pki and --user need --security sign-and-encrypt: over policy None a password would travel in clear");
            }
            return Ok(ClientSecurity::default());
        }
        if !opcua {
            bail!("--security applies to --opcua");
        }
        let name = self.policy.as_deref().unwrap_or("Basic256Sha256");
        let policy = Policy::ALL
            .into_iter()
            .find(|p| p.name() == name)
            .with_context(|| format!("--policy {name}: expected Basic256Sha256, Aes128_Sha256_RsaOaep or Aes256_Sha256_RsaPss"))?;
        let Some(pki) = self.pki.clone() else {
            bail!("--security sign-and-encrypt needs --pki DIR: the twin's certificate and key (made there on first use) and, in DIR/trusted/, the PLC's certificate");
        };
        let user = match &self.user {
            None => None,
            Some(u) => Some((u.clone(), self.password()?)),
        };
        let (cert, trusted_as) =
            prepare_pki(&pki).map_err(|e| anyhow::anyhow!("--pki {}: {e}", pki.display()))?;
        eprintln!("the twin's certificate is {}: the PLC trusts it once it is in the PLC's <pki>/trusted/ as `{trusted_as}` (or after its first refusal, moved from <pki>/rejected/)", cert.display());
        Ok(ClientSecurity {
            policy: Some(policy),
            pki: Some(pki),
            user,
        })
    }

    fn password(&self) -> anyhow::Result<String> {
        if let Some(f) = &self.password_file {
            let text = std::fs::read_to_string(f)
                .with_context(|| format!("--password-file {}", f.display()))?;
            let line = text.lines().next().unwrap_or("").to_string();
            if line.is_empty() {
                bail!(
                    "--password-file {}: the first line is empty; write the password there",
                    f.display()
                );
            }
            return Ok(line);
        }
        match std::env::var(PASSWORD_ENV) {
            Ok(p) if !p.is_empty() => Ok(p),
            _ => bail!("--user needs a password: set {PASSWORD_ENV}, or give --password-file FILE (never on the command line)"),
        }
    }
}

/// Drives `twin` from the PLC at `url` and prints the closing summary.
pub fn run(
    twin: Twin,
    url: &str,
    plc: Option<&str>,
    until_us: u64,
    stop: &AtomicBool,
    security: &ClientSecurity,
    json: bool,
) -> anyhow::Result<()> {
    let name = twin.name().to_string();
    if !json {
        eprintln!("the {name} twin connects to {url} (retrying until the PLC is up); Ctrl-C stops");
    }
    let target = PlcTarget { url, plc, security };
    let report = serve(twin, target, until_us, stop, |plc| {
        if !json {
            eprintln!("connected: the {name} twin is the plant of {plc}");
        }
    })?;
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{} twin: {:.1} s, {} parts finished, {} faults; OPC UA: {} reads, {} writes, {} errors",
            report.twin,
            report.seconds,
            report.parts_finished,
            report.twin_faults,
            report.opcua.reads,
            report.opcua.writes,
            report.opcua.errors
        );
        for f in report.faults.iter().take(20) {
            println!("  {f}");
        }
    }
    Ok(())
}
