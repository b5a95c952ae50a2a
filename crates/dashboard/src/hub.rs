//! The MQTT side: one rumqttc MQTT 5 client that feeds the [`Fleet`] and the browsers' streams,
//! and sends the browsers' commands as requests with a response topic and correlation data.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use rumqttc::v5::mqttbytes::v5::{Packet, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{AsyncClient, Event, EventLoop, MqttOptions};
use serde_json::{json, Value};
use tokio::sync::{broadcast, oneshot, watch};

use cetratus_proto::{BrokerUrl, PlcId, ProtoError, Topics, Verb, ALL_PLCS_FILTER};

use crate::store::{Fleet, Ignored, Update};
use crate::DashboardError;

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

/// What the browsers' streams receive.
#[derive(Clone, Debug)]
pub(crate) enum Push {
    /// A message of one PLC.
    Plc(Arc<Update>),
    /// The PLC list changed.
    Plcs(Value),
    /// The broker connection went up or down.
    Broker(bool),
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
    pending: Mutex<HashMap<Vec<u8>, oneshot::Sender<Value>>>,
    client: AsyncClient,
    // The last levels of the reply topics, `reply/dashboard-<process>-<nonce>`, under each PLC's
    // own reply level: the only place a PLC replies to.
    reply_leaf: String,
    next_correlation: AtomicU64,
    broker: String,
    signer: Option<crate::CommandSigner>,
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
    /// The hub and the event loop to drive with [`run_mqtt`].
    pub(crate) fn new(
        target: &BrokerUrl,
        signer: Option<crate::CommandSigner>,
    ) -> (Arc<Hub>, EventLoop) {
        // Unique per process and start, so two dashboards on one broker do not kick each other
        // off (a broker drops the older of two clients with the same id).
        let nonce = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let client_id = format!("cetratus-dashboard-{}-{nonce:08x}", std::process::id());
        let mut opts = MqttOptions::new(client_id.clone(), target.host(), target.port());
        opts.set_keep_alive(Duration::from_secs(10))
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
            reply_leaf: format!("reply/dashboard-{}-{nonce:08x}", std::process::id()),
            next_correlation: AtomicU64::new(1),
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

    fn pending(&self) -> MutexGuard<'_, HashMap<Vec<u8>, oneshot::Sender<Value>>> {
        self.pending.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A new receiver of every change.
    pub(crate) fn subscribe(&self) -> broadcast::Receiver<Push> {
        self.tx.subscribe()
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

    fn on_publish(&self, topic: &str, payload: &[u8], props: Option<&PublishProperties>) {
        let is_reply = topic.starts_with("cetratus/")
            && topic
                .strip_suffix(self.reply_leaf.as_str())
                .is_some_and(|t| t.ends_with('/'));
        if is_reply {
            let Some(corr) = props.and_then(|p| p.correlation_data.as_ref()) else {
                tracing::debug!("a reply without correlation data was dropped");
                return;
            };
            let waiter = self.pending().remove(corr.as_ref());
            if let Some(w) = waiter {
                let reply = serde_json::from_slice(payload).unwrap_or_else(|e| {
                    json!({"ok": false, "error": {"code": "malformed",
                        "message": format!("the PLC's reply is not JSON: {e}")}})
                });
                let _ = w.send(reply);
            }
            return;
        }
        let result = self.fleet().apply(topic, payload, unix_ms());
        match result {
            Ok(update) => {
                let list = update.list_changed.then(|| self.fleet().list());
                let _ = self.tx.send(Push::Plc(Arc::new(update)));
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
        }
    }

    /// Sends `cetratus/<plc>/cmd/<verb>` with `body` and waits for the PLC's reply.
    pub(crate) async fn command(
        &self,
        plc: &PlcId,
        verb: Verb,
        body: Value,
        timeout: Option<Duration>,
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
        let corr = self
            .next_correlation
            .fetch_add(1, Ordering::Relaxed)
            .to_string()
            .into_bytes();
        let (tx, rx) = oneshot::channel();
        self.pending().insert(corr.clone(), tx);
        let topics = Topics::new(plc.clone());
        let props = PublishProperties {
            response_topic: Some(format!("{}{}", topics.prefix(), self.reply_leaf)),
            correlation_data: Some(corr.clone().into()),
            content_type: Some("application/json".into()),
            ..PublishProperties::default()
        };
        let topic = topics.cmd(verb).to_string();
        let payload = match &self.signer {
            Some(sign) => {
                let body = body.to_string();
                let request = crate::SignRequest {
                    plc: plc.as_str(),
                    verb: verb.as_str(),
                    correlation: &corr,
                    payload: body.as_bytes(),
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
                // The PLCs' replies come under `cetratus/<plc>/reply/…`, in this subscription.
                let subs = [(ALL_PLCS_FILTER.to_string(), QoS::AtLeastOnce)];
                for (t, q) in subs {
                    if let Err(e) = hub.client.try_subscribe(t.clone(), q) {
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
