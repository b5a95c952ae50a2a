//! The PLC node's local configuration: a directory that only someone at the machine can change
//! (docs/configuration.md has the whole schema).
//!
//! ```text
//! <config dir>/config.toml     the settings: one schema, unknown keys refused
//! <config dir>/trusted/*.pub   keys whose update packages this PLC accepts
//! <config dir>/operators/*.pub keys whose commands this PLC accepts; when there is at least one,
//!                              every MQTT command must be a signed envelope
//! ```
//!
//! The directory is the one given, else `$XDG_CONFIG_HOME/cetratus`, else `~/.config/cetratus`.
//! A missing directory is an empty configuration.

mod private;

use std::path::{Path, PathBuf};

use cetratus_mct::{BrokerAccount, BrokerTls, OperatorKeys};
use cetratus_program::duration::{self, Bare};
use cetratus_program::{TrustStore, VerifyingKeyFile};
use cetratus_runtime::Limits;

use crate::gate::GatePolicy;
use crate::validate::{AutoSubstitute, ValidationMode, ValidationPolicy};
use serde::Deserialize;

/// Why the local configuration cannot be used. The PLC does not start.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// `config.toml` could not be read.
    #[error("cannot read {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// `config.toml` is not UTF-8.
    #[error("{0}")]
    NotUtf8(cetratus_program::NotUtf8),
    /// The `[io]` section is wrong (docs/io.md).
    #[error("{0}")]
    Io(cetratus_io::IoError),
    /// `config.toml` does not follow the schema.
    #[error("{at}: {message}; remove the key, or fix its spelling or value against docs/configuration.md")]
    Schema {
        /// file:line:column.
        at: String,
        /// What toml said.
        message: String,
    },
    /// A setting has a value this version refuses.
    #[error("{path}: {key} = \"{value}\": {reason}")]
    Value {
        /// The file.
        path: String,
        /// The key, with its section.
        key: &'static str,
        /// The value as written.
        value: String,
        /// Why, and what to write instead.
        reason: String,
    },
    /// A directory of keys cannot be read, or is not a directory.
    #[error("{path}: cannot read the key directory: {reason}; fix its permissions or remove it")]
    Unreadable {
        /// The directory.
        path: String,
        /// Why.
        reason: String,
    },
    /// A file or directory of the configuration belongs to another user than the process's
    /// (root aside), who could change it.
    #[error("{path} belongs to user {owner}, not to this process's user {me}, so that user could trust their own keys; run `chown {me} {path}`, or use a configuration of this user's own")]
    OwnedByOther {
        /// The file or directory.
        path: String,
        /// Its owner's uid.
        owner: u32,
        /// The process's effective uid.
        me: u32,
    },
    /// A TLS private key that others may read.
    #[error("{path} is readable by others (mode {mode:o}), so anyone on this machine could pose as this PLC; run `chmod 600 {path}`")]
    KeyReadable {
        /// The key file.
        path: String,
        /// Its permission bits.
        mode: u32,
    },
    /// Someone other than its owner may change the configuration.
    #[error("{path} is writable by others (mode {mode:o}), so anyone on this machine could trust their own keys; run `chmod go-w {path}`")]
    WritableByOthers {
        /// The file or directory.
        path: String,
        /// Its permission bits.
        mode: u32,
    },
    /// A key file does not load.
    #[error("{what} key {path}: {source}")]
    Key {
        /// `trusted` or `operator`.
        what: &'static str,
        /// The file.
        path: String,
        /// Why.
        source: Box<cetratus_program::PackageError>,
    },
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    allow_unsigned: bool,
    replay_window: Option<String>,
    #[serde(default)]
    mqtt: MqttSection,
    #[serde(default)]
    io: IoSection,
    #[serde(default)]
    dashboard: DashboardSection,
    #[serde(default)]
    updates: UpdatesSection,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct MqttSection {
    #[serde(default)]
    users: Vec<User>,
    user: Option<String>,
    password: Option<String>,
    tls_cert: Option<PathBuf>,
    tls_key: Option<PathBuf>,
}

/// `[[mqtt.users]]`: an account of the embedded broker.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct User {
    name: String,
    password_hash: Option<String>,
    /// Earlier versions kept the password in clear; refused with what to write instead.
    password: Option<toml::Value>,
    #[serde(default)]
    plcs: Vec<String>,
}

/// `[io]`: the node's I/O configuration, read and checked by `cetratus_io::config` from the
/// file's text (so that its errors keep their lines).
#[derive(Deserialize, Default)]
struct IoSection {}

/// `[dashboard]`: who may log in to the dashboard, and the host names it is reached under.
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct DashboardSection {
    #[serde(default)]
    accounts: Vec<DashboardAccount>,
    #[serde(default)]
    hosts: Vec<String>,
    tls_cert: Option<PathBuf>,
    tls_key: Option<PathBuf>,
}

/// `[[dashboard.accounts]]`: a name and the argon2 hash of its password.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DashboardAccount {
    name: String,
    password_hash: String,
}

/// `[updates]`: update policies.
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct UpdatesSection {
    probation: Option<String>,
    state_trans_timeout: Option<String>,
    candidate_work_budget: Option<u64>,
    gate_max_states: Option<u64>,
    gate_time: Option<String>,
    gate_deadlock: Option<String>,
    gate_lost_transitions: Option<String>,
    gate_broken_invariants: Option<String>,
    validation: Option<String>,
    validation_twin: Option<String>,
    horizon: Option<String>,
    revalidate: Option<String>,
    throughput_share: Option<f64>,
    #[serde(default)]
    require_verdict: bool,
    auto_substitute: Option<String>,
    #[serde(default)]
    auto_substitute_keys: Vec<String>,
}

/// The probation window when `[updates] probation` is absent: a minute.
pub const DEFAULT_PROBATION_US: u64 = 60_000_000;

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
    /// Accounts of the embedded broker, with their password hashes and the PLCs they may command.
    pub users: Vec<BrokerAccount>,
    /// The embedded broker's TLS certificate and key, resolved against the directory.
    pub mqtt_tls: Option<BrokerTls>,
    /// The dashboard's TLS certificate and key (PEM), resolved against the directory.
    pub dashboard_tls: Option<(PathBuf, PathBuf)>,
    /// Credentials for a plant broker.
    pub credentials: Option<(String, String)>,
    /// The probation window after a substitution, in microseconds (0: none).
    pub probation_us: u64,
    /// Dashboard accounts: (name, argon2 hash of the password as a PHC string); the dashboard
    /// checks them when it starts.
    pub dashboard_accounts: Vec<(String, String)>,
    /// Host names the dashboard is reached under, besides IP addresses and `localhost`.
    pub dashboard_hosts: Vec<String>,
    /// stateTransTimeout, the budget of an update's in-cycle install, in microseconds; `None`:
    /// one scan period.
    pub state_trans_timeout_us: Option<u64>,
    /// The work budget of a candidate scan (guard evaluations and firings); `None`: the default
    /// for the scan period.
    pub candidate_work_budget: Option<u64>,
    /// The node's I/O configuration from `[io]`, when it names a device or a server.
    pub io: Option<cetratus_io::config::IoConfig>,
    /// The analysis gate at load: its budget and what each finding does.
    pub gate: GatePolicy,
    /// Twin validation: the mode, the horizon and the throughput share.
    pub validation: ValidationPolicy,
    /// A substitution needs a passing twin verdict.
    pub require_verdict: bool,
    /// `auto_substitute = "on-pass"`: the operator key ids whose loads the PLC substitutes by
    /// itself on a passing twin verdict; `None` when off.
    pub auto_substitute: Option<AutoSubstitute>,
}

/// The default configuration directory.
pub fn default_dir() -> PathBuf {
    crate::dirs::xdg("XDG_CONFIG_HOME", ".config")
        .map_or_else(|| PathBuf::from(".cetratus"), |d| d.join("cetratus"))
}

/// The key files of `dir`; an absent directory holds none. A directory that cannot be read, or a
/// file in its place, is an error: for `operators/`, treating it as empty would silently turn
/// command authentication off.
fn keys_in(dir: &Path, what: &'static str) -> Result<Vec<VerifyingKeyFile>, ConfigError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound && !dir.is_symlink() => {
            return Ok(Vec::new())
        }
        Err(e) => {
            return Err(ConfigError::Unreadable {
                path: dir.display().to_string(),
                reason: if dir.exists() && !dir.is_dir() {
                    "it is not a directory".into()
                } else {
                    e.to_string()
                },
            })
        }
    };
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| cetratus_program::keys::is_key_file(p))
        .collect();
    paths.sort();
    // A key file others may change is a key they choose.
    for p in &paths {
        private::check_not_writable_by_others(p)?;
    }
    paths
        .iter()
        .map(|p| {
            VerifyingKeyFile::load(p).map_err(|source| ConfigError::Key {
                what,
                path: p.display().to_string(),
                source: Box::new(source),
            })
        })
        .collect()
}

/// A section's TLS certificate and private key, when it gives them, after their checks.
type TlsFiles = Result<Option<(PathBuf, PathBuf)>, ConfigError>;

/// The TLS certificate and key of a section, under `dir`, each checked ([`private`]); `None`
/// when neither is given, `Err` naming the one missing when only one is.
fn tls_pair(
    dir: &Path,
    cert: Option<PathBuf>,
    key: Option<PathBuf>,
) -> Result<TlsFiles, &'static str> {
    match (cert, key) {
        (None, None) => Ok(Ok(None)),
        (Some(c), Some(k)) => {
            let (c, k) = (dir.join(c), dir.join(k));
            Ok(private::check_not_writable_by_others(&c)
                .and_then(|()| private::check_private_key(&k))
                .map(|()| Some((c, k))))
        }
        (Some(_), None) => Err("tls_key"),
        (None, Some(_)) => Err("tls_cert"),
    }
}

/// `file:line:column` of a byte offset of `text`.
fn position(path: &Path, text: &str, offset: usize) -> String {
    let offset = offset.min(text.len());
    let line = text[..offset].matches('\n').count() + 1;
    let col = offset - text[..offset].rfind('\n').map_or(0, |i| i + 1) + 1;
    format!("{}:{line}:{col}", path.display())
}

impl LocalConfig {
    /// Loads the configuration from `dir`, or from [`default_dir`].
    pub fn load(dir: Option<&Path>) -> Result<LocalConfig, ConfigError> {
        let dir = dir.map_or_else(default_dir, Path::to_path_buf);
        let file_path = dir.join("config.toml");
        let mut io = None;
        let file: File = match std::fs::read(&file_path) {
            Ok(bytes) => {
                let text = cetratus_program::toml_text(bytes, &file_path.display().to_string())
                    .map_err(ConfigError::NotUtf8)?;
                let file = toml::from_str(&text).map_err(|e| ConfigError::Schema {
                    at: e.span().map_or_else(
                        || file_path.display().to_string(),
                        |s| position(&file_path, &text, s.start),
                    ),
                    message: e.message().trim_end().to_string(),
                })?;
                io = cetratus_io::config::IoConfig::from_local(
                    &file_path.display().to_string(),
                    &text,
                )
                .map_err(ConfigError::Io)?;
                file
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => File::default(),
            Err(source) => {
                return Err(ConfigError::Read {
                    path: file_path.display().to_string(),
                    source,
                })
            }
        };
        let value_error = |key, value: &str, reason: String| ConfigError::Value {
            path: file_path.display().to_string(),
            key,
            value: value.to_string(),
            reason,
        };
        for path in [
            dir.clone(),
            file_path.clone(),
            dir.join("trusted"),
            dir.join("operators"),
        ] {
            private::check_not_writable_by_others(&path)?;
        }
        let mut trust = TrustStore::empty();
        for k in keys_in(&dir.join("trusted"), "trusted")? {
            trust.add(k);
        }
        let window_s = match &file.replay_window {
            Some(w) => {
                duration::parse_us(w, Bare::Seconds)
                    .map_err(|e| value_error("replay_window", w, e.to_string()))?
                    / 1_000_000
            }
            None => 60,
        };
        let probation_us = match &file.updates.probation {
            Some(p) => duration::parse_us(p, Bare::Seconds)
                .map_err(|e| value_error("[updates] probation", p, e.to_string()))?,
            None => DEFAULT_PROBATION_US,
        };
        let state_trans_timeout_us = match &file.updates.state_trans_timeout {
            Some(t) => {
                let us = duration::parse_us(t, Bare::Seconds)
                    .map_err(|e| value_error("[updates] state_trans_timeout", t, e.to_string()))?;
                if us == 0 {
                    return Err(value_error(
                        "[updates] state_trans_timeout",
                        t,
                        "no install can take 0 µs; give a duration such as \"10ms\", or remove the key for one scan period".into(),
                    ));
                }
                Some(us)
            }
            None => None,
        };
        if let Some(0) = file.updates.candidate_work_budget {
            return Err(value_error(
                "[updates] candidate_work_budget",
                "0",
                "a candidate could not evaluate a single guard; give a positive number, or remove the key for the default".into(),
            ));
        }
        let validation = validation_policy(&file.updates, &value_error)?;
        let auto_substitute = match file.updates.auto_substitute.as_deref() {
            None | Some("off") => None,
            Some("on-pass") if file.updates.auto_substitute_keys.is_empty() => {
                return Err(value_error(
                    "[updates] auto_substitute",
                    "on-pass",
                    "name the operator keys whose loads may be substituted by the PLC itself: auto_substitute_keys = [\"<key id>\"]".into(),
                ))
            }
            Some("on-pass") if validation.mode == ValidationMode::Off => {
                return Err(value_error(
                    "[updates] auto_substitute",
                    "on-pass",
                    "a substitution on a passing verdict needs twin validation: set validation = \"fork\" or \"commission\"".into(),
                ))
            }
            Some("on-pass") => Some(AutoSubstitute {
                keys: file.updates.auto_substitute_keys.clone(),
            }),
            Some(other) => {
                return Err(value_error(
                    "[updates] auto_substitute",
                    other,
                    "write \"off\" or \"on-pass\"".into(),
                ))
            }
        };
        let gate = gate_policy(&file.updates, value_error)?;
        let mut ops = OperatorKeys::new(std::time::Duration::from_secs(window_s.max(1)));
        for k in keys_in(&dir.join("operators"), "operator")? {
            ops.add(k.key_id(), *k.verifying_key());
        }
        let _ = file.io;
        let io_from_file = io;
        let mut users = Vec::with_capacity(file.mqtt.users.len());
        for u in file.mqtt.users {
            let hash = match (u.password_hash, u.password) {
                (Some(h), None) => h,
                (_, Some(_)) => {
                    return Err(value_error(
                        "[[mqtt.users]] name",
                        &u.name,
                        "passwords are stored as hashes: replace `password = …` with \
                         `password_hash = …`, the output of `echo -n 'PASSWORD' | cetratus \
                         hash-password`"
                            .into(),
                    ))
                }
                (None, None) => {
                    return Err(value_error(
                        "[[mqtt.users]] name",
                        &u.name,
                        "the account has no `password_hash`; add the output of \
                         `cetratus hash-password`"
                            .into(),
                    ))
                }
            };
            users.push(BrokerAccount {
                name: u.name,
                password_hash: hash,
                plcs: u.plcs,
            });
        }
        let pair = |section, cert, key| {
            tls_pair(&dir, cert, key).map_err(|missing| {
                value_error(
                    section,
                    missing,
                    "TLS needs both `tls_cert` (the certificate chain, PEM) and `tls_key` (its \
                     private key, PEM); give both, or neither"
                        .into(),
                )
            })?
        };
        let mqtt_tls = pair("[mqtt] tls", file.mqtt.tls_cert, file.mqtt.tls_key)?
            .map(|(cert, key)| BrokerTls { cert, key });
        let dashboard_tls = pair(
            "[dashboard] tls",
            file.dashboard.tls_cert,
            file.dashboard.tls_key,
        )?;
        Ok(LocalConfig {
            mqtt_tls,
            dashboard_tls,
            dashboard_accounts: file
                .dashboard
                .accounts
                .into_iter()
                .map(|a| (a.name, a.password_hash))
                .collect(),
            dashboard_hosts: file.dashboard.hosts,
            dir,
            trust,
            allow_unsigned: file.allow_unsigned,
            operators: (!ops.is_empty()).then_some(ops),
            users,
            credentials: file
                .mqtt
                .user
                .map(|u| (u, file.mqtt.password.unwrap_or_default())),
            probation_us,
            state_trans_timeout_us,
            candidate_work_budget: file.updates.candidate_work_budget,
            io: io_from_file,
            gate,
            validation,
            require_verdict: file.updates.require_verdict,
            auto_substitute,
        })
    }

    /// Refuses `validation = "fork"` for a run without an in-process twin: there is nothing to
    /// fork, and every update would go unvalidated (with `require_verdict`, unsubstitutable).
    pub fn check_validation(&self, has_twin: bool) -> Result<(), ConfigError> {
        if self.validation.mode != ValidationMode::Fork || has_twin {
            return Ok(());
        }
        Err(ConfigError::Value {
            path: self.dir.join("config.toml").display().to_string(),
            key: "[updates] validation",
            value: "fork".into(),
            reason: "fork mode forks the twin the PLC runs against, and this run has none: run it with --twin, or set validation = \"commission\" with validation_twin = \"vernadat\" or \"festo\"".into(),
        })
    }

    /// `limits` with what `[updates]` sets: stateTransTimeout, the candidate's work budget and
    /// the probation window.
    pub fn limits(&self, limits: Limits) -> Limits {
        Limits {
            probation_us: self.probation_us,
            require_verdict: self.require_verdict,
            state_trans_timeout_ns: self
                .state_trans_timeout_us
                .map_or(limits.state_trans_timeout_ns, |us| us.saturating_mul(1000)),
            candidate_work_budget: self
                .candidate_work_budget
                .unwrap_or(limits.candidate_work_budget),
            ..limits
        }
    }
}

/// `[updates] validation`, `validation_twin`, `horizon`, `revalidate`, `throughput_share`.
fn validation_policy(
    u: &UpdatesSection,
    value_error: &impl Fn(&'static str, &str, String) -> ConfigError,
) -> Result<ValidationPolicy, ConfigError> {
    let mut v = ValidationPolicy::default();
    let twin = match &u.validation_twin {
        None => None,
        Some(t) => Some(
            t.parse::<cetratus_twin::TwinKind>()
                .map_err(|e| value_error("[updates] validation_twin", t, e.to_string()))?,
        ),
    };
    v.mode = match (u.validation.as_deref(), twin) {
        (None | Some("off"), _) => ValidationMode::Off,
        (Some("fork"), _) => ValidationMode::Fork,
        (Some("commission"), Some(kind)) => ValidationMode::Commission(kind),
        (Some("commission"), None) => {
            return Err(value_error(
                "[updates] validation",
                "commission",
                "commissioning runs fresh twins of a model: name it with validation_twin = \"vernadat\" or \"festo\"".into(),
            ))
        }
        (Some(other), _) => {
            return Err(value_error(
                "[updates] validation",
                other,
                "write \"off\", \"fork\" or \"commission\"".into(),
            ))
        }
    };
    if let Some(h) = &u.horizon {
        let us = duration::parse_us(h, Bare::Seconds)
            .map_err(|e| value_error("[updates] horizon", h, e.to_string()))?;
        if us == 0 {
            return Err(value_error(
                "[updates] horizon",
                h,
                "a validation over no plant time says nothing; give one such as \"10min\"".into(),
            ));
        }
        v.horizon_us = us;
    }
    if let Some(r) = &u.revalidate {
        v.revalidate_us = duration::parse_us(r, Bare::Seconds)
            .map_err(|e| value_error("[updates] revalidate", r, e.to_string()))?;
    }
    if let Some(share) = u.throughput_share {
        if !(0.0..=1.0).contains(&share) {
            return Err(value_error(
                "[updates] throughput_share",
                &share.to_string(),
                "a share is between 0 and 1, e.g. 0.9 for 90 %".into(),
            ));
        }
        v.throughput_share = share;
    }
    Ok(v)
}

/// `[updates] gate_*`: the analysis gate's budget and policy.
fn gate_policy(
    u: &UpdatesSection,
    value_error: impl Fn(&'static str, &str, String) -> ConfigError,
) -> Result<GatePolicy, ConfigError> {
    let mut g = GatePolicy::default();
    if let Some(n) = u.gate_max_states {
        if n == 0 {
            return Err(value_error(
                "[updates] gate_max_states",
                "0",
                "the gate could not look at a single state; give a positive number, or remove the key for 200000".into(),
            ));
        }
        g.max_states = n;
    }
    if let Some(t) = &u.gate_time {
        let us = duration::parse_us(t, Bare::Seconds)
            .map_err(|e| value_error("[updates] gate_time", t, e.to_string()))?;
        g.time = std::time::Duration::from_micros(us);
    }
    for (key, value, slot) in [
        ("[updates] gate_deadlock", &u.gate_deadlock, &mut g.deadlock),
        (
            "[updates] gate_lost_transitions",
            &u.gate_lost_transitions,
            &mut g.lost_transitions,
        ),
        (
            "[updates] gate_broken_invariants",
            &u.gate_broken_invariants,
            &mut g.broken_invariants,
        ),
    ] {
        if let Some(v) = value {
            *slot = v
                .parse()
                .map_err(|e: cetratus_vocab::UnknownName| value_error(key, v, e.to_string()))?;
        }
    }
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gate::Severity;

    fn dir_with(config: &str) -> PathBuf {
        static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let d = std::env::temp_dir().join(format!(
            "cetratus-config-{}-{}",
            std::process::id(),
            N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&d).unwrap();
        owner_only(&d);
        std::fs::write(d.join("config.toml"), config).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(
            d.join("config.toml"),
            std::fs::Permissions::from_mode(0o600),
        )
        .unwrap();
        d
    }

    fn owner_only(d: &Path) {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(d, std::fs::Permissions::from_mode(0o700)).unwrap();
    }

    #[test]
    fn an_operators_path_that_is_a_file_or_unreadable_stops_the_start() {
        let d = dir_with("");
        std::fs::write(d.join("operators"), "not a directory").unwrap();
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(
            e.contains("operators") && e.contains("not a directory"),
            "{e}"
        );
    }

    #[test]
    fn a_configuration_others_can_write_is_refused() {
        use std::os::unix::fs::PermissionsExt;
        let d = dir_with("");
        std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o777)).unwrap();
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(
            e.contains("writable by others") && e.contains("chmod go-w"),
            "{e}"
        );
        owner_only(&d);
        std::fs::create_dir(d.join("operators")).unwrap();
        std::fs::set_permissions(d.join("operators"), std::fs::Permissions::from_mode(0o775))
            .unwrap();
        assert!(LocalConfig::load(Some(&d)).is_err());
    }

    #[test]
    fn a_missing_directory_is_the_defaults() {
        let c = LocalConfig::load(Some(Path::new("/nonexistent/cetratus-config"))).unwrap();
        assert!(!c.allow_unsigned && c.operators.is_none() && c.users.is_empty());
        assert_eq!(c.probation_us, 60_000_000, "a minute of probation");
    }

    #[test]
    fn the_reserved_sections_may_be_present_and_empty() {
        let d = dir_with("[io]\n[dashboard]\n[updates]\nprobation = \"0s\"\n");
        assert!(LocalConfig::load(Some(&d)).is_ok());
    }

    #[test]
    fn an_unknown_key_names_the_file_line_and_the_keys_known() {
        let d = dir_with("[updates]\nprobation = \"0s\"\nhorizn = \"10min\"\n");
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(e.contains("config.toml:3:1"), "{e}");
        assert!(e.contains("horizn") && e.contains("probation"), "{e}");
        assert!(e.contains("docs/configuration.md"), "{e}");
        let d = dir_with("[io]\ndevice = 1\n");
        assert!(LocalConfig::load(Some(&d)).is_err());
    }

    #[test]
    fn the_validation_settings_are_read_and_commission_needs_a_twin() {
        let c = LocalConfig::load(Some(&dir_with("[updates]\n"))).unwrap();
        assert_eq!(c.validation, ValidationPolicy::default());
        assert!(!c.require_verdict);
        let d = dir_with(
            "[updates]\nvalidation = \"commission\"\nvalidation_twin = \"festo\"\nhorizon = \"2min\"\nthroughput_share = 0.8\nrequire_verdict = true\nrevalidate = \"30s\"\n",
        );
        let c = LocalConfig::load(Some(&d)).unwrap();
        assert_eq!(
            c.validation.mode,
            ValidationMode::Commission(cetratus_twin::TwinKind::Festo)
        );
        assert_eq!(
            (c.validation.horizon_us, c.validation.throughput_share),
            (120_000_000, 0.8)
        );
        assert_eq!(c.validation.revalidate_us, 30_000_000);
        assert_eq!(
            ValidationPolicy::default().revalidate_us,
            10_000_000,
            "every 10 s of the window by default"
        );
        let e = LocalConfig::load(Some(&dir_with("[updates]\nrevalidate = \"often\"\n")))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("[updates] revalidate"), "{e}");
        assert!(c.limits(Limits::for_period_us(10_000)).require_verdict);
        let e = LocalConfig::load(Some(&dir_with("[updates]\nvalidation = \"commission\"\n")))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("validation_twin"), "{e}");
        let e = LocalConfig::load(Some(&dir_with("[updates]\nthroughput_share = 90\n")))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("between 0 and 1"), "{e}");
    }

    #[test]
    fn fork_validation_needs_a_twin_to_fork() {
        let c = LocalConfig::load(Some(&dir_with("[updates]\nvalidation = \"fork\"\n"))).unwrap();
        assert!(c.check_validation(true).is_ok());
        let e = c.check_validation(false).unwrap_err().to_string();
        assert!(
            e.contains("validation = \"fork\"") && e.contains("--twin"),
            "{e}"
        );
        assert!(e.contains("config.toml"), "{e}");
        let off = LocalConfig::load(Some(&dir_with("[updates]\n"))).unwrap();
        assert!(off.check_validation(false).is_ok());
    }

    #[test]
    fn auto_substitute_needs_its_keys_and_a_validation() {
        let ok = "[updates]\nvalidation = \"fork\"\nauto_substitute = \"on-pass\"\nauto_substitute_keys = [\"0011223344556677\"]\n";
        let c = LocalConfig::load(Some(&dir_with(ok))).unwrap();
        assert_eq!(
            c.auto_substitute,
            Some(AutoSubstitute {
                keys: vec!["0011223344556677".into()]
            })
        );
        for bad in [
            "[updates]\nvalidation = \"fork\"\nauto_substitute = \"on-pass\"\n",
            "[updates]\nauto_substitute = \"on-pass\"\nauto_substitute_keys = [\"00\"]\n",
            "[updates]\nauto_substitute = \"always\"\n",
        ] {
            let e = LocalConfig::load(Some(&dir_with(bad)))
                .err()
                .unwrap()
                .to_string();
            assert!(e.contains("[updates] auto_substitute"), "{e}");
        }
    }

    #[test]
    fn the_gate_policy_is_read_and_a_wrong_value_names_its_key() {
        let c = LocalConfig::load(Some(&dir_with("[updates]\n"))).unwrap();
        assert_eq!(c.gate, GatePolicy::default());
        let d = dir_with(
            "[updates]\ngate_deadlock = \"refuse\"\ngate_max_states = 50\ngate_time = \"100ms\"\n",
        );
        let c = LocalConfig::load(Some(&d)).unwrap();
        assert_eq!(c.gate.deadlock, Severity::Refuse);
        assert_eq!(c.gate.lost_transitions, Severity::Warn);
        assert_eq!((c.gate.max_states, c.gate.time.as_millis()), (50, 100));
        let d = dir_with("[updates]\ngate_lost_transitions = \"block\"\n");
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(
            e.contains("gate_lost_transitions") && e.contains("\"refuse\""),
            "{e}"
        );
    }

    #[test]
    fn the_probation_window_is_read_and_0s_turns_it_off() {
        for (text, us) in [
            ("\"10s\"", 10_000_000),
            ("\"0s\"", 0),
            ("\"2min\"", 120_000_000),
        ] {
            let d = dir_with(&format!("[updates]\nprobation = {text}\n"));
            let c = LocalConfig::load(Some(&d)).unwrap();
            assert_eq!(c.probation_us, us, "{text}");
            assert_eq!(c.limits(Limits::for_period_us(10_000)).probation_us, us);
        }
        let d = dir_with("[updates]\nprobation = \"soon\"\n");
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(e.contains("[updates] probation"), "{e}");
    }

    #[test]
    fn state_trans_timeout_and_the_candidate_work_budget_replace_the_limits_of_the_period() {
        let period = Limits::for_period_us(10_000);
        let d =
            dir_with("[updates]\nstate_trans_timeout = \"25ms\"\ncandidate_work_budget = 500\n");
        let c = LocalConfig::load(Some(&d)).unwrap();
        let l = c.limits(period);
        assert_eq!(l.state_trans_timeout_ns, 25_000_000);
        assert_eq!(l.candidate_work_budget, 500);
        assert_eq!(l.watchdog_ns, period.watchdog_ns);
        let c = LocalConfig::load(Some(Path::new("/nonexistent/cetratus-config"))).unwrap();
        assert_eq!(
            c.limits(period).state_trans_timeout_ns,
            10_000_000,
            "one period"
        );
    }

    #[test]
    fn a_zero_state_trans_timeout_or_work_budget_is_refused_with_what_to_write() {
        let d = dir_with("[updates]\nstate_trans_timeout = \"0s\"\n");
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(
            e.contains("[updates] state_trans_timeout") && e.contains("10ms"),
            "{e}"
        );
        let d = dir_with("[updates]\ncandidate_work_budget = 0\n");
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(e.contains("[updates] candidate_work_budget"), "{e}");
    }

    #[test]
    fn a_bad_replay_window_names_its_key() {
        let d = dir_with("replay_window = \"soon\"\n");
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(e.contains("replay_window") && e.contains("soon"), "{e}");
    }
}
