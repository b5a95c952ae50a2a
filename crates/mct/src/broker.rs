//! The embedded broker: rmqtt in its own thread and Tokio runtime, one TCP port for MQTT 3.1.1
//! and MQTT 5 clients (rmqtt reads the protocol level of each CONNECT and picks the codec),
//! retained messages kept in memory, last wills, and user/password from configuration.

use std::net::SocketAddr;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use async_trait::async_trait;
use rmqtt::context::ServerContext;
use rmqtt::hook::{Handler, HookResult, Parameter, ReturnType, Type};
use rmqtt::retain::{DefaultRetainStorage, RetainStorage};
use rmqtt::server::MqttServer;
use rmqtt::types::{AuthResult, Retain, TopicFilter, TopicName};
use subtle::ConstantTimeEq as _;

use crate::MctError;

/// Largest MQTT packet the embedded broker accepts: above the 1 MiB command limit, so an
/// oversized command reaches the control plane and gets a `too_large` reply instead of a dropped
/// connection.
pub const BROKER_MAX_PACKET: u32 = 4 << 20;

/// rmqtt's default retain storage only logs (retention lives in a plugin configured from files);
/// the same tree, enabled, is all a single PLC needs.
struct MemRetain(DefaultRetainStorage);

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
        self.0.set_with_timeout(topic, retain, expiry).await
    }
    async fn get(&self, filter: &TopicFilter) -> rmqtt::Result<Vec<(TopicName, Retain)>> {
        self.0.get_message(filter).await
    }
    async fn count(&self) -> isize {
        self.0.count().await
    }
    async fn max(&self) -> isize {
        self.0.max().await
    }
}

/// Checks user/password against the configured list.
struct Users(Arc<Vec<(String, String)>>);

// Constant time in the contents, so the time taken does not reveal how much of a password
// matched; only the length can show.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.ct_eq(b).into()
}

#[async_trait]
impl Handler for Users {
    async fn hook(&self, param: &Parameter, acc: Option<HookResult>) -> ReturnType {
        let Parameter::ClientAuthenticate(info) = param else {
            return (true, acc);
        };
        let user = info
            .username()
            .map(|u| u.as_bytes().to_vec())
            .unwrap_or_default();
        let pass = info.password().map(|p| p.to_vec()).unwrap_or_default();
        let ok = self
            .0
            .iter()
            .any(|(u, p)| same(u.as_bytes(), &user) & same(p.as_bytes(), &pass));
        let r = if ok {
            AuthResult::Allow(false, None)
        } else {
            AuthResult::BadUsernameOrPassword
        };
        (false, Some(HookResult::AuthResult(r)))
    }
}

/// A running embedded broker; stops when dropped.
pub struct EmbeddedBroker {
    addr: SocketAddr,
    stop: Option<std::sync::mpsc::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for EmbeddedBroker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EmbeddedBroker")
            .field("addr", &self.addr)
            .finish()
    }
}

impl EmbeddedBroker {
    /// Starts a broker on `addr`; with a non-empty `users`, clients must log in as one of them.
    /// Port 0 picks a free port (see [`EmbeddedBroker::addr`]).
    pub fn start(addr: SocketAddr, users: Vec<(String, String)>) -> Result<Self, MctError> {
        let addr = if addr.port() == 0 {
            free_port(addr)?
        } else {
            addr
        };
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("cetratus-mqtt-broker")
            .enable_all()
            .build()?;
        let anonymous = users.is_empty();
        let listener = rt
            .block_on(async {
                rmqtt::net::Builder::new()
                    .name("cetratus")
                    .laddr(addr)
                    // A restart must not wait for the last run's connections to leave TIME_WAIT;
                    // a live listener on the port is still refused.
                    .reuseaddr(Some(true))
                    .max_packet_size(BROKER_MAX_PACKET)
                    .allow_anonymous(anonymous)
                    .bind()
                    .and_then(|l| l.tcp())
            })
            .map_err(|e| bind_error(addr, e))?;
        let users = Arc::new(users);
        let server = rt.block_on(async move {
            let scx = ServerContext::new().build().await;
            *scx.extends.retain_mut().await = Box::new(MemRetain(DefaultRetainStorage::new()));
            if !users.is_empty() {
                let reg = scx.extends.hook_mgr().register();
                reg.add(Type::ClientAuthenticate, Box::new(Users(users)))
                    .await;
                reg.start().await;
            }
            MqttServer::new(scx)
                .listener_by_id(listener, addr.port())
                .build()
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
            stop: Some(stop),
            thread: Some(thread),
        })
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
    use super::same;

    #[test]
    fn same_is_true_only_for_equal_bytes_whatever_the_lengths() {
        assert!(same(b"", b""));
        assert!(same(b"secret", b"secret"));
        assert!(!same(b"secret", b"secreT"));
        assert!(!same(b"secret", b"xecret"));
        assert!(!same(b"secret", b"secret!"));
        assert!(!same(b"secret!", b"secret"));
        assert!(!same(b"secret", b""));
        assert!(!same(b"", b"secret"));
    }
}
