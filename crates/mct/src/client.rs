//! The client side of the control plane: one MQTT 5 session with a PLC, for the CLI commands
//! (`load`, `substitute`, `status`, `watch`, …). Commands go out as requests with a response
//! topic and correlation data, signed as an envelope when the operator has a key.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use cetratus_proto::{Command, Ending, EventMsg, Leaf, PlcId, Reply, Topics, Verb};
use ed25519_dalek::SigningKey;
use rumqttc::v5::mqttbytes::v5::{Packet, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{Client, Connection, Event};
use serde_json::Value;

use crate::{client_options, sign, unix_now, MctError, Signed};

/// An operator key that signs commands: its id and the secret key.
#[derive(Clone)]
pub struct OperatorKey {
    /// The key id, as the PLC's `operators/` directory knows it.
    pub id: String,
    /// The secret key.
    pub key: SigningKey,
}

/// Where to reach a PLC and how long to wait for it.
pub struct SessionConfig {
    /// The broker URL.
    pub url: String,
    /// Credentials that override the URL's.
    pub credentials: Option<(String, String)>,
    /// The PLC.
    pub plc: PlcId,
    /// How long to wait for the broker, a reply, a message.
    pub timeout: Duration,
    /// Signs every command when given.
    pub key: Option<OperatorKey>,
}

/// A message on one of the PLC's topics.
pub struct Message {
    /// The topic's leaf under `cetratus/<plc-id>/` (`state`, `events`, or the reply leaf).
    pub leaf: String,
    /// The payload as JSON (`null` when it is not JSON).
    pub payload: Value,
}

/// How a command sent with [`Session::command`] ended, as far as the session saw it.
#[derive(Debug)]
pub enum Outcome {
    /// The PLC refused the command in its reply; nothing changed.
    Refused(Reply),
    /// Accepted, and the event that completes it arrived (`substituted`, `removed`, …).
    Done {
        /// The PLC's reply.
        reply: Reply,
        /// The event.
        event: EventMsg,
    },
    /// Accepted, then an event ended it without its effect: refused at the cycle boundary, its
    /// condition given up, or the update it acted on ended otherwise.
    Failed {
        /// The PLC's reply.
        reply: Reply,
        /// The event.
        event: EventMsg,
    },
    /// Accepted, and no event ended it within the session's timeout: it may still happen (a
    /// substitution waiting for its `--when`).
    Pending {
        /// The PLC's reply.
        reply: Reply,
    },
    /// Accepted; the reply is the whole outcome (`exec_info`).
    Replied(Reply),
}

/// Messages that arrived while waiting for a reply, kept for [`Session::next_message`]; beyond
/// this many the oldest are dropped.
const HELD: usize = 256;

/// One session with one PLC.
pub struct Session {
    client: Client,
    conn: Connection,
    topics: Topics,
    timeout: Duration,
    key: Option<OperatorKey>,
    reply_leaf: Option<String>,
    events: bool,
    online: bool,
    held: VecDeque<Message>,
}

impl Session {
    /// Connects to the broker; fails when it cannot be reached within the timeout.
    pub fn open(config: SessionConfig) -> Result<Self, MctError> {
        let id = format!(
            "cetratus-cli-{}-{:x}",
            std::process::id(),
            unix_now() ^ u64::from(Instant::now().elapsed().subsec_nanos())
        );
        let mut o = client_options(&config.url, &id)?;
        if let Some((u, p)) = &config.credentials {
            o.set_credentials(u.clone(), p.clone());
        }
        o.set_keep_alive(Duration::from_secs(10));
        o.set_max_packet_size(Some(8 << 20));
        let (client, conn) = Client::new(o, 64);
        let mut s = Session {
            client,
            conn,
            topics: Topics::new(config.plc),
            timeout: config.timeout,
            key: config.key,
            reply_leaf: None,
            events: false,
            online: false,
            held: VecDeque::new(),
        };
        s.wait_for(|e| matches!(e, Packet::ConnAck(_)))
            .map_err(|e| MctError::Connect {
                url: config.url.clone(),
                reason: format!("{e}; is the PLC running? (--broker URL or --mqtt ADDR)"),
            })?;
        Ok(s)
    }

    /// How long the session waits.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// The PLC's topics.
    pub fn topics(&self) -> &Topics {
        &self.topics
    }

    /// Subscribes to one of the PLC's topics and waits for the broker's acknowledgement.
    pub fn subscribe(&mut self, leaf: Leaf) -> Result<(), MctError> {
        let topic = self.topics.leaf(leaf).to_string();
        self.subscribe_topic(topic)
    }

    fn subscribe_topic(&mut self, topic: String) -> Result<(), MctError> {
        self.client
            .subscribe(topic, QoS::AtLeastOnce)
            .map_err(|e| MctError::Client(e.to_string()))?;
        self.wait_for(|p| matches!(p, Packet::SubAck(_)))
    }

    fn wait_for(&mut self, mut f: impl FnMut(&Packet) -> bool) -> Result<(), MctError> {
        let end = Instant::now() + self.timeout;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(MctError::Timeout(self.timeout));
            }
            match self.conn.recv_timeout(left) {
                Ok(Ok(Event::Incoming(p))) if f(&p) => return Ok(()),
                Ok(Ok(_)) => {}
                Ok(Err(e)) => return Err(MctError::Client(e.to_string())),
                Err(_) => return Err(MctError::Timeout(self.timeout)),
            }
        }
    }

    /// The next message on a subscribed topic, waiting at most `wait` (`None`: for ever).
    /// `Ok(None)` when the wait ended or the connection closed.
    pub fn next_message(&mut self, wait: Option<Duration>) -> Result<Option<Message>, MctError> {
        if let Some(m) = self.held.pop_front() {
            return Ok(Some(m));
        }
        self.receive(wait)
    }

    fn receive(&mut self, wait: Option<Duration>) -> Result<Option<Message>, MctError> {
        let end = wait.map(|w| Instant::now() + w);
        loop {
            let r = match end {
                Some(end) => {
                    let left = end.saturating_duration_since(Instant::now());
                    if left.is_zero() {
                        return Ok(None);
                    }
                    match self.conn.recv_timeout(left) {
                        Ok(r) => r,
                        Err(_) => return Ok(None),
                    }
                }
                None => match self.conn.recv() {
                    Ok(r) => r,
                    Err(_) => return Ok(None),
                },
            };
            match r {
                Ok(Event::Incoming(Packet::Publish(p))) => {
                    let topic = String::from_utf8_lossy(&p.topic);
                    let leaf = self.topics.strip(&topic).unwrap_or(&topic).to_string();
                    let payload = serde_json::from_slice(&p.payload).unwrap_or(Value::Null);
                    return Ok(Some(Message { leaf, payload }));
                }
                Ok(_) => {}
                Err(e) => return Err(MctError::Client(e.to_string())),
            }
        }
    }

    /// Keeps `m` for whoever reads next, dropping the oldest beyond [`HELD`].
    fn hold(&mut self, m: Message) {
        if self.held.len() == HELD {
            self.held.pop_front();
        }
        self.held.push_back(m);
    }

    /// Waits, once a session and until `end`, for the PLC's retained `state` to say it is
    /// online. A PLC says so only once it has subscribed to its commands, so a command sent then
    /// is not lost, even right after the PLC started.
    fn wait_online(&mut self, end: Instant) -> Result<(), MctError> {
        if self.online {
            return Ok(());
        }
        self.subscribe(Leaf::State)?;
        let mut seen = "it had no state of it";
        loop {
            let left = end.saturating_duration_since(Instant::now());
            let m = if left.is_zero() {
                None
            } else {
                self.receive(Some(left))?
            };
            let Some(m) = m else {
                return Err(MctError::Offline {
                    plc: self.topics.plc().to_string(),
                    after: self.timeout,
                    seen,
                });
            };
            if m.leaf != Leaf::State.as_str() {
                self.hold(m);
                continue;
            }
            if m.payload["online"] == Value::Bool(true) {
                self.online = true;
                return Ok(());
            }
            seen = "its last state said offline";
        }
    }

    /// Sends a command with a response topic and correlation data, and returns the PLC's reply,
    /// once the PLC is online.
    pub fn request(&mut self, command: &Command) -> Result<Reply, MctError> {
        self.wait_online(Instant::now() + self.timeout)?;
        let verb = command.verb();
        let reply_leaf = format!("reply/cli-{}", std::process::id());
        if self.reply_leaf.as_deref() != Some(reply_leaf.as_str()) {
            let topic = format!("{}{reply_leaf}", self.topics.prefix());
            self.subscribe_topic(topic)?;
            self.reply_leaf = Some(reply_leaf.clone());
        }
        let correlation = format!("{verb}-{}", unique()).into_bytes();
        let body = self.body(verb, &correlation, &cetratus_proto::command_body(command))?;
        let props = PublishProperties {
            response_topic: Some(format!("{}{reply_leaf}", self.topics.prefix())),
            correlation_data: Some(correlation.into()),
            content_type: Some("application/json".into()),
            ..Default::default()
        };
        self.client
            .publish_with_properties(
                self.topics.cmd(verb).to_string(),
                QoS::AtLeastOnce,
                false,
                body,
                props,
            )
            .map_err(|e| MctError::Client(e.to_string()))?;
        let end = Instant::now() + self.timeout;
        while Instant::now() < end {
            if let Some(m) = self.receive(Some(end - Instant::now()))? {
                if m.leaf == reply_leaf {
                    return serde_json::from_value(m.payload).map_err(|e| {
                        MctError::Client(format!("the PLC's reply is malformed: {e}"))
                    });
                }
                // An event may come before the reply; it is kept for whoever reads next.
                self.hold(m);
            }
        }
        Err(MctError::NoReply {
            plc: self.topics.plc().to_string(),
            after: self.timeout,
        })
    }

    /// Sends a command and, once the PLC accepts it, waits for the event that ends it
    /// ([`cetratus_proto::endings`]), all within the session's timeout. Events are followed from before the
    /// command is sent, so an outcome that comes at once is not missed.
    pub fn command(&mut self, command: &Command) -> Result<Outcome, MctError> {
        let verb = command.verb();
        if cetratus_proto::endings(verb).is_empty() {
            let reply = self.request(command)?;
            return Ok(if reply.ok {
                Outcome::Replied(reply)
            } else {
                Outcome::Refused(reply)
            });
        }
        if !self.events {
            self.subscribe(Leaf::Events)?;
            self.events = true;
        }
        let end = Instant::now() + self.timeout;
        let reply = self.request(command)?;
        if !reply.ok {
            return Ok(Outcome::Refused(reply));
        }
        loop {
            let left = end.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(Outcome::Pending { reply });
            }
            let Some(m) = self.next_message(Some(left))? else {
                return Ok(Outcome::Pending { reply });
            };
            if m.leaf != "events" {
                continue;
            }
            let Ok(event) = serde_json::from_value::<EventMsg>(m.payload) else {
                continue;
            };
            match cetratus_proto::ending(verb, &event.kind) {
                Some(Ending::Done) => return Ok(Outcome::Done { reply, event }),
                Some(Ending::Failed) => return Ok(Outcome::Failed { reply, event }),
                None => {}
            }
        }
    }

    /// The payload of a command: the body, or a signed envelope holding it, bound to this PLC
    /// and to the request's correlation data.
    fn body(&self, verb: Verb, correlation: &[u8], body: &Value) -> Result<Vec<u8>, MctError> {
        let plc = self.topics.plc().as_str();
        command_payload((self.key.as_ref(), None), plc, verb, correlation, body)
    }
}

/// The payload of a command to `plc`: the body, or, with an operator key, a signed envelope
/// holding it, bound to the PLC and to the request's correlation data, and naming the account
/// the signer acts for when one is given.
pub fn command_payload(
    (key, account): (Option<&OperatorKey>, Option<&str>),
    plc: &str,
    verb: Verb,
    correlation: &[u8],
    body: &Value,
) -> Result<Vec<u8>, MctError> {
    let inner = serde_json::to_vec(body).map_err(|e| MctError::Client(e.to_string()))?;
    let Some(k) = key else {
        return Ok(inner);
    };
    // The nonce only has to be unique per key within the replay window.
    let nonce = unique();
    let signed = Signed {
        plc,
        verb: verb.as_str(),
        correlation,
        timestamp: unix_now(),
        nonce: &nonce,
        account,
    };
    let env = sign(&signed, &inner, &k.id, &k.key);
    serde_json::to_vec(&serde_json::json!({ "envelope": env }))
        .map_err(|e| MctError::Client(e.to_string()))
}

/// A string unique to this process and instant: the process id and the nanoseconds of the wall
/// clock.
pub fn unique() -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    format!("{}-{nanos}", std::process::id())
}
