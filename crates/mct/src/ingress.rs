//! What the embedded broker takes from clients other than the PLC's own, for all of them
//! together: bytes per second ([`INGRESS_BYTES_PER_S`]) and commands per second
//! ([`COMMANDS_PER_S`]).
//!
//! A byte limit alone lets small commands through at any rate, and every command costs the whole
//! machine: the broker routes it to the PLC's client, which parses it and publishes a reply that
//! the broker routes back. So a command passes in three tiers:
//!
//! 1. within [`COMMANDS_PER_S`] (and [`INGRESS_BYTES_PER_S`]) it passes;
//! 2. past the command rate, up to [`BUSY_ANSWERS_PER_S`] more, it is passed on without its
//!    payload, marked with [`TURNED_AWAY_PROPERTY`]: the PLC answers it `busy` and the sender
//!    learns why (so is a command within the command rate but past the byte rate);
//! 3. past both, it is refused at the ACL check: the PLC's client never reads it, and an MQTT 5
//!    sender at QoS 1 hears `not authorized` with the reason, after [`REFUSAL_PAUSE`], which
//!    holds back a client that keeps sending.
//!
//! A command is charged once to each bucket it draws on, never twice to one: a command token and
//! then its bytes, or a `busy` token alone (a command that travels without its payload costs no
//! bytes). A publish the ACL refuses is not charged at all, so a client that may not command
//! cannot spend the budget of those who may. The PLC's own login is never limited: what it
//! publishes is its own.
//!
//! rmqtt 0.18.1 runs the `MessagePublish` hooks before the `MessagePublishCheckAcl` ones (in
//! `Session::_publish`), and only the first may change a message, only the second refuse it. So a
//! command is judged once, at `MessagePublish`, and one to be refused carries an internal mark
//! ([`REFUSED_PROPERTY`]) to the ACL check, which refuses it there.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use async_trait::async_trait;
use rmqtt::hook::{Handler, HookResult, Parameter, ReturnType};
use rmqtt::types::{Publish, PublishAclResult};

use crate::acl::{Acl, PLC_USER};
use crate::broker::{detached, BROKER_MAX_PACKET};
use crate::strikes::{Strikes, STRIKES, STRIKE_WINDOW};
use cetratus_slots::rate::{worth_logging, Rate, TokenBucket as Bucket};

/// Bytes per second the broker takes from all clients together but the PLC's own: sixteen
/// full-size packages a second, far more than operators and dashboards send, and less than the
/// PLC's MQTT client and its dashboard read even in a debug build.
pub const INGRESS_BYTES_PER_S: f64 = 16.0 * (1 << 20) as f64;

/// Bytes that may arrive at once before [`INGRESS_BYTES_PER_S`] applies.
pub const INGRESS_BURST: f64 = 2.0 * BROKER_MAX_PACKET as f64;

/// Commands (`cetratus/+/cmd/#`) per second the broker passes on from all clients together but
/// the PLC's own. An operator sends a few a minute, a dashboard one per click, a script that
/// waits for each reply at most one per round trip; `cetratus bench command-load` drives a PLC at
/// this rate, and it keeps its scan latency there. A flood sends a hundred times more (about
/// 100,000 `exec_info` a second from one client on loopback).
pub const COMMANDS_PER_S: f64 = 1000.0;

/// Commands that may arrive at once before [`COMMANDS_PER_S`] applies: a script that sends a
/// batch without waiting, or many dashboards opening at once.
pub const COMMAND_BURST: f64 = 2000.0;

/// Commands per second past [`COMMANDS_PER_S`] that are still passed on, without their payload,
/// for the PLC to answer `busy`, so that a sender learns why; past it a command is refused at
/// the broker. Enough for every client that overshoots to hear it, a twentieth of the command
/// rate in what it costs.
pub const BUSY_ANSWERS_PER_S: f64 = 50.0;

/// `busy` answers that may be owed at once before [`BUSY_ANSWERS_PER_S`] applies.
pub const BUSY_BURST: f64 = 100.0;

/// How long the broker waits before it refuses a message over the limits, and so before it
/// reads the sender's next packet (rmqtt reads one client's packets one at a time). Refusing is
/// cheap, but reading and parsing what a client sends as fast as it can is not: 100,000 small
/// commands a second keep a core busy even when every one is refused. Paused, a client that
/// goes on sending past the limits gets at most a hundred refusals a second and its socket
/// fills, so the kernel holds it back; other clients are not held up.
pub const REFUSAL_PAUSE: Duration = Duration::from_millis(10);

/// The user property the embedded broker sets on a command it passed on without its payload
/// (it came faster than [`COMMANDS_PER_S`] or [`INGRESS_BYTES_PER_S`]): the PLC answers it
/// `busy`. Its value says which limit: [`TurnedAway::name`].
pub const TURNED_AWAY_PROPERTY: &str = "cetratus-turned-away";

/// The user property that carries a command to be refused from the `MessagePublish` hook to the
/// ACL check, where it is refused; such a command is never routed. A client that sets it
/// itself only has its own command refused.
const REFUSED_PROPERTY: &str = "cetratus-refused";

/// Which limit a command was turned away by, as the value of [`TURNED_AWAY_PROPERTY`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TurnedAway {
    /// Past [`COMMANDS_PER_S`].
    Commands,
    /// Past [`INGRESS_BYTES_PER_S`].
    Bytes,
}

impl TurnedAway {
    /// The property value.
    pub fn name(self) -> &'static str {
        match self {
            TurnedAway::Commands => "commands",
            TurnedAway::Bytes => "bytes",
        }
    }

    /// Which limit a [`TURNED_AWAY_PROPERTY`] value names; `None` for any other value (the
    /// PLC's client turns commands away too, and a client may set the property itself).
    pub fn from_name(value: &str) -> Option<Self> {
        match value {
            "commands" => Some(TurnedAway::Commands),
            "bytes" => Some(TurnedAway::Bytes),
            _ => None,
        }
    }

    /// Why, for the `busy` answer.
    pub fn why(self) -> String {
        match self {
            TurnedAway::Commands => format!(
                "commands come faster than the embedded broker passes them on ({COMMANDS_PER_S} \
                 a second from all clients together)"
            ),
            TurnedAway::Bytes => format!(
                "others publish faster than the embedded broker takes ({} MiB a second from \
                 all clients together)",
                INGRESS_BYTES_PER_S / f64::from(1 << 20)
            ),
        }
    }
}

/// What becomes of one publish from a client other than the PLC's own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Verdict {
    Pass,
    /// A command passed on without its payload, to be answered `busy`.
    TurnAway(TurnedAway),
    /// Refused at the ACL check.
    Refuse(TurnedAway),
}

fn rate(per_s: f64, burst: f64) -> Rate {
    Rate { per_s, burst }
}

/// The three buckets, taken under one lock.
struct Buckets {
    bytes: Bucket,
    commands: Bucket,
    busy: Bucket,
}

impl Buckets {
    fn new(now: Instant) -> Self {
        Buckets {
            bytes: Bucket::new(rate(INGRESS_BYTES_PER_S, INGRESS_BURST), now),
            commands: Bucket::new(rate(COMMANDS_PER_S, COMMAND_BURST), now),
            busy: Bucket::new(rate(BUSY_ANSWERS_PER_S, BUSY_BURST), now),
        }
    }

    /// Charges a publish of `bytes` (a command when `command`) at `now`.
    fn judge(&mut self, command: bool, bytes: f64, now: Instant) -> Verdict {
        if !command {
            if self.bytes.take(bytes, now) {
                return Verdict::Pass;
            }
            return Verdict::Refuse(TurnedAway::Bytes);
        }
        if self.commands.take(1.0, now) {
            // Within the command rate the PLC answers it in any case, with or without its
            // payload: its token is spent either way.
            if self.bytes.take(bytes, now) {
                return Verdict::Pass;
            }
            return Verdict::TurnAway(TurnedAway::Bytes);
        }
        if self.busy.take(1.0, now) {
            Verdict::TurnAway(TurnedAway::Commands)
        } else {
            Verdict::Refuse(TurnedAway::Commands)
        }
    }
}

/// Counts of what was turned away or refused, each logged on its 1st, 2nd, 4th… occurrence.
#[derive(Default)]
struct Counts {
    turned_away: [AtomicU64; 2],
    refused: [AtomicU64; 2],
}

/// The `MessagePublish` and `MessagePublishCheckAcl` handler that keeps what others publish
/// within [`INGRESS_BYTES_PER_S`] and [`COMMANDS_PER_S`].
pub(crate) struct Ingress {
    acl: Arc<Acl>,
    buckets: Mutex<Buckets>,
    counts: Counts,
    strikes: Strikes,
    struck_out: AtomicU64,
}

impl Ingress {
    pub(crate) fn new(acl: Arc<Acl>) -> Self {
        Ingress {
            acl,
            buckets: Mutex::new(Buckets::new(Instant::now())),
            counts: Counts::default(),
            strikes: Strikes::default(),
            struck_out: AtomicU64::new(0),
        }
    }

    /// Refuses a message of `client` for `why`, after [`REFUSAL_PAUSE`]; disconnects the client
    /// when it has been refused [`STRIKES`] times in [`STRIKE_WINDOW`] (`crate::strikes`).
    async fn refuse(&self, client: &str, why: TurnedAway) -> ReturnType {
        tokio::time::sleep(REFUSAL_PAUSE).await;
        if !self.strikes.refuse(client, Instant::now()) {
            return refused(why);
        }
        let n = self.struck_out.fetch_add(1, Ordering::Relaxed) + 1;
        if worth_logging(n) {
            tracing::warn!(
                client,
                count = n,
                "a client went on sending past the embedded broker's limits and was \
                 disconnected, with what it had not yet sent"
            );
        }
        let reason = format!(
            "{} {STRIKES} messages of this client were refused within {} s: it is disconnected, \
             with what it had queued; send fewer messages, and wait for each reply",
            refusal(why),
            STRIKE_WINDOW.as_secs()
        );
        let r = rmqtt::types::PublishResult::reason_code(
            rmqtt::codec::v5::PublishAckReason::QuotaExceeded,
            Some(reason.into()),
            true,
        );
        (
            false,
            Some(HookResult::PublishAclResult(PublishAclResult(r))),
        )
    }

    /// Charges `publish` from the client `client`, logged in as `user`.
    fn judge(&self, client: &str, user: Option<&str>, publish: &Publish, command: bool) -> Verdict {
        // The user name, not the client id that anyone may claim: the PLC's login is checked.
        if user == Some(PLC_USER) {
            return Verdict::Pass;
        }
        // What the ACL will refuse costs nobody else's budget.
        if self
            .acl
            .may_publish(self.acl.who(user), &publish.topic)
            .is_err()
        {
            return Verdict::Pass;
        }
        let bytes = (publish.payload.len() + publish.topic.len()) as f64;
        let verdict = self
            .buckets
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .judge(command, bytes, Instant::now());
        let (counter, what) = match verdict {
            Verdict::Pass => return verdict,
            Verdict::TurnAway(why) => (
                &self.counts.turned_away[why as usize],
                "passed a command on without its payload, to be answered busy",
            ),
            Verdict::Refuse(why) => (&self.counts.refused[why as usize], "refused a message"),
        };
        let n = counter.fetch_add(1, Ordering::Relaxed) + 1;
        if worth_logging(n) {
            let limit = match verdict {
                Verdict::TurnAway(TurnedAway::Commands) | Verdict::Refuse(TurnedAway::Commands) => {
                    format!("{COMMANDS_PER_S} commands/s")
                }
                _ => format!("{INGRESS_BYTES_PER_S} bytes/s"),
            };
            tracing::warn!(
                topic = %publish.topic,
                client,
                count = n,
                "others publish faster than {limit}; the embedded broker {what}"
            );
        }
        verdict
    }
}

fn is_command(publish: &Publish) -> bool {
    matches!(
        cetratus_proto::parse_topic(&publish.topic),
        Ok((_, cetratus_proto::Leaf::Cmd(_)))
    )
}

fn marked_refused(publish: &Publish) -> bool {
    publish
        .properties
        .as_ref()
        .is_some_and(|p| p.user_properties.iter().any(|(k, _)| k == REFUSED_PROPERTY))
}

/// The reason an MQTT 5 sender at QoS 1 hears with `not authorized`.
fn refusal(why: TurnedAway) -> String {
    match why {
        TurnedAway::Commands => format!(
            "the embedded broker passes on at most {COMMANDS_PER_S} commands a second from all \
             clients together, and answers {BUSY_ANSWERS_PER_S} more busy; this one was \
             refused: send fewer commands, and wait for each reply"
        ),
        TurnedAway::Bytes => format!(
            "the embedded broker takes at most {} MiB a second from all clients together; \
             this message was refused: retry later",
            INGRESS_BYTES_PER_S / f64::from(1 << 20)
        ),
    }
}

fn refused(why: TurnedAway) -> ReturnType {
    let r = PublishAclResult::rejected(false, Some(refusal(why).into()));
    (false, Some(HookResult::PublishAclResult(r)))
}

/// `publish` with the user property `key` = `value`, and without its payload.
fn marked(publish: &Publish, key: &str, value: &str) -> Publish {
    let mut m = detached(publish);
    drop(std::mem::take(&mut m.inner.payload));
    m.inner
        .properties
        .get_or_insert_with(Default::default)
        .user_properties
        .push((key.into(), value.into()));
    m
}

#[async_trait]
impl Handler for Ingress {
    async fn hook(&self, param: &Parameter, acc: Option<HookResult>) -> ReturnType {
        match param {
            // Before the ACL check: a command is judged here, where it can still be changed.
            Parameter::MessagePublish(_, from, publish) if is_command(publish) => {
                let user = from.id.username.as_deref();
                match self.judge(&from.id.client_id, user, publish, true) {
                    Verdict::Pass => (true, Some(HookResult::Publish(detached(publish)))),
                    Verdict::TurnAway(why) => {
                        let m = marked(publish, TURNED_AWAY_PROPERTY, why.name());
                        (false, Some(HookResult::Publish(m)))
                    }
                    Verdict::Refuse(why) => {
                        let m = marked(publish, REFUSED_PROPERTY, why.name());
                        (false, Some(HookResult::Publish(m)))
                    }
                }
            }
            // Every other publication is copied out of its read buffer before it is routed.
            Parameter::MessagePublish(_, _, publish) => {
                (true, Some(HookResult::Publish(detached(publish))))
            }
            Parameter::MessagePublishCheckAcl(session, publish) if is_command(publish) => {
                let user = session.id.username.as_deref();
                if user != Some(PLC_USER) && marked_refused(publish) {
                    return self
                        .refuse(&session.id.client_id, TurnedAway::Commands)
                        .await;
                }
                (true, acc)
            }
            // Anything else is charged at the ACL check, where it can be refused.
            Parameter::MessagePublishCheckAcl(session, publish) => {
                let user = session.id.username.as_deref();
                match self.judge(&session.id.client_id, user, publish, false) {
                    Verdict::Pass => (true, acc),
                    Verdict::TurnAway(why) | Verdict::Refuse(why) => {
                        self.refuse(&session.id.client_id, why).await
                    }
                }
            }
            _ => (true, acc),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count(b: &mut Buckets, n: usize, command: bool, bytes: f64, now: Instant) -> [usize; 3] {
        let mut seen = [0; 3];
        for _ in 0..n {
            match b.judge(command, bytes, now) {
                Verdict::Pass => seen[0] += 1,
                Verdict::TurnAway(_) => seen[1] += 1,
                Verdict::Refuse(_) => seen[2] += 1,
            }
        }
        seen
    }

    #[test]
    fn a_flood_of_small_commands_passes_the_burst_then_busy_then_nothing() {
        let t0 = Instant::now();
        let mut b = Buckets::new(t0);
        let [pass, busy, refused] = count(&mut b, 10_000, true, 40.0, t0);
        assert_eq!(pass, COMMAND_BURST as usize);
        assert_eq!(busy, BUSY_BURST as usize);
        assert_eq!(refused, 10_000 - pass - busy);
        // A second later the rates have come back, and only they.
        let t1 = t0 + Duration::from_secs(1);
        let [pass, busy, _] = count(&mut b, 10_000, true, 40.0, t1);
        assert_eq!(pass, COMMANDS_PER_S as usize);
        assert_eq!(busy, BUSY_ANSWERS_PER_S as usize);
        assert_eq!(
            b.judge(true, 40.0, t1),
            Verdict::Refuse(TurnedAway::Commands)
        );
    }

    #[test]
    fn a_command_past_the_byte_rate_is_turned_away_within_the_command_rate_and_costs_no_busy() {
        let t0 = Instant::now();
        let mut b = Buckets::new(t0);
        let big = BROKER_MAX_PACKET as f64;
        assert_eq!(count(&mut b, 2, true, big, t0), [2, 0, 0], "the byte burst");
        assert_eq!(b.judge(true, big, t0), Verdict::TurnAway(TurnedAway::Bytes));
        // The byte limit spent no `busy` token, and a small command still passes on the bytes
        // that are left.
        assert!(b.busy.take(BUSY_BURST, t0));
        assert_eq!(b.judge(true, 0.0, t0), Verdict::Pass);
    }

    #[test]
    fn a_command_past_the_command_rate_is_not_charged_bytes() {
        let t0 = Instant::now();
        let mut b = Buckets::new(t0);
        assert!(b.commands.take(COMMAND_BURST, t0));
        let big = BROKER_MAX_PACKET as f64;
        for _ in 0..BUSY_BURST as usize {
            assert_eq!(
                b.judge(true, big, t0),
                Verdict::TurnAway(TurnedAway::Commands)
            );
        }
        assert_eq!(
            b.judge(true, big, t0),
            Verdict::Refuse(TurnedAway::Commands)
        );
        assert!(
            b.bytes.take(INGRESS_BURST, t0),
            "the bytes were all left for messages that pass"
        );
    }

    #[test]
    fn other_messages_are_limited_in_bytes_only() {
        let t0 = Instant::now();
        let mut b = Buckets::new(t0);
        assert_eq!(count(&mut b, 100_000, false, 10.0, t0), [100_000, 0, 0]);
        assert_eq!(
            b.judge(false, INGRESS_BURST, t0),
            Verdict::Refuse(TurnedAway::Bytes)
        );
        assert_eq!(
            b.judge(true, 10.0, t0),
            Verdict::Pass,
            "commands own theirs"
        );
    }

    #[test]
    fn turned_away_names_round_trip() {
        for t in [TurnedAway::Commands, TurnedAway::Bytes] {
            assert_eq!(TurnedAway::from_name(t.name()), Some(t));
        }
        assert_eq!(TurnedAway::from_name("rate"), None);
    }
}
