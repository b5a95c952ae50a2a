//! The embedded broker's checks on every client, as rmqtt hooks: who may log in and with which
//! client id and last will ([`Auth`]), what may be published ([`PublishAcl`]) and subscribed
//! ([`SubscribeLimits`]). Each refusal is counted, and logged on its 1st, 2nd, 4th… occurrence
//! ([`Tally`]), so that a flood of refused packets is reported with its size and costs no line a
//! packet.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use async_trait::async_trait;
use rmqtt::hook::{Handler, HookResult, Parameter, ReturnType};
use rmqtt::types::AuthResult;

use crate::acl::{Acl, Checked, Who};
use crate::broker::LOGINS;
use crate::logins::LoginGate;
use crate::password::HashedPassword;
use crate::topics::{check_topic, TopicRefusal};

/// Counts one kind of refusal; a log line goes out for the 1st, 2nd, 4th… of them, with the
/// count, so that a flood is reported with its size and costs no line a packet.
#[derive(Default)]
struct Tally(AtomicU64);

impl Tally {
    /// Counts one more: its number, when that one is worth a log line.
    fn count(&self) -> Option<u64> {
        let n = self.0.fetch_add(1, Ordering::Relaxed) + 1;
        crate::budget::worth_logging(n).then_some(n)
    }

    /// Counts a packet refused for the shape of its topic, and logs it with its client when
    /// worth a line; `what` says what the broker refused, and what it did about it.
    fn refused(&self, client: &rmqtt::types::Id, what: &str, why: &TopicRefusal) {
        if let Some(n) = self.count() {
            tracing::warn!(
                user = %client.username_ref(),
                from = ?client.remote_addr,
                refused = n,
                "the embedded broker refused {what}: {why}"
            );
        }
    }
}

/// Checks logins: the internal ones against their secrets at once, an account's password with
/// argon2 on a blocking thread, one at a time and at most [`LOGINS`] a second, with a share
/// kept for those who logged in before ([`crate::logins`]). Then what
/// the client asked for at CONNECT: a client id reserved for the process's own clients
/// ([`crate::acl::is_internal_client_id`]) is refused to everyone else, before any password is
/// checked, and so is a last will that the login could not publish itself (its topic's shape,
/// [`check_topic`], and the ACL, [`Acl::may_publish`]), as Mosquitto refuses it.
pub(crate) struct Auth {
    acl: Arc<Acl>,
    one_at_a_time: tokio::sync::Semaphore,
    rate: Mutex<LoginGate>,
    reserved_ids: Tally,
    wills: Tally,
}

/// The topic of the last will a client gave at CONNECT.
fn will_topic(info: &rmqtt::types::ConnectInfo) -> Option<&str> {
    match info.last_will()? {
        rmqtt::types::LastWill::V3(w) => Some(&w.topic),
        rmqtt::types::LastWill::V5(w) => Some(&w.topic),
    }
}

impl Auth {
    /// Checks logins against `acl`, at most [`LOGINS`] account passwords a second.
    pub(crate) fn new(acl: Arc<Acl>) -> Self {
        Auth {
            acl,
            one_at_a_time: tokio::sync::Semaphore::new(1),
            rate: Mutex::new(LoginGate::new(LOGINS, Instant::now())),
            reserved_ids: Tally::default(),
            wills: Tally::default(),
        }
    }

    async fn authenticate(&self, info: &rmqtt::types::ConnectInfo) -> AuthResult {
        let user = info.username().map(|u| u.to_string()).unwrap_or_default();
        let pass = info.password().map(|p| p.to_vec()).unwrap_or_default();
        let (from, client_id) = (info.id().remote_addr, &info.id().client_id);
        let checked = self.acl.check(&user, &pass);
        match checked {
            Checked::Refused => {
                tracing::warn!(?from, user = %user.escape_debug(), "MQTT login refused: wrong secret for an internal login");
                return AuthResult::BadUsernameOrPassword;
            }
            Checked::Internal => {}
            _ if crate::acl::is_internal_client_id(client_id) => {
                if let Some(n) = self.reserved_ids.count() {
                    tracing::warn!(
                        ?from,
                        user = %user.escape_debug(),
                        client_id = %client_id.escape_debug(),
                        refused = n,
                        "MQTT login refused: the client id is reserved for the PLC's own \
                         clients; someone tried to take over the PLC's or the dashboard's session"
                    );
                }
                return AuthResult::NotAuthorized;
            }
            Checked::Anonymous => {}
            Checked::Account(h) => {
                let h = h.clone();
                if let Err(refused) = self.check_password(Some(h), pass, &user, from).await {
                    return refused;
                }
            }
            Checked::Unknown => {
                // Refused either way; the decoy keeps the time the same as a wrong password.
                return match self.check_password(None, pass, &user, from).await {
                    Err(refused) => refused,
                    Ok(()) => AuthResult::BadUsernameOrPassword,
                };
            }
        }
        if let Some(topic) = will_topic(info) {
            let who = self.acl.who(Some(&user));
            let refusal = check_topic(topic)
                .map_err(|e| e.to_string())
                .and_then(|()| self.acl.may_publish(who, topic).map_err(str::to_string));
            if let Err(why) = refusal {
                if let Some(n) = self.wills.count() {
                    tracing::warn!(?from, user = %user.escape_debug(), will = %topic.escape_debug(), refused = n, "MQTT login refused: its last will could not be published by it: {why}");
                }
                return AuthResult::NotAuthorized;
            }
        }
        if matches!(checked, Checked::Account(_)) {
            tracing::info!(?from, user = %user, "MQTT login");
        }
        AuthResult::Allow(false, None)
    }

    /// Checks `pass` against the account's hash (the decoy's for an unknown name), within the
    /// login rate; `Err` is the refusal to answer.
    async fn check_password(
        &self,
        hash: Option<HashedPassword>,
        pass: Vec<u8>,
        user: &str,
        from: Option<SocketAddr>,
    ) -> Result<(), AuthResult> {
        let ip = from.map(|a| a.ip());
        let taken =
            self.rate
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .admit(ip, user, Instant::now());
        if !taken {
            tracing::warn!(?from, user = %user.escape_debug(), "MQTT login refused: more than {} logins a second", LOGINS.per_s);
            return Err(AuthResult::NotAuthorized);
        }
        let known = hash.is_some();
        let hash = hash.unwrap_or_else(|| self.acl.decoy().clone());
        let right = match self.one_at_a_time.acquire().await {
            Ok(_permit) => tokio::task::spawn_blocking(move || hash.verify(&pass))
                .await
                .unwrap_or(false),
            Err(_) => false,
        };
        if right && known {
            let mut gate = self.rate.lock().unwrap_or_else(|e| e.into_inner());
            gate.succeeded(ip, user);
            Ok(())
        } else {
            tracing::warn!(?from, user = %user.escape_debug(), "MQTT login failed: wrong user name or password");
            Err(AuthResult::BadUsernameOrPassword)
        }
    }
}

#[async_trait]
impl Handler for Auth {
    async fn hook(&self, param: &Parameter, acc: Option<HookResult>) -> ReturnType {
        let Parameter::ClientAuthenticate(info) = param else {
            return (true, acc);
        };
        let r = self.authenticate(info).await;
        (false, Some(HookResult::AuthResult(r)))
    }
}

/// Refuses what a client may not publish ([`Acl::may_publish`]), before anything is charged.
pub(crate) struct PublishAcl {
    acl: Arc<Acl>,
    shapes: Tally,
    refused: Tally,
}

impl PublishAcl {
    /// Checks publishes against `acl`.
    pub(crate) fn new(acl: Arc<Acl>) -> Self {
        PublishAcl {
            acl,
            shapes: Tally::default(),
            refused: Tally::default(),
        }
    }
}

#[async_trait]
impl Handler for PublishAcl {
    async fn hook(&self, param: &Parameter, acc: Option<HookResult>) -> ReturnType {
        let Parameter::MessagePublishCheckAcl(session, publish) = param else {
            return (true, acc);
        };
        // The topic's shape first: a deep topic must reach no tree.
        if let Err(why) = check_topic(&publish.topic) {
            self.shapes
                .refused(&session.id, "a publish and closed the connection", &why);
            let refused = rmqtt::types::PublishResult::reason_code(
                rmqtt::codec::v5::PublishAckReason::TopicNameInvalid,
                Some(why.to_string().into()),
                true,
            );
            let refused = rmqtt::types::PublishAclResult(refused);
            return (false, Some(HookResult::PublishAclResult(refused)));
        }
        let who = self.acl.who(session.id.username.as_deref());
        match self.acl.may_publish(who, &publish.topic) {
            Ok(()) => (true, acc),
            Err(why) => {
                let quiet = who == Who::Anonymous && self.acl.anonymous();
                if let Some(n) = self.refused.count().filter(|_| !quiet) {
                    tracing::warn!(topic = %publish.topic, user = %session.id.username_ref(), refused = n, "the embedded broker refused a publish: {why}");
                }
                let refused = rmqtt::types::PublishAclResult::rejected(false, Some(why.into()));
                (false, Some(HookResult::PublishAclResult(refused)))
            }
        }
    }
}

/// Refuses a subscription whose filter is over the topic limits ([`check_topic`]) with the
/// reason code *topic filter invalid* (0x8F; MQTT 3.1.1 clients see 0x80), before it reaches the
/// subscription tree or the retained messages.
#[derive(Default)]
pub(crate) struct SubscribeLimits(Tally);

#[async_trait]
impl Handler for SubscribeLimits {
    async fn hook(&self, param: &Parameter, acc: Option<HookResult>) -> ReturnType {
        let Parameter::ClientSubscribeCheckAcl(session, sub) = param else {
            return (true, acc);
        };
        match check_topic(&sub.topic_filter) {
            Ok(()) => (true, acc),
            Err(why) => {
                self.0.refused(&session.id, "a subscription", &why);
                let refused = rmqtt::types::SubscribeAclResult::new_failure(
                    rmqtt::codec::v5::SubscribeAckReason::TopicFilterInvalid,
                );
                (false, Some(HookResult::SubscribeAclResult(refused)))
            }
        }
    }
}
