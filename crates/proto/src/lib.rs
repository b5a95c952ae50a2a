//! The Cetratus wire protocol, in one place: the MQTT topics under `cetratus/<plc-id>/`, the
//! command verbs, PLC ids, broker URLs, and every JSON payload (docs/mqtt.md is the contract).
//!
//! Nothing here touches the network: the PLC (`cetratus-mct`), the dashboard and the CLI client
//! build and read their messages with these types so that the three agree by construction.
//!
//! ```
//! use cetratus_proto::{PlcId, Topics, Verb, Leaf, parse_topic};
//! let t = Topics::new(PlcId::new("cell1")?);
//! assert_eq!(t.cmd(Verb::Substitute), "cetratus/cell1/cmd/substitute");
//! assert_eq!(parse_topic(t.state())?.1, Leaf::State);
//! # Ok::<(), cetratus_proto::ProtoError>(())
//! ```

// Every public item carries a doc line (house style); the compiler keeps us honest.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod broker;
mod error;
mod labels;
mod names;
mod outcome;
mod payload;
mod topic;

pub use broker::{BrokerUrl, DEFAULT_PORT, DEFAULT_TLS_PORT};
pub use error::ProtoError;
pub use labels::{
    check_label, check_labels, Labels, Selector, MAX_LABELS, MAX_LABEL_KEY, MAX_LABEL_VALUE,
};
pub use names::{
    ErrorCode, EventKind, LinkState, Open, Quality, Role, Slot, Status, SubstituteMode,
    UnknownName, VerdictKind, VerdictResult,
};
pub use outcome::{ending, endings, Ending};
pub use payload::{
    command_body, command_from_body, decode, encode, within_error, Accepted, Command,
    ControlCounters, Coverage, CycleFigures, DeclaredChanges, ErrorBody, EventMsg, ExecInfo,
    ExecInfoMsg, InputQuality, IoMsg, IoNames, LoadArgs, NetMsg, NoArgs, PersistFault, ProgramInfo,
    Programs, Reply, ReplyFields, Sample, SignalMask, SignalValue, Signals, StateMsg, StatePayload,
    SubstituteArgs, TimingSummary, UpdatePolicy, Verdict, MAX_PAYLOAD, MAX_WITHIN_MS,
};
pub use topic::{parse_topic, parse_verb, Leaf, PlcId, Topics, Verb, ALL_PLCS_FILTER, ROOT};
