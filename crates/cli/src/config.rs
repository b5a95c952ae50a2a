//! The PLC's local configuration: a directory that only someone at the machine can change.
//!
//! ```text
//! <config dir>/config.toml    optional settings (below)
//! <config dir>/trusted/*.pub  keys whose update packages this PLC accepts
//! <config dir>/operators/*.pub keys whose commands this PLC accepts; when there is at least one,
//!                              every MQTT command must be a signed envelope
//! ```
//!
//! `config.toml`:
//!
//! ```toml
//! allow_unsigned = false            # accept unsigned packages (never settable by a command)
//! replay_window = "60s"             # how old or new a signed command may be
//! [mqtt]
//! users = [{ name = "mct", password = "…" }]   # accounts of the embedded broker
//! user = "plc-7"                    # credentials for a plant broker (--broker)
//! password = "…"
//! ```
//!
//! The directory is `--config DIR`, else `$XDG_CONFIG_HOME/cetratus`, else `~/.config/cetratus`.
//! A missing directory is an empty configuration.

use std::path::{Path, PathBuf};

use anyhow::Context;
use cetratus_mct::OperatorKeys;
use cetratus_program::{TrustStore, VerifyingKeyFile};
use serde::Deserialize;

/// Where the configuration directory is.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ConfigArgs {
    /// The local configuration directory (trusted keys, operator keys, config.toml).
    #[arg(long = "config")]
    pub config: Option<PathBuf>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    allow_unsigned: bool,
    replay_window: Option<String>,
    #[serde(default)]
    mqtt: MqttFile,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct MqttFile {
    #[serde(default)]
    users: Vec<User>,
    user: Option<String>,
    password: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct User {
    name: String,
    password: String,
}

/// The loaded configuration.
pub struct LocalConfig {
    /// The directory it came from.
    pub dir: PathBuf,
    /// Keys trusted for update packages.
    pub trust: TrustStore,
    /// Accept unsigned packages.
    pub allow_unsigned: bool,
    /// Keys trusted for commands; `None` when there are none (commands need no signature).
    pub operators: Option<OperatorKeys>,
    /// Accounts of the embedded broker.
    pub users: Vec<(String, String)>,
    /// Credentials for a plant broker.
    pub credentials: Option<(String, String)>,
}

/// The default configuration directory.
pub fn default_dir() -> PathBuf {
    if let Some(x) = std::env::var_os("XDG_CONFIG_HOME") {
        return PathBuf::from(x).join("cetratus");
    }
    if let Some(h) = std::env::var_os("HOME") {
        return PathBuf::from(h).join(".config/cetratus");
    }
    PathBuf::from(".cetratus")
}

fn keys_in(dir: &Path) -> anyhow::Result<Vec<VerifyingKeyFile>> {
    let mut keys = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(keys);
    };
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "pub"))
        .collect();
    paths.sort();
    for p in paths {
        keys.push(
            VerifyingKeyFile::load(&p).with_context(|| format!("operator key {}", p.display()))?,
        );
    }
    Ok(keys)
}

impl ConfigArgs {
    /// Loads the configuration.
    pub fn load(&self) -> anyhow::Result<LocalConfig> {
        let dir = self.config.clone().unwrap_or_else(default_dir);
        let file_path = dir.join("config.toml");
        let file: File = match std::fs::read_to_string(&file_path) {
            Ok(text) => toml::from_str(&text).map_err(|e| {
                let at = e
                    .span()
                    .map(|s| {
                        let line = text[..s.start].matches('\n').count() + 1;
                        let col = s.start - text[..s.start].rfind('\n').map_or(0, |i| i + 1) + 1;
                        format!("{}:{line}:{col}", file_path.display())
                    })
                    .unwrap_or_else(|| file_path.display().to_string());
                anyhow::anyhow!("{at}: {}", e.message().trim_end())
            })?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => File::default(),
            Err(e) => {
                return Err(e).with_context(|| format!("cannot read {}", file_path.display()))
            }
        };
        let trusted = dir.join("trusted");
        let trust = if trusted.is_dir() {
            TrustStore::load_dir(&trusted)?
        } else {
            TrustStore::empty()
        };
        let window = match &file.replay_window {
            Some(w) => crate::duration::parse_duration_us(w)? / 1_000_000,
            None => 60,
        };
        let mut ops = OperatorKeys::new(std::time::Duration::from_secs(window.max(1)));
        for k in keys_in(&dir.join("operators"))? {
            ops.add(k.key_id(), *k.verifying_key());
        }
        Ok(LocalConfig {
            dir,
            trust,
            allow_unsigned: file.allow_unsigned,
            operators: (!ops.is_empty()).then_some(ops),
            users: file
                .mqtt
                .users
                .into_iter()
                .map(|u| (u.name, u.password))
                .collect(),
            credentials: file
                .mqtt
                .user
                .map(|u| (u, file.mqtt.password.unwrap_or_default())),
        })
    }
}
