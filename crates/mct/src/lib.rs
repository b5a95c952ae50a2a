//! The Machine Configuration Tool's control plane: the PLC over MQTT (docs/design.md §5, docs/mqtt.md).
//!
//! Two halves:
//! * [`ControlPlane`], transport-independent: turns `(topic, payload, response topic, correlation
//!   data)` into a typed, authorised [`IncomingCommand`] or a [`Rejection`] holding the error reply
//!   and the event; formats replies. The payloads are the structs of `cetratus-proto`.
//! * [`start`] / [`spawn_mqtt`]: an MQTT 5 client (rumqttc) in its own threads, connected to the
//!   [`EmbeddedBroker`] (rmqtt, one port for MQTT 3.1.1 and 5) or to a plant broker.
//!
//! The scan thread meets MQTT only through [`MctLink`], two bounded queues, and only with
//! non-blocking calls. Every queue on the way in is bounded in bytes as well as in entries
//! ([`budget`], [`CommandQueue`], [`UNREAD_BYTES`], [`COMMAND_QUEUE_BYTES`], and in the embedded
//! broker); a command that does not fit is answered `busy`, so what others send never decides
//! the PLC's memory:
//!
//! ```no_run
//! # use cetratus_mct::*;
//! let (link, handle) = start(MqttConfig::new("cell1"))?;
//! loop {
//!     // once per cycle, on the scan thread:
//!     while let Some(cmd) = link.try_command() {
//!         let outcome = accepted(); // or Err(refused(reason)) when Plc::command refuses
//!         let _ = link.send(Outgoing::Reply(cmd.reply, outcome));
//!     }
//!     // `send` never blocks: a full queue gives the message back; keep events/replies for the
//!     // next cycle, drop periodic figures.
//!     # break;
//! }
//! handle.shutdown();
//! # Ok::<(), MctError>(())
//! ```

// Every public item carries a doc line (house style); the compiler keeps us honest.
#![warn(missing_docs)]

pub mod acl;
mod broker;
pub mod budget;
mod checks;
pub mod client;
mod control;
mod envelope;
mod error;
mod inbound;
mod ingress;
mod link;
pub mod logins;
pub mod password;
mod strikes;
pub mod topics;

pub use acl::{BrokerAccount, BrokerSettings, BrokerTls, Login, DASHBOARD_USER, PLC_USER};
pub use broker::{
    EmbeddedBroker, BROKER_MAX_PACKET, CONNECTION_BUFFER_BYTES, INTERNAL_SESSIONS_BYTES, LOGINS,
    MAX_CLIENTS, PARTIALS_BYTES, PARTIAL_FLOOR_BYTES, SESSIONS_BYTES, SESSION_FLOOR_BYTES,
    SESSION_INBOX_BYTES, SESSION_QUEUE, SESSION_QUEUE_BYTES,
};
pub use control::{
    accepted, refused, unix_now, ControlPlane, IncomingCommand, Outcome, Rejection, ReplyHandle,
    Request,
};
pub use envelope::{
    parse_envelope, sign, signing_message, Envelope, OperatorKeys, Signed, ENVELOPE_VERSION,
};
pub use error::MctError;
pub use inbound::{CommandQueue, UNREAD_BYTES};
pub use ingress::{
    TurnedAway, BUSY_ANSWERS_PER_S, BUSY_BURST, COMMANDS_PER_S, COMMAND_BURST, INGRESS_BURST,
    INGRESS_BYTES_PER_S, REFUSAL_PAUSE, TURNED_AWAY_PROPERTY,
};
pub use link::{
    client_options, join_within, spawn_mqtt, start, BrokerChoice, LinkStats, MctLink, MqttConfig,
    MqttHandle, Outgoing, StatsReader, COMMAND_QUEUE_BYTES, DEFAULT_MQTT_ADDR, MAX_INFLIGHT,
    STOP_WITHIN,
};
pub use rumqttc::v5::MqttOptions;
pub use strikes::{STRIKES, STRIKE_WINDOW};
pub use topics::{MAX_TOPIC_BYTES, MAX_TOPIC_LEVELS};
