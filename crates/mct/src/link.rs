//! The MQTT side: a rumqttc MQTT 5 client in its own threads, connected to the embedded broker or
//! to a plant broker, exchanging with the scan thread only through bounded queues.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use cetratus_proto::{
    BrokerUrl, EventMsg, ExecInfoMsg, IoMsg, NetMsg, ProtoError, StateMsg, StatePayload, Topics,
};
use rumqttc::v5::mqttbytes::v5::{LastWill, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{AsyncClient, MqttOptions};
use rumqttc::Transport;

use crate::acl::{BrokerAccount, BrokerSettings, BrokerTls, Login};
use crate::broker::{EmbeddedBroker, BROKER_MAX_PACKET};
use crate::budget::{worth_logging, Budget};
use crate::control::{ControlPlane, IncomingCommand, Outcome, ReplyHandle};
use crate::envelope::OperatorKeys;
use crate::inbound::{control_loop, event_loop, CommandQueue};
use crate::MctError;

/// How many bytes of commands may wait for the PLC at once (their packages, reply addresses and
/// correlation data): four commands of the 1 MiB maximum. Past it a command is answered `busy`,
/// so the PLC's memory does not grow with what others send.
pub const COMMAND_QUEUE_BYTES: usize = 4 << 20;

/// The default address of the embedded broker: loopback only, so nothing outside the machine can
/// command the PLC unless the operator says so.
pub const DEFAULT_MQTT_ADDR: &str = "127.0.0.1:1883";

/// Which broker the PLC talks through.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BrokerChoice {
    /// Start the embedded broker (`--mqtt ADDR`), with the accounts and TLS of the local
    /// configuration; the PLC's own client logs in with a secret drawn at start.
    Embedded(BrokerSettings),
    /// Connect to a plant broker (`--broker mqtt://host:port` or `mqtts://host:port`).
    External {
        /// `mqtt://host[:port]` or `mqtts://host[:port]`; `user:password@` in the URL is accepted.
        url: String,
        /// User name (overrides the URL's).
        user: Option<String>,
        /// Password (overrides the URL's).
        password: Option<String>,
    },
}

impl BrokerChoice {
    /// The choice made by the CLI flags `--mqtt ADDR` and `--broker URL` (neither: the embedded
    /// broker on [`DEFAULT_MQTT_ADDR`]); accounts, TLS and credentials come from the
    /// configuration file.
    pub fn from_cli(
        mqtt: Option<&str>,
        broker: Option<&str>,
        accounts: Vec<BrokerAccount>,
        tls: Option<BrokerTls>,
        credentials: Option<(String, String)>,
    ) -> Result<Self, MctError> {
        match (mqtt, broker) {
            (Some(_), Some(_)) => Err(MctError::BothBrokers),
            (_, Some(url)) => {
                // Fail at startup, not at the first reconnect, on a URL the client cannot use.
                client_options(url, "check")?;
                let (user, password) =
                    credentials.map_or((None, None), |(u, p)| (Some(u), Some(p)));
                Ok(BrokerChoice::External {
                    url: url.to_string(),
                    user,
                    password,
                })
            }
            (m, None) => {
                let a = m.unwrap_or(DEFAULT_MQTT_ADDR);
                let addr = a.parse().map_err(|_| MctError::MqttAddr(a.to_string()))?;
                Ok(BrokerChoice::Embedded(BrokerSettings {
                    addr,
                    accounts,
                    tls,
                }))
            }
        }
    }
}

/// Configuration of the MQTT control plane.
#[derive(Clone, Debug)]
pub struct MqttConfig {
    /// The `<plc-id>` topic level.
    pub plc_id: String,
    /// Embedded or external broker.
    pub broker: BrokerChoice,
    /// How often `exec_info` and `io` are published (the latest value wins in between).
    pub publish_period: Duration,
    /// Operator keys; when set, every command must be a signed envelope.
    pub operator_keys: Option<OperatorKeys>,
    /// Capacity of each of the two queues to and from the scan thread, in entries.
    pub queue_capacity: usize,
    /// Bytes of commands that may wait at once ([`COMMAND_QUEUE_BYTES`]); see [`CommandQueue`].
    pub command_bytes: usize,
}

impl MqttConfig {
    /// The embedded broker on [`DEFAULT_MQTT_ADDR`], publishing every 500 ms, no operator keys.
    pub fn new(plc_id: &str) -> Self {
        MqttConfig {
            plc_id: plc_id.to_string(),
            broker: BrokerChoice::Embedded(BrokerSettings::open(SocketAddr::from((
                [127, 0, 0, 1],
                1883,
            )))),
            publish_period: Duration::from_millis(500),
            operator_keys: None,
            queue_capacity: 256,
            command_bytes: COMMAND_QUEUE_BYTES,
        }
    }
}

/// A message from the scan thread to MQTT.
#[derive(Clone, Debug)]
pub enum Outgoing {
    /// The retained `state`; published at once when PRIMARY, STATUS or the programs change, else
    /// at the publish period.
    State(Box<StateMsg>),
    /// `program_exec_info` of both containers; the latest is published every period.
    ExecInfo(Box<ExecInfoMsg>),
    /// Inputs, outputs of A and B, dispatched outputs; the latest is published every period.
    Io(IoMsg),
    /// An event (update lifecycle, refusals); published at once, in order.
    Event(EventMsg),
    /// The nets of A and B as SVG drawings; retained, published at once when a program changes.
    Net(NetMsg),
    /// The answer to a command.
    Reply(ReplyHandle, Outcome),
    /// The answer to `exec_info`: the figures are shared with other answers and turned into
    /// JSON on the MQTT thread, so a flood of requests costs neither copies nor the scan thread.
    ExecInfoReply(ReplyHandle, Arc<ExecInfoMsg>),
}

impl Outgoing {
    /// About how many bytes the message holds beyond its own size, for queues bounded in bytes.
    /// Periodic figures are counted by their scalar parts only: they are replaced, not queued.
    pub fn approx_bytes(&self) -> usize {
        const BASE: usize = 128;
        BASE + match self {
            Outgoing::Event(e) => e.kind.as_str().len() + e.message.len() + approx_json(&e.detail),
            Outgoing::Reply(h, r) => {
                handle_bytes(h)
                    + match r {
                        Ok(v) => v.as_ref().map_or(0, approx_json),
                        Err(e) => e.message.len(),
                    }
            }
            Outgoing::ExecInfoReply(h, _) => handle_bytes(h),
            Outgoing::Net(n) => {
                n.a.as_ref().map_or(0, String::len) + n.b.as_ref().map_or(0, String::len)
            }
            Outgoing::State(_) | Outgoing::ExecInfo(_) | Outgoing::Io(_) => 0,
        }
    }
}

pub(crate) fn handle_bytes(h: &ReplyHandle) -> usize {
    h.verb.len()
        + h.topic.as_ref().map_or(0, String::len)
        + h.correlation_data.as_ref().map_or(0, Vec::len)
        + h.correlation.as_ref().map_or(0, approx_json)
}

/// About the size of a JSON value in memory; walks it, so use it on small values only.
fn approx_json(v: &serde_json::Value) -> usize {
    use serde_json::Value;
    match v {
        Value::Null | Value::Bool(_) | Value::Number(_) => 16,
        Value::String(s) => 24 + s.len(),
        Value::Array(a) => 24 + a.iter().map(approx_json).sum::<usize>(),
        Value::Object(o) => {
            24 + o
                .iter()
                .map(|(k, v)| 24 + k.len() + approx_json(v))
                .sum::<usize>()
        }
    }
}

/// What the MQTT side turned away or lost, since it started.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Commands answered `busy` because a queue was full (in entries or in bytes).
    pub commands_busy: u64,
    /// Commands dropped unanswered: they came too fast to be read, and named no reply topic
    /// outside their payload (or too many waited for their `busy` answer already).
    pub commands_dropped: u64,
    /// Replies and events that could not be handed to the MQTT client (its queue was full).
    pub messages_lost: u64,
}

/// The scan thread's end: commands in, everything else out. Use only the non-blocking calls.
#[derive(Debug)]
pub struct MctLink {
    /// Commands, parsed and authorised; read with `try_recv` once per cycle.
    pub commands: CommandQueue,
    /// Everything the PLC publishes; write with `try_send` (see [`MctLink::send`]).
    pub outgoing: SyncSender<Outgoing>,
    /// What the MQTT side has turned away or lost so far, for the PLC's `state`.
    pub stats: StatsReader,
}

/// Reads the MQTT side's [`LinkStats`] from another thread: three relaxed atomic loads.
#[derive(Clone, Debug)]
pub struct StatsReader(Arc<Shared>);

impl StatsReader {
    /// What was turned away or lost so far.
    pub fn read(&self) -> LinkStats {
        LinkStats {
            commands_busy: self.0.commands_busy.load(Ordering::Relaxed),
            commands_dropped: self.0.commands_dropped.load(Ordering::Relaxed),
            messages_lost: self.0.messages_lost.load(Ordering::Relaxed),
        }
    }
}

impl MctLink {
    /// The next command, if any; never blocks.
    pub fn try_command(&self) -> Option<IncomingCommand> {
        self.commands.try_recv()
    }
    /// Queues a message without blocking; gives it back when the queue is full (or MQTT is gone),
    /// so the caller can keep an event or a reply for the next cycle and drop periodic data.
    // Giving the message back is the point (the caller keeps it for the next cycle), so the large
    // `Err` is deliberate.
    #[allow(clippy::result_large_err)]
    pub fn send(&self, msg: Outgoing) -> Result<(), Outgoing> {
        self.outgoing.try_send(msg).map_err(|e| match e {
            TrySendError::Full(m) | TrySendError::Disconnected(m) => m,
        })
    }
}

/// What the MQTT threads share.
#[derive(Debug)]
pub(crate) struct Shared {
    pub(crate) connected: AtomicBool,
    pub(crate) stopping: AtomicBool,
    pub(crate) commands_busy: AtomicU64,
    pub(crate) commands_dropped: AtomicU64,
    pub(crate) messages_lost: AtomicU64,
}

impl Shared {
    /// Counts a message the client's queue had no room for, and says so now and then.
    pub(crate) fn lost(&self, what: &str, topic: &str, error: &dyn std::fmt::Display) {
        let n = self.messages_lost.fetch_add(1, Ordering::Relaxed) + 1;
        if worth_logging(n) {
            tracing::warn!(
                topic,
                error = %error,
                lost = n,
                "cannot publish {what}: the MQTT client's queue is full"
            );
        }
    }
}

/// The MQTT threads (and the embedded broker); stops them when dropped.
pub struct MqttHandle {
    shared: Arc<Shared>,
    client: AsyncClient,
    state_topic: String,
    rt: Option<tokio::runtime::Runtime>,
    loop_task: Option<tokio::task::JoinHandle<()>>,
    out_thread: Option<JoinHandle<()>>,
    control_thread: Option<JoinHandle<()>>,
    broker: Option<EmbeddedBroker>,
    url: String,
}

impl std::fmt::Debug for MqttHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MqttHandle")
            .field("url", &self.url)
            .finish()
    }
}

impl MqttHandle {
    /// Whether the client is connected and subscribed to the commands.
    pub fn is_connected(&self) -> bool {
        self.shared.connected.load(Ordering::Acquire)
    }
    /// Waits (off the scan thread!) until connected and subscribed; false on timeout.
    pub fn wait_connected(&self, timeout: Duration) -> bool {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            if self.is_connected() {
                return true;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        self.is_connected()
    }
    /// The embedded broker's address, when it runs.
    pub fn broker_addr(&self) -> Option<SocketAddr> {
        self.broker.as_ref().map(EmbeddedBroker::addr)
    }
    /// Where clients of this process reach the embedded broker without TLS (a loopback port of
    /// its own when it serves TLS), when it runs.
    pub fn broker_local_addr(&self) -> Option<SocketAddr> {
        self.broker.as_ref().map(EmbeddedBroker::local_addr)
    }
    /// The login of the dashboard in this process at the embedded broker, when it runs.
    pub fn dashboard_login(&self) -> Option<Login> {
        self.broker.as_ref().map(|b| b.dashboard_login().clone())
    }
    /// The broker URL the client uses.
    pub fn url(&self) -> &str {
        &self.url
    }
    /// What was turned away or lost so far.
    pub fn stats(&self) -> LinkStats {
        StatsReader(self.shared.clone()).read()
    }
    /// Publishes `{"online": false}` on `state`, disconnects and stops the threads and the broker.
    pub fn shutdown(mut self) {
        self.stop();
    }

    fn stop(&mut self) {
        if self.shared.stopping.swap(true, Ordering::AcqRel) {
            return;
        }
        if let Some(rt) = self.rt.take() {
            let client = self.client.clone();
            let topic = self.state_topic.clone();
            let task = self.loop_task.take();
            rt.block_on(async move {
                // A clean disconnect suppresses the last will, so say "offline" ourselves. The
                // client's queue may be full of what a flood left: try for a while, then go.
                let goodbye = async {
                    let _ = client
                        .publish(
                            topic,
                            QoS::AtLeastOnce,
                            true,
                            StatePayload::OFFLINE_JSON.to_vec(),
                        )
                        .await;
                    let _ = client.disconnect().await;
                    if let Some(t) = task {
                        let _ = tokio::time::timeout(Duration::from_millis(250), t).await;
                    }
                };
                if tokio::time::timeout(STOP_WITHIN, goodbye).await.is_err() {
                    tracing::warn!(
                        "the offline state could not be published within {STOP_WITHIN:?}; the \
                         broker publishes the last will when the connection ends"
                    );
                }
            });
            if let Some(t) = self.out_thread.take() {
                join_within(t, STOP_WITHIN, "the MQTT publishing thread");
            }
            rt.shutdown_timeout(Duration::from_millis(200));
            // The event loop is gone with the runtime, and with it the control thread's input.
            if let Some(t) = self.control_thread.take() {
                join_within(t, STOP_WITHIN, "the MQTT control thread");
            }
        }
        if let Some(b) = self.broker.take() {
            // The offline state reached the embedded broker before the disconnect; its
            // subscribers get it from their sessions' queues, which a flood of what others send
            // can keep the broker's threads from serving at once. A bounded moment for them,
            // before the broker goes with the process.
            std::thread::sleep(OFFLINE_GRACE);
            b.stop();
        }
    }
}

/// How long the embedded broker stays up after the offline state, for its subscribers to get it.
pub const OFFLINE_GRACE: Duration = Duration::from_millis(300);

/// How long a stop waits for each thread of the control plane (and the offline message) before it
/// leaves it behind: a stop always ends, whatever is queued or whoever holds the broker.
pub const STOP_WITHIN: Duration = Duration::from_secs(2);

/// Joins `thread`, waiting at most `within`; false (and a warning naming `what`) when it had not
/// ended by then: it is left to end with the process.
pub fn join_within(thread: JoinHandle<()>, within: Duration, what: &str) -> bool {
    let end = Instant::now() + within;
    while !thread.is_finished() {
        if Instant::now() >= end {
            tracing::warn!("{what} did not stop within {within:?}; left behind");
            return false;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let _ = thread.join();
    true
}

impl Drop for MqttHandle {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Most QoS 1 publishes of one client that may await their acknowledgement at once; more wait in
/// the client's request queue. rumqttc keeps a slot for every one that may be in flight, and its
/// default (65,535) costs 14 MiB a client, most of a PLC's resident memory.
pub const MAX_INFLIGHT: u16 = 256;

/// Client options for a broker URL (`mqtt://[user:password@]host[:port]`, `mqtts://…`; the one
/// parser is [`BrokerUrl`]).
pub fn client_options(url: &str, client_id: &str) -> Result<MqttOptions, MctError> {
    let u = BrokerUrl::parse(url).map_err(|e| MctError::BrokerUrl {
        url: url.to_string(),
        reason: match e {
            ProtoError::BrokerUrl { reason, .. } => reason,
            other => other.to_string(),
        },
    })?;
    let mut o = MqttOptions::new(client_id, u.host(), u.port());
    o.set_outgoing_inflight_upper_limit(MAX_INFLIGHT);
    if u.tls() {
        // Both ring and aws-lc-rs end up in the dependency tree, so rustls cannot choose on its
        // own and would panic on the first handshake. An `Err` means a provider is already
        // installed (by us or by the embedding program), which is as good.
        let _ = rustls::crypto::ring::default_provider().install_default();
        o.set_transport(Transport::tls_with_default_config());
    }
    if let Some((user, password)) = u.credentials() {
        o.set_credentials(user, password);
    }
    Ok(o)
}

/// Starts the broker (when embedded) and the MQTT client; returns the scan thread's end and the
/// handle that keeps the MQTT side alive.
pub fn start(config: MqttConfig) -> Result<(MctLink, MqttHandle), MctError> {
    let control = ControlPlane::new(&config.plc_id, config.operator_keys.clone())?;
    let client_id = format!("cetratus-{}", config.plc_id);
    let (broker, mut opts, url) = match &config.broker {
        BrokerChoice::Embedded(settings) => {
            let b = EmbeddedBroker::start_with(settings.clone(), &config.plc_id)?;
            let url = format!("mqtt://{}", b.local_addr());
            // An id no other login may take on this broker.
            let id = crate::acl::plc_client_id(&config.plc_id);
            let mut o = client_options(&url, &id)?;
            let login = b.plc_login();
            o.set_credentials(&login.user, &login.password);
            (Some(b), o, url)
        }
        BrokerChoice::External {
            url,
            user,
            password,
        } => {
            let mut o = client_options(url, &client_id)?;
            if let Some(u) = user {
                o.set_credentials(u, password.clone().unwrap_or_default());
            }
            (None, o, url.clone())
        }
    };
    let (link, handle) = spawn_mqtt(
        control,
        &mut opts,
        config.publish_period,
        config.queue_capacity.max(1),
        Budget::new(config.command_bytes),
    )?;
    let mut handle = handle;
    handle.broker = broker;
    handle.url = url;
    Ok((link, handle))
}

/// Runs the MQTT client for `control` with `opts` in its own threads (a Tokio runtime for the
/// event loop, a thread for outgoing messages) and returns the two queue ends. Commands wait in a
/// queue of `queue_capacity` entries and `command_bytes` bytes ([`CommandQueue`]).
pub fn spawn_mqtt(
    control: ControlPlane,
    opts: &mut MqttOptions,
    publish_period: Duration,
    queue_capacity: usize,
    command_bytes: Budget,
) -> Result<(MctLink, MqttHandle), MctError> {
    let topics = control.topics().clone();
    let state_topic = topics.state().to_string();
    opts.set_keep_alive(Duration::from_secs(10))
        .set_clean_start(true)
        .set_max_packet_size(Some(BROKER_MAX_PACKET))
        .set_last_will(LastWill::new(
            state_topic.clone(),
            StatePayload::OFFLINE_JSON.to_vec(),
            QoS::AtLeastOnce,
            true,
            None,
        ));
    let (client, eventloop) = AsyncClient::new(opts.clone(), 256);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name("cetratus-mqtt-client")
        .enable_all()
        .build()?;
    let shared = Arc::new(Shared {
        connected: AtomicBool::new(false),
        stopping: AtomicBool::new(false),
        commands_busy: AtomicU64::new(0),
        commands_dropped: AtomicU64::new(0),
        messages_lost: AtomicU64::new(0),
    });
    let (cmd_tx, cmd_rx) = std::sync::mpsc::sync_channel(queue_capacity);
    let (out_tx, out_rx) = std::sync::mpsc::sync_channel(queue_capacity);
    let (inbound_tx, inbound_rx) = std::sync::mpsc::channel();
    let loop_task = rt.spawn(event_loop(
        eventloop,
        client.clone(),
        control.topics().clone(),
        inbound_tx,
        shared.clone(),
    ));
    let control_thread = {
        let (client, shared) = (client.clone(), shared.clone());
        std::thread::Builder::new()
            .name("cetratus-mqtt-control".into())
            .spawn(move || {
                control_loop(inbound_rx, client, control, (cmd_tx, command_bytes), shared)
            })?
    };
    let out_thread = {
        let (client, shared, rt) = (client.clone(), shared.clone(), rt.handle().clone());
        std::thread::Builder::new()
            .name("cetratus-mqtt-out".into())
            .spawn(move || outgoing_loop(out_rx, client, rt, shared, topics, publish_period))?
    };
    Ok((
        MctLink {
            commands: CommandQueue(cmd_rx),
            outgoing: out_tx,
            stats: StatsReader(shared.clone()),
        },
        MqttHandle {
            shared,
            client,
            state_topic,
            rt: Some(rt),
            loop_task: Some(loop_task),
            out_thread: Some(out_thread),
            control_thread: Some(control_thread),
            broker: None,
            url: String::new(),
        },
    ))
}

pub(crate) fn reply_props(handle: &ReplyHandle) -> PublishProperties {
    PublishProperties {
        correlation_data: handle.correlation_data.clone().map(Into::into),
        content_type: Some("application/json".into()),
        ..Default::default()
    }
}

fn state_key(s: &StateMsg) -> (cetratus_proto::Slot, cetratus_proto::Status, String) {
    (
        s.primary,
        s.status,
        serde_json::to_string(&s.programs).unwrap_or_default(),
    )
}

fn outgoing_loop(
    rx: Receiver<Outgoing>,
    client: AsyncClient,
    rt: tokio::runtime::Handle,
    shared: Arc<Shared>,
    topics: Topics,
    period: Duration,
) {
    let publish =
        |topic: &str, retain: bool, payload: Vec<u8>, props: Option<PublishProperties>| {
            let r = rt.block_on(async {
                match props {
                    Some(p) => {
                        client
                            .publish_with_properties(topic, QoS::AtLeastOnce, retain, payload, p)
                            .await
                    }
                    None => {
                        client
                            .publish(topic, QoS::AtLeastOnce, retain, payload)
                            .await
                    }
                }
            });
            if let Err(e) = r {
                tracing::warn!(topic, error = %e, "cannot publish");
            }
        };
    let mut exec_info: Option<Box<ExecInfoMsg>> = None;
    let mut io: Option<IoMsg> = None;
    let mut state: Option<Box<StateMsg>> = None;
    let mut last_state_key = None;
    let mut next = Instant::now();
    let tick = period
        .min(Duration::from_millis(50))
        .max(Duration::from_millis(1));
    while !shared.stopping.load(Ordering::Acquire) {
        match rx.recv_timeout(tick) {
            Ok(Outgoing::State(s)) => {
                let key = state_key(&s);
                // Online only once subscribed to the commands: a client that waits for the
                // state (`client::Session`) then never sends a command into the void.
                let subscribed = shared.connected.load(Ordering::Acquire);
                if subscribed && last_state_key.as_ref() != Some(&key) {
                    last_state_key = Some(key);
                    publish(topics.state(), true, to_json(&s), None);
                    state = None;
                } else {
                    state = Some(s);
                }
            }
            Ok(Outgoing::ExecInfo(v)) => exec_info = Some(v),
            Ok(Outgoing::Io(v)) => io = Some(v),
            Ok(Outgoing::Net(v)) => publish(topics.net(), true, to_json(&v), None),
            Ok(Outgoing::Event(v)) => publish(topics.events(), false, to_json(&v), None),
            Ok(Outgoing::Reply(h, r)) => {
                if let Some(t) = &h.topic {
                    publish(
                        t,
                        false,
                        ControlPlane::reply_payload(&h, &r),
                        Some(reply_props(&h)),
                    );
                }
            }
            Ok(Outgoing::ExecInfoReply(h, info)) => {
                if let Some(t) = &h.topic {
                    let r = Ok(serde_json::to_value(&*info).ok());
                    publish(
                        t,
                        false,
                        ControlPlane::reply_payload(&h, &r),
                        Some(reply_props(&h)),
                    );
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
        if Instant::now() >= next {
            next = Instant::now() + period;
            let subscribed = shared.connected.load(Ordering::Acquire);
            if let Some(s) = state.take_if(|_| subscribed) {
                publish(
                    topics.state(),
                    true,
                    serde_json::to_vec(&s).unwrap_or_default(),
                    None,
                );
            }
            if let Some(v) = exec_info.take() {
                publish(topics.exec_info(), false, to_json(&v), None);
            }
            if let Some(mut v) = io.take() {
                // Stamped when it leaves, so a subscriber can measure the delivery latency.
                v.unix_ms = Some(unix_ms());
                publish(topics.io(), false, to_json(&v), None);
            }
        }
    }
}

fn to_json<T: serde::Serialize>(v: &T) -> Vec<u8> {
    serde_json::to_vec(v).unwrap_or_default()
}

/// Wall-clock milliseconds since the Unix epoch.
fn unix_ms() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cli_flags_choose_the_broker() {
        assert!(matches!(
            BrokerChoice::from_cli(None, None, vec![], None, None),
            Ok(BrokerChoice::Embedded(s)) if s.addr.to_string() == DEFAULT_MQTT_ADDR
        ));
        assert!(matches!(
            BrokerChoice::from_cli(Some("0.0.0.0:1884"), None, vec![], None, None),
            Ok(BrokerChoice::Embedded(s)) if s.addr.port() == 1884
        ));
        assert!(matches!(
            BrokerChoice::from_cli(None, Some("mqtts://plant:8883"), vec![], None, None),
            Ok(BrokerChoice::External { .. })
        ));
        assert!(matches!(
            BrokerChoice::from_cli(Some("localhost"), None, vec![], None, None),
            Err(MctError::MqttAddr(_))
        ));
        assert!(matches!(
            BrokerChoice::from_cli(None, Some("http://x"), vec![], None, None),
            Err(MctError::BrokerUrl { .. })
        ));
        assert!(matches!(
            BrokerChoice::from_cli(Some("a"), Some("b"), vec![], None, None),
            Err(MctError::BothBrokers)
        ));
    }

    #[test]
    fn a_broker_url_gives_host_port_tls_and_credentials() {
        let o = client_options("mqtt://op:pw@10.0.0.5:1999", "id").expect("valid");
        assert_eq!(o.broker_address(), ("10.0.0.5".to_string(), 1999));
        assert!(o.credentials().is_some());
        let o = client_options("mqtts://plant.example", "id").expect("valid");
        assert_eq!(o.broker_address().1, 8883);
        assert!(matches!(o.transport(), Transport::Tls(_)));
    }
}
