//! PLC ids, command verbs and the topics under `cetratus/<plc-id>/`.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::ProtoError;

/// The first topic level of everything Cetratus publishes or listens to.
pub const ROOT: &str = "cetratus";

/// The subscription that receives every topic of every PLC, commands and replies included.
pub const ALL_PLCS_FILTER: &str = "cetratus/+/#";

/// A PLC id: the `<plc-id>` topic level. Non-empty, at most [`PlcId::MAX_LEN`] bytes, without
/// `/`, `+`, `#` or control characters.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct PlcId(String);

impl PlcId {
    /// Checks `id` and wraps it; the error says what was wrong and what an id looks like.
    pub fn new(id: impl Into<String>) -> Result<Self, ProtoError> {
        let id = id.into();
        let reason = if id.is_empty() {
            Some("it is empty")
        } else if id.len() > Self::MAX_LEN {
            Some("it is longer than 256 bytes")
        } else if id.contains('/') {
            Some("it contains `/`, which would split it into two topic levels")
        } else if id.contains(['+', '#']) {
            Some("it contains an MQTT wildcard (`+` or `#`)")
        } else if id.chars().any(char::is_control) {
            Some("it contains a control character")
        } else {
            None
        };
        match reason {
            None => Ok(PlcId(id)),
            Some(reason) => Err(ProtoError::PlcId {
                id: id.escape_debug().to_string(),
                reason,
            }),
        }
    }

    /// The longest id, in bytes: it also names a URL path of the dashboard.
    pub const MAX_LEN: usize = 256;

    /// Whether `id` would be accepted by [`PlcId::new`].
    pub fn is_valid(id: &str) -> bool {
        !id.is_empty()
            && id.len() <= Self::MAX_LEN
            && !id.contains(['/', '+', '#'])
            && !id.chars().any(char::is_control)
    }

    /// The id as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// The id as an owned string.
    pub fn into_string(self) -> String {
        self.0
    }
}

impl fmt::Display for PlcId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl FromStr for PlcId {
    type Err = ProtoError;
    fn from_str(s: &str) -> Result<Self, ProtoError> {
        PlcId::new(s)
    }
}

impl TryFrom<String> for PlcId {
    type Error = ProtoError;
    fn try_from(s: String) -> Result<Self, ProtoError> {
        PlcId::new(s)
    }
}

impl TryFrom<&str> for PlcId {
    type Error = ProtoError;
    fn try_from(s: &str) -> Result<Self, ProtoError> {
        PlcId::new(s)
    }
}

impl AsRef<str> for PlcId {
    fn as_ref(&self) -> &str {
        &self.0
    }
}

impl Serialize for PlcId {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.0)
    }
}

impl<'de> Deserialize<'de> for PlcId {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        PlcId::new(s).map_err(serde::de::Error::custom)
    }
}

pub use cetratus_vocab::Verb;

/// The leaf `cmd/<verb>` of a verb.
fn cmd_leaf(verb: Verb) -> &'static str {
    match verb {
        Verb::Load => "cmd/load",
        Verb::Substitute => "cmd/substitute",
        Verb::Remove => "cmd/remove",
        Verb::Abort => "cmd/abort",
        Verb::Reset => "cmd/reset",
        Verb::ExecInfo => "cmd/exec_info",
        Verb::Revert => "cmd/revert",
        Verb::Accept => "cmd/accept",
    }
}

/// Reads a verb; an unknown one is [`ProtoError::UnknownVerb`], answered with `unknown_verb`.
pub fn parse_verb(s: &str) -> Result<Verb, ProtoError> {
    s.parse()
        .map_err(|e: cetratus_vocab::UnknownName| ProtoError::UnknownVerb(e.value))
}

/// What follows `cetratus/<plc-id>/`: a published topic or a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Leaf {
    /// `state` (retained).
    State,
    /// `exec_info`.
    ExecInfo,
    /// `io`.
    Io,
    /// `net` (retained).
    Net,
    /// `events`.
    Events,
    /// `cmd/<verb>`.
    Cmd(Verb),
}

impl Leaf {
    /// The published leaves, in the order of docs/mqtt.md.
    pub const PUBLISHED: [Leaf; 5] = [
        Leaf::State,
        Leaf::ExecInfo,
        Leaf::Io,
        Leaf::Net,
        Leaf::Events,
    ];

    /// The leaf as it stands in a topic, e.g. `events` or `cmd/load`.
    pub fn as_str(self) -> &'static str {
        match self {
            Leaf::State => "state",
            Leaf::ExecInfo => "exec_info",
            Leaf::Io => "io",
            Leaf::Net => "net",
            Leaf::Events => "events",
            Leaf::Cmd(v) => cmd_leaf(v),
        }
    }

    /// Whether the PLC publishes this leaf retained (`state`, `net`).
    pub fn retained(self) -> bool {
        matches!(self, Leaf::State | Leaf::Net)
    }
}

impl fmt::Display for Leaf {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Leaf {
    type Err = ProtoError;
    /// `state`, `exec_info`, `io`, `net`, `events` or `cmd/<verb>`; an unknown verb is
    /// [`ProtoError::UnknownVerb`] so that it can be answered with `unknown_verb`.
    fn from_str(s: &str) -> Result<Self, ProtoError> {
        if let Some(verb) = s.strip_prefix("cmd/") {
            return parse_verb(verb).map(Leaf::Cmd);
        }
        Leaf::PUBLISHED
            .into_iter()
            .find(|l| l.as_str() == s)
            .ok_or_else(|| ProtoError::UnknownName {
                what: "topic leaf",
                value: s.chars().take(64).collect(),
                expected: "state, exec_info, io, net, events or cmd/<verb>",
            })
    }
}

/// Splits a topic into its PLC id and its leaf: `cetratus/cell1/cmd/load` gives
/// (`cell1`, `Leaf::Cmd(Verb::Load)`). An unknown verb under `cmd/` is
/// [`ProtoError::UnknownVerb`]; anything else that is not ours is [`ProtoError::Topic`].
pub fn parse_topic(topic: &str) -> Result<(PlcId, Leaf), ProtoError> {
    let bad = |reason: &str| ProtoError::Topic {
        topic: topic.chars().take(256).collect(),
        reason: reason.to_string(),
    };
    let rest = topic
        .strip_prefix(ROOT)
        .and_then(|r| r.strip_prefix('/'))
        .ok_or_else(|| bad("it does not start with `cetratus/`"))?;
    let (plc, leaf) = rest
        .split_once('/')
        .ok_or_else(|| bad("expected `cetratus/<plc-id>/<leaf>`"))?;
    let plc = PlcId::new(plc).map_err(|e| bad(&e.to_string()))?;
    let leaf = match leaf.parse::<Leaf>() {
        Ok(l) => l,
        Err(e @ ProtoError::UnknownVerb(_)) => return Err(e),
        Err(e) => return Err(bad(&e.to_string())),
    };
    Ok((plc, leaf))
}

/// The topics of one PLC, built once: `cetratus/<plc-id>/state`, ..., `cetratus/<plc-id>/cmd/+`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Topics {
    plc: PlcId,
    prefix: String,
    state: String,
    exec_info: String,
    io: String,
    net: String,
    events: String,
    commands: [String; Verb::ALL.len()],
    command_filter: String,
    all: String,
}

impl Topics {
    /// The topics of PLC `plc`.
    pub fn new(plc: PlcId) -> Self {
        let prefix = format!("{ROOT}/{plc}/");
        let t = |leaf: &str| format!("{prefix}{leaf}");
        Topics {
            state: t(Leaf::State.as_str()),
            exec_info: t(Leaf::ExecInfo.as_str()),
            io: t(Leaf::Io.as_str()),
            net: t(Leaf::Net.as_str()),
            events: t(Leaf::Events.as_str()),
            commands: std::array::from_fn(|i| t(cmd_leaf(Verb::ALL[i]))),
            command_filter: t("cmd/+"),
            all: t("#"),
            prefix,
            plc,
        }
    }

    /// The PLC id.
    pub fn plc(&self) -> &PlcId {
        &self.plc
    }

    /// `cetratus/<plc-id>/`, with the trailing slash.
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// `cetratus/<plc-id>/state` (retained).
    pub fn state(&self) -> &str {
        &self.state
    }

    /// `cetratus/<plc-id>/exec_info`.
    pub fn exec_info(&self) -> &str {
        &self.exec_info
    }

    /// `cetratus/<plc-id>/io`.
    pub fn io(&self) -> &str {
        &self.io
    }

    /// `cetratus/<plc-id>/net` (retained).
    pub fn net(&self) -> &str {
        &self.net
    }

    /// `cetratus/<plc-id>/events`.
    pub fn events(&self) -> &str {
        &self.events
    }

    /// `cetratus/<plc-id>/cmd/<verb>`.
    pub fn cmd(&self, verb: Verb) -> &str {
        &self.commands[verb as usize]
    }

    /// The topic of any leaf.
    pub fn leaf(&self, leaf: Leaf) -> &str {
        match leaf {
            Leaf::State => &self.state,
            Leaf::ExecInfo => &self.exec_info,
            Leaf::Io => &self.io,
            Leaf::Net => &self.net,
            Leaf::Events => &self.events,
            Leaf::Cmd(v) => self.cmd(v),
        }
    }

    /// `cetratus/<plc-id>/cmd/+`: the subscription that receives every command.
    pub fn command_filter(&self) -> &str {
        &self.command_filter
    }

    /// `cetratus/<plc-id>/#`: every topic of this PLC.
    pub fn all_filter(&self) -> &str {
        &self.all
    }

    /// The text after the prefix, if `topic` is under this PLC's prefix (e.g. `cmd/explode`,
    /// `reply/cli-42`); no check of the leaf.
    pub fn strip<'t>(&self, topic: &'t str) -> Option<&'t str> {
        topic.strip_prefix(&self.prefix)
    }

    /// The leaf of `topic` when it is one of this PLC's topics; errors as [`parse_topic`], plus
    /// [`ProtoError::Topic`] for another PLC's topic.
    pub fn parse(&self, topic: &str) -> Result<Leaf, ProtoError> {
        let (plc, leaf) = parse_topic(topic)?;
        if plc != self.plc {
            return Err(ProtoError::Topic {
                topic: topic.chars().take(256).collect(),
                reason: format!("it belongs to PLC `{plc}`, not `{}`", self.plc),
            });
        }
        Ok(leaf)
    }
}
