//! The MQTT side: one rumqttc MQTT 5 client that feeds the [`Fleet`] and the browsers' streams,
//! and sends the browsers' commands as requests with a response topic and correlation data.
//!
//! A reply is trusted only when both its topic and its correlation data are the ones the command
//! named: the topic is under the PLC's own reply namespace, `cetratus/<plc>/reply/dashboard-<t>`
//! with `t` random per dashboard connection, and the correlation data is 16 random bytes per
//! command, so that nobody can answer a command by guessing.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use cetratus_mct::budget::{worth_logging, Budget, Permit};
use rumqttc::v5::mqttbytes::v5::{Packet, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{AsyncClient, Event, EventLoop, MqttOptions};
use serde_json::{json, Value};
use tokio::sync::{broadcast, oneshot, watch};

use cetratus_proto::{BrokerUrl, Leaf, PlcId, ProtoError, Topics, Verb, ROOT};

use crate::store::{Fleet, Ignored, Update};
use crate::DashboardError;

/// Bytes of updates that may wait for the browsers' streams at once. A browser that falls behind
/// holds every update it has not read yet; past this budget, streams start over from a fresh
/// snapshot instead.
const PUSH_BYTES: usize = 32 << 20;

/// `n` random bytes as lowercase hex, from the operating system.
pub(crate) fn random_hex(n: usize) -> Result<String, getrandom::Error> {
    let mut b = vec![0u8; n];
    getrandom::fill(&mut b)?;
    Ok(b.iter().map(|x| format!("{x:02x}")).collect())
}
/// Largest MQTT packet taken from the broker: a `net` message carries two SVG drawings, far over
/// rumqttc's 10 KiB default.
const MAX_PACKET: u32 = 8 << 20;

/// How long a command waits for the PLC's reply by default.
const REPLY_TIMEOUT: Duration = Duration::from_secs(15);

/// The broker to connect to (`mqtt://[user[:password]@]host[:port]`, parsed by the one parser
/// of the protocol); `user` and `password` override the URL's. TLS brokers are refused: the
/// dashboard's client speaks plain MQTT.
pub(crate) fn broker_target(
    url: &str,
    user: Option<&str>,
    password: Option<&str>,
) -> Result<BrokerUrl, DashboardError> {
    let bad = |reason: String| DashboardError::BrokerUrl {
        url: url.to_string(),
        reason,
    };
    let u = BrokerUrl::parse(url).map_err(|e| {
        bad(match e {
            ProtoError::BrokerUrl { reason, .. } => reason,
            other => other.to_string(),
        })
    })?;
    if u.tls() {
        return Err(bad(
            "TLS brokers are not supported by the dashboard yet; reach the broker over a \
             plain `mqtt://host:port` listener on a trusted network"
                .into(),
        ));
    }
    Ok(u.with_credentials(user, password))
}

/// An update on its way to the browsers, holding its share of [`PUSH_BYTES`] until every
/// stream has read it.
#[derive(Debug)]
pub(crate) struct Pushed {
    /// The update.
    pub(crate) update: Update,
    _permit: Permit,
}

/// What the browsers' streams receive.
#[derive(Clone, Debug)]
pub(crate) enum Push {
    /// A message of one PLC.
    Plc(Arc<Pushed>),
    /// The PLC list changed.
    Plcs(Vec<crate::store::Listed>),
    /// The broker connection went up or down.
    Broker(bool),
    /// Updates were not pushed (the streams are behind): start over from a fresh snapshot.
    Restart,
    /// The page's rollout changed: its report.
    Rollout(Arc<Value>),
    /// The page's rollout ended, or was acted on while none ran: read its status again.
    RolloutEnded,
}

/// A command that could not be answered by the PLC: the HTTP status and the reply body.
#[derive(Debug)]
pub(crate) struct CommandFailure {
    /// 503 (no broker), 504 (no reply in time).
    pub(crate) status: u16,
    /// `{"ok": false, "error": {"code", "message"}}`.
    pub(crate) body: Value,
}

/// Shared by the MQTT task and the HTTP handlers.
pub(crate) struct Hub {
    fleet: Mutex<Fleet>,
    tx: broadcast::Sender<Push>,
    connected: AtomicBool,
    pending: Mutex<HashMap<Vec<u8>, Waiter>>,
    client: AsyncClient,
    /// `/reply/dashboard-<random>`: the end of every reply topic of this connection.
    reply_suffix: String,
    pushes: Budget,
    broker: String,
    signer: Option<crate::CommandSigner>,
}

/// A command waiting for its reply: the topic the reply must come on, and who waits.
struct Waiter {
    topic: String,
    tx: oneshot::Sender<Value>,
}

/// Unix time in milliseconds, with sub-millisecond digits, comparable with the browser's
/// `performance.timeOrigin + performance.now()`.
pub(crate) fn unix_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1000.0)
}

fn failure(status: u16, code: &str, message: String) -> CommandFailure {
    CommandFailure {
        status,
        body: json!({"ok": false, "error": {"code": code, "message": message}}),
    }
}

impl Hub {
    /// The hub and the event loop to drive with [`run_mqtt`]; `token` (random, per connection)
    /// names its reply topics.
    pub(crate) fn new(
        target: &BrokerUrl,
        signer: Option<crate::CommandSigner>,
        token: &str,
    ) -> (Arc<Hub>, EventLoop) {
        // Unique per process and start, so two dashboards on one broker do not kick each other
        // off (a broker drops the older of two clients with the same id).
        let nonce = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let name = format!("dashboard-{}-{nonce:08x}", std::process::id());
        // The dashboard of a PLC's own process takes an id that no other login may take on
        // that PLC's broker; elsewhere, a plain one.
        let client_id = match target.credentials() {
            Some((user, _)) if user == cetratus_mct::DASHBOARD_USER => {
                cetratus_mct::acl::internal_client_id(&name)
            }
            _ => format!("cetratus-{name}"),
        };
        let mut opts = MqttOptions::new(client_id.clone(), target.host(), target.port());
        opts.set_keep_alive(Duration::from_secs(10))
            .set_outgoing_inflight_upper_limit(cetratus_mct::MAX_INFLIGHT)
            .set_clean_start(true)
            .set_max_packet_size(Some(MAX_PACKET));
        if let Some((u, p)) = target.credentials() {
            opts.set_credentials(u, p);
        }
        let (client, eventloop) = AsyncClient::new(opts, 256);
        // Lagging browsers are cut off and reconnect with a fresh snapshot, so this only needs
        // to cover a burst.
        let (tx, _) = broadcast::channel(1024);
        let hub = Arc::new(Hub {
            fleet: Mutex::new(Fleet::new()),
            tx,
            connected: AtomicBool::new(false),
            pending: Mutex::new(HashMap::new()),
            client,
            reply_suffix: format!("/reply/dashboard-{token}"),
            pushes: Budget::new(PUSH_BYTES),
            broker: target.to_string(),
            signer,
        });
        (hub, eventloop)
    }

    /// The fleet, even if a panicking thread poisoned the lock (its data is still consistent:
    /// every update is one assignment or one push).
    pub(crate) fn fleet(&self) -> MutexGuard<'_, Fleet> {
        self.fleet.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn pending(&self) -> MutexGuard<'_, HashMap<Vec<u8>, Waiter>> {
        self.pending.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A new receiver of every change.
    pub(crate) fn subscribe(&self) -> broadcast::Receiver<Push> {
        self.tx.subscribe()
    }

    /// What sends changes to the browsers.
    pub(crate) fn sender(&self) -> broadcast::Sender<Push> {
        self.tx.clone()
    }

    /// Whether the client is connected to the broker.
    pub(crate) fn connected(&self) -> bool {
        self.connected.load(Ordering::Acquire)
    }

    /// The broker's address, for the page.
    pub(crate) fn broker(&self) -> &str {
        &self.broker
    }

    fn set_connected(&self, up: bool) {
        if self.connected.swap(up, Ordering::AcqRel) != up {
            let _ = self.tx.send(Push::Broker(up));
        }
    }

    /// The reply topic of this connection for commands to `plc`.
    fn reply_topic(&self, plc: &PlcId) -> String {
        format!("{ROOT}/{plc}{}", self.reply_suffix)
    }

    /// The subscriptions: what the page shows of every PLC, and the replies to this connection.
    fn filters(&self) -> Vec<String> {
        Leaf::PUBLISHED
            .iter()
            .map(|leaf| format!("{ROOT}/+/{}", leaf.as_str()))
            .chain(std::iter::once(format!("{ROOT}/+{}", self.reply_suffix)))
            .collect()
    }

    /// Resolves the command waiting for this reply, if its correlation data and its topic are
    /// both the ones the command named; anything else is dropped.
    fn on_reply(&self, topic: &str, payload: &[u8], props: Option<&PublishProperties>) {
        let Some(corr) = props.and_then(|p| p.correlation_data.as_ref()) else {
            tracing::debug!(topic, "a reply without correlation data was dropped");
            return;
        };
        let waiter = {
            let mut pending = self.pending();
            match pending.get(corr.as_ref()) {
                Some(w) if w.topic == topic => pending.remove(corr.as_ref()),
                _ => None,
            }
        };
        let Some(w) = waiter else {
            tracing::debug!(topic, "a reply that answers no command of ours was dropped");
            return;
        };
        let reply = serde_json::from_slice(payload).unwrap_or_else(|e| {
            json!({"ok": false, "error": {"code": "malformed",
                "message": format!("the PLC's reply is not JSON: {e}")}})
        });
        let _ = w.tx.send(reply);
    }

    fn on_publish(&self, topic: &str, payload: &[u8], props: Option<&PublishProperties>) {
        if topic.ends_with(&self.reply_suffix) {
            self.on_reply(topic, payload, props);
            return;
        }
        let result = self.fleet().apply(topic, payload, unix_ms());
        match result {
            Ok(update) => {
                let list = update.list_changed.then(|| self.fleet().list());
                self.push(update);
                if let Some(l) = list {
                    let _ = self.tx.send(Push::Plcs(l));
                }
            }
            Err(Ignored::NotOurs) => {}
            // `why` names the topic already.
            Err(Ignored::Malformed(why)) => tracing::warn!(reason = %why, "ignored a message"),
            Err(Ignored::TooManyPlcs) => {
                tracing::warn!(topic, "ignored a message: too many PLC ids on this broker")
            }
            Err(Ignored::TooLarge { kind, bytes }) => {
                let n = self.fleet().dropped().too_large;
                if worth_logging(n) {
                    tracing::warn!(
                        topic,
                        bytes,
                        limit = kind.max_bytes(),
                        refused = n,
                        "ignored a message larger than its kind allows"
                    );
                }
            }
        }
    }

    /// Sends an update to the streams, within [`PUSH_BYTES`]; when they are that far behind,
    /// tells them to start over instead.
    fn push(&self, update: Update) {
        if self.tx.receiver_count() == 0 {
            return;
        }
        match self.pushes.try_take(update.bytes) {
            Some(permit) => {
                let _ = self.tx.send(Push::Plc(Arc::new(Pushed {
                    update,
                    _permit: permit,
                })));
            }
            None => {
                let n = self.pushes.refused();
                if worth_logging(n) {
                    tracing::warn!(
                        refused = n,
                        "browsers are behind; their streams start over from a snapshot"
                    );
                }
                let _ = self.tx.send(Push::Restart);
            }
        }
    }

    /// Sends `cetratus/<plc>/cmd/<verb>` with `body` and waits for the PLC's reply.
    pub(crate) async fn command(
        &self,
        plc: &PlcId,
        verb: Verb,
        body: Value,
        timeout: Option<Duration>,
        account: &str,
    ) -> Result<Value, CommandFailure> {
        if !self.connected() {
            return Err(failure(
                503,
                "unavailable",
                format!(
                    "the dashboard is not connected to the broker {}; check that the broker \
                     runs and that --broker names it",
                    self.broker
                ),
            ));
        }
        let corr = match random_hex(16) {
            Ok(c) => c.into_bytes(),
            Err(e) => {
                return Err(failure(
                    503,
                    "unavailable",
                    format!("no random correlation id for the command: {e}"),
                ))
            }
        };
        let reply_topic = self.reply_topic(plc);
        let (tx, rx) = oneshot::channel();
        self.pending().insert(
            corr.clone(),
            Waiter {
                topic: reply_topic.clone(),
                tx,
            },
        );
        let props = PublishProperties {
            response_topic: Some(reply_topic),
            correlation_data: Some(corr.clone().into()),
            content_type: Some("application/json".into()),
            ..PublishProperties::default()
        };
        let topic = Topics::new(plc.clone()).cmd(verb).to_string();
        let payload = match &self.signer {
            Some(sign) => {
                let body = body.to_string();
                let request = crate::SignRequest {
                    plc: plc.as_str(),
                    verb: verb.as_str(),
                    correlation: &corr,
                    payload: body.as_bytes(),
                    account,
                };
                serde_json::json!({ "envelope": (sign.0)(&request) }).to_string()
            }
            None => body.to_string(),
        };
        let sent = self
            .client
            .publish_with_properties(topic, QoS::AtLeastOnce, false, payload, props)
            .await;
        if let Err(e) = sent {
            self.pending().remove(&corr);
            return Err(failure(
                503,
                "unavailable",
                format!("cannot send the command to the broker: {e}"),
            ));
        }
        let wait = timeout.unwrap_or(REPLY_TIMEOUT);
        match tokio::time::timeout(wait, rx).await {
            Ok(Ok(reply)) => Ok(reply),
            _ => {
                self.pending().remove(&corr);
                Err(failure(
                    504,
                    "timeout",
                    format!(
                        "PLC `{plc}` did not answer `{verb}` within {} s; is it online \
                         (see the PLC list) and connected to {}?",
                        wait.as_secs(),
                        self.broker
                    ),
                ))
            }
        }
    }
}

/// Drives the MQTT client until `shutdown`: (re)connects every second, (re)subscribes on every
/// connection, and feeds every message to the hub.
pub(crate) async fn run_mqtt(
    hub: Arc<Hub>,
    mut eventloop: EventLoop,
    mut shutdown: watch::Receiver<bool>,
) {
    // One warning per outage, not one per retry: a broker that stays away for an hour would
    // otherwise fill the log with a line a second.
    let mut outage_reported = false;
    loop {
        if *shutdown.borrow() {
            break;
        }
        let polled = tokio::select! {
            p = eventloop.poll() => p,
            _ = shutdown.changed() => break,
        };
        match polled {
            Ok(Event::Incoming(Packet::ConnAck(_))) => {
                // try_subscribe: awaiting here could deadlock, since this task is the one that
                // drains the request queue.
                for t in hub.filters() {
                    if let Err(e) = hub.client.try_subscribe(t.clone(), QoS::AtLeastOnce) {
                        tracing::warn!(filter = %t, error = %e, "cannot subscribe");
                    }
                }
                hub.set_connected(true);
                outage_reported = false;
            }
            Ok(Event::Incoming(Packet::Publish(p))) => match std::str::from_utf8(&p.topic) {
                Ok(topic) => hub.on_publish(topic, &p.payload, p.properties.as_ref()),
                Err(_) => tracing::debug!("a message with a non-UTF-8 topic was dropped"),
            },
            Ok(_) => {}
            Err(e) => {
                if hub.connected() {
                    tracing::warn!(broker = %hub.broker, error = %e, "dashboard lost the broker");
                    outage_reported = true;
                } else if !outage_reported {
                    tracing::warn!(
                        broker = %hub.broker,
                        error = %e,
                        "dashboard cannot reach the broker; retrying every second"
                    );
                    outage_reported = true;
                } else {
                    tracing::debug!(broker = %hub.broker, error = %e, "broker still unreachable");
                }
                hub.set_connected(false);
                // Fail every waiting command now rather than at its timeout.
                hub.pending().clear();
                tokio::select! {
                    _ = tokio::time::sleep(Duration::from_secs(1)) => {}
                    _ = shutdown.changed() => break,
                }
            }
        }
    }
    let _ = hub.client.try_disconnect();
    // Give the disconnect a moment to leave.
    let _ = tokio::time::timeout(Duration::from_millis(100), eventloop.poll()).await;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(url: &str) -> Result<BrokerUrl, DashboardError> {
        broker_target(url, None, None)
    }

    #[test]
    fn broker_url_forms_are_understood() {
        let t = parse("mqtt://127.0.0.1:1884").expect("valid");
        assert_eq!(
            (t.host(), t.port(), t.credentials()),
            ("127.0.0.1", 1884, None)
        );
        assert_eq!(parse("mqtt://broker").expect("valid").port(), 1883);
        let t = parse("mqtt://alice:s3cret@plant:1883/").expect("valid");
        assert_eq!(t.credentials(), Some(("alice", "s3cret")));
        assert_eq!(t.to_string(), "mqtt://plant:1883");
        let t = parse("mqtt://[::1]:1999").expect("valid");
        assert_eq!((t.host(), t.port()), ("::1", 1999));
        assert_eq!(t.to_string(), "mqtt://[::1]:1999");
    }

    #[test]
    fn a_reply_resolves_a_command_only_with_its_correlation_data_on_its_topic() {
        let target = parse("mqtt://127.0.0.1:9").expect("valid");
        let (hub, _el) = Hub::new(&target, None, "00ff");
        let plc = PlcId::new("cell1").expect("an id");
        let topic = hub.reply_topic(&plc);
        assert_eq!(topic, "cetratus/cell1/reply/dashboard-00ff");
        assert!(hub
            .filters()
            .contains(&"cetratus/+/reply/dashboard-00ff".to_string()));
        assert!(
            !hub.filters().iter().any(|f| f.ends_with('#')),
            "no command is received"
        );
        let (tx, mut rx) = oneshot::channel();
        let corr = random_hex(16).expect("random bytes");
        assert_eq!(corr.len(), 32);
        hub.pending().insert(
            corr.clone().into_bytes(),
            Waiter {
                topic: topic.clone(),
                tx,
            },
        );
        let props = |c: &str| PublishProperties {
            correlation_data: Some(c.as_bytes().to_vec().into()),
            ..PublishProperties::default()
        };
        let forged = br#"{"ok": true, "forged": true}"#;
        // A guessed id on the right topic; the right id on another PLC's reply topic.
        hub.on_publish(&topic, forged, Some(&props("1")));
        hub.on_publish(
            "cetratus/other/reply/dashboard-00ff",
            forged,
            Some(&props(&corr)),
        );
        hub.on_publish(&topic, forged, None);
        assert!(rx.try_recv().is_err(), "nothing resolved the command");
        hub.on_publish(&topic, br#"{"ok": true}"#, Some(&props(&corr)));
        assert_eq!(rx.try_recv().expect("resolved"), json!({"ok": true}));
    }

    #[test]
    fn configured_credentials_override_the_url() {
        let t = broker_target("mqtt://a:b@h", Some("ops"), Some("pw")).expect("valid");
        assert_eq!(t.credentials(), Some(("ops", "pw")));
        let t = broker_target("mqtt://a:b@h", None, Some("pw")).expect("valid");
        assert_eq!(t.credentials(), Some(("a", "pw")));
    }

    #[test]
    fn unusable_broker_urls_say_what_to_write() {
        for bad in [
            "127.0.0.1:1883",
            "http://h",
            "mqtt://:1883",
            "mqtt://h:port",
            "mqtts://h",
        ] {
            let e = parse(bad).expect_err(bad).to_string();
            assert!(e.contains(bad), "{e}");
        }
    }
}
