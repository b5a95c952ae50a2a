//! Who may use the dashboard, and the checks that keep other web pages from using an operator's
//! browser against it (docs/dashboard.md, *Access*).
//!
//! * **Sessions.** Every `/api/` request but the login needs a session: a random 256-bit token in
//!   the cookie `cetratus_session`, `HttpOnly` (no script reads it) and `SameSite=Strict` (no
//!   other site's page makes the browser send it). Sessions end after [`SESSION_IDLE`] without a
//!   request; at most [`MAX_SESSIONS`] are kept, the least recently used going first.
//! * **One-time login links**, as Jupyter prints them: whoever can read the console of `cetratus
//!   run`, `demo` or `mct` may log in once with the link printed there, as the account `local`.
//! * **Accounts** with argon2 password hashes (`[dashboard] accounts` of the local
//!   configuration). Logins are rate-limited, for all clients together and per address, and
//!   every attempt is logged; the hash is checked on a blocking thread, never the server's.
//! * **Request checks.** The `Host` must be an IP address, `localhost`, or a name the
//!   configuration lists (a page that rebinds its own name to the dashboard's address gets
//!   nothing); a POST's `Origin`, when the browser sends one, must be the dashboard itself; and a
//!   POST must say `application/json` (or `application/octet-stream`, for a package), which a
//!   cross-site form cannot.
//!
//! Every store here is bounded in bytes: the entries have a fixed size (a 64-character token, an
//! account name of at most [`MAX_NAME`] bytes) and a fixed count.

use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use axum::http::{header, HeaderMap};
use cetratus_mct::logins::LoginGate;
pub use cetratus_mct::password::hash_password;
use cetratus_mct::password::HashedPassword;
use cetratus_slots::rate::{PerAddress, Rate};

/// The name of the session cookie.
pub const COOKIE: &str = "cetratus_session";

/// The account of a one-time login link: whoever could read the PLC's console.
pub const LOCAL_ACCOUNT: &str = "local";

/// Sessions kept at once; past it, the least recently used one ends.
pub const MAX_SESSIONS: usize = 64;

/// One-time login links not yet used, kept at once; past it, the oldest one is void.
pub const MAX_LINKS: usize = 16;

/// A session ends after this long without a request.
pub const SESSION_IDLE: Duration = Duration::from_secs(12 * 3600);

/// A login link is void after this long unused.
pub const LINK_LIFETIME: Duration = Duration::from_secs(24 * 3600);

/// Longest account name, in bytes.
pub const MAX_NAME: usize = 64;

/// Login attempts per second from all clients together, and the burst allowed above it.
const LOGINS: Rate = Rate {
    per_s: 4.0,
    burst: 8.0,
};

/// Login attempts per second from one address, and the burst allowed above it.
const LOGINS_PER_ADDRESS: Rate = Rate {
    per_s: 0.5,
    burst: 4.0,
};

/// A dashboard account: a name and its password's argon2 hash, as a PHC string
/// (`$argon2id$v=19$…`, what `cetratus hash-password` prints).
#[derive(Clone, Debug)]
pub struct Account {
    /// The name to log in with.
    pub name: String,
    /// The password's argon2 hash, in the PHC string format.
    pub password_hash: String,
}

/// Who may log in, and under which names the dashboard is reached.
#[derive(Clone, Debug, Default)]
pub struct AccessConfig {
    /// Accounts that log in with a password; none means only login links work.
    pub accounts: Vec<Account>,
    /// Host names the dashboard is reached under, besides IP addresses and `localhost`.
    pub hosts: Vec<String>,
}

/// Why an access configuration cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum AccessError {
    /// An account name is empty, too long, or uses other characters.
    #[error(
        "the dashboard account name `{0}` is not allowed: use 1 to {MAX_NAME} letters, digits, \
         `.`, `_` or `-`"
    )]
    BadName(String),
    /// The name of one-time login links was given to an account.
    #[error(
        "the dashboard account name `{LOCAL_ACCOUNT}` is reserved for login links; choose another"
    )]
    Reserved,
    /// Two accounts have the same name.
    #[error("the dashboard account `{0}` is defined twice; keep one")]
    Duplicate(String),
    /// A password hash is not an argon2 PHC string.
    #[error(
        "the password hash of the dashboard account `{name}` is not an argon2 hash: {reason}; \
         make one with `cetratus hash-password`"
    )]
    BadHash {
        /// The account.
        name: String,
        /// What the parser said.
        reason: cetratus_mct::password::PasswordError,
    },
}

/// Whether `name` may name an account.
fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_NAME
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'))
}

struct Session {
    account: String,
    last_seen: Instant,
}

struct Limits {
    /// All clients together, with a share for those who logged in before.
    all: LoginGate,
    /// Each address on its own.
    by_addr: PerAddress,
}

/// The dashboard's accounts, sessions and login links.
pub(crate) struct Access {
    accounts: HashMap<String, HashedPassword>,
    hosts: Vec<String>,
    sessions: Mutex<HashMap<String, Session>>,
    links: Mutex<HashMap<String, Instant>>,
    limits: Mutex<Limits>,
    /// Login attempts refused unchecked because they came too fast, since the start.
    refused: std::sync::atomic::AtomicU64,
    /// Checked when the account does not exist, so that a wrong name costs what a wrong
    /// password does and timing does not tell which names exist.
    decoy: HashedPassword,
    /// The page is served over TLS: cookies are `Secure`, and an `Origin` must be `https://`.
    secure: bool,
}

impl std::fmt::Debug for Access {
    // Never the hashes or the tokens.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Access")
            .field("accounts", &self.accounts.len())
            .field("hosts", &self.hosts)
            .finish_non_exhaustive()
    }
}

/// Why a login failed.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum LoginError {
    /// Too many attempts: try again later.
    TooMany,
    /// The name or the password is wrong.
    Wrong,
}

impl Access {
    /// Checks and keeps the configuration.
    pub(crate) fn new(config: AccessConfig, secure: bool) -> Result<Self, AccessError> {
        let mut accounts = HashMap::new();
        for a in config.accounts {
            if !valid_name(&a.name) {
                return Err(AccessError::BadName(a.name));
            }
            if a.name == LOCAL_ACCOUNT {
                return Err(AccessError::Reserved);
            }
            let hash =
                HashedPassword::parse(&a.password_hash).map_err(|reason| AccessError::BadHash {
                    name: a.name.clone(),
                    reason,
                })?;
            if accounts.insert(a.name.clone(), hash).is_some() {
                return Err(AccessError::Duplicate(a.name));
            }
        }
        let decoy = HashedPassword::decoy();
        Ok(Access {
            accounts,
            hosts: config
                .hosts
                .into_iter()
                .map(|h| h.to_ascii_lowercase())
                .collect(),
            sessions: Mutex::new(HashMap::new()),
            links: Mutex::new(HashMap::new()),
            limits: Mutex::new(Limits {
                all: LoginGate::new(LOGINS, Instant::now()),
                by_addr: PerAddress::new(LOGINS_PER_ADDRESS),
            }),
            refused: std::sync::atomic::AtomicU64::new(0),
            decoy,
            secure,
        })
    }

    /// A new one-time login token, for the account [`LOCAL_ACCOUNT`].
    pub(crate) fn new_link(&self) -> Result<String, getrandom::Error> {
        let token = crate::hub::random_hex(32)?;
        let now = Instant::now();
        let mut links = self.links.lock().unwrap_or_else(|e| e.into_inner());
        links.retain(|_, made| now.saturating_duration_since(*made) < LINK_LIFETIME);
        if links.len() >= MAX_LINKS {
            if let Some(oldest) = links
                .iter()
                .min_by_key(|(_, t)| **t)
                .map(|(k, _)| k.clone())
            {
                links.remove(&oldest);
            }
        }
        links.insert(token.clone(), now);
        Ok(token)
    }

    /// Uses up a login link; returns a new session's token when it was valid.
    pub(crate) fn redeem(&self, token: &str) -> Option<String> {
        let made = self
            .links
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(token)?;
        if made.elapsed() >= LINK_LIFETIME {
            return None;
        }
        tracing::info!(
            account = LOCAL_ACCOUNT,
            "dashboard login with a one-time link"
        );
        self.open_session(LOCAL_ACCOUNT)
    }

    /// Checks a name and password (on a blocking thread) and opens a session.
    pub(crate) async fn login(
        self: &std::sync::Arc<Self>,
        from: IpAddr,
        name: String,
        password: String,
    ) -> Result<String, LoginError> {
        if !self.may_try(from, &name, Instant::now()) {
            // Counted, and logged on the 1st, 2nd, 4th… refusal: a flood of guesses must not
            // become a flood of log lines.
            let n = self
                .refused
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
                + 1;
            if cetratus_mct::budget::worth_logging(n) {
                tracing::warn!(%from, account = %name.escape_debug(), refused = n, "dashboard login refused: too many attempts");
            }
            return Err(LoginError::TooMany);
        }
        let access = self.clone();
        let checked_name = name.clone();
        let ok = tokio::task::spawn_blocking(move || {
            let known = access.accounts.get(&checked_name);
            let hash = known.unwrap_or(&access.decoy);
            let right = hash.verify(password.as_bytes());
            right && known.is_some()
        })
        .await
        .unwrap_or(false);
        if !ok {
            tracing::warn!(%from, account = %name.escape_debug(), "dashboard login failed: wrong account name or password");
            return Err(LoginError::Wrong);
        }
        tracing::info!(%from, account = %name, "dashboard login");
        let mut limits = self.limits.lock().unwrap_or_else(|e| e.into_inner());
        limits.all.succeeded(Some(from), &name);
        drop(limits);
        self.open_session(&name).ok_or(LoginError::Wrong)
    }

    /// Whether a login attempt of `account` from `from` at `now` is within the rate limits;
    /// takes its token (from the reserve of [`LoginGate`] when the common rate is spent and this
    /// address logged in to this account before).
    fn may_try(&self, from: IpAddr, account: &str, now: Instant) -> bool {
        let mut limits = self.limits.lock().unwrap_or_else(|e| e.into_inner());
        let mine = limits.by_addr.admit(from, now);
        mine && limits.all.admit(Some(from), account, now)
    }

    fn open_session(&self, account: &str) -> Option<String> {
        let token = crate::hub::random_hex(32).ok()?;
        let now = Instant::now();
        let mut sessions = self.sessions.lock().unwrap_or_else(|e| e.into_inner());
        sessions.retain(|_, s| now.saturating_duration_since(s.last_seen) < SESSION_IDLE);
        if sessions.len() >= MAX_SESSIONS {
            if let Some(lru) = sessions
                .iter()
                .min_by_key(|(_, s)| s.last_seen)
                .map(|(k, _)| k.clone())
            {
                sessions.remove(&lru);
            }
        }
        sessions.insert(
            token.clone(),
            Session {
                account: account.to_string(),
                last_seen: now,
            },
        );
        Some(token)
    }

    /// The account of the request's session, if it has a live one.
    pub(crate) fn account(&self, headers: &HeaderMap) -> Option<String> {
        let token = session_cookie(headers)?;
        let now = Instant::now();
        let mut sessions = self.sessions.lock().unwrap_or_else(|e| e.into_inner());
        let s = sessions.get_mut(token)?;
        if now.saturating_duration_since(s.last_seen) >= SESSION_IDLE {
            sessions.remove(token);
            return None;
        }
        s.last_seen = now;
        Some(s.account.clone())
    }

    /// Ends the request's session.
    pub(crate) fn logout(&self, headers: &HeaderMap) {
        if let Some(token) = session_cookie(headers) {
            self.sessions
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .remove(token);
        }
    }

    /// The `Set-Cookie` value of a new session: `Secure` when the page is served over TLS, so
    /// the browser never sends it in clear.
    pub(crate) fn set_cookie(&self, token: &str) -> String {
        let secure = if self.secure { "; Secure" } else { "" };
        format!("{COOKIE}={token}; Path=/; HttpOnly; SameSite=Strict{secure}")
    }

    /// Checks `Host` (every request) and, for a POST, `Origin`; returns what is wrong.
    pub(crate) fn check_origin(&self, headers: &HeaderMap, post: bool) -> Result<(), String> {
        let Some(host) = headers.get(header::HOST).and_then(|h| h.to_str().ok()) else {
            return Err("the request names no Host".into());
        };
        let name = host_name(host);
        let allowed = name.eq_ignore_ascii_case("localhost")
            || name.parse::<IpAddr>().is_ok()
            || self.hosts.iter().any(|h| h.eq_ignore_ascii_case(name));
        if !allowed {
            return Err(format!(
                "the dashboard is not served under the name `{}`; reach it by its IP address, or \
                 add the name to `hosts` in the `[dashboard]` section of the local configuration",
                name.escape_debug()
            ));
        }
        if !post {
            return Ok(());
        }
        if let Some(origin) = headers.get(header::ORIGIN) {
            let origin = origin.to_str().unwrap_or("");
            let scheme = if self.secure { "https://" } else { "http://" };
            let same = origin
                .strip_prefix(scheme)
                .is_some_and(|o| o.eq_ignore_ascii_case(host));
            if !same {
                return Err(format!(
                    "a page of `{}` may not send commands to this dashboard",
                    origin.escape_debug()
                ));
            }
        }
        if let Some(site) = headers.get("sec-fetch-site").and_then(|v| v.to_str().ok()) {
            if !matches!(site, "same-origin" | "none") {
                return Err(format!(
                    "a {site} request may not send commands to this dashboard"
                ));
            }
        }
        Ok(())
    }
}

/// The host name of a `Host` header, without its port (and without the brackets of an IPv6
/// address).
fn host_name(host: &str) -> &str {
    if let Some(rest) = host.strip_prefix('[') {
        return rest.split(']').next().unwrap_or(rest);
    }
    host.rsplit_once(':').map_or(host, |(name, _)| name)
}

/// The session token of the request's `Cookie` header.
fn session_cookie(headers: &HeaderMap) -> Option<&str> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(';'))
        .filter_map(|kv| kv.trim().split_once('='))
        .find(|(k, _)| *k == COOKIE)
        .map(|(_, v)| v)
        .filter(|v| v.len() == 64 && v.bytes().all(|b| b.is_ascii_hexdigit()))
}

/// The `Set-Cookie` value that ends a session in the browser.
pub(crate) fn clear_cookie() -> String {
    format!("{COOKIE}=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0")
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn access(hosts: &[&str]) -> Access {
        Access::new(
            AccessConfig {
                accounts: vec![Account {
                    name: "ops".into(),
                    password_hash: hash_password("right horse").expect("hash"),
                }],
                hosts: hosts.iter().map(|h| h.to_string()).collect(),
            },
            false,
        )
        .expect("a valid configuration")
    }

    fn headers(pairs: &[(&'static str, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.append(*k, HeaderValue::from_str(v).expect("a header value"));
        }
        h
    }

    #[test]
    fn a_login_link_works_once_and_its_session_names_the_local_account() {
        let a = access(&[]);
        let link = a.new_link().expect("random");
        let session = a.redeem(&link).expect("a first use");
        assert!(a.redeem(&link).is_none(), "a second use");
        let cookie = format!("x=1; {COOKIE}={session}");
        let h = headers(&[("cookie", &cookie)]);
        assert_eq!(a.account(&h).as_deref(), Some(LOCAL_ACCOUNT));
        a.logout(&h);
        assert_eq!(a.account(&h), None);
    }

    #[test]
    fn only_a_right_password_opens_a_session() {
        let a = std::sync::Arc::new(access(&[]));
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime");
        let ip = |k: u8| IpAddr::from([192, 0, 2, k]);
        rt.block_on(async {
            let token = a
                .login(ip(1), "ops".into(), "right horse".into())
                .await
                .expect("the right password");
            let h = headers(&[("cookie", &format!("{COOKIE}={token}"))]);
            assert_eq!(a.account(&h).as_deref(), Some("ops"));
            let wrong = a.login(ip(2), "ops".into(), "wrong".into()).await;
            assert_eq!(wrong, Err(LoginError::Wrong));
            let nobody = a.login(ip(3), "nobody".into(), "right horse".into()).await;
            assert_eq!(nobody, Err(LoginError::Wrong));
        });
    }

    #[test]
    fn guessing_is_limited_per_address_and_for_everyone_and_the_limit_refills() {
        let a = access(&[]);
        let t0 = Instant::now();
        let one = IpAddr::from([192, 0, 2, 1]);
        let tries: Vec<bool> = (0..6).map(|_| a.may_try(one, "ops", t0)).collect();
        assert_eq!(
            tries,
            [true, true, true, true, false, false],
            "a burst of 4 per address"
        );
        let others: Vec<bool> = (10..30)
            .map(|k| a.may_try(IpAddr::from([192, 0, 2, k]), "ops", t0))
            .collect();
        let allowed = others.iter().filter(|ok| **ok).count();
        assert_eq!(
            allowed, 4,
            "a burst of 8 for everyone, 4 of it used already: {others:?}"
        );
        assert!(
            a.may_try(one, "ops", t0 + Duration::from_secs(2)),
            "one more after 2 s"
        );
    }

    #[test]
    fn an_operator_who_logged_in_before_gets_in_while_others_spend_the_common_rate() {
        let a = access(&[]);
        let t0 = Instant::now();
        let ops = IpAddr::from([192, 0, 2, 1]);
        assert!(a.may_try(ops, "ops", t0));
        a.limits
            .lock()
            .expect("limits")
            .all
            .succeeded(Some(ops), "ops");
        let flood = (10..60).filter(|&k| a.may_try(IpAddr::from([192, 0, 2, k]), "ops", t0));
        assert_eq!(
            flood.count(),
            7,
            "the common burst, one used by the operator"
        );
        assert!(a.may_try(ops, "ops", t0), "the operator, from the reserve");
        assert!(!a.may_try(IpAddr::from([192, 0, 2, 77]), "ops", t0));
    }

    #[test]
    fn bad_accounts_are_refused_with_what_to_do() {
        let bad = |name: &str, hash: &str| {
            Access::new(
                AccessConfig {
                    accounts: vec![Account {
                        name: name.into(),
                        password_hash: hash.into(),
                    }],
                    hosts: vec![],
                },
                false,
            )
            .map(|_| ())
            .expect_err("refused")
            .to_string()
        };
        let good = hash_password("p").expect("hash");
        assert!(bad("a b", &good).contains("letters, digits"));
        assert!(bad(LOCAL_ACCOUNT, &good).contains("reserved"));
        assert!(bad("ops", "hunter2").contains("cetratus hash-password"));
    }

    #[test]
    fn host_and_origin_must_be_the_dashboards_own() {
        let a = access(&["plc1.plant"]);
        for host in [
            "127.0.0.1:8080",
            "localhost:8080",
            "[::1]:8080",
            "PLC1.plant:8080",
            "10.0.0.5",
        ] {
            assert!(
                a.check_origin(&headers(&[("host", host)]), false).is_ok(),
                "{host}"
            );
        }
        let err = a
            .check_origin(&headers(&[("host", "evil.example:8080")]), false)
            .expect_err("a rebound name");
        assert!(err.contains("[dashboard]"), "{err}");
        let post = |origin: &str| {
            a.check_origin(
                &headers(&[("host", "127.0.0.1:8080"), ("origin", origin)]),
                true,
            )
        };
        assert!(post("http://127.0.0.1:8080").is_ok());
        assert!(post("https://evil.example").is_err());
        assert!(post("null").is_err());
        let cross = headers(&[("host", "127.0.0.1:8080"), ("sec-fetch-site", "cross-site")]);
        assert!(a.check_origin(&cross, true).is_err());
    }
}
