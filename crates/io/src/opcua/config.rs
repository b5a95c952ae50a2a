//! The `[opcua]` section of the I/O configuration (docs/io.md, *The PLC's OPC UA server*): where
//! the server listens, whether OPC UA clients provide the program's inputs, its limits, and its
//! security. Checked when the configuration is read, with the file, line and column of what is
//! wrong; a server that would listen beyond loopback without security is refused here.

use std::net::SocketAddr;
use std::path::PathBuf;

use serde::Deserialize;
use toml::Spanned;

use crate::config::{Reader, StalePolicy};
use crate::IoError;

/// The security policies offered with `security = "sign-and-encrypt"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Policy {
    /// Basic256Sha256.
    Basic256Sha256,
    /// Aes128_Sha256_RsaOaep.
    Aes128Sha256RsaOaep,
    /// Aes256_Sha256_RsaPss.
    Aes256Sha256RsaPss,
}

impl Policy {
    /// Every policy, in the order endpoints are offered.
    pub const ALL: [Policy; 3] = [
        Policy::Basic256Sha256,
        Policy::Aes128Sha256RsaOaep,
        Policy::Aes256Sha256RsaPss,
    ];

    /// The name OPC UA gives it.
    pub fn name(self) -> &'static str {
        match self {
            Policy::Basic256Sha256 => "Basic256Sha256",
            Policy::Aes128Sha256RsaOaep => "Aes128_Sha256_RsaOaep",
            Policy::Aes256Sha256RsaPss => "Aes256_Sha256_RsaPss",
        }
    }
}

/// How clients reach the server.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Security {
    /// Security policy None, anonymous clients: only on a loopback address.
    None,
    /// Sign & encrypt with each of `policies`; clients log in as a user or with a trusted
    /// certificate.
    SignAndEncrypt {
        /// Offered policies.
        policies: Vec<Policy>,
        /// The server's certificate and key (`own/`, `private/`, made on the first start) and the
        /// trust list of client certificates (`trusted/`).
        pki: PathBuf,
    },
}

/// One user that may log in with a password.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct User {
    /// The user name.
    pub name: String,
    /// Its argon2 hash as a PHC string (`cetratus hash-password`).
    pub password_hash: String,
    /// Where it is declared (`file:line:column`).
    pub at: String,
}

/// The PLC's OPC UA server.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OpcUaConfig {
    /// The endpoint URL, `opc.tcp://IP:PORT`.
    pub url: String,
    /// The address it listens on.
    pub listen: SocketAddr,
    /// Whether OPC UA clients write the program's inputs (a twin host, the paper's setup).
    pub inputs: bool,
    /// What the program gets when no client has written an input for `stale_after` cycles.
    pub stale: StalePolicy,
    /// Cycles without a write before the inputs are stale.
    pub stale_after: u32,
    /// Sessions at once.
    pub max_sessions: usize,
    /// TCP connections at once; more are closed at once.
    pub max_connections: usize,
    /// How clients are checked.
    pub security: Security,
    /// Users with passwords.
    pub users: Vec<User>,
    /// Where the section is declared.
    pub at: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct OpcUaSrc {
    listen: Spanned<String>,
    #[serde(default)]
    inputs: bool,
    stale: Option<Spanned<String>>,
    stale_after: Option<Spanned<i64>>,
    max_sessions: Option<Spanned<i64>>,
    max_connections: Option<Spanned<i64>>,
    security: Option<Spanned<String>>,
    policies: Option<Spanned<Vec<Spanned<String>>>>,
    pki: Option<Spanned<String>>,
    #[serde(default)]
    user: Vec<UserSrc>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UserSrc {
    name: Spanned<String>,
    password_hash: Spanned<String>,
}

/// Cycles without a write before OPC UA inputs are stale, by default: 50 cycles, half a second
/// at a 10 ms cycle, five times the keep-alive of `twin serve --opcua` (every input rewritten
/// every 100 ms).
pub const DEFAULT_STALE_AFTER: u32 = 50;

/// `opc.tcp://IP:PORT` (an optional `/` at the end) as a socket address.
pub fn parse_url(url: &str) -> Result<SocketAddr, IoError> {
    let bad = |reason| IoError::OpcUaUrl {
        url: url.chars().take(256).collect(),
        reason,
    };
    let rest = url
        .strip_prefix("opc.tcp://")
        .ok_or_else(|| bad("is not an opc.tcp URL"))?;
    let rest = rest.strip_suffix('/').unwrap_or(rest);
    let rest = rest.replace("localhost:", "127.0.0.1:");
    rest.parse()
        .map_err(|_| bad("does not name an IP address and a port"))
}

impl OpcUaConfig {
    /// Checks the `[opcua]` section of the text `r` reads; relative paths are read from the
    /// directory of `r.file`.
    pub(crate) fn build(r: &Reader<'_>, src: &Spanned<OpcUaSrc>) -> Result<OpcUaConfig, IoError> {
        let s = src.get_ref();
        let url = s.listen.get_ref().clone();
        let listen = parse_url(&url).map_err(|m| r.err(s.listen.span(), m.to_string()))?;
        let max_sessions = limit(r, &s.max_sessions, 8, "max_sessions")?;
        let max_connections = limit(r, &s.max_connections, 16, "max_connections")?;
        if !s.inputs {
            if let Some(span) = s
                .stale
                .as_ref()
                .map(|x| x.span())
                .or(s.stale_after.as_ref().map(|x| x.span()))
            {
                return Err(r.err(span, "`stale` and `stale_after` apply to inputs written by OPC UA clients: set inputs = true, or leave them out"));
            }
        }
        let stale = r.stale(&s.stale)?;
        let stale_after = r.count(
            &s.stale_after,
            DEFAULT_STALE_AFTER,
            "stale_after",
            1_000_000,
        )?;
        let security = security(r, src, listen)?;
        let users = users(r, &s.user)?;
        if matches!(security, Security::None) && !users.is_empty() {
            return Err(r.err(s.user[0].name.span(), "users log in only with security = \"sign-and-encrypt\": a password over policy None would travel in clear"));
        }
        Ok(OpcUaConfig {
            url,
            listen,
            inputs: s.inputs,
            stale,
            stale_after,
            max_sessions,
            max_connections,
            security,
            users,
            at: r.at(src.span()),
        })
    }
}

/// A limit of the server (sessions, connections): from 1 to 256, `default` when none is written.
fn limit(
    r: &Reader<'_>,
    n: &Option<Spanned<i64>>,
    default: usize,
    what: &str,
) -> Result<usize, IoError> {
    match n {
        None => Ok(default),
        Some(v) => usize::try_from(*v.get_ref())
            .ok()
            .filter(|k| (1..=256).contains(k))
            .ok_or_else(|| r.err(v.span(), format!("`{what}` must be from 1 to 256"))),
    }
}

/// How clients reach a server listening on `listen`: policy None is refused beyond loopback.
fn security(
    r: &Reader<'_>,
    src: &Spanned<OpcUaSrc>,
    listen: SocketAddr,
) -> Result<Security, IoError> {
    let s = src.get_ref();
    let security_span = s.security.as_ref().map_or(s.listen.span(), |x| x.span());
    match s.security.as_ref().map(|x| x.get_ref().as_str()) {
        None | Some("none") => {
            if let Some(p) = &s.policies {
                return Err(r.err(
                    p.span(),
                    "`policies` needs security = \"sign-and-encrypt\"",
                ));
            }
            if !listen.ip().is_loopback() {
                return Err(r.err(security_span, format!("the OPC UA server would listen on {listen} without security: policy None is only for loopback. Listen on 127.0.0.1, or set security = \"sign-and-encrypt\" with a pki directory and users")));
            }
            Ok(Security::None)
        }
        Some("sign-and-encrypt") => {
            let policies = policies(r, &s.policies)?;
            let Some(pki) = &s.pki else {
                return Err(r.err(src.span(), "security = \"sign-and-encrypt\" needs `pki`, the directory of the server's certificate and of the trusted client certificates"));
            };
            let base = std::path::Path::new(r.file)
                .parent()
                .map(|p| p.to_path_buf())
                .unwrap_or_default();
            Ok(Security::SignAndEncrypt {
                policies,
                pki: base.join(pki.get_ref()),
            })
        }
        Some(other) => Err(r.err(security_span, format!("unknown security `{other}`; expected \"none\" (loopback only) or \"sign-and-encrypt\""))),
    }
}

/// The policies offered, each once and in the order written; all of them when none is written.
fn policies(
    r: &Reader<'_>,
    list: &Option<Spanned<Vec<Spanned<String>>>>,
) -> Result<Vec<Policy>, IoError> {
    let Some(list) = list else {
        return Ok(Policy::ALL.to_vec());
    };
    let mut policies = Vec::new();
    for p in list.get_ref() {
        let found = Policy::ALL
            .into_iter()
            .find(|k| k.name() == p.get_ref())
            .ok_or_else(|| {
                r.err(p.span(), format!("unknown security policy `{}`; expected \"Basic256Sha256\", \"Aes128_Sha256_RsaOaep\" or \"Aes256_Sha256_RsaPss\"", p.get_ref()))
            })?;
        if !policies.contains(&found) {
            policies.push(found);
        }
    }
    if policies.is_empty() {
        return Err(r.err(
            list.span(),
            "`policies` is empty; leave it out to offer all three",
        ));
    }
    Ok(policies)
}

/// The users that may log in with a password, each with an argon2 hash and a name of its own.
fn users(r: &Reader<'_>, list: &[UserSrc]) -> Result<Vec<User>, IoError> {
    let mut users: Vec<User> = Vec::new();
    for u in list {
        let name = u.name.get_ref();
        if name.is_empty() || name.len() > 64 {
            return Err(r.err(u.name.span(), "a user needs a name of 1 to 64 characters"));
        }
        if users.iter().any(|o| &o.name == name) {
            return Err(r.err(u.name.span(), format!("user `{name}` is declared twice")));
        }
        if !u.password_hash.get_ref().starts_with("$argon2") {
            return Err(r.err(u.password_hash.span(), format!("the password of `{name}` must be an argon2 hash as `cetratus hash-password` prints it, never the password itself")));
        }
        users.push(User {
            name: name.clone(),
            password_hash: u.password_hash.get_ref().clone(),
            at: r.at(u.name.span()),
        });
    }
    Ok(users)
}

#[cfg(test)]
mod tests {
    use crate::config::IoConfig;

    fn err(text: &str) -> String {
        match IoConfig::parse("io.toml", text) {
            Ok(c) => panic!("accepted: {c:?}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn policy_none_beyond_loopback_is_refused_where_it_is_written() {
        let e = err("[opcua]\nlisten = \"opc.tcp://0.0.0.0:4840\"\n");
        assert!(e.starts_with("io.toml:2:10:"), "{e}");
        assert!(e.contains("policy None is only for loopback"), "{e}");
        let e = err("[opcua]\nlisten = \"opc.tcp://192.168.1.4:4840\"\nsecurity = \"none\"\n");
        assert!(e.starts_with("io.toml:3:"), "{e}");
        let ok = IoConfig::parse(
            "io.toml",
            "[opcua]\nlisten = \"opc.tcp://localhost:4840/\"\n",
        )
        .unwrap();
        let o = ok.opcua.unwrap();
        assert_eq!(o.listen.to_string(), "127.0.0.1:4840");
        assert_eq!(
            (o.max_sessions, o.max_connections, o.inputs),
            (8, 16, false)
        );
    }

    #[test]
    fn encrypted_servers_need_a_pki_known_policies_and_hashed_passwords() {
        let base =
            "[opcua]\nlisten = \"opc.tcp://10.0.0.1:4840\"\nsecurity = \"sign-and-encrypt\"\n";
        assert!(err(base).contains("needs `pki`"));
        let e = err(&format!(
            "{base}pki = \"p\"\npolicies = [\"Basic128Rsa15\"]\n"
        ));
        assert!(e.contains("unknown security policy `Basic128Rsa15`"), "{e}");
        let e = err(&format!(
            "{base}pki = \"p\"\n[[opcua.user]]\nname = \"hmi\"\npassword_hash = \"secret\"\n"
        ));
        assert!(e.contains("never the password itself"), "{e}");
        let c = IoConfig::parse(
            "/etc/cetratus/io.toml",
            &format!("{base}pki = \"p\"\npolicies = [\"Aes256_Sha256_RsaPss\"]\n[[opcua.user]]\nname = \"hmi\"\npassword_hash = \"$argon2id$x\"\n"),
        )
        .unwrap()
        .opcua
        .unwrap();
        assert_eq!(
            c.security,
            super::Security::SignAndEncrypt {
                policies: vec![super::Policy::Aes256Sha256RsaPss],
                pki: "/etc/cetratus/p".into()
            }
        );
        assert_eq!(c.users[0].name, "hmi");
        let e = err("[opcua]\nlisten = \"opc.tcp://127.0.0.1:4840\"\n[[opcua.user]]\nname = \"a\"\npassword_hash = \"$argon2id$x\"\n");
        assert!(e.contains("travel in clear"), "{e}");
        let e = err("[opcua]\nlisten = \"127.0.0.1:4840\"\n");
        assert!(e.contains("not an opc.tcp URL"), "{e}");
        let e = err("[opcua]\nlisten = \"opc.tcp://127.0.0.1:4840\"\nstale = \"safe\"\n");
        assert!(
            e.starts_with("io.toml:3:") && e.contains("set inputs = true"),
            "{e}"
        );
        let e = err(
            "[opcua]\nlisten = \"opc.tcp://127.0.0.1:4840\"\ninputs = true\nstale = \"drop\"\n",
        );
        assert!(e.contains("unknown stale policy `drop`"), "{e}");
        let e =
            err("[opcua]\nlisten = \"opc.tcp://127.0.0.1:4840\"\ninputs = true\nstale_after = 0\n");
        assert!(e.contains("`stale_after` must be"), "{e}");
        let e = err("[opcua]\nlisten = \"opc.tcp://127.0.0.1:4840\"\nmax_session = 3\n");
        assert!(e.contains("unknown field `max_session`"), "{e}");
    }
}
