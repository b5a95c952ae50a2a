//! The rollout's one connection to the broker: it reads every PLC's `state`, `events` and
//! `exec_info` and its own replies, and sends commands, signed with the operator's key when
//! one is given, as `cetratus load` and the others do. It needs no broker right beyond reading
//! and the `cmd/*` of its PLCs.

use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use base64::Engine as _;
use cetratus_mct::client::{command_payload, unique, OperatorKey};
use cetratus_mct::{client_options, unix_now};
use cetratus_proto::{command_body, Command, PlcId, SubstituteArgs, Topics, Verb};
use rumqttc::v5::mqttbytes::v5::{Filter, Packet, Publish, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{Client, Event};

use crate::FleetError;

/// Most bytes of one message the rollout reads; a larger one ends the connection, which is
/// made again.
pub const MAX_MESSAGE: usize = 1 << 20;
/// Messages read but not yet taken in; the reader waits when they are this many.
const QUEUE: usize = 4096;

/// Where the broker is, and who the rollout is on it.
#[derive(Clone)]
pub struct LinkConfig {
    /// The broker URL (`mqtt://host:port`, `mqtts://…`).
    pub url: String,
    /// User and password that override the URL's.
    pub credentials: Option<(String, String)>,
    /// Signs every command when given.
    pub key: Option<OperatorKey>,
    /// How long to wait for the broker.
    pub timeout: Duration,
    /// The account the signed commands name (a dashboard login), for the PLCs' audit logs.
    pub account: Option<String>,
}

/// One message of a PLC: its id, its topic's leaf, its payload.
pub struct Incoming {
    /// The PLC.
    pub plc: String,
    /// The leaf under `cetratus/<plc>/`.
    pub leaf: String,
    /// The payload.
    pub payload: Vec<u8>,
    /// Its MQTT 5 correlation data, if it had any.
    pub correlation: Option<Vec<u8>>,
}

/// The connection: a reader thread fills a bounded queue, the rollout's loop takes from it and
/// sends.
pub struct Link {
    client: Client,
    rx: Receiver<Option<Incoming>>,
    key: Option<OperatorKey>,
    account: Option<String>,
    reply_leaf: String,
    package_b64: String,
}

impl Link {
    /// Connects, subscribes, and waits for the broker's acknowledgement. `package` is what a
    /// `load` sends.
    pub fn connect(config: LinkConfig, package: &[u8]) -> Result<Link, FleetError> {
        let reply_leaf = format!("reply/rollout-{}", std::process::id());
        let id = format!("cetratus-rollout-{}-{:x}", std::process::id(), unix_now());
        let mut o = client_options(&config.url, &id).map_err(FleetError::Broker)?;
        if let Some((u, p)) = &config.credentials {
            o.set_credentials(u.clone(), p.clone());
        }
        o.set_keep_alive(Duration::from_secs(10));
        o.set_max_packet_size(Some(MAX_MESSAGE as u32));
        let (client, mut conn) = Client::new(o, 256);
        let (tx, rx) = sync_channel::<Option<Incoming>>(QUEUE);
        let filters: Vec<Filter> = ["state", "events", "exec_info", reply_leaf.as_str()]
            .iter()
            .map(|leaf| Filter::new(format!("cetratus/+/{leaf}"), QoS::AtLeastOnce))
            .collect();
        let sub = client.clone();
        std::thread::Builder::new()
            .name("cetratus-rollout-mqtt".into())
            .spawn(move || {
                for event in conn.iter() {
                    let m = match event {
                        Ok(Event::Incoming(Packet::ConnAck(_))) => {
                            // (Re)subscribes on every connection: the broker may have lost the
                            // session.
                            let _ = sub.subscribe_many(filters.clone());
                            None
                        }
                        Ok(Event::Incoming(Packet::Publish(p))) => incoming(&p),
                        Ok(_) => continue,
                        Err(_) => {
                            std::thread::sleep(Duration::from_millis(500));
                            continue;
                        }
                    };
                    if tx.send(m).is_err() {
                        return;
                    }
                }
            })
            .map_err(|e| FleetError::Broker(cetratus_mct::MctError::Client(e.to_string())))?;
        let link = Link {
            client,
            rx,
            key: config.key,
            account: config.account,
            reply_leaf,
            package_b64: base64::engine::general_purpose::STANDARD.encode(package),
        };
        // The first `None` is the connection's acknowledgement.
        match link.rx.recv_timeout(config.timeout) {
            Ok(_) => Ok(link),
            Err(_) => Err(FleetError::NoBroker {
                url: config.url,
                after: config.timeout,
            }),
        }
    }

    /// The leaf of the rollout's replies.
    pub fn reply_leaf(&self) -> &str {
        &self.reply_leaf
    }

    /// The next message within `wait`; `Ok(None)` when none came.
    pub fn recv(&self, wait: Duration) -> Result<Option<Incoming>, FleetError> {
        let end = Instant::now() + wait;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            match self.rx.recv_timeout(left) {
                Ok(Some(m)) => return Ok(Some(m)),
                Ok(None) if !left.is_zero() => continue,
                Ok(None) | Err(RecvTimeoutError::Timeout) => return Ok(None),
                Err(RecvTimeoutError::Disconnected) => return Err(FleetError::LinkClosed),
            }
        }
    }

    /// Sends `verb` to `plc`, as a request whose reply comes to the rollout's reply topic and
    /// carries `correlation` ([`correlation`]) back.
    pub fn send(&self, plc: &str, verb: Verb, correlation: &[u8]) -> Result<(), FleetError> {
        let plc_id = PlcId::new(plc).map_err(FleetError::Proto)?;
        let topics = Topics::new(plc_id);
        let command: Command = match verb {
            Verb::Load => Command::Load(cetratus_proto::LoadArgs {
                package_b64: self.package_b64.clone(),
            }),
            Verb::Substitute => Command::Substitute(SubstituteArgs::default()),
            bare => Command::bare(bare).unwrap_or(Command::ExecInfo),
        };
        let body = command_payload(
            (self.key.as_ref(), self.account.as_deref()),
            plc,
            verb,
            correlation,
            &command_body(&command),
        )
        .map_err(FleetError::Broker)?;
        let props = PublishProperties {
            response_topic: Some(format!("{}{}", topics.prefix(), self.reply_leaf)),
            correlation_data: Some(correlation.to_vec().into()),
            content_type: Some("application/json".into()),
            ..Default::default()
        };
        self.client
            .publish_with_properties(
                topics.cmd(verb).to_string(),
                QoS::AtLeastOnce,
                false,
                body,
                props,
            )
            .map_err(|e| FleetError::Broker(cetratus_mct::MctError::Client(e.to_string())))
    }

    /// Disconnects.
    pub fn close(self) {
        let _ = self.client.disconnect();
    }
}

/// Fresh correlation data for a command of `verb`: unique to this process's commands, so that a
/// reply is matched to the one command it answers.
pub fn correlation(verb: Verb) -> Vec<u8> {
    format!("rollout-{verb}-{}", unique()).into_bytes()
}

/// A publish on `cetratus/<plc>/<leaf>`; anything else is dropped.
fn incoming(p: &Publish) -> Option<Incoming> {
    let topic = std::str::from_utf8(&p.topic).ok()?;
    let rest = topic.strip_prefix("cetratus/")?;
    let (plc, leaf) = rest.split_once('/')?;
    PlcId::new(plc).ok()?;
    let correlation = (p.properties.as_ref()).and_then(|pr| pr.correlation_data.clone());
    Some(Incoming {
        plc: plc.to_string(),
        leaf: leaf.to_string(),
        payload: p.payload.to_vec(),
        correlation: correlation.map(|c| c.to_vec()),
    })
}
