//! The sections of `config.toml`, each twice: as serde reads it, and checked. A section's
//! `check` turns the first into the second or into the [`ConfigError`] that says what to write
//! instead; a key left out keeps the checked form's default, so that an absent file and an empty
//! one give the same configuration.

use std::path::{Path, PathBuf};

use cetratus_mct::{BrokerAccount, BrokerTls};
use cetratus_program::duration::{self, Bare};
use serde::Deserialize;

use super::{private, ConfigError, DEFAULT_PROBATION_US};
use crate::gate::GatePolicy;
use crate::validate::{AutoSubstitute, ValidationMode, ValidationPolicy};

/// Where the sections come from: the directory their file names resolve against, and
/// `config.toml`, which every refused value names.
pub(super) struct Origin<'a> {
    /// The configuration directory.
    pub dir: &'a Path,
    /// Its `config.toml`.
    pub file: &'a Path,
}

impl Origin<'_> {
    /// Refuses `key = value`; `reason` says why and what to write instead.
    fn refuse(&self, key: &'static str, value: &str, reason: impl Into<String>) -> ConfigError {
        ConfigError::Value {
            path: self.file.display().to_string(),
            key,
            value: value.to_string(),
            reason: reason.into(),
        }
    }

    /// The duration `value` of `key`, in µs; a bare number is seconds.
    fn duration(&self, key: &'static str, value: &str) -> Result<u64, ConfigError> {
        duration::parse_us(value, Bare::Seconds).map_err(|e| self.refuse(key, value, e.to_string()))
    }

    /// A section's TLS certificate and key, under the directory, each checked ([`private`]);
    /// `None` when neither is given. One without the other is refused, naming the one missing.
    fn tls(
        &self,
        section: &'static str,
        cert: Option<PathBuf>,
        key: Option<PathBuf>,
    ) -> Result<Option<(PathBuf, PathBuf)>, ConfigError> {
        let missing = match (cert, key) {
            (None, None) => return Ok(None),
            (Some(c), Some(k)) => {
                let (c, k) = (self.dir.join(c), self.dir.join(k));
                private::check_not_writable_by_others(&c)?;
                private::check_private_key(&k)?;
                return Ok(Some((c, k)));
            }
            (Some(_), None) => "tls_key",
            (None, Some(_)) => "tls_cert",
        };
        Err(self.refuse(
            section,
            missing,
            "TLS needs both `tls_cert` (the certificate chain, PEM) and `tls_key` (its private \
             key, PEM); give both, or neither",
        ))
    }
}

/// What `config.toml` decides, checked; the keys of the directory aside.
#[derive(Default)]
pub(super) struct Settings {
    /// Accept unsigned packages.
    pub allow_unsigned: bool,
    /// `[io]`, when it names a device or a server.
    pub io: Option<cetratus_io::config::IoConfig>,
    /// `[mqtt]`.
    pub mqtt: Mqtt,
    /// `[dashboard]`.
    pub dashboard: Dashboard,
    /// `[updates]`.
    pub updates: Updates,
    /// `[labels]`, checked.
    pub labels: cetratus_proto::Labels,
}

/// `config.toml` as serde reads it.
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct File {
    /// Accept unsigned packages.
    #[serde(default)]
    pub allow_unsigned: bool,
    /// The operator commands' replay window, checked by [`File::replay_window`].
    replay_window: Option<String>,
    /// `[mqtt]`.
    #[serde(default)]
    pub mqtt: MqttSection,
    /// `[io]`, which the schema must know; [`File::read`] takes its content from the text.
    #[serde(default, rename = "io")]
    _io: IoSection,
    /// `[dashboard]`.
    #[serde(default)]
    pub dashboard: DashboardSection,
    /// `[updates]`.
    #[serde(default)]
    pub updates: UpdatesSection,
    /// `[labels]`: the PLC's labels, checked by [`File::labels`].
    #[serde(default)]
    labels: cetratus_proto::Labels,
}

impl File {
    /// `[labels]`, each key and value as `cetratus_proto::check_labels` wants them.
    pub fn labels(&self, at: &Origin) -> Result<cetratus_proto::Labels, ConfigError> {
        cetratus_proto::check_labels(&self.labels).map_err(|e| ConfigError::Value {
            path: at.file.display().to_string(),
            key: "[labels]",
            value: (self.labels.iter())
                .map(|(k, v)| format!("{k} = {v:?}"))
                .collect::<Vec<_>>()
                .join(", "),
            reason: e.to_string(),
        })?;
        Ok(self.labels.clone())
    }

    /// Reads `path` against the schema, and its `[io]` section through `cetratus_io`, from the
    /// text so that its errors keep their lines. An absent file is an empty one.
    pub fn read(path: &Path) -> Result<(File, Option<cetratus_io::config::IoConfig>), ConfigError> {
        let bytes = match std::fs::read(path) {
            Ok(bytes) => bytes,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Ok((File::default(), None))
            }
            Err(source) => {
                return Err(ConfigError::Read {
                    path: path.display().to_string(),
                    source,
                })
            }
        };
        let text = cetratus_program::toml_text(bytes, &path.display().to_string())
            .map_err(ConfigError::NotUtf8)?;
        let file = toml::from_str(&text).map_err(|e| ConfigError::Schema {
            at: e.span().map_or_else(
                || path.display().to_string(),
                |s| position(path, &text, s.start),
            ),
            message: e.message().trim_end().to_string(),
        })?;
        let io = cetratus_io::config::IoConfig::from_local(&path.display().to_string(), &text)
            .map_err(ConfigError::Io)?;
        Ok((file, io))
    }

    /// The replay window of operator commands: `replay_window`, in whole seconds, else a
    /// minute; never under a second, or no command would be fresh.
    pub fn replay_window(&self, at: &Origin) -> Result<std::time::Duration, ConfigError> {
        let seconds = match &self.replay_window {
            Some(w) => at.duration("replay_window", w)? / 1_000_000,
            None => 60,
        };
        Ok(std::time::Duration::from_secs(seconds.max(1)))
    }
}

/// `file:line:column` of a byte offset of `text`.
fn position(path: &Path, text: &str, offset: usize) -> String {
    let offset = offset.min(text.len());
    let line = text[..offset].matches('\n').count() + 1;
    let col = offset - text[..offset].rfind('\n').map_or(0, |i| i + 1) + 1;
    format!("{}:{line}:{col}", path.display())
}

/// `[mqtt]` as serde reads it.
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct MqttSection {
    #[serde(default)]
    users: Vec<User>,
    user: Option<String>,
    password: Option<String>,
    tls_cert: Option<PathBuf>,
    tls_key: Option<PathBuf>,
}

/// `[mqtt]`, checked.
#[derive(Default)]
pub(super) struct Mqtt {
    /// The embedded broker's accounts.
    pub users: Vec<BrokerAccount>,
    /// Credentials for a plant broker.
    pub credentials: Option<(String, String)>,
    /// The embedded broker's TLS files.
    pub tls: Option<BrokerTls>,
}

impl MqttSection {
    /// Checks the accounts, in order, then the TLS files.
    pub fn check(self, at: &Origin) -> Result<Mqtt, ConfigError> {
        let users = self
            .users
            .into_iter()
            .map(|u| u.check(at))
            .collect::<Result<_, _>>()?;
        let tls = at
            .tls("[mqtt] tls", self.tls_cert, self.tls_key)?
            .map(|(cert, key)| BrokerTls { cert, key });
        let password = self.password;
        Ok(Mqtt {
            users,
            credentials: self.user.map(|u| (u, password.unwrap_or_default())),
            tls,
        })
    }
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

impl User {
    /// The account, which must give its password as a hash, and only so.
    fn check(self, at: &Origin) -> Result<BrokerAccount, ConfigError> {
        let password_hash = match (self.password_hash, self.password) {
            (Some(h), None) => h,
            (_, Some(_)) => {
                return Err(at.refuse(
                    "[[mqtt.users]] name",
                    &self.name,
                    "passwords are stored as hashes: replace `password = …` with \
                     `password_hash = …`, the output of `echo -n 'PASSWORD' | cetratus \
                     hash-password`",
                ))
            }
            (None, None) => {
                return Err(at.refuse(
                    "[[mqtt.users]] name",
                    &self.name,
                    "the account has no `password_hash`; add the output of \
                     `cetratus hash-password`",
                ))
            }
        };
        Ok(BrokerAccount {
            name: self.name,
            password_hash,
            plcs: self.plcs,
        })
    }
}

/// `[io]`: the node's I/O configuration, read and checked by `cetratus_io::config` from the
/// file's text (so that its errors keep their lines).
#[derive(Deserialize, Default)]
struct IoSection {}

/// `[dashboard]`: who may log in to the dashboard, and the host names it is reached under.
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct DashboardSection {
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

/// `[dashboard]`, checked.
#[derive(Default)]
pub(super) struct Dashboard {
    /// (name, argon2 hash as a PHC string); the dashboard checks the hashes when it starts.
    pub accounts: Vec<(String, String)>,
    /// Host names besides IP addresses and `localhost`.
    pub hosts: Vec<String>,
    /// The TLS certificate and key.
    pub tls: Option<(PathBuf, PathBuf)>,
}

impl DashboardSection {
    /// Checks the TLS files; the accounts' hashes are the dashboard's to check.
    pub fn check(self, at: &Origin) -> Result<Dashboard, ConfigError> {
        Ok(Dashboard {
            tls: at.tls("[dashboard] tls", self.tls_cert, self.tls_key)?,
            accounts: self
                .accounts
                .into_iter()
                .map(|a| (a.name, a.password_hash))
                .collect(),
            hosts: self.hosts,
        })
    }
}

/// `[updates]`: update policies.
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct UpdatesSection {
    probation: Option<String>,
    revert_wait: Option<String>,
    quarantine_cycles: Option<u64>,
    state_trans_timeout: Option<String>,
    candidate_instruction_budget: Option<u64>,
    primary_instruction_budget: Option<u64>,
    /// Retired: its unit changed (guard evaluations, now instructions); refused with the new key.
    candidate_work_budget: Option<toml::Value>,
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

/// `[updates]`, checked (the fields of the same names in [`super::LocalConfig`]).
pub(super) struct Updates {
    pub probation_us: u64,
    pub revert_wait_us: u64,
    pub quarantine_cycles: u64,
    pub state_trans_timeout_us: Option<u64>,
    pub candidate_instruction_budget: Option<u64>,
    pub primary_instruction_budget: Option<u64>,
    pub gate: GatePolicy,
    pub validation: ValidationPolicy,
    pub require_verdict: bool,
    pub auto_substitute: Option<AutoSubstitute>,
}

impl Default for Updates {
    fn default() -> Self {
        Updates {
            probation_us: DEFAULT_PROBATION_US,
            revert_wait_us: cetratus_runtime::DEFAULT_REVERT_WAIT_US,
            quarantine_cycles: cetratus_runtime::DEFAULT_QUARANTINE_CYCLES,
            state_trans_timeout_us: None,
            candidate_instruction_budget: None,
            primary_instruction_budget: None,
            gate: GatePolicy::default(),
            validation: ValidationPolicy::default(),
            require_verdict: false,
            auto_substitute: None,
        }
    }
}

impl UpdatesSection {
    /// Checks the keys in a fixed order, so that of several wrong values the same one is named.
    pub fn check(self, at: &Origin) -> Result<Updates, ConfigError> {
        let d = Updates::default();
        let probation_us = match &self.probation {
            Some(p) => at.duration("[updates] probation", p)?,
            None => d.probation_us,
        };
        let revert_wait_us = match &self.revert_wait {
            Some(w) => at.duration("[updates] revert_wait", w)?,
            None => d.revert_wait_us,
        };
        if let Some(0) = self.quarantine_cycles {
            return Err(at.refuse(
                "[updates] quarantine_cycles",
                "0",
                "a quarantine verdict needs some cycles on the plant; give a positive number, or remove the key for 500",
            ));
        }
        let state_trans_timeout_us = match &self.state_trans_timeout {
            Some(t) => match at.duration("[updates] state_trans_timeout", t)? {
                0 => return Err(at.refuse(
                    "[updates] state_trans_timeout",
                    t,
                    "no install can take 0 µs; give a duration such as \"10ms\", or remove the key for one scan period",
                )),
                us => Some(us),
            },
            None => d.state_trans_timeout_us,
        };
        if let Some(old) = &self.candidate_work_budget {
            return Err(at.refuse(
                "[updates] candidate_work_budget",
                &old.to_string(),
                "this key is retired: it counted guard evaluations, whatever their size; write `candidate_instruction_budget`, which counts the instructions of guards and action bodies (the default is 25 per µs of the scan period), or remove the key for the default",
            ));
        }
        if let Some(0) = self.candidate_instruction_budget {
            return Err(at.refuse(
                "[updates] candidate_instruction_budget",
                "0",
                "a candidate could not evaluate a single guard; give a positive number, or remove the key for the default",
            ));
        }
        if let Some(0) = self.primary_instruction_budget {
            return Err(at.refuse(
                "[updates] primary_instruction_budget",
                "0",
                "the running program could not evaluate a single guard; give a positive number, or remove the key for the default",
            ));
        }
        let validation = self.validation_policy(d.validation, at)?;
        let auto_substitute = self.auto_substitute(validation.mode, at)?;
        let gate = self.gate_policy(d.gate, at)?;
        Ok(Updates {
            probation_us,
            revert_wait_us,
            quarantine_cycles: self.quarantine_cycles.unwrap_or(d.quarantine_cycles),
            state_trans_timeout_us,
            candidate_instruction_budget: self
                .candidate_instruction_budget
                .or(d.candidate_instruction_budget),
            primary_instruction_budget: self
                .primary_instruction_budget
                .or(d.primary_instruction_budget),
            gate,
            validation,
            require_verdict: self.require_verdict,
            auto_substitute,
        })
    }

    /// `validation`, `validation_twin`, `horizon`, `revalidate`, `throughput_share` over `v`.
    fn validation_policy(
        &self,
        mut v: ValidationPolicy,
        at: &Origin,
    ) -> Result<ValidationPolicy, ConfigError> {
        let twin = match &self.validation_twin {
            None => None,
            Some(t) => Some(
                t.parse::<cetratus_twin::TwinKind>()
                    .map_err(|e| at.refuse("[updates] validation_twin", t, e.to_string()))?,
            ),
        };
        v.mode = match (self.validation.as_deref(), twin) {
            (None | Some("off"), _) => ValidationMode::Off,
            (Some("fork"), _) => ValidationMode::Fork,
            (Some("commission"), Some(kind)) => ValidationMode::Commission(kind),
            (Some("commission"), None) => {
                return Err(at.refuse(
                    "[updates] validation",
                    "commission",
                    "commissioning runs fresh twins of a model: name it with validation_twin = \"vernadat\" or \"festo\"",
                ))
            }
            (Some(other), _) => {
                return Err(at.refuse(
                    "[updates] validation",
                    other,
                    "write \"off\", \"fork\" or \"commission\"",
                ))
            }
        };
        if let Some(h) = &self.horizon {
            v.horizon_us =
                match at.duration("[updates] horizon", h)? {
                    0 => return Err(at.refuse(
                        "[updates] horizon",
                        h,
                        "a validation over no plant time says nothing; give one such as \"10min\"",
                    )),
                    us => us,
                };
        }
        if let Some(r) = &self.revalidate {
            v.revalidate_us = at.duration("[updates] revalidate", r)?;
        }
        if let Some(share) = self.throughput_share {
            if !(0.0..=1.0).contains(&share) {
                return Err(at.refuse(
                    "[updates] throughput_share",
                    &share.to_string(),
                    "a share is between 0 and 1, e.g. 0.9 for 90 %",
                ));
            }
            v.throughput_share = share;
        }
        Ok(v)
    }

    /// `auto_substitute` and its keys, which need a validation `mode` to give a verdict.
    fn auto_substitute(
        &self,
        mode: ValidationMode,
        at: &Origin,
    ) -> Result<Option<AutoSubstitute>, ConfigError> {
        let key = "[updates] auto_substitute";
        match self.auto_substitute.as_deref() {
            None | Some("off") => Ok(None),
            Some("on-pass") if self.auto_substitute_keys.is_empty() => Err(at.refuse(
                key,
                "on-pass",
                "name the operator keys whose loads may be substituted by the PLC itself: auto_substitute_keys = [\"<key id>\"]",
            )),
            Some("on-pass") if mode == ValidationMode::Off => Err(at.refuse(
                key,
                "on-pass",
                "a substitution on a passing verdict needs twin validation: set validation = \"fork\" or \"commission\"",
            )),
            Some("on-pass") => Ok(Some(AutoSubstitute {
                keys: self.auto_substitute_keys.clone(),
            })),
            Some(other) => Err(at.refuse(key, other, "write \"off\" or \"on-pass\"")),
        }
    }

    /// `gate_*` over `g`: the analysis gate's budget and what each finding does.
    fn gate_policy(&self, mut g: GatePolicy, at: &Origin) -> Result<GatePolicy, ConfigError> {
        if let Some(n) = self.gate_max_states {
            if n == 0 {
                return Err(at.refuse(
                    "[updates] gate_max_states",
                    "0",
                    "the gate could not look at a single state; give a positive number, or remove the key for 200000",
                ));
            }
            g.max_states = n;
        }
        if let Some(t) = &self.gate_time {
            g.time = std::time::Duration::from_micros(at.duration("[updates] gate_time", t)?);
        }
        for (key, value, slot) in [
            (
                "[updates] gate_deadlock",
                &self.gate_deadlock,
                &mut g.deadlock,
            ),
            (
                "[updates] gate_lost_transitions",
                &self.gate_lost_transitions,
                &mut g.lost_transitions,
            ),
            (
                "[updates] gate_broken_invariants",
                &self.gate_broken_invariants,
                &mut g.broken_invariants,
            ),
        ] {
            if let Some(v) = value {
                *slot = v
                    .parse()
                    .map_err(|e: cetratus_vocab::UnknownName| at.refuse(key, v, e.to_string()))?;
            }
        }
        Ok(g)
    }
}
