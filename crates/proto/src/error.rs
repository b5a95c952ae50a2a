//! The crate's one error type.

/// Everything that can be wrong with a topic, an id, a URL or a payload.
#[derive(Debug, thiserror::Error)]
pub enum ProtoError {
    /// The PLC id cannot stand as a topic level.
    #[error(
        "bad PLC id `{id}`: {reason}; a PLC id must be non-empty, at most 256 bytes, and must not contain `/`, `+`, \
         `#` or control characters, e.g. `cell1` or `press-7`"
    )]
    PlcId {
        /// The id as given (control characters escaped).
        id: String,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The last topic level under `cmd/` is not a known verb.
    #[error(
        "unknown verb `{0}`; expected one of load, remove, substitute, abort, reset, exec_info, revert, accept"
    )]
    UnknownVerb(String),
    /// A name (slot, status, role, error code, ...) is not one of the known ones.
    #[error("unknown {what} `{value}`; expected {expected}")]
    UnknownName {
        /// What kind of name, e.g. `container`.
        what: &'static str,
        /// The name as given.
        value: String,
        /// The accepted names.
        expected: &'static str,
    },
    /// The topic is not `cetratus/<plc-id>/<leaf>` with a known leaf.
    #[error("topic `{topic}` is not a Cetratus topic: {reason}")]
    Topic {
        /// The topic as given.
        topic: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The broker URL cannot be used.
    #[error(
        "bad broker URL `{url}`: {reason}; expected mqtt://host:port or mqtts://host:port, \
         e.g. mqtt://127.0.0.1:1883"
    )]
    BrokerUrl {
        /// The URL as given, with any password replaced by `***`.
        url: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A payload is not the JSON its topic carries.
    #[error("malformed {what} payload: {source}")]
    Payload {
        /// Which payload, e.g. `state`.
        what: &'static str,
        /// What serde_json said.
        #[source]
        source: serde_json::Error,
    },
    /// A label (`[labels]` of a PLC's configuration) breaks a rule.
    #[error("{0}")]
    Label(String),
    /// A selector cannot be read.
    #[error("bad selector `{selector}`: {reason}")]
    Selector {
        /// The selector as given.
        selector: String,
        /// What is wrong, and what to write instead.
        reason: String,
    },
}

impl From<cetratus_vocab::UnknownName> for ProtoError {
    fn from(e: cetratus_vocab::UnknownName) -> Self {
        ProtoError::UnknownName {
            what: e.what,
            value: e.value,
            expected: e.expected,
        }
    }
}
