//! The crate's one error type.

use std::net::SocketAddr;

/// What went wrong when starting or running the MQTT control plane.
#[derive(Debug, thiserror::Error)]
pub enum MctError {
    /// The embedded broker could not listen because another process holds the port.
    #[error(
        "cannot start the embedded MQTT broker: {addr} is already in use (another broker, or another cetratus?); \
         choose another port with `--mqtt 127.0.0.1:1884`, or use the broker that is already there with \
         `--broker mqtt://{addr}`"
    )]
    PortTaken {
        /// The address asked for.
        addr: SocketAddr,
    },
    /// The embedded broker could not start for another reason.
    #[error("cannot start the embedded MQTT broker on {addr}: {reason}")]
    Broker {
        /// The address asked for.
        addr: SocketAddr,
        /// What the broker said.
        reason: String,
    },
    /// The embedded broker would listen beyond loopback without what that needs.
    #[error(
        "the embedded MQTT broker would listen on {addr}, beyond this machine, without {missing}: \
         anyone on the network could read and command the PLC; set `tls_cert` and `tls_key` and at \
         least one account in `[mqtt] users` of the local configuration (docs/security.md), or \
         listen on loopback with `--mqtt 127.0.0.1:{port}`", port = addr.port()
    )]
    Exposed {
        /// The address asked for.
        addr: SocketAddr,
        /// What is missing: TLS, accounts, or both.
        missing: &'static str,
    },
    /// An account of `[mqtt] users` cannot be used.
    #[error("[mqtt] users: the account `{name}`: {reason}")]
    Account {
        /// The account's name as written (at most 64 characters of it).
        name: String,
        /// What is wrong and what to write instead.
        reason: String,
    },
    /// The embedded broker's TLS certificate or key cannot be used.
    #[error(
        "cannot start the embedded MQTT broker with TLS on {addr}: {reason}; check `tls_cert` and \
         `tls_key` in [mqtt] of the local configuration (PEM files: the certificate chain, and its \
         private key)"
    )]
    Tls {
        /// The address asked for.
        addr: SocketAddr,
        /// What rustls or the file system said.
        reason: String,
    },
    /// The operating system gave no random bytes for the internal logins.
    #[error(
        "cannot start the embedded MQTT broker: no random bytes from the operating system ({0})"
    )]
    Random(String),
    /// `--broker` is not a usable URL.
    #[error("bad broker URL `{url}`: {reason}; expected mqtt://host:port or mqtts://host:port")]
    BrokerUrl {
        /// The URL as given.
        url: String,
        /// What is wrong with it.
        reason: String,
    },
    /// `--mqtt` is not an address.
    #[error("bad --mqtt address `{0}`: expected IP:PORT, e.g. 127.0.0.1:1883 or 0.0.0.0:1883")]
    MqttAddr(String),
    /// Both `--mqtt` and `--broker` were given.
    #[error("--mqtt (embedded broker) and --broker (plant broker) exclude each other; give one")]
    BothBrokers,
    /// The PLC id cannot be used as a topic level.
    #[error("bad PLC id `{0}`: it must be non-empty, at most 256 bytes, and must not contain `/`, `+`, `#` or control characters")]
    PlcId(String),
    /// An operator key in the configuration is not a valid ed25519 public key.
    #[error("bad operator key `{id}`: {reason}")]
    OperatorKey {
        /// Key id.
        id: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A thread or runtime could not be created.
    #[error("cannot start the MQTT threads: {0}")]
    Spawn(#[from] std::io::Error),
    /// The client did not reach the broker in time.
    #[error("cannot connect to the MQTT broker at {url}: {reason}")]
    Connect {
        /// Where.
        url: String,
        /// What the client said.
        reason: String,
    },
    /// The client did not get what it waited for in time.
    #[error("timed out after {0:?}")]
    Timeout(std::time::Duration),
    /// The client's MQTT connection failed.
    #[error("MQTT connection: {0}")]
    Client(String),
    /// The PLC did not answer a command.
    #[error("no reply from PLC `{plc}` within {after:?}; check --plc and that it is running")]
    NoReply {
        /// The PLC id.
        plc: String,
        /// How long the client waited.
        after: std::time::Duration,
    },
    /// No state of the PLC said it was online within the client's timeout.
    #[error(
        "PLC `{plc}` is not online on this broker (waited {after:?}; {seen}); check --plc, the \
         broker (--mqtt or --broker), and that the PLC is running"
    )]
    Offline {
        /// The PLC id.
        plc: String,
        /// How long the client waited.
        after: std::time::Duration,
        /// What the broker had of it: its last state said offline, or it had no state at all.
        seen: &'static str,
    },
}
