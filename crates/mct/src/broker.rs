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
//! messages are bounded in bytes ([`RETAINED_BYTES`]), the messages queued for a slow subscriber
//! in count ([`SESSION_QUEUE`], [`SESSION_INFLIGHT`]), the clients in number ([`MAX_CLIENTS`]),
//! and what others publish in bytes and in commands per second ([`crate::ingress`]): rmqtt
//! hands a message to each subscriber's session through an unbounded channel, so a subscriber
//! that reads slower than others publish (the PLC parsing 1 MiB commands, the dashboard parsing
//! events) would have the difference kept here, and every command costs the broker, the PLC's
//! client and the machine a round trip. The PLC's own client is not limited: what it publishes
//! is its own.
//!
//! An account's password is checked with argon2 on one blocking thread at a time, at most
//! [`LOGINS_PER_S`] a second: a flood of wrong passwords costs a core at most and never the
//! internal logins, which compare a random secret.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::num::NonZeroU16;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::acl::{Acl, BrokerSettings, Checked, Login, Who};
use crate::budget::TokenBucket as Bucket;
use crate::ingress::Ingress;
use crate::MctError;
use async_trait::async_trait;
use rmqtt::context::ServerContext;
use rmqtt::hook::{Handler, HookResult, Parameter, ReturnType, Type};
use rmqtt::retain::{DefaultRetainStorage, RetainStorage};
use rmqtt::server::MqttServer;
use rmqtt::types::{AuthResult, Retain, TopicFilter, TopicName};

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

/// QoS 1 and 2 messages in flight to one subscriber (rmqtt's default).
pub const SESSION_INFLIGHT: u16 = 16;

/// Clients connected at once: a PLC, its dashboard, operators and a few tools.
pub const MAX_CLIENTS: usize = 256;

/// Account logins whose password the broker checks per second, for all clients together; past
/// it (and [`LOGIN_BURST`]) a login is refused without being checked.
pub const LOGINS_PER_S: f64 = 8.0;

/// Account logins that may arrive at once before [`LOGINS_PER_S`] applies.
pub const LOGIN_BURST: f64 = 16.0;

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

/// Checks logins: the internal ones against their secrets at once, an account's password with
/// argon2 on a blocking thread, one at a time and at most [`LOGINS_PER_S`] a second.
struct Auth {
    acl: Arc<Acl>,
    one_at_a_time: tokio::sync::Semaphore,
    rate: Mutex<Bucket>,
}

#[async_trait]
impl Handler for Auth {
    async fn hook(&self, param: &Parameter, acc: Option<HookResult>) -> ReturnType {
        let Parameter::ClientAuthenticate(info) = param else {
            return (true, acc);
        };
        let user = info.username().map(|u| u.to_string()).unwrap_or_default();
        let pass = info.password().map(|p| p.to_vec()).unwrap_or_default();
        let from = info.id().remote_addr;
        let allow = AuthResult::Allow(false, None);
        let hash = match self.acl.check(&user, &pass) {
            Checked::Internal | Checked::Anonymous => {
                return (false, Some(HookResult::AuthResult(allow)))
            }
            Checked::Refused => {
                tracing::warn!(?from, user = %user.escape_debug(), "MQTT login refused: wrong secret for an internal login");
                let r = AuthResult::BadUsernameOrPassword;
                return (false, Some(HookResult::AuthResult(r)));
            }
            Checked::Account(h) => Some(h.clone()),
            Checked::Unknown => None,
        };
        let taken = self
            .rate
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take(1.0, Instant::now());
        if !taken {
            tracing::warn!(?from, user = %user.escape_debug(), "MQTT login refused: more than {LOGINS_PER_S} logins a second");
            return (
                false,
                Some(HookResult::AuthResult(AuthResult::NotAuthorized)),
            );
        }
        let known = hash.is_some();
        let hash = hash.unwrap_or_else(|| self.acl.decoy().clone());
        let right = match self.one_at_a_time.acquire().await {
            Ok(_permit) => tokio::task::spawn_blocking(move || hash.verify(&pass))
                .await
                .unwrap_or(false),
            Err(_) => false,
        };
        let r = if right && known {
            tracing::info!(?from, user = %user, "MQTT login");
            allow
        } else {
            tracing::warn!(?from, user = %user.escape_debug(), "MQTT login failed: wrong user name or password");
            AuthResult::BadUsernameOrPassword
        };
        (false, Some(HookResult::AuthResult(r)))
    }
}

/// Refuses what a client may not publish ([`Acl::may_publish`]), before anything is charged.
struct PublishAcl(Arc<Acl>);

#[async_trait]
impl Handler for PublishAcl {
    async fn hook(&self, param: &Parameter, acc: Option<HookResult>) -> ReturnType {
        let Parameter::MessagePublishCheckAcl(session, publish) = param else {
            return (true, acc);
        };
        let who = self.0.who(session.id.username.as_deref());
        match self.0.may_publish(who, &publish.topic) {
            Ok(()) => (true, acc),
            Err(why) => {
                if who != Who::Anonymous || !self.0.anonymous() {
                    tracing::warn!(topic = %publish.topic, user = %session.id.username_ref(), "the embedded broker refused a publish: {why}");
                }
                let refused = rmqtt::types::PublishAclResult::rejected(false, Some(why.into()));
                (false, Some(HookResult::PublishAclResult(refused)))
            }
        }
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

/// One rmqtt listener on `addr`, with TLS when `tls` names its files.
async fn listener(
    addr: SocketAddr,
    anonymous: bool,
    tls: Option<&crate::acl::BrokerTls>,
) -> Result<rmqtt::net::Listener, MctError> {
    let b = rmqtt::net::Builder::new()
        .name("cetratus")
        .laddr(addr)
        // A restart must not wait for the last run's connections to leave TIME_WAIT; a live
        // listener on the port is still refused.
        .reuseaddr(Some(true))
        .max_packet_size(BROKER_MAX_PACKET)
        .max_mqueue_len(SESSION_QUEUE)
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
        let public = rt.block_on(listener(addr, anonymous, tls))?;
        // With TLS, the process's own clients come in on loopback, without it.
        let own = match tls {
            Some(_) => {
                let local = free_port(SocketAddr::from(([127, 0, 0, 1], 0)))?;
                Some((local, rt.block_on(listener(local, anonymous, None))?))
            }
            None => None,
        };
        let local = own.as_ref().map_or(addr, |(a, _)| *a);
        let hooks = acl.clone();
        let server = rt.block_on(async move {
            let scx = ServerContext::new().build().await;
            *scx.extends.retain_mut().await = Box::new(MemRetain::new());
            let reg = scx.extends.hook_mgr().register();
            reg.add(
                Type::ClientAuthenticate,
                Box::new(Auth {
                    acl: hooks.clone(),
                    one_at_a_time: tokio::sync::Semaphore::new(1),
                    rate: Mutex::new(Bucket::new(LOGINS_PER_S, LOGIN_BURST, Instant::now())),
                }),
            )
            .await;
            // rmqtt runs a type's hooks from the highest priority down: the ACL before the
            // ingress budget, so a refused publish is not charged.
            reg.add_priority(
                Type::MessagePublishCheckAcl,
                10,
                Box::new(PublishAcl(hooks.clone())),
            )
            .await;
            let ingress = Arc::new(Ingress::new(hooks.clone()));
            reg.add(Type::MessagePublish, Box::new(Shared(ingress.clone())))
                .await;
            reg.add(Type::MessagePublishCheckAcl, Box::new(Shared(ingress)))
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
    use crate::budget::TokenBucket as Bucket;
    use std::time::{Duration, Instant};

    #[test]
    fn the_bucket_passes_a_burst_then_its_rate() {
        let t0 = Instant::now();
        let mut b = Bucket::new(100.0, 300.0, t0);
        assert!(b.take(300.0, t0), "the burst");
        assert!(!b.take(1.0, t0), "nothing left");
        assert!(
            !b.take(60.0, t0 + Duration::from_millis(500)),
            "50 came back, not 60"
        );
        assert!(b.take(100.0, t0 + Duration::from_secs(1)));
        // Saved up to the burst, not beyond.
        assert!(!b.take(301.0, t0 + Duration::from_secs(100)));
        assert!(b.take(300.0, t0 + Duration::from_secs(100)));
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
