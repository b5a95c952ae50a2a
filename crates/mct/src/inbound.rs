//! The MQTT side's way in: what the client reads, and the commands it hands to the PLC.
//!
//! The event loop (a Tokio task) only reads: it passes each command on, unparsed, within
//! [`UNREAD_BYTES`], or turns it away without its payload. The control thread parses and
//! authorises (the [`ControlPlane`]), answers what cannot be queued, and queues the rest for the
//! PLC in the [`CommandQueue`], bounded in entries and in bytes. Whatever cannot be queued is
//! answered `busy` where a reply address is known, and counted.

use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::Duration;

use cetratus_proto::{ErrorBody, ErrorCode, EventKind, EventMsg, Topics};
use rumqttc::v5::mqttbytes::v5::{DisconnectReasonCode, Packet, Publish};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{AsyncClient, ConnectionError, Event, EventLoop, StateError};

use crate::broker::BROKER_MAX_PACKET;
use crate::budget::{worth_logging, Budget, Permit};
use crate::control::{unix_now, ControlPlane, IncomingCommand, Outcome, ReplyHandle, Request};
use crate::ingress::{TurnedAway, TURNED_AWAY_PROPERTY};
use crate::link::{handle_bytes, reply_props, Shared};

/// What a queued command costs: its package, its reply address, its correlation data.
fn command_bytes(c: &IncomingCommand) -> usize {
    let payload = match &c.request {
        Request::Load(package) => package.len(),
        Request::Substitute(a) => a.when.as_ref().map_or(0, String::len),
        _ => 0,
    };
    256 + payload + handle_bytes(&c.reply) + c.key_id.as_ref().map_or(0, String::len)
}

/// The commands waiting for the PLC: bounded in entries ([`crate::MqttConfig::queue_capacity`]) and in
/// bytes ([`crate::MqttConfig::command_bytes`]); a command's bytes are given back when it is taken.
#[derive(Debug)]
pub struct CommandQueue(pub(crate) Receiver<(IncomingCommand, Permit)>);

impl CommandQueue {
    /// The next command, if any; never blocks.
    pub fn try_recv(&self) -> Option<IncomingCommand> {
        self.0.try_recv().ok().map(|(c, _permit)| c)
    }

    /// The next command, waiting up to `timeout` (not on the scan thread).
    pub fn recv_timeout(&self, timeout: Duration) -> Result<IncomingCommand, RecvTimeoutError> {
        self.0.recv_timeout(timeout).map(|(c, _permit)| c)
    }
}

// Never awaits the client (its queue is drained by the event loop task, which must not wait on
// itself): try_publish, and a full queue loses the message, counted and logged.
fn try_reply(client: &AsyncClient, shared: &Shared, handle: &ReplyHandle, outcome: &Outcome) {
    if let Some(topic) = &handle.topic {
        let payload = ControlPlane::reply_payload(handle, outcome);
        if let Err(e) = client.try_publish_with_properties(
            topic.clone(),
            QoS::AtLeastOnce,
            false,
            payload,
            reply_props(handle),
        ) {
            shared.lost("a reply", topic, &e);
        }
    }
}

fn try_event(client: &AsyncClient, shared: &Shared, topic: &str, event: &EventMsg) {
    let payload = serde_json::to_vec(event).unwrap_or_default();
    if let Err(e) = client.try_publish(topic, QoS::AtLeastOnce, false, payload) {
        shared.lost("an event", topic, &e);
    }
}

fn busy(shared: &Shared, why: &str) -> Outcome {
    let n = shared.commands_busy.fetch_add(1, Ordering::Relaxed) + 1;
    if worth_logging(n) {
        tracing::warn!(busy = n, "a command was answered busy: {why}");
    }
    Err(ErrorBody {
        code: ErrorCode::Busy,
        message: format!("{why}; retry in a moment"),
    })
}

/// A command as it came off the wire, on its way to the control thread.
pub(crate) enum Inbound {
    /// To be parsed, authorised and queued; the permit holds its bytes of [`UNREAD_BYTES`].
    Command(Publish, Permit),
    /// Turned away unread (its payload is dropped already): only answered `busy`.
    TurnedAway(Publish, Permit),
}

/// Bytes of commands the MQTT client may hold before they are parsed: two of the largest the
/// broker passes. The client reads them at the network's pace and the control thread parses
/// them at its own; past this budget a command is turned away unread, so that neither this
/// process nor the broker in it holds what the PLC cannot read (the embedded broker queues
/// without bound for a subscriber that does not read).
pub const UNREAD_BYTES: usize = 2 * BROKER_MAX_PACKET as usize;

/// Commands turned away unread that may wait for their `busy` answer.
const TURNED_AWAY: usize = 1024;

/// A connection the broker accepted and closed again within this time counts as taken.
const SHORT_LIVED: Duration = Duration::from_secs(5);

/// Three such connections within this time are another client taking the client id.
const FLAPPING_WITHIN: Duration = Duration::from_secs(60);

/// Watches for another client taking this client id: the broker says so (MQTT 5's *session
/// taken over*), or, as Mosquitto does, closes the older connection without a word; then the
/// sign is a connection it accepted and closed again at once, three times within a minute.
#[derive(Default)]
struct Takeovers {
    /// When the current connection was accepted.
    since: Option<std::time::Instant>,
    /// When the latest short-lived connections ended within the last minute (fewer than three:
    /// the third is a takeover, and clears them).
    short: std::collections::VecDeque<std::time::Instant>,
    /// Takeovers seen.
    count: u64,
    /// Whether the latest is still to be told on `events`.
    to_tell: bool,
}

impl Takeovers {
    fn connected(&mut self) {
        self.since = Some(std::time::Instant::now());
    }

    /// Whether the connection's end `e` is a takeover; counts it.
    fn lost(&mut self, e: &ConnectionError) -> bool {
        let said = matches!(
            e,
            ConnectionError::MqttState(StateError::ServerDisconnect {
                reason_code: DisconnectReasonCode::SessionTakenOver,
                ..
            })
        );
        let now = std::time::Instant::now();
        let closed = matches!(e, ConnectionError::MqttState(StateError::ConnectionAborted));
        if closed && self.since.take().is_some_and(|t| now - t < SHORT_LIVED) {
            self.short.push_back(now);
        }
        while self
            .short
            .front()
            .is_some_and(|t| now - *t > FLAPPING_WITHIN)
        {
            self.short.pop_front();
        }
        if !said && self.short.len() < 3 {
            return false;
        }
        self.short.clear();
        self.count += 1;
        self.to_tell = true;
        true
    }

    /// What the PLC says, naming its id and what to do.
    fn message(&self, topics: &Topics) -> String {
        format!(
            "another client connected with this PLC's client id and the broker dropped this \
             connection ({} times so far): does another PLC on this broker have the id `{}`? \
             give each PLC its own id (--plc)",
            self.count,
            topics.plc()
        )
    }
}

pub(crate) async fn event_loop(
    mut eventloop: EventLoop,
    client: AsyncClient,
    topics: Topics,
    inbound: std::sync::mpsc::Sender<Inbound>,
    shared: Arc<Shared>,
) {
    let filter = topics.command_filter().to_string();
    let mut takeovers = Takeovers::default();
    let unread = Budget::new(UNREAD_BYTES);
    let turned_away = Budget::new(TURNED_AWAY);
    // One warning per outage, not one per retry: a broker that stays away for an hour would
    // otherwise fill the log with a line a second.
    let mut outage_reported = false;
    loop {
        match eventloop.poll().await {
            Ok(Event::Incoming(Packet::ConnAck(_))) => {
                if let Err(e) = client.try_subscribe(filter.clone(), QoS::AtLeastOnce) {
                    tracing::warn!(%filter, error = %e, "cannot subscribe");
                }
            }
            Ok(Event::Incoming(Packet::SubAck(_))) => {
                shared.connected.store(true, Ordering::Release);
                if std::mem::take(&mut outage_reported) {
                    tracing::info!("MQTT connection restored");
                }
                takeovers.connected();
                if std::mem::take(&mut takeovers.to_tell) {
                    let event = EventMsg {
                        cycle: None,
                        time_us: None,
                        kind: EventKind::IdTakenOver.into(),
                        message: takeovers.message(&topics),
                        detail: serde_json::json!({"times": takeovers.count}),
                    };
                    try_event(&client, &shared, topics.events(), &event);
                }
            }
            Ok(Event::Incoming(Packet::Publish(mut p))) => {
                if p.retain {
                    // A command acts when it is sent, never again from the broker's store: a
                    // retained one would run at every start and every reconnect.
                    tracing::warn!(
                        topic = %String::from_utf8_lossy(&p.topic),
                        "a retained command was ignored; clear it with an empty retained message"
                    );
                    continue;
                }
                // Nothing is parsed here: this task only reads, so that it keeps up with the
                // network whatever a command costs to parse.
                let marked = p.properties.as_ref().is_some_and(|pr| {
                    pr.user_properties
                        .iter()
                        .any(|(k, _)| k == TURNED_AWAY_PROPERTY)
                });
                let permit = (!marked)
                    .then(|| unread.try_take(p.payload.len() + 256))
                    .flatten();
                let msg = match permit {
                    Some(permit) => Inbound::Command(p, permit),
                    None => {
                        drop(std::mem::take(&mut p.payload));
                        match turned_away.try_take(1) {
                            Some(permit) => Inbound::TurnedAway(p, permit),
                            None => {
                                let n = shared.commands_dropped.fetch_add(1, Ordering::Relaxed) + 1;
                                if worth_logging(n) {
                                    tracing::warn!(
                                        dropped = n,
                                        "commands come faster than the PLC reads them; one was \
                                         dropped unread and unanswered"
                                    );
                                }
                                continue;
                            }
                        }
                    }
                };
                if inbound.send(msg).is_err() {
                    return;
                }
            }
            Ok(_) => {}
            Err(e) => {
                shared.connected.store(false, Ordering::Release);
                if shared.stopping.load(Ordering::Acquire) {
                    return;
                }
                if takeovers.lost(&e) {
                    if worth_logging(takeovers.count) {
                        tracing::error!("{}", takeovers.message(&topics));
                    }
                } else if outage_reported {
                    tracing::debug!(error = %e, "MQTT connection still down; retrying in 1 s");
                } else {
                    tracing::warn!(error = %e, "MQTT connection lost; retrying in 1 s");
                    outage_reported = true;
                }
                // In slices, so a shutdown does not wait out the whole back-off.
                for _ in 0..20 {
                    if shared.stopping.load(Ordering::Acquire) {
                        return;
                    }
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
            }
        }
    }
}

/// The control thread: parses and authorises what the event loop read, answers what cannot be
/// queued, and queues the rest for the PLC within the command queue's bytes.
pub(crate) fn control_loop(
    inbound: Receiver<Inbound>,
    client: AsyncClient,
    mut control: ControlPlane,
    (commands, budget): (SyncSender<(IncomingCommand, Permit)>, Budget),
    shared: Arc<Shared>,
) {
    let events = control.topics().events().to_string();
    while let Ok(msg) = inbound.recv() {
        let (p, turned_away) = match msg {
            Inbound::Command(p, _permit) => (p, false),
            Inbound::TurnedAway(p, _permit) => (p, true),
        };
        let Ok(topic) = std::str::from_utf8(&p.topic) else {
            continue;
        };
        let props = p.properties.as_ref();
        let response_topic = props.and_then(|pr| pr.response_topic.as_deref());
        let correlation = props.and_then(|pr| pr.correlation_data.as_deref());
        if turned_away {
            // The control plane's own rules say where a reply may go, read from the topic and
            // the properties alone (the payload is gone): an empty payload is never queued,
            // whatever the verb, only answered.
            let reply = match control.parse(topic, b"", response_topic, correlation, unix_now()) {
                Ok(cmd) => Some(cmd.reply),
                Err(rej) => rej.reply.map(|(h, _)| h),
            };
            // The embedded broker says which of its limits turned the command away; without
            // that, it was this client's own budget.
            let why = props
                .into_iter()
                .flat_map(|pr| &pr.user_properties)
                .find(|(k, _)| k == TURNED_AWAY_PROPERTY)
                .and_then(|(_, v)| TurnedAway::from_name(v))
                .map_or_else(
                    || "the PLC reads commands slower than they come".to_string(),
                    TurnedAway::why,
                );
            match reply {
                Some(h) if h.topic.is_some() => {
                    try_reply(&client, &shared, &h, &busy(&shared, &why))
                }
                _ => {
                    shared.commands_dropped.fetch_add(1, Ordering::Relaxed);
                }
            }
            continue;
        }
        match control.parse(topic, &p.payload, response_topic, correlation, unix_now()) {
            Ok(cmd) => {
                try_event(
                    &client,
                    &shared,
                    &events,
                    &ControlPlane::accepted_event(&cmd),
                );
                let Some(permit) = budget.try_take(command_bytes(&cmd)) else {
                    let why = format!(
                        "the PLC's command queue is full ({} of {} bytes waiting)",
                        budget.used(),
                        budget.limit()
                    );
                    try_reply(&client, &shared, &cmd.reply, &busy(&shared, &why));
                    continue;
                };
                match commands.try_send((cmd, permit)) {
                    Ok(()) => {}
                    Err(TrySendError::Full((cmd, _))) => {
                        let why = "the PLC's command queue is full";
                        try_reply(&client, &shared, &cmd.reply, &busy(&shared, why));
                    }
                    Err(TrySendError::Disconnected((cmd, _))) => try_reply(
                        &client,
                        &shared,
                        &cmd.reply,
                        &Err(ErrorBody {
                            code: ErrorCode::Unavailable,
                            message: "the PLC's scan loop is not running".into(),
                        }),
                    ),
                }
            }
            Err(rej) => {
                if let Some((h, e)) = &rej.reply {
                    try_reply(&client, &shared, h, &Err(e.clone()));
                }
                try_event(&client, &shared, &events, &rej.event);
            }
        }
    }
}
