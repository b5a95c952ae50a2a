//! Broker URLs: `mqtt://[user[:password]@]host[:port]` and `mqtts://...`, one parser for every
//! tool.

use std::fmt;
use std::net::SocketAddr;
use std::str::FromStr;

use crate::ProtoError;

/// The port of a plain MQTT broker when the URL gives none.
pub const DEFAULT_PORT: u16 = 1883;

/// The port of an MQTT-over-TLS broker when the URL gives none.
pub const DEFAULT_TLS_PORT: u16 = 8883;

/// A parsed broker URL.
///
/// Accepted: the schemes `mqtt` and `tcp` (plain) and `mqtts` and `ssl` (TLS), in any case; a
/// host name, an IPv4 address or a bracketed IPv6 address; an optional port (1883 plain, 8883
/// TLS by default); optional `user[:password]@` (percent-encoded characters are decoded); an
/// optional trailing `/`. Refused: no scheme (`127.0.0.1:1883`), another scheme, no host, port 0
/// or a port that is not a number up to 65535, a path, a query or a fragment.
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct BrokerUrl {
    tls: bool,
    host: String,
    port: u16,
    username: Option<String>,
    password: Option<String>,
}

/// The password of `url` replaced by `***`, for error messages.
fn redact(url: &str) -> String {
    let (scheme, rest) = match url.split_once("://") {
        Some((scheme, rest)) => (&url[..scheme.len() + 3], rest),
        None => ("", url),
    };
    let end = rest.find(['/', '?', '#']).unwrap_or(rest.len());
    let (authority, tail) = rest.split_at(end);
    match authority.rsplit_once('@') {
        Some((userinfo, hostport)) => match userinfo.split_once(':') {
            Some((user, _)) => format!("{scheme}{user}:***@{hostport}{tail}"),
            None => url.to_string(),
        },
        None => url.to_string(),
    }
}

fn hex(b: u8) -> Option<u8> {
    match b {
        b'0'..=b'9' => Some(b - b'0'),
        b'a'..=b'f' => Some(b - b'a' + 10),
        b'A'..=b'F' => Some(b - b'A' + 10),
        _ => None,
    }
}

/// Decodes `%XX` escapes (the `url` crate keeps user info percent-encoded).
fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'%' => {
                let hi = bytes.get(i + 1).copied().and_then(hex);
                let lo = bytes.get(i + 2).copied().and_then(hex);
                match (hi, lo) {
                    (Some(h), Some(l)) => {
                        out.push(h << 4 | l);
                        i += 3;
                    }
                    _ => {
                        out.push(b'%');
                        i += 1;
                    }
                }
            }
            b => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8(out).ok()
}

impl BrokerUrl {
    /// Parses a broker URL; the error says what is wrong and shows the expected form.
    pub fn parse(input: &str) -> Result<Self, ProtoError> {
        let bad = |reason: String| ProtoError::BrokerUrl {
            url: redact(input),
            reason,
        };
        let trimmed = input.trim();
        if trimmed.is_empty() {
            return Err(bad("it is empty".into()));
        }
        if !trimmed.contains("://") {
            return Err(bad(format!(
                "it has no scheme; write `mqtt://{}` for a plain broker or `mqtts://{}` for TLS",
                redact(trimmed),
                redact(trimmed)
            )));
        }
        let u = url::Url::parse(trimmed).map_err(|e| bad(e.to_string()))?;
        let tls = match u.scheme() {
            "mqtt" | "tcp" => false,
            "mqtts" | "ssl" => true,
            other => {
                return Err(bad(format!(
                    "unknown scheme `{other}`; write `mqtt://host:port` (the accepted schemes are mqtt, tcp, mqtts and ssl)"
                )))
            }
        };
        let host = match u.host() {
            Some(url::Host::Domain(d)) if !d.is_empty() => {
                percent_decode(d).ok_or_else(|| bad("the host is not UTF-8".into()))?
            }
            Some(url::Host::Ipv4(a)) => a.to_string(),
            Some(url::Host::Ipv6(a)) => a.to_string(),
            _ => return Err(bad("it has no host".into())),
        };
        let port = match u.port() {
            Some(0) => return Err(bad("the port must be a number from 1 to 65535".into())),
            Some(p) => p,
            None if tls => DEFAULT_TLS_PORT,
            None => DEFAULT_PORT,
        };
        if !(u.path().is_empty() || u.path() == "/")
            || u.query().is_some()
            || u.fragment().is_some()
        {
            return Err(bad(
                "a broker URL has no path, query or fragment after host:port".into(),
            ));
        }
        let username = match u.username() {
            "" => None,
            n => Some(percent_decode(n).ok_or_else(|| bad("the user name is not UTF-8".into()))?),
        };
        let password = match u.password() {
            None => None,
            Some(p) => {
                Some(percent_decode(p).ok_or_else(|| bad("the password is not UTF-8".into()))?)
            }
        };
        Ok(BrokerUrl {
            tls,
            host,
            port,
            username,
            password,
        })
    }

    /// `mqtt://<addr>`: how a client reaches a broker listening on `addr` (the embedded one).
    pub fn from_socket_addr(addr: SocketAddr) -> Self {
        BrokerUrl {
            tls: false,
            host: addr.ip().to_string(),
            port: addr.port(),
            username: None,
            password: None,
        }
    }

    /// The host name or address; an IPv6 address comes without brackets.
    pub fn host(&self) -> &str {
        &self.host
    }

    /// The port (1883 plain, 8883 TLS when the URL gives none).
    pub fn port(&self) -> u16 {
        self.port
    }

    /// Whether the connection uses TLS (`mqtts://` or `ssl://`).
    pub fn tls(&self) -> bool {
        self.tls
    }

    /// The URL's user name, decoded; `None` when it has none.
    pub fn username(&self) -> Option<&str> {
        self.username.as_deref()
    }

    /// The URL's password, decoded; `None` when it has none.
    pub fn password(&self) -> Option<&str> {
        self.password.as_deref()
    }

    /// User and password to log in with (the password empty when only a user is given).
    pub fn credentials(&self) -> Option<(&str, &str)> {
        self.username
            .as_deref()
            .map(|u| (u, self.password.as_deref().unwrap_or("")))
    }

    /// Credentials from the configuration or the command line override the URL's: a `user`
    /// replaces the URL's user (keeping the URL's password unless `password` is given), a
    /// `password` alone replaces the URL's password.
    pub fn with_credentials(mut self, user: Option<&str>, password: Option<&str>) -> Self {
        if let Some(u) = user {
            self.username = Some(u.to_string());
            if let Some(p) = password {
                self.password = Some(p.to_string());
            }
        } else if let (Some(p), Some(_)) = (password, self.username.as_ref()) {
            self.password = Some(p.to_string());
        }
        self
    }

    /// `host:port`, the IPv6 address in brackets.
    pub fn host_port(&self) -> String {
        if self.host.contains(':') {
            format!("[{}]:{}", self.host, self.port)
        } else {
            format!("{}:{}", self.host, self.port)
        }
    }
}

impl fmt::Display for BrokerUrl {
    /// `mqtt://host:port` or `mqtts://host:port`, never with the credentials (safe for logs).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let scheme = if self.tls { "mqtts" } else { "mqtt" };
        write!(f, "{scheme}://{}", self.host_port())
    }
}

impl fmt::Debug for BrokerUrl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("BrokerUrl")
            .field("tls", &self.tls)
            .field("host", &self.host)
            .field("port", &self.port)
            .field("username", &self.username)
            .field("password", &self.password.as_ref().map(|_| "***"))
            .finish()
    }
}

impl FromStr for BrokerUrl {
    type Err = ProtoError;
    fn from_str(s: &str) -> Result<Self, ProtoError> {
        BrokerUrl::parse(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn redaction_hides_only_the_password() {
        assert_eq!(redact("mqtt://a:b@h:1"), "mqtt://a:***@h:1");
        assert_eq!(redact("mqtt://a@h"), "mqtt://a@h");
        assert_eq!(redact("mqtt://h:1/x@y"), "mqtt://h:1/x@y");
        assert_eq!(redact("h:1"), "h:1");
        assert_eq!(redact("a:b@h:1"), "a:***@h:1");
    }

    #[test]
    fn percent_escapes_are_decoded() {
        assert_eq!(percent_decode("p%40ss%3A").as_deref(), Some("p@ss:"));
        assert_eq!(percent_decode("100%").as_deref(), Some("100%"));
        assert_eq!(percent_decode("%ff"), None);
    }
}
