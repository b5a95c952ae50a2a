//! The embedded broker: rmqtt in its own thread and Tokio runtime, one TCP port for MQTT 3.1.1
//! and MQTT 5 clients (rmqtt reads the protocol level of each CONNECT and picks the codec),
//! retained messages kept in memory, last wills, accounts with argon2 password hashes and an ACL
//! ([`crate::acl`]), and TLS from the local configuration.
//!
//! With TLS the broker listens twice: on the configured address with TLS, and on a loopback port
//! of its own without it, for the clients of its own process (the PLC's client, the dashboard of
//! `run`), which log in with secrets drawn at start. The ACL and the logins apply on both.
//!
//! It runs inside the PLC's process, so what it keeps for others is the PLC's memory: retained
//! messages are bounded in bytes ([`RETAINED_BYTES`]), the messages handed to one subscriber's
//! session and not yet taken by it in bytes ([`SESSION_INBOX_BYTES`]), the messages queued
//! behind that and in flight to it in count and bytes ([`SESSION_QUEUE`], [`SESSION_INFLIGHT`],
//! [`SESSION_QUEUE_BYTES`]), what all sessions hold together in bytes ([`SESSIONS_BYTES`], with
//! a reserve for the process's own clients, [`INTERNAL_SESSIONS_BYTES`]), the packets that all
//! connections have begun to receive ([`PARTIALS_BYTES`]) and each connection's buffers once
//! empty ([`CONNECTION_BUFFER_BYTES`]), the clients in number
//! ([`MAX_CLIENTS`]), and what others publish in bytes and in commands per second
//! ([`crate::ingress`]): every command costs the broker, the PLC's client and the machine a round
//! trip. The PLC's own client is not limited: what it publishes is its own.
//!
//! rmqtt hands each message for a subscriber to the subscriber's session through a channel that
//! rmqtt leaves unbounded, and bounds the queue behind it in messages only, so a subscriber that
//! reads just fast enough never to hit the send timeout, or that never acknowledges, would have
//! what others publish kept here. The workspace builds rmqtt from a patched copy (`vendor/rmqtt`,
//! `vendor/README.md`) that counts those bytes per session and in total and hands a message that
//! does not fit to the `message_dropped` hook instead; [`Drops`] counts and logs them. Each
//! publication is copied out of the buffer it was read into before it is routed ([`detached`]),
//! so that what a session is charged for is what it holds.
//!
//! An account's password is checked with argon2 on one blocking thread at a time, at most
//! eight a second ([`LOGINS`]): a flood of wrong passwords costs a core at most and never the
//! internal logins, which compare a random secret.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::num::NonZeroU16;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use cetratus_slots::rate::Rate;

use crate::acl::{Acl, BrokerSettings, Login, DASHBOARD_USER, PLC_USER};
use crate::checks::{Auth, PublishAcl, SubscribeLimits};
use crate::ingress::Ingress;
use crate::MctError;
use async_trait::async_trait;
use rmqtt::context::ServerContext;
use rmqtt::hook::{Handler, HookResult, Parameter, ReturnType, Type};
use rmqtt::net::{PartialsBudget, SessionsBudget};
use rmqtt::retain::{DefaultRetainStorage, RetainStorage};
use rmqtt::server::MqttServer;
use rmqtt::types::{Retain, TopicFilter, TopicName};

/// Largest MQTT packet the embedded broker accepts: above the 1 MiB command limit, so an
/// oversized command reaches the control plane and gets a `too_large` reply instead of a dropped
/// connection.
pub const BROKER_MAX_PACKET: u32 = 4 << 20;

/// Bytes of retained messages (topics and payloads) the embedded broker keeps for everyone
/// together. A PLC retains two messages (`state` and `net`); anyone else on the port could retain
/// a message of [`BROKER_MAX_PACKET`] bytes on as many topics as they like.
pub const RETAINED_BYTES: usize = 32 << 20;

/// Messages queued for one subscriber that does not read fast enough (rmqtt's default is 1000:
/// 4 GB of 4 MiB messages); past it the broker drops them for that subscriber.
pub const SESSION_QUEUE: usize = 64;

/// Bytes of messages handed to one subscriber's session and not yet taken by the session's task
/// (payload, topic and rmqtt's fixed overhead of 512 bytes a message); past it a message is
/// dropped for that subscriber and counted ([`Drops`]). Four full packets ([`BROKER_MAX_PACKET`]):
/// * every message fits in an empty inbox, since the broker takes no larger packet from anyone,
///   the PLC included: a full 1 MiB command, and a larger one that earns `too_large`;
/// * the two subscribers in the PLC's process, its own client (commands) and its dashboard
///   (everything the PLCs publish), read faster than others may publish
///   ([`INGRESS_BYTES_PER_S`](crate::ingress::INGRESS_BYTES_PER_S)), so their inboxes hold at most what others send at once
///   ([`INGRESS_BURST`](crate::ingress::INGRESS_BURST), two packets) plus what arrives while the session writes one message
///   (less than two more): they lose nothing to this bound while they keep up;
/// * a subscriber that reads slowly costs the PLC at most this (and its queue behind it,
///   [`SESSION_QUEUE`]), however long others publish. Payloads are shared between sessions, so
///   many slow subscribers of the same messages cost little more than one.
pub const SESSION_INBOX_BYTES: usize = 4 * BROKER_MAX_PACKET as usize;

/// QoS 1 and 2 messages in flight to one subscriber (rmqtt's default).
pub const SESSION_INFLIGHT: u16 = 16;

/// Bytes of messages in one subscriber's deliver queue (behind its inbox) and in its in-flight
/// window together, counted as in the inbox; past it a message is dropped for that subscriber and
/// counted ([`Drops`]). Without it the queue is bounded in messages only: [`SESSION_QUEUE`] and
/// [`SESSION_INFLIGHT`] messages of [`BROKER_MAX_PACKET`] bytes are 320 MiB for one subscriber that
/// takes its messages and never acknowledges them. Two full packets:
/// * every message fits in an empty queue, and a full-size message fits beside one in flight;
/// * the two subscribers in the PLC's process take every message as soon as it is written and
///   acknowledge it at once, so their queues hold a message or two (the inbox before it absorbs
///   bursts): they lose nothing to this bound while they keep up.
pub const SESSION_QUEUE_BYTES: usize = 2 * BROKER_MAX_PACKET as usize;

/// Bytes that the sessions of all clients but the process's own hold together, in their inboxes,
/// deliver queues and in-flight windows, counted as in each of them; past it a message is dropped
/// for the subscriber it was for, whichever that is, and counted ([`Drops`]). Without it each of
/// [`MAX_CLIENTS`] sessions could hold its own budgets ([`SESSION_INBOX_BYTES`] and
/// [`SESSION_QUEUE_BYTES`], 24 MiB): 6 GiB. 64 MiB is room for more than two sessions full to
/// their budgets, or for a burst of [`INGRESS_BURST`](crate::ingress::INGRESS_BURST) to each of eight subscribers at once; with
/// [`RETAINED_BYTES`] and [`INTERNAL_SESSIONS_BYTES`] it keeps what the broker holds for others
/// well under the 256 MB that the PLC may use under any flood.
pub const SESSIONS_BYTES: usize = 64 << 20;

/// Bytes that a session's inbox, and its deliver queue, may each hold however full
/// [`SESSIONS_BYTES`] is: a session that holds less is never refused by the total, so slow
/// subscribers that hold the total leave an operator's session room for the replies to its
/// commands and for events (a few KiB each). The total may pass its bound by this much twice a
/// session, 32 MiB over [`MAX_CLIENTS`].
pub const SESSION_FLOOR_BYTES: usize = 64 << 10;

/// Bytes that the sessions of the process's own clients (the PLC's, logged in as
/// [`crate::PLC_USER`], and the dashboard's of `run`, [`crate::DASHBOARD_USER`]) hold together,
/// apart from [`SESSIONS_BYTES`], so that what others make the broker hold for slow subscribers
/// can never leave the PLC's commands, nor its dashboard, without room. The two sessions' own
/// budgets, summed: the reserve itself never refuses them a message their budgets admit.
pub const INTERNAL_SESSIONS_BYTES: usize = 2 * (SESSION_INBOX_BYTES + SESSION_QUEUE_BYTES);

/// Sessions at once: a PLC, its dashboard, operators and a few tools. Past it a CONNECT is
/// refused with *server unavailable* (3 in MQTT 3.1.1, 0x88 in MQTT 5) before its login is
/// checked; the process's own clients are never refused, so the PLC's client reconnects whoever
/// holds the sessions.
pub const MAX_CLIENTS: usize = 256;

/// Bytes of packets that all connections together have begun to receive and not yet received
/// whole: the capacity of each connection's read buffer, past [`PARTIAL_FLOOR_BYTES`], booked
/// before every read (rmqtt's codec reserves a packet's announced length once it has its
/// header); a connection whose read would take the total past it is disconnected, counted and
/// logged. A packet is read whole before it is decoded, so without it each of [`MAX_CLIENTS`]
/// clients could make the broker hold all but the last byte of a packet of
/// [`BROKER_MAX_PACKET`] bytes for as long as it likes: 1 GiB. 32 MiB is eight full-size
/// packets arriving at once, four times the ingress burst ([`INGRESS_BURST`](crate::ingress::INGRESS_BURST)) that others may
/// publish together anyway; with [`RETAINED_BYTES`], [`SESSIONS_BYTES`],
/// [`INTERNAL_SESSIONS_BYTES`] and the floors it keeps what the broker holds for others under the
/// 256 MB that the PLC may use under any flood. The process's own clients (the PLC's and the
/// dashboard's, recognised by their login once it is checked) are not counted.
pub const PARTIALS_BYTES: usize = 32 << 20;

/// Capacity of a read buffer that a connection may always have, whatever [`PARTIALS_BYTES`]
/// holds: a login, an acknowledgement, an operator's command of up to about this size is never
/// refused because other clients hold the total. The total may pass its bound by this much a
/// connection, 16 MiB over [`MAX_CLIENTS`].
pub const PARTIAL_FLOOR_BYTES: usize = 64 << 10;

/// Capacity past which a connection's read or write buffer, once empty again, is given back and
/// replaced by a new one: one large packet costs its size while it is read or written, not for
/// the life of the connection. Packets up to this size, the most common by far, reuse their
/// buffer.
pub const CONNECTION_BUFFER_BYTES: usize = 64 << 10;

/// Account logins whose password the broker checks per second, for all clients together; past
/// it (16 may arrive at once) a login is refused without being checked.
pub const LOGINS: Rate = Rate {
    per_s: 8.0,
    burst: 16.0,
};

/// A copy of `publish` that shares no memory with the buffer it was read into. rmqtt's codec
/// cuts a packet's topic, payload and properties out of the connection's read buffer without
/// copying them, so a message kept for a subscriber kept alive the whole buffer it was read
/// with: a 64-byte message read together with a 3 MiB one kept the 3 MiB, and a session charged
/// for 80 such messages (about 48 KiB) held 280 MiB (`crates/cli/tests/hoarding_subscribers.rs`).
/// The broker copies every publication once, before it is routed, so that what the sessions are
/// charged for is what they hold.
pub(crate) fn detached(publish: &rmqtt::types::Publish) -> rmqtt::types::Publish {
    fn own(s: &TopicName) -> TopicName {
        TopicName::from(s.to_string())
    }
    let mut copy = publish.clone();
    let inner = &mut *copy.inner;
    inner.topic = own(&publish.topic);
    inner.payload = publish.payload.to_vec().into();
    if let Some(p) = inner.properties.as_mut() {
        p.correlation_data = p.correlation_data.as_ref().map(|b| b.to_vec().into());
        p.content_type = p.content_type.as_ref().map(own);
        p.response_topic = p.response_topic.as_ref().map(own);
        for (name, value) in &mut p.user_properties {
            (*name, *value) = (own(name), own(value));
        }
    }
    copy
}

/// Counts the messages the broker dropped for one subscriber, by cause, and logs each cause on
/// its 1st, 2nd, 4th… occurrence: a session inbox over [`SESSION_INBOX_BYTES`], a deliver
/// queue over [`SESSION_QUEUE`] or [`SESSION_QUEUE_BYTES`], or all sessions over
/// [`SESSIONS_BYTES`] (or [`INTERNAL_SESSIONS_BYTES`]).
#[derive(Default)]
struct Drops {
    inbox_full: AtomicU64,
    queue_full: AtomicU64,
    total_full: AtomicU64,
}

#[async_trait]
impl Handler for Drops {
    async fn hook(&self, param: &Parameter, acc: Option<HookResult>) -> ReturnType {
        let Parameter::MessageDropped(to, _, publish, reason) = param else {
            return (true, acc);
        };
        let (counter, limit) = match reason {
            rmqtt::types::Reason::SessionInboxFull => (
                &self.inbox_full,
                "its session's inbox (SESSION_INBOX_BYTES)",
            ),
            rmqtt::types::Reason::MessageQueueFull => (
                &self.queue_full,
                "its deliver queue (SESSION_QUEUE messages or SESSION_QUEUE_BYTES)",
            ),
            rmqtt::types::Reason::SessionsBudgetFull => (
                &self.total_full,
                "what all sessions hold together (SESSIONS_BYTES, or INTERNAL_SESSIONS_BYTES for \
                 the PLC's own clients)",
            ),
            _ => return (true, acc),
        };
        let n = counter.fetch_add(1, Ordering::Relaxed) + 1;
        if crate::budget::worth_logging(n) {
            let subscriber = to.as_ref().map(|id| id.client_id.to_string());
            tracing::warn!(
                topic = %publish.topic,
                bytes = publish.payload.len(),
                subscriber = subscriber.as_deref().unwrap_or("?"),
                dropped = n,
                "a subscriber of the embedded broker reads slower than messages come for it; a \
                 message for it was dropped: {limit} is full"
            );
        }
        (true, acc)
    }
}

/// One handler registered for several hook types.
struct Shared<H>(Arc<H>);

#[async_trait]
impl<H: Handler> Handler for Shared<H> {
    async fn hook(&self, param: &Parameter, acc: Option<HookResult>) -> ReturnType {
        self.0.hook(param, acc).await
    }
}

/// What the retained messages hold, by topic, in bytes.
#[derive(Default)]
struct RetainedBytes {
    by_topic: HashMap<String, usize>,
    total: usize,
}

/// rmqtt's default retain storage only logs (retention lives in a plugin configured from files);
/// the same tree, enabled, is all a single PLC needs, bounded in bytes.
struct MemRetain {
    tree: DefaultRetainStorage,
    bytes: Mutex<RetainedBytes>,
    refused: AtomicU64,
}

impl MemRetain {
    fn new() -> Self {
        MemRetain {
            tree: DefaultRetainStorage::new(),
            bytes: Mutex::new(RetainedBytes::default()),
            refused: AtomicU64::new(0),
        }
    }

    /// Books `size` bytes for `topic` (0 deletes it); false when that would pass
    /// [`RETAINED_BYTES`]. Replacing a topic's message gives its old bytes back first.
    fn book(&self, topic: &str, size: usize) -> bool {
        let mut b = self.bytes.lock().unwrap_or_else(|e| e.into_inner());
        let old = b.by_topic.get(topic).copied().unwrap_or(0);
        let after = b.total - old + size;
        if size > 0 && after > RETAINED_BYTES {
            return false;
        }
        b.total = after;
        if size == 0 {
            b.by_topic.remove(topic);
        } else {
            b.by_topic.insert(topic.to_string(), size);
        }
        true
    }
}

#[async_trait]
impl RetainStorage for MemRetain {
    fn enable(&self) -> bool {
        true
    }
    async fn set(
        &self,
        topic: &TopicName,
        retain: Retain,
        expiry: Option<Duration>,
    ) -> rmqtt::Result<()> {
        let payload = retain.publish.payload.len();
        let size = if payload == 0 {
            0
        } else {
            // The topic is stored twice (the tree's levels and the message) beside the payload.
            payload + 2 * topic.len() + 256
        };
        if !self.book(topic, size) {
            let n = self.refused.fetch_add(1, Ordering::Relaxed) + 1;
            if crate::budget::worth_logging(n) {
                tracing::warn!(
                    %topic,
                    bytes = payload,
                    refused = n,
                    "the embedded broker keeps at most {RETAINED_BYTES} bytes of retained \
                     messages; this one is delivered but not retained"
                );
            }
            return Ok(());
        }
        self.tree.set_with_timeout(topic, retain, expiry).await
    }
    async fn get(&self, filter: &TopicFilter) -> rmqtt::Result<Vec<(TopicName, Retain)>> {
        self.tree.get_message(filter).await
    }
    async fn count(&self) -> isize {
        self.tree.count().await
    }
    async fn max(&self) -> isize {
        self.tree.max().await
    }
}

/// A running embedded broker; stops when dropped.
pub struct EmbeddedBroker {
    addr: SocketAddr,
    local: SocketAddr,
    acl: Arc<Acl>,
    stop: Option<std::sync::mpsc::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for EmbeddedBroker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EmbeddedBroker")
            .field("addr", &self.addr)
            .field("local", &self.local)
            .finish()
    }
}

/// The total of [`PARTIALS_BYTES`] for all listeners, which logs each client it disconnects on the
/// 1st, 2nd, 4th… occurrence.
fn partials_budget() -> PartialsBudget {
    PartialsBudget::new(PARTIALS_BYTES, PARTIAL_FLOOR_BYTES).on_refused(Box::new(|n, from, bytes| {
        if crate::budget::worth_logging(n) {
            tracing::warn!(
                %from,
                bytes,
                disconnected = n,
                "a client of the embedded broker was disconnected in the middle of a packet: the \
                 packets begun and not yet received by all clients passed {PARTIALS_BYTES} bytes"
            );
        }
    }))
}

/// One rmqtt listener on `addr`, with TLS when `tls` names its files.
async fn listener(
    addr: SocketAddr,
    anonymous: bool,
    tls: Option<&crate::acl::BrokerTls>,
    sessions: &Arc<SessionsBudget>,
    partials: &Arc<PartialsBudget>,
) -> Result<rmqtt::net::Listener, MctError> {
    let b = rmqtt::net::Builder::new()
        .name("cetratus")
        .laddr(addr)
        // A restart must not wait for the last run's connections to leave TIME_WAIT; a live
        // listener on the port is still refused.
        .reuseaddr(Some(true))
        .max_packet_size(BROKER_MAX_PACKET)
        .max_mqueue_len(SESSION_QUEUE)
        .max_session_inbox_bytes(SESSION_INBOX_BYTES)
        .max_session_queue_bytes(SESSION_QUEUE_BYTES)
        .sessions_budget(sessions.clone())
        .partials_budget(partials.clone())
        .idle_buffer_bytes(CONNECTION_BUFFER_BYTES)
        .max_inflight(NonZeroU16::new(SESSION_INFLIGHT).unwrap_or(NonZeroU16::MIN))
        .max_connections(MAX_CLIENTS)
        .handshake_timeout(Duration::from_secs(10))
        .allow_anonymous(anonymous);
    match tls {
        None => b
            .bind()
            .and_then(|l| l.tcp())
            .map_err(|e| bind_error(addr, e)),
        Some(t) => {
            // rmqtt reads the files itself and says little about which one failed: check first.
            for (what, path) in [("tls_cert", &t.cert), ("tls_key", &t.key)] {
                std::fs::metadata(path).map_err(|e| MctError::Tls {
                    addr,
                    reason: format!("{what} {}: {e}", path.display()),
                })?;
            }
            let l = b
                .tls_cert(Some(t.cert.display().to_string()))
                .tls_key(Some(t.key.display().to_string()))
                .bind()
                .map_err(|e| bind_error(addr, e))?;
            l.tls().map_err(|e| MctError::Tls {
                addr,
                reason: format!("{e:#}"),
            })
        }
    }
}

impl EmbeddedBroker {
    /// Starts an anonymous broker on `addr` for the PLC `plc`: loopback only, anyone may command.
    /// Port 0 picks a free port (see [`EmbeddedBroker::addr`]).
    pub fn start(addr: SocketAddr, plc: &str) -> Result<Self, MctError> {
        Self::start_with(BrokerSettings::open(addr), plc)
    }

    /// Starts a broker for the PLC `plc` with accounts and TLS as `settings` say. Beyond loopback
    /// it refuses to start without TLS and accounts ([`MctError::Exposed`]).
    pub fn start_with(settings: BrokerSettings, plc: &str) -> Result<Self, MctError> {
        settings.check_exposure()?;
        let acl = Arc::new(Acl::new(plc, &settings.accounts)?);
        let anonymous = acl.anonymous();
        let addr = if settings.addr.port() == 0 {
            free_port(settings.addr)?
        } else {
            settings.addr
        };
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("cetratus-mqtt-broker")
            .enable_all()
            .build()?;
        let tls = settings.tls.as_ref();
        // One total for both listeners: the broker's, not a port's.
        let sessions = Arc::new(
            SessionsBudget::new(
                SESSIONS_BYTES,
                vec![PLC_USER.to_owned(), DASHBOARD_USER.to_owned()],
                INTERNAL_SESSIONS_BYTES,
            )
            .with_floor(SESSION_FLOOR_BYTES),
        );
        let partials = Arc::new(partials_budget());
        let public = rt.block_on(listener(addr, anonymous, tls, &sessions, &partials))?;
        // With TLS, the process's own clients come in on loopback, without it.
        let own = match tls {
            Some(_) => {
                let local = free_port(SocketAddr::from(([127, 0, 0, 1], 0)))?;
                Some((
                    local,
                    rt.block_on(listener(local, anonymous, None, &sessions, &partials))?,
                ))
            }
            None => None,
        };
        let local = own.as_ref().map_or(addr, |(a, _)| *a);
        let hooks = acl.clone();
        let server = rt.block_on(async move {
            let scx = ServerContext::new()
                .mqtt_max_sessions(MAX_CLIENTS as isize)
                .build()
                .await;
            *scx.extends.retain_mut().await = Box::new(MemRetain::new());
            let reg = scx.extends.hook_mgr().register();
            reg.add(Type::ClientAuthenticate, Box::new(Auth::new(hooks.clone())))
                .await;
            // rmqtt runs a type's hooks from the highest priority down: the ACL before the
            // ingress budget, so a refused publish is not charged.
            reg.add_priority(
                Type::MessagePublishCheckAcl,
                10,
                Box::new(PublishAcl::new(hooks.clone())),
            )
            .await;
            reg.add(
                Type::ClientSubscribeCheckAcl,
                Box::new(SubscribeLimits::default()),
            )
            .await;
            let ingress = Arc::new(Ingress::new(hooks.clone()));
            reg.add(Type::MessagePublish, Box::new(Shared(ingress.clone())))
                .await;
            reg.add(Type::MessagePublishCheckAcl, Box::new(Shared(ingress)))
                .await;
            reg.add(Type::MessageDropped, Box::new(Drops::default()))
                .await;
            reg.start().await;
            let mut server = MqttServer::new(scx).listener_by_id(public, addr.port());
            if let Some((local, l)) = own {
                server = server.listener_by_id(l, local.port());
            }
            server.build()
        });
        rt.spawn(async move {
            if let Err(e) = server.run().await {
                tracing::error!(%addr, error = %e, "the embedded MQTT broker stopped");
            }
        });
        let (stop, stopped) = std::sync::mpsc::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("cetratus-mqtt-broker-owner".into())
            .spawn(move || {
                // Either a stop message or the handle being dropped ends the broker.
                let _ = stopped.recv();
                rt.shutdown_timeout(Duration::from_millis(200));
            })?;
        Ok(EmbeddedBroker {
            addr,
            local,
            acl,
            stop: Some(stop),
            thread: Some(thread),
        })
    }

    /// Where the clients of this process connect, without TLS: a loopback port of its own when
    /// the broker serves TLS, else [`EmbeddedBroker::addr`].
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }

    /// The login of the PLC's own client, drawn at start.
    pub fn plc_login(&self) -> &Login {
        self.acl.plc_login()
    }

    /// The login of the dashboard in the PLC's process, drawn at start.
    pub fn dashboard_login(&self) -> &Login {
        self.acl.dashboard_login()
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stops the broker and waits for its threads.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for EmbeddedBroker {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn free_port(addr: SocketAddr) -> Result<SocketAddr, MctError> {
    let l = std::net::TcpListener::bind(addr).map_err(|e| MctError::Broker {
        addr,
        reason: e.to_string(),
    })?;
    Ok(l.local_addr()?)
}

fn bind_error(addr: SocketAddr, e: rmqtt::Error) -> MctError {
    match e.downcast_ref::<std::io::Error>() {
        Some(io) if io.kind() == std::io::ErrorKind::AddrInUse => MctError::PortTaken { addr },
        _ => MctError::Broker {
            addr,
            reason: e.to_string(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::{MemRetain, RETAINED_BYTES};

    /// A message of `n` payload bytes on the topic `t`.
    fn message(n: usize) -> rmqtt::types::Publish {
        rmqtt::codec::types::Publish {
            dup: false,
            retain: false,
            qos: rmqtt::types::QoS::AtMostOnce,
            topic: "t".into(),
            packet_id: None,
            payload: vec![0u8; n].into(),
            properties: None,
        }
        .into()
    }

    #[test]
    fn a_session_inbox_refuses_what_passes_its_budget_never_a_control_message_and_frees_what_is_taken(
    ) {
        use futures::StreamExt;
        use rmqtt::types::{ByteBudget, From, Id, Message, Reason, SessionTx};
        let (tx, mut rx) = futures::channel::mpsc::unbounded();
        let image = message(1000);
        let cost = SessionTx::inbox_cost(&image);
        assert_eq!(cost, 1000 + 1 + rmqtt::types::INBOX_MESSAGE_OVERHEAD);
        let tx = SessionTx::new(tx).with_inbox_budget(ByteBudget::new(2 * cost, None, None));
        let from = || From::from_custom(Id::new(0, 0, None, None, "camera".into(), None));
        for k in 0..2 {
            assert!(tx.inbox_charge(&image).is_ok(), "{k}");
            assert!(tx
                .unbounded_send(Message::Forward(from(), image.clone()))
                .is_ok());
        }
        let other = tx.clone();
        assert!(
            matches!(other.inbox_charge(&image), Err(Reason::SessionInboxFull)),
            "the budget is spent, for every sender of the session"
        );
        assert_eq!(
            tx.inbox_bytes(),
            2 * cost,
            "a refused message is not booked"
        );
        assert!(
            tx.unbounded_send(Message::Closed(Reason::Unknown)).is_ok(),
            "a control message is never refused"
        );
        let taken = futures::executor::block_on(rx.next()).expect("the first message");
        tx.inbox_taken(&taken);
        assert_eq!(other.inbox_bytes(), cost, "what is taken is given back");
        assert!(other.inbox_charge(&message(1000)).is_ok());
        assert!(
            SessionTx::new(futures::channel::mpsc::unbounded().0)
                .inbox_charge(&message(64 << 20))
                .is_ok(),
            "without a budget, rmqtt's inbox is unbounded as published"
        );
    }

    #[test]
    fn retained_bytes_are_bounded_and_a_replacement_gives_the_old_bytes_back() {
        let r = MemRetain::new();
        let big = RETAINED_BYTES / 4;
        for k in 0..4 {
            assert!(r.book(&format!("t/{k}"), big), "{k}");
        }
        assert!(!r.book("t/4", 1), "the budget is spent");
        assert!(
            r.book("t/0", big - 10),
            "a replacement fits in its own bytes"
        );
        assert!(r.book("t/4", 10));
        assert!(r.book("t/1", 0), "a deletion always passes");
        assert!(r.book("t/5", big));
    }
}
