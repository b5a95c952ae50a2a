//! Who may do what on the embedded broker (docs/security.md): the accounts of `[mqtt] users`,
//! each with the PLCs it may command, and the two logins the PLC's process makes for itself.
//!
//! * The PLC's own client logs in as [`PLC_USER`] with a secret drawn at every start and never
//!   written anywhere; only it may publish under `cetratus/<its id>/` anything but commands
//!   (`state`, `exec_info`, `io`, `net`, `events`, `reply/…`).
//! * The dashboard in the same process logs in as [`DASHBOARD_USER`], with a secret of its own,
//!   and may command that PLC only.
//! * An account may publish `cetratus/<plc>/cmd/<verb>` for the PLCs of its `plcs` (`"*"`: all),
//!   and anything outside `cetratus/`.
//! * Without accounts the broker is anonymous (loopback only): anyone may command, but still only
//!   the PLC publishes its state.
//!
//! The names of the two internal logins start with `$`, which no account name may contain.

use std::collections::{HashMap, HashSet};
use std::net::SocketAddr;
use std::path::PathBuf;

use subtle::ConstantTimeEq as _;

use crate::password::HashedPassword;
use crate::MctError;

/// The user name the PLC's own client logs in with.
pub const PLC_USER: &str = "$cetratus-plc";
/// The user name the dashboard of `cetratus run` logs in with.
pub const DASHBOARD_USER: &str = "$cetratus-dashboard";

/// What the client ids of the process's own clients start with: inside the ids that start with
/// `$`, which the embedded broker refuses to every other login ([`is_internal_client_id`]). A
/// broker drops the older of two clients with one id, so whoever took the PLC's id would cut the
/// PLC off its own control plane.
pub const INTERNAL_CLIENT_ID_PREFIX: &str = "$cetratus-";

/// The client id of one of the process's own clients, named `name` (the PLC's id, or the
/// dashboard's).
pub fn internal_client_id(name: &str) -> String {
    format!("{INTERNAL_CLIENT_ID_PREFIX}{name}")
}

/// The client id of the PLC `plc`'s own client on its embedded broker.
pub fn plc_client_id(plc: &str) -> String {
    internal_client_id(&format!("plc-{plc}"))
}

/// Whether `client_id` is reserved for the process's own clients: any id that starts with `$`,
/// as the names of their logins do.
pub fn is_internal_client_id(client_id: &str) -> bool {
    client_id.starts_with('$')
}

/// An account of the embedded broker, as the local configuration gives it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BrokerAccount {
    /// The user name: 1 to 64 letters, digits, `.`, `_` or `-`.
    pub name: String,
    /// The argon2 hash of its password, as a PHC string.
    pub password_hash: String,
    /// The PLC ids it may command; `"*"` stands for every PLC. Empty: it may only read.
    pub plcs: Vec<String>,
}

/// The certificate chain and private key (PEM files) the embedded broker serves TLS with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BrokerTls {
    /// The certificate chain, PEM.
    pub cert: PathBuf,
    /// The private key, PEM.
    pub key: PathBuf,
}

/// How the embedded broker listens and whom it lets in.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BrokerSettings {
    /// Where it listens; port 0 picks a free port.
    pub addr: SocketAddr,
    /// The accounts; none makes the broker anonymous, which only loopback allows.
    pub accounts: Vec<BrokerAccount>,
    /// TLS on `addr`; required beyond loopback.
    pub tls: Option<BrokerTls>,
}

impl BrokerSettings {
    /// An anonymous broker without TLS on `addr` (loopback only).
    pub fn open(addr: SocketAddr) -> Self {
        BrokerSettings {
            addr,
            accounts: Vec::new(),
            tls: None,
        }
    }

    /// Refuses to expose the broker beyond loopback without TLS and accounts.
    pub(crate) fn check_exposure(&self) -> Result<(), MctError> {
        if self.addr.ip().is_loopback() {
            return Ok(());
        }
        let missing = match (self.tls.is_some(), !self.accounts.is_empty()) {
            (true, true) => return Ok(()),
            (false, false) => "TLS and accounts",
            (false, true) => "TLS",
            (true, false) => "accounts",
        };
        Err(MctError::Exposed {
            addr: self.addr,
            missing,
        })
    }
}

/// A login drawn by the process for itself: a reserved user name and a random secret.
#[derive(Clone)]
pub struct Login {
    /// The user name ([`PLC_USER`] or [`DASHBOARD_USER`]).
    pub user: String,
    /// 256 random bits in hex.
    pub password: String,
}

impl std::fmt::Debug for Login {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Login").field("user", &self.user).finish()
    }
}

impl Login {
    fn draw(user: &str) -> Result<Self, MctError> {
        let mut secret = [0u8; 32];
        getrandom::fill(&mut secret).map_err(|e| MctError::Random(e.to_string()))?;
        Ok(Login {
            user: user.to_string(),
            password: hex::encode(secret),
        })
    }

    fn matches(&self, password: &[u8]) -> bool {
        self.password.as_bytes().ct_eq(password).into()
    }
}

/// Which PLCs an account may command.
#[derive(Debug)]
enum Commands {
    All,
    Only(HashSet<String>),
}

/// Who a client is, as far as the ACL cares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Who<'a> {
    /// The PLC's own client.
    Plc,
    /// The dashboard of the PLC's process.
    Dashboard,
    /// A configured account.
    Account(&'a str),
    /// No login (an anonymous broker).
    Anonymous,
}

/// What a client presented at CONNECT, checked.
pub(crate) enum Checked<'a> {
    /// One of the process's own logins, with the right secret.
    Internal,
    /// A configured account: its hash must be checked (slowly) against the password.
    Account(&'a HashedPassword),
    /// An unknown name: check the decoy, then refuse.
    Unknown,
    /// A reserved name with a wrong secret: refuse at once.
    Refused,
    /// Any name on an anonymous broker.
    Anonymous,
}

/// The accounts, the internal logins and the rules.
pub(crate) struct Acl {
    plc: String,
    plc_login: Login,
    dashboard_login: Login,
    accounts: HashMap<String, (HashedPassword, Commands)>,
    decoy: HashedPassword,
}

fn valid_name(name: &str) -> bool {
    (1..=64).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'))
}

impl Acl {
    /// Checks the accounts and draws the internal logins for the PLC `plc`.
    pub(crate) fn new(plc: &str, accounts: &[BrokerAccount]) -> Result<Self, MctError> {
        let bad = |name: &str, reason: String| MctError::Account {
            name: name.chars().take(64).collect(),
            reason,
        };
        let mut map = HashMap::new();
        for a in accounts {
            if !valid_name(&a.name) {
                return Err(bad(
                    &a.name,
                    "a name is 1 to 64 letters, digits, `.`, `_` or `-`".into(),
                ));
            }
            let hash = HashedPassword::parse(&a.password_hash).map_err(|e| {
                bad(
                    &a.name,
                    format!(
                        "`password_hash` is not an argon2 hash: {e}; write the output of \
                         `cetratus hash-password`"
                    ),
                )
            })?;
            let commands = if a.plcs.iter().any(|p| p == "*") {
                Commands::All
            } else {
                Commands::Only(a.plcs.iter().cloned().collect())
            };
            if map.insert(a.name.clone(), (hash, commands)).is_some() {
                return Err(bad(&a.name, "the name is given twice".into()));
            }
        }
        Ok(Acl {
            plc: plc.to_string(),
            plc_login: Login::draw(PLC_USER)?,
            dashboard_login: Login::draw(DASHBOARD_USER)?,
            accounts: map,
            decoy: HashedPassword::decoy(),
        })
    }

    /// Whether the broker lets clients in without a login.
    pub(crate) fn anonymous(&self) -> bool {
        self.accounts.is_empty()
    }

    /// The PLC's own login.
    pub(crate) fn plc_login(&self) -> &Login {
        &self.plc_login
    }

    /// The login of the dashboard in the PLC's process.
    pub(crate) fn dashboard_login(&self) -> &Login {
        &self.dashboard_login
    }

    /// The first, fast step of a login: the internal names are settled here; an account needs its
    /// hash checked.
    pub(crate) fn check(&self, user: &str, password: &[u8]) -> Checked<'_> {
        if user == PLC_USER || user == DASHBOARD_USER {
            let login = if user == PLC_USER {
                &self.plc_login
            } else {
                &self.dashboard_login
            };
            return if login.matches(password) {
                Checked::Internal
            } else {
                Checked::Refused
            };
        }
        if self.anonymous() {
            return Checked::Anonymous;
        }
        match self.accounts.get(user) {
            Some((hash, _)) => Checked::Account(hash),
            None => Checked::Unknown,
        }
    }

    /// The hash a wrong name is checked against.
    pub(crate) fn decoy(&self) -> &HashedPassword {
        &self.decoy
    }

    /// Who a logged-in client is, from the user name it logged in with.
    pub(crate) fn who<'a>(&self, user: Option<&'a str>) -> Who<'a> {
        match user {
            Some(PLC_USER) => Who::Plc,
            Some(DASHBOARD_USER) => Who::Dashboard,
            Some(name) if self.accounts.contains_key(name) => Who::Account(name),
            _ => Who::Anonymous,
        }
    }

    /// Whether `who` may publish on `topic`; `Err` says why not.
    pub(crate) fn may_publish(&self, who: Who<'_>, topic: &str) -> Result<(), &'static str> {
        let mut levels = topic.splitn(4, '/');
        if levels.next() != Some(cetratus_proto::ROOT) {
            return Ok(());
        }
        let plc = levels.next().unwrap_or_default();
        let command = levels.next() == Some("cmd");
        match who {
            Who::Plc if plc == self.plc && !command => Ok(()),
            Who::Plc => Err("the PLC publishes only its own topics"),
            _ if !command => {
                Err("only the PLC itself publishes its state, figures, events and replies")
            }
            Who::Dashboard if plc == self.plc => Ok(()),
            Who::Dashboard => Err("the dashboard of this PLC commands only this PLC"),
            Who::Anonymous if self.anonymous() => Ok(()),
            Who::Anonymous => Err("log in to command a PLC"),
            Who::Account(name) => match self.accounts.get(name) {
                Some((_, Commands::All)) => Ok(()),
                Some((_, Commands::Only(plcs))) if plcs.contains(plc) => Ok(()),
                _ => Err("this account may not command this PLC; see `plcs` in [mqtt] users"),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // A real argon2 hash of "pw"; parsing is all these tests need of it.
    const HASH: &str = "$argon2id$v=19$m=19456,t=2,p=1$c29tZXNhbHRzb21lc2FsdA$0XzFlcxA4ud8sQUEA0Mh3kydlsDtqHZ2d9LV1Fm5bfg";

    fn acl() -> Acl {
        Acl::new(
            "cell1",
            &[
                BrokerAccount {
                    name: "ops".into(),
                    password_hash: HASH.into(),
                    plcs: vec!["cell1".into()],
                },
                BrokerAccount {
                    name: "viewer".into(),
                    password_hash: HASH.into(),
                    plcs: vec![],
                },
                BrokerAccount {
                    name: "fleet".into(),
                    password_hash: HASH.into(),
                    plcs: vec!["*".into()],
                },
            ],
        )
        .expect("accounts")
    }

    #[test]
    fn an_account_commands_only_the_plcs_it_is_allowed() {
        let a = acl();
        let ops = a.who(Some("ops"));
        assert!(a.may_publish(ops, "cetratus/cell1/cmd/abort").is_ok());
        assert!(a.may_publish(ops, "cetratus/cell2/cmd/abort").is_err());
        assert!(a
            .may_publish(a.who(Some("viewer")), "cetratus/cell1/cmd/abort")
            .is_err());
        assert!(a
            .may_publish(a.who(Some("fleet")), "cetratus/cell9/cmd/load")
            .is_ok());
        assert!(a.may_publish(ops, "plant/anything").is_ok());
    }

    #[test]
    fn only_the_plc_publishes_its_state_figures_events_and_replies() {
        let a = acl();
        for leaf in [
            "state",
            "exec_info",
            "io",
            "net",
            "events",
            "reply/x",
            "other",
        ] {
            let topic = format!("cetratus/cell1/{leaf}");
            assert!(a.may_publish(Who::Plc, &topic).is_ok(), "{topic}");
            for who in [a.who(Some("fleet")), Who::Dashboard, Who::Anonymous] {
                assert!(a.may_publish(who, &topic).is_err(), "{who:?} {topic}");
            }
        }
        assert!(a.may_publish(Who::Plc, "cetratus/cell2/state").is_err());
        assert!(a.may_publish(Who::Plc, "cetratus/cell1/cmd/load").is_err());
        assert!(a
            .may_publish(Who::Dashboard, "cetratus/cell1/cmd/load")
            .is_ok());
        assert!(a
            .may_publish(Who::Dashboard, "cetratus/cell2/cmd/load")
            .is_err());
    }

    #[test]
    fn a_claimed_internal_name_needs_its_secret() {
        let a = acl();
        assert!(matches!(a.check(PLC_USER, b"guess"), Checked::Refused));
        let secret = a.plc_login().password.clone();
        assert!(matches!(
            a.check(PLC_USER, secret.as_bytes()),
            Checked::Internal
        ));
        assert!(matches!(
            a.check(DASHBOARD_USER, secret.as_bytes()),
            Checked::Refused
        ));
        assert!(matches!(a.check("nobody", b"pw"), Checked::Unknown));
        assert!(matches!(a.check("ops", b"pw"), Checked::Account(_)));
        assert_eq!(a.who(Some("nobody")), Who::Anonymous);
    }

    #[test]
    fn bad_accounts_are_refused_with_what_to_do() {
        let one = |name: &str, hash: &str| {
            Acl::new(
                "cell1",
                &[BrokerAccount {
                    name: name.into(),
                    password_hash: hash.into(),
                    plcs: vec![],
                }],
            )
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
        };
        assert!(one("ops", "s3cret").contains("cetratus hash-password"));
        assert!(one("$cetratus-plc", HASH).contains("letters"));
        let twice = Acl::new(
            "cell1",
            &[
                BrokerAccount {
                    name: "a".into(),
                    password_hash: HASH.into(),
                    plcs: vec![],
                },
                BrokerAccount {
                    name: "a".into(),
                    password_hash: HASH.into(),
                    plcs: vec![],
                },
            ],
        );
        assert!(twice
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
            .contains("twice"));
    }

    #[test]
    fn beyond_loopback_the_broker_needs_tls_and_accounts() {
        let mut s = BrokerSettings::open("0.0.0.0:1883".parse().expect("addr"));
        let e = s.check_exposure().expect_err("open").to_string();
        assert!(
            e.contains("TLS and accounts") && e.contains("0.0.0.0:1883"),
            "{e}"
        );
        s.tls = Some(BrokerTls {
            cert: "c.pem".into(),
            key: "k.pem".into(),
        });
        s.accounts.push(BrokerAccount {
            name: "ops".into(),
            password_hash: HASH.into(),
            plcs: vec![],
        });
        assert!(s.check_exposure().is_ok());
        assert!(
            BrokerSettings::open("127.0.0.1:1883".parse().expect("addr"))
                .check_exposure()
                .is_ok()
        );
    }
}
