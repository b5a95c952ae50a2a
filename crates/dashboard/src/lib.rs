//! The Cetratus dashboard: the paper's Machine Configuration Tool as a web page (docs/design.md §5,
//! docs/dashboard.md).
//!
//! An HTTP server (axum on Tokio, in its own thread with its own runtime) that is itself an MQTT
//! client: it subscribes to `cetratus/+/#` on a broker, keeps the latest `state`, `exec_info` and
//! `net` of every PLC and a bounded history of `io` samples ([`store::Fleet`]), pushes every
//! change to browsers with Server-Sent Events, and forwards the browsers' commands as MQTT 5
//! requests (response topic + correlation data), answering the HTTP request with the PLC's reply.
//! The page (HTML, CSS, JS) is embedded in the binary: no CDN, no build step.
//!
//! ```no_run
//! # use cetratus_dashboard::*;
//! let handle = serve(DashboardConfig {
//!     http: "127.0.0.1:8080".parse().expect("address"),
//!     broker_url: "mqtt://127.0.0.1:1883".into(),
//!     user: None,
//!     password: None,
//!     signer: None,
//!     access: AccessConfig::default(),
//!     tls: None,
//!     rollouts: None,
//! })?;
//! println!("dashboard on {}", handle.login_url()?);
//! handle.stop();
//! # Ok::<(), DashboardError>(())
//! ```

// Every public item carries a doc line (house style); the compiler keeps us honest.
#![warn(missing_docs)]

pub mod access;
mod http;
mod hub;
mod rollouts;
pub mod store;
pub mod tls;

use std::net::SocketAddr;
use std::sync::Arc;
use std::thread::JoinHandle;

pub use access::{hash_password, AccessConfig, AccessError, Account};
pub use rollouts::RolloutConfig;
pub use tls::DashboardTls;

use tokio::sync::watch;

/// Signs a command for PLCs that accept only signed envelopes (operator keys): given the verb
/// and the JSON payload's bytes, returns the envelope object to send as `{"envelope": …}`.
#[derive(Clone)]
pub struct CommandSigner(pub std::sync::Arc<SignFn>);

/// What a [`CommandSigner`] signs: the command and what it is bound to.
#[derive(Clone, Copy, Debug)]
pub struct SignRequest<'a> {
    /// The PLC the command is for.
    pub plc: &'a str,
    /// The verb.
    pub verb: &'a str,
    /// The request's MQTT 5 correlation data.
    pub correlation: &'a [u8],
    /// The command's JSON body.
    pub payload: &'a [u8],
    /// The account of the session that asked for it (`local` for a login link), signed into
    /// the envelope so the PLC's audit log names the operator and not only the key.
    pub account: &'a str,
}

/// The signing function of a [`CommandSigner`]: a request in, an envelope out.
pub type SignFn = dyn Fn(&SignRequest<'_>) -> serde_json::Value + Send + Sync;

impl std::fmt::Debug for CommandSigner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("CommandSigner")
    }
}

/// Where the dashboard listens and which broker it watches.
#[derive(Clone, Debug)]
pub struct DashboardConfig {
    /// HTTP listening address (`--http`); port 0 picks a free port.
    pub http: SocketAddr,
    /// `mqtt://[user[:password]@]host[:port]` of the broker the PLCs publish on.
    pub broker_url: String,
    /// Broker user name (overrides the URL's).
    pub user: Option<String>,
    /// Broker password (overrides the URL's).
    pub password: Option<String>,
    /// Signs the commands the page sends, for PLCs with operator keys; `None` sends them plain.
    pub signer: Option<CommandSigner>,
    /// Who may log in, and under which host names the dashboard is reached.
    pub access: AccessConfig,
    /// TLS for the page; required when `http` is not a loopback address.
    pub tls: Option<DashboardTls>,
    /// The fleet page's rollouts; `None` runs none.
    pub rollouts: Option<RolloutConfig>,
}

/// Everything that can stop the dashboard from starting.
#[derive(Debug, thiserror::Error)]
pub enum DashboardError {
    /// The HTTP port is taken.
    #[error(
        "cannot start the dashboard: {addr} is already in use (another dashboard, or another \
         cetratus?); choose another address with `--http {suggestion}`"
    )]
    AddrInUse {
        /// The address asked for.
        addr: SocketAddr,
        /// A nearby address to suggest.
        suggestion: SocketAddr,
    },
    /// The HTTP address cannot be bound for another reason.
    #[error(
        "cannot start the dashboard on {addr}: {source}; choose another address with \
         `--http 127.0.0.1:8080`"
    )]
    Bind {
        /// The address asked for.
        addr: SocketAddr,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The broker URL cannot be used.
    #[error("the dashboard cannot use the broker URL `{url}`: {reason}")]
    BrokerUrl {
        /// The URL given.
        url: String,
        /// What is wrong with it and what to write instead.
        reason: String,
    },
    /// The dashboard's thread or runtime could not be started.
    #[error("cannot start the dashboard's thread: {0}")]
    Thread(#[source] std::io::Error),
    /// The operating system gave no random bytes for the reply topic or a login link.
    #[error("cannot start the dashboard: no random bytes from the operating system ({0})")]
    Random(String),
    /// The accounts cannot be used.
    #[error(transparent)]
    Access(#[from] AccessError),
    /// The dashboard would listen beyond loopback without TLS.
    #[error(
        "the dashboard would serve {addr}, beyond this machine, without TLS: its login and session \
         cookie would cross the network in clear; set `tls_cert` and `tls_key` in [dashboard] of \
         the local configuration (docs/security.md), or listen on loopback with \
         `--http 127.0.0.1:{port}`", port = addr.port()
    )]
    Exposed {
        /// The address asked for.
        addr: SocketAddr,
    },
    /// The TLS certificate or key cannot be used.
    #[error(
        "cannot serve the dashboard with TLS: {0}; check `tls_cert` (the certificate chain, PEM) \
         and `tls_key` (its private key, PEM) in [dashboard] of the local configuration"
    )]
    Tls(String),
}

/// The running dashboard; stops it when dropped.
#[derive(Debug)]
pub struct DashboardHandle {
    addr: SocketAddr,
    scheme: &'static str,
    access: Arc<access::Access>,
    shutdown: watch::Sender<bool>,
    thread: Option<JoinHandle<()>>,
}

impl DashboardHandle {
    /// The address the HTTP server listens on (the real port when port 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's URL, `http://<local_addr>/` (`https://` under TLS).
    pub fn url(&self) -> String {
        format!("{}://{}/", self.scheme, self.addr)
    }

    /// A new one-time login link, `http://<local_addr>/login?token=…`: it logs one browser in,
    /// once, within a day (docs/dashboard.md, *Access*).
    pub fn login_url(&self) -> Result<String, DashboardError> {
        let token = self
            .access
            .new_link()
            .map_err(|e| DashboardError::Random(e.to_string()))?;
        Ok(format!(
            "{}://{}/login?token={token}",
            self.scheme, self.addr
        ))
    }

    /// Closes the browsers' streams, stops the HTTP server and disconnects from the broker.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        let _ = self.shutdown.send(true);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for DashboardHandle {
    fn drop(&mut self) {
        self.halt();
    }
}

/// Starts the dashboard: binds the HTTP address at once (so a taken port is an error here, not
/// later in a log), then serves and watches the broker from its own thread. The broker need not
/// be up: the client retries every second and the page shows the connection state.
pub fn serve(config: DashboardConfig) -> Result<DashboardHandle, DashboardError> {
    let broker = hub::broker_target(
        &config.broker_url,
        config.user.as_deref(),
        config.password.as_deref(),
    )?;
    // Names this connection's reply topics; random, so that nobody can answer its commands
    // by guessing where the replies go.
    let token = hub::random_hex(16).map_err(|e| DashboardError::Random(e.to_string()))?;
    if !config.http.ip().is_loopback() && config.tls.is_none() {
        return Err(DashboardError::Exposed { addr: config.http });
    }
    let acceptor = match &config.tls {
        Some(t) => Some(t.acceptor().map_err(DashboardError::Tls)?),
        None => None,
    };
    let scheme = if acceptor.is_some() { "https" } else { "http" };
    let access = Arc::new(access::Access::new(config.access, acceptor.is_some())?);
    let listener = std::net::TcpListener::bind(config.http).map_err(|source| {
        if source.kind() == std::io::ErrorKind::AddrInUse {
            let mut suggestion = config.http;
            suggestion.set_port(config.http.port().wrapping_add(1).max(1024));
            DashboardError::AddrInUse {
                addr: config.http,
                suggestion,
            }
        } else {
            DashboardError::Bind {
                addr: config.http,
                source,
            }
        }
    })?;
    let bind_err = |source| DashboardError::Bind {
        addr: config.http,
        source,
    };
    let addr = listener.local_addr().map_err(bind_err)?;
    listener.set_nonblocking(true).map_err(bind_err)?;
    // One thread is plenty for a page that a few operators watch, and it keeps the dashboard
    // from competing with the scan thread for cores.
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(DashboardError::Thread)?;
    let (shutdown, shutdown_rx) = watch::channel(false);
    let served = access.clone();
    let thread = std::thread::Builder::new()
        .name("cetratus-dashboard".into())
        .spawn(move || {
            rt.block_on(http::run(
                listener,
                broker,
                shutdown_rx,
                (config.signer, config.rollouts),
                token,
                served,
                acceptor,
            ))
        })
        .map_err(DashboardError::Thread)?;
    Ok(DashboardHandle {
        addr,
        scheme,
        access,
        shutdown,
        thread: Some(thread),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(http: SocketAddr) -> DashboardConfig {
        DashboardConfig {
            http,
            // Nothing listens there; the dashboard must start anyway and keep retrying.
            broker_url: "mqtt://127.0.0.1:9".into(),
            user: None,
            password: None,
            signer: None,
            access: AccessConfig::default(),
            tls: None,
            rollouts: None,
        }
    }

    #[test]
    fn taken_port_is_a_clear_error_at_once() {
        let first = serve(config("127.0.0.1:0".parse().expect("addr"))).expect("starts");
        let taken = first.local_addr();
        let err = serve(config(taken)).expect_err("port is taken");
        let msg = err.to_string();
        assert!(msg.contains(&taken.to_string()), "{msg}");
        assert!(msg.contains("already in use"), "{msg}");
        assert!(msg.contains("--http"), "{msg}");
        first.stop();
    }

    #[test]
    fn serves_the_page_without_a_broker_and_stops() {
        use std::io::{Read, Write};
        let h = serve(config("127.0.0.1:0".parse().expect("addr"))).expect("starts");
        let mut s = std::net::TcpStream::connect(h.local_addr()).expect("connects");
        s.write_all(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")
            .expect("writes");
        let mut body = String::new();
        s.read_to_string(&mut body).expect("reads");
        assert!(body.starts_with("HTTP/1.1 200"), "{body}");
        assert!(
            body.contains("id=\"login-form\""),
            "the login page, without a session"
        );
        h.stop();
    }

    #[test]
    fn bad_broker_url_is_refused() {
        let mut c = config("127.0.0.1:0".parse().expect("addr"));
        c.broker_url = "http://example".into();
        let err = serve(c).expect_err("bad scheme");
        assert!(err.to_string().contains("mqtt://"), "{err}");
    }
}
