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
//! A missing directory is an empty configuration. Each section of `config.toml` checks itself
//! (`config/sections.rs`); [`LocalConfig::load`] puts them together with the keys.

mod private;
mod sections;

use std::path::{Path, PathBuf};

use cetratus_mct::{BrokerAccount, BrokerTls, OperatorKeys};
use cetratus_program::{TrustStore, VerifyingKeyFile};
use cetratus_runtime::Limits;

use crate::gate::GatePolicy;
use crate::validate::{AutoSubstitute, ValidationMode, ValidationPolicy};
use sections::{File, Origin, Settings};

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
    /// How long an operator's revert may wait for a marking that agrees with the plant, µs.
    pub revert_wait_us: u64,
    /// The least cycles of quarantine, compared with the twin's signature, before a pass.
    pub quarantine_cycles: u64,
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
    pub candidate_instruction_budget: Option<u64>,
    /// The work budget of a primary scan; `None`: ten times a candidate's default.
    pub primary_instruction_budget: Option<u64>,
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
    /// `[labels]`: published in the retained `state`, for selectors (docs/fleet.md).
    pub labels: cetratus_proto::Labels,
}

/// The keys of the configuration directory, beside `config.toml`.
#[derive(Default)]
struct Keys {
    /// `trusted/`.
    trust: TrustStore,
    /// `operators/`; `None` when it holds none.
    operators: Option<OperatorKeys>,
}

impl Default for LocalConfig {
    /// No local configuration: no keys, no accounts, no field I/O, and the defaults of every
    /// section.
    fn default() -> Self {
        LocalConfig::of(PathBuf::new(), Keys::default(), Settings::default())
    }
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

impl LocalConfig {
    /// Loads the configuration from `dir`, or from [`default_dir`].
    pub fn load(dir: Option<&Path>) -> Result<LocalConfig, ConfigError> {
        let dir = dir.map_or_else(default_dir, Path::to_path_buf);
        let file_path = dir.join("config.toml");
        let (file, io) = File::read(&file_path)?;
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
        let at = Origin {
            dir: &dir,
            file: &file_path,
        };
        let replay_window = file.replay_window(&at)?;
        let labels = file.labels(&at)?;
        let updates = file.updates.check(&at)?;
        let mut ops = OperatorKeys::new(replay_window);
        for k in keys_in(&dir.join("operators"), "operator")? {
            ops.add(k.key_id(), *k.verifying_key());
        }
        let mqtt = file.mqtt.check(&at)?;
        let dashboard = file.dashboard.check(&at)?;
        let keys = Keys {
            trust,
            operators: (!ops.is_empty()).then_some(ops),
        };
        let settings = Settings {
            allow_unsigned: file.allow_unsigned,
            io,
            mqtt,
            dashboard,
            updates,
            labels,
        };
        Ok(LocalConfig::of(dir, keys, settings))
    }

    /// The configuration of `dir`: the one place the sections' fields become its own, so that
    /// [`LocalConfig::load`] and [`Default`] cannot map them differently.
    fn of(dir: PathBuf, keys: Keys, s: Settings) -> LocalConfig {
        let (mqtt, dashboard, updates) = (s.mqtt, s.dashboard, s.updates);
        LocalConfig {
            dir,
            trust: keys.trust,
            allow_unsigned: s.allow_unsigned,
            operators: keys.operators,
            users: mqtt.users,
            mqtt_tls: mqtt.tls,
            dashboard_tls: dashboard.tls,
            credentials: mqtt.credentials,
            probation_us: updates.probation_us,
            revert_wait_us: updates.revert_wait_us,
            quarantine_cycles: updates.quarantine_cycles,
            dashboard_accounts: dashboard.accounts,
            dashboard_hosts: dashboard.hosts,
            state_trans_timeout_us: updates.state_trans_timeout_us,
            candidate_instruction_budget: updates.candidate_instruction_budget,
            primary_instruction_budget: updates.primary_instruction_budget,
            io: s.io,
            gate: updates.gate,
            validation: updates.validation,
            require_verdict: updates.require_verdict,
            auto_substitute: updates.auto_substitute,
            labels: s.labels,
        }
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
            revert_wait_us: self.revert_wait_us,
            quarantine_cycles: self.quarantine_cycles,
            require_verdict: self.require_verdict,
            state_trans_timeout_ns: self
                .state_trans_timeout_us
                .map_or(limits.state_trans_timeout_ns, |us| us.saturating_mul(1000)),
            candidate_instruction_budget: self
                .candidate_instruction_budget
                .unwrap_or(limits.candidate_instruction_budget),
            primary_instruction_budget: self
                .primary_instruction_budget
                .unwrap_or(limits.primary_instruction_budget),
            ..limits
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gate::Severity;

    fn empty_dir() -> PathBuf {
        static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let d = std::env::temp_dir().join(format!(
            "cetratus-config-{}-{}",
            std::process::id(),
            N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&d).unwrap();
        owner_only(&d);
        d
    }

    fn dir_with(config: &str) -> PathBuf {
        let d = empty_dir();
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

    /// Every field but `dir`, as text to compare.
    fn comparable(c: &LocalConfig) -> String {
        format!(
            "{:?} {:?}",
            (
                c.trust.len(),
                c.allow_unsigned,
                c.operators.is_none(),
                &c.users,
                &c.mqtt_tls,
                &c.dashboard_tls,
                &c.credentials,
                c.probation_us,
                &c.dashboard_accounts,
                &c.dashboard_hosts,
            ),
            (
                c.state_trans_timeout_us,
                c.candidate_instruction_budget,
                &c.io,
                c.gate,
                c.validation,
                c.require_verdict,
                &c.auto_substitute,
            )
        )
    }

    #[test]
    fn an_empty_directory_an_empty_file_and_empty_sections_are_the_default() {
        let default = comparable(&LocalConfig::default());
        for d in [
            empty_dir(),
            dir_with(""),
            dir_with("[mqtt]\n[io]\n[dashboard]\n[updates]\n"),
        ] {
            let c = LocalConfig::load(Some(&d)).unwrap();
            assert_eq!(comparable(&c), default, "{}", d.display());
        }
        assert_eq!(LocalConfig::default().dir, PathBuf::new());
        assert_eq!(LocalConfig::default().probation_us, DEFAULT_PROBATION_US);
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
    fn an_operators_revert_waits_two_seconds_unless_revert_wait_says_otherwise() {
        let limits = |c: &LocalConfig| c.limits(Limits::for_period_us(10_000)).revert_wait_us;
        assert_eq!(limits(&LocalConfig::default()), 2_000_000);
        let d = dir_with("[updates]\nrevert_wait = \"500ms\"\n");
        assert_eq!(limits(&LocalConfig::load(Some(&d)).unwrap()), 500_000);
        let d = dir_with("[updates]\nrevert_wait = \"a while\"\n");
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(e.contains("[updates] revert_wait"), "{e}");
    }

    #[test]
    fn state_trans_timeout_and_the_candidate_instruction_budget_replace_the_limits_of_the_period() {
        let period = Limits::for_period_us(10_000);
        let d = dir_with(
            "[updates]\nstate_trans_timeout = \"25ms\"\ncandidate_instruction_budget = 500\n",
        );
        let c = LocalConfig::load(Some(&d)).unwrap();
        let l = c.limits(period);
        assert_eq!(l.state_trans_timeout_ns, 25_000_000);
        assert_eq!(l.candidate_instruction_budget, 500);
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
        let d = dir_with("[updates]\ncandidate_instruction_budget = 0\n");
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(e.contains("[updates] candidate_instruction_budget"), "{e}");
    }

    #[test]
    fn a_bad_replay_window_names_its_key() {
        let d = dir_with("replay_window = \"soon\"\n");
        let e = LocalConfig::load(Some(&d)).err().unwrap().to_string();
        assert!(e.contains("replay_window") && e.contains("soon"), "{e}");
    }
}
