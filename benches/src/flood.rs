//! The floods of what others can send, against the Vernadat node as `cetratus run` has it
//! (`cetratus bench flood`): every kind of [`FloodKind`] in short slices, round-robin with
//! unloaded slices, so that every kind and its unloaded reference see the same machine.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use cetratus_runtime::LoopTiming;

use crate::harness::{vernadat_node, BenchError, Figures};

/// How long a flood's client waits before looking again whether its kind is on.
const IDLE_POLL: Duration = Duration::from_millis(1);

/// The wait after a flood slice stops, unmeasured, for what it left in the queues to drain (its
/// replies still count for it).
pub const SETTLE_US: u64 = 1_000_000;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// What a flood sends, one kind per slice of [`flood`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FloodKind {
    /// Bytes that are not JSON, on `cmd/load` and on verbs that do not exist.
    Garbage,
    /// A real signed package (U.1) from a key the PLC does not trust: verified, then refused.
    RefusedLoads,
    /// `exec_info` requests.
    ExecInfo,
    /// `load` commands of just under 1 MiB (random bytes, refused).
    LargePayloads,
    /// 32 KiB events on another PLC's `events` topic, for the embedded dashboard to keep.
    EventSpam,
    /// Dashboard logins with wrong passwords, over HTTP (not MQTT), as fast as they are answered.
    Logins,
    /// A connection that subscribes with a filter of 6,000 levels, then publishes a retained
    /// message on a topic of 8,000 levels (both refused: `MAX_TOPIC_LEVELS`), again and again.
    DeepTopics,
    /// Connections whose last will is the PLC's retained `state`, forged (refused at CONNECT).
    Wills,
    /// Connections that take the client id of the PLC's own client (refused at CONNECT).
    IdTakeover,
    /// TCP connections to the broker that send nothing, [`IDLE_HELD`] held open at once, the
    /// oldest replaced by a new one.
    IdleSockets,
}

/// Silent connections [`FloodKind::IdleSockets`] holds open at once.
pub const IDLE_HELD: usize = 200;

impl FloodKind {
    /// Every kind, in the order a run floods them.
    pub const ALL: [FloodKind; 10] = [
        FloodKind::Garbage,
        FloodKind::RefusedLoads,
        FloodKind::ExecInfo,
        FloodKind::LargePayloads,
        FloodKind::EventSpam,
        FloodKind::Logins,
        FloodKind::DeepTopics,
        FloodKind::Wills,
        FloodKind::IdTakeover,
        FloodKind::IdleSockets,
    ];

    /// Its place in [`FloodKind::ALL`].
    fn index(self) -> usize {
        FloodKind::ALL
            .iter()
            .position(|k| *k == self)
            .unwrap_or_default()
    }

    /// The kind called `name` (as in the figures), or an error that lists them.
    pub fn from_name(name: &str) -> Result<Self, BenchError> {
        FloodKind::ALL
            .into_iter()
            .find(|k| k.name() == name.trim())
            .ok_or_else(|| {
                let names: Vec<_> = FloodKind::ALL.iter().map(|k| k.name()).collect();
                BenchError::from(format!(
                    "unknown flood kind `{name}`; choose among {}",
                    names.join(", ")
                ))
            })
    }

    /// The kinds `names` name, each once, in the order of [`FloodKind::ALL`]; all of them when
    /// `names` is empty.
    pub fn list(names: &[String]) -> Result<Vec<Self>, BenchError> {
        if names.is_empty() {
            return Ok(FloodKind::ALL.to_vec());
        }
        let picked = names
            .iter()
            .map(|n| FloodKind::from_name(n))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(FloodKind::ALL
            .into_iter()
            .filter(|k| picked.contains(k))
            .collect())
    }

    /// Its name in the figures.
    pub fn name(self) -> &'static str {
        match self {
            FloodKind::Garbage => "garbage",
            FloodKind::RefusedLoads => "refused_loads",
            FloodKind::ExecInfo => "exec_info",
            FloodKind::LargePayloads => "large_payloads",
            FloodKind::EventSpam => "event_spam",
            FloodKind::Logins => "dashboard_logins",
            FloodKind::DeepTopics => "deep_topics",
            FloodKind::Wills => "wills",
            FloodKind::IdTakeover => "id_takeover",
            FloodKind::IdleSockets => "idle_sockets",
        }
    }

    /// The messages it sends, in turn: topic and payload (shared, so that sending one costs the
    /// flooding client no copy: a flood from another machine would not use this one's CPU).
    fn messages(self, plc: &str, u1: &[u8]) -> Vec<(String, bytes::Bytes)> {
        self.payloads(plc, u1)
            .into_iter()
            .map(|(t, p)| (t, bytes::Bytes::from(p)))
            .collect()
    }

    fn payloads(self, plc: &str, u1: &[u8]) -> Vec<(String, Vec<u8>)> {
        use base64::Engine as _;
        let cmd = |verb: &str| format!("cetratus/{plc}/cmd/{verb}");
        let b64 = |bytes: &[u8]| base64::engine::general_purpose::STANDARD.encode(bytes);
        match self {
            FloodKind::Garbage => vec![
                (cmd("load"), noise(300, 1)),
                (cmd("frobnicate"), b"{}".to_vec()),
                (cmd("substitute"), b"{\"mode\": \"sideways\"}".to_vec()),
                (cmd("load"), b"{\"package_b64\": 42".to_vec()),
            ],
            FloodKind::RefusedLoads => {
                vec![(
                    cmd("load"),
                    format!("{{\"package_b64\":\"{}\"}}", b64(u1)).into_bytes(),
                )]
            }
            FloodKind::ExecInfo => vec![(cmd("exec_info"), b"{}".to_vec())],
            FloodKind::LargePayloads => {
                let body = format!("{{\"package_b64\":\"{}\"}}", b64(&noise(760_000, 2)));
                vec![(cmd("load"), body.into_bytes())]
            }
            FloodKind::EventSpam => {
                let body = serde_json::json!({"kind": "spam", "message": "s".repeat(32 << 10)});
                vec![(
                    "cetratus/other/events".to_string(),
                    body.to_string().into_bytes(),
                )]
            }
            // Sent by connections of their own ([`connection_flood`], [`login_flood`]).
            FloodKind::Logins
            | FloodKind::DeepTopics
            | FloodKind::Wills
            | FloodKind::IdTakeover
            | FloodKind::IdleSockets => Vec::new(),
        }
    }
}

/// `n` bytes that look random, the same for a seed (SplitMix64).
fn noise(n: usize, seed: u64) -> Vec<u8> {
    let mut x = seed;
    (0..n)
        .map(|_| {
            x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = x;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            (z ^ (z >> 31)) as u8
        })
        .collect()
}

/// This process's resident memory, in KiB.
fn rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmRSS:"))
                .and_then(|v| v.split_whitespace().next())
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(0)
}

/// What [`Beside`] starts: something that stops when dropped, and the dashboard's HTTP address
/// with an account name whose password the login flood gets wrong.
pub type BesideParts = (
    Box<dyn std::any::Any>,
    Option<(std::net::SocketAddr, String)>,
);

/// Whatever runs beside the PLC while it is flooded (the dashboard, in `cetratus bench flood`),
/// given the broker's URL. The caller provides it: the dashboard is the binary's to start, not
/// this crate's.
pub type Beside<'a> = &'a dyn Fn(&str) -> Result<BesideParts, BenchError>;

/// What the flooding threads share with the run: which kind is on (none between flood slices),
/// what they sent, per kind, and the replies they got, by code.
struct Control {
    /// 0 for none, else 1 + the kind's index in [`FloodKind::ALL`].
    active: AtomicUsize,
    done: AtomicBool,
    sent: [AtomicU64; FloodKind::ALL.len()],
    codes: Mutex<BTreeMap<String, u64>>,
}

impl Control {
    fn new() -> Self {
        Control {
            active: AtomicUsize::new(0),
            done: AtomicBool::new(false),
            sent: std::array::from_fn(|_| AtomicU64::new(0)),
            codes: Mutex::default(),
        }
    }

    fn set(&self, kind: Option<FloodKind>) {
        self.active
            .store(kind.map_or(0, |k| k.index() + 1), Ordering::Relaxed);
    }

    fn active(&self) -> Option<FloodKind> {
        let i = self.active.load(Ordering::Relaxed);
        i.checked_sub(1).map(|i| FloodKind::ALL[i])
    }

    fn count_sent(&self, kind: FloodKind) {
        self.sent[kind.index()].fetch_add(1, Ordering::Relaxed);
    }
}

/// Posts logins with a wrong password for `account` to the dashboard at `addr` while `active`
/// says logins, until `done`, one connection per attempt as a script would; counts the answers by
/// HTTP status.
fn login_flood(addr: std::net::SocketAddr, account: &str, ctl: &Control) {
    use std::io::{Read, Write};
    let body = serde_json::json!({"account": account, "password": "wrong"}).to_string();
    let request = format!(
        "POST /api/login HTTP/1.0\r\nHost: {addr}\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    );
    let mut answer = Vec::with_capacity(1024);
    while !ctl.done.load(Ordering::Relaxed) {
        if ctl.active() != Some(FloodKind::Logins) {
            std::thread::sleep(IDLE_POLL);
            continue;
        }
        let Ok(mut s) = std::net::TcpStream::connect(addr) else {
            continue;
        };
        answer.clear();
        if s.write_all(request.as_bytes()).is_err() || s.read_to_end(&mut answer).is_err() {
            continue;
        }
        ctl.count_sent(FloodKind::Logins);
        let status = String::from_utf8_lossy(&answer[..answer.len().min(12)])
            .split_whitespace()
            .nth(1)
            .unwrap_or("?")
            .to_string();
        *lock(&ctl.codes)
            .entry(format!("http_{status}"))
            .or_default() += 1;
    }
}

/// The attacks that are connections of their own ([`FloodKind::DeepTopics`],
/// [`FloodKind::Wills`], [`FloodKind::IdTakeover`], [`FloodKind::IdleSockets`]), one after the
/// other while their kind is on, each counted once the broker has answered it; what it answered
/// is tallied as a code (`connack_<return code>`, `suback_<return code>`, `closed`,
/// `idle_open`).
fn connection_flood(broker: std::net::SocketAddr, plc: &str, ctl: &Control) {
    let deep_filter = vec!["a"; 6000].join("/");
    let deep_topic = vec!["b"; 8000].join("/");
    let state = format!("cetratus/{plc}/state");
    let plc_id = cetratus_mct::acl::plc_client_id(plc);
    let mut held = std::collections::VecDeque::with_capacity(IDLE_HELD);
    while !ctl.done.load(Ordering::Relaxed) {
        let kind = ctl.active();
        if kind != Some(FloodKind::IdleSockets) {
            held.clear();
        }
        let (id, will) = match kind {
            Some(FloodKind::IdleSockets) => {
                idle_socket(broker, &mut held, ctl);
                continue;
            }
            Some(FloodKind::DeepTopics) => ("flood-deep", None),
            Some(FloodKind::Wills) => ("flood-will", Some(state.as_str())),
            Some(FloodKind::IdTakeover) => (plc_id.as_str(), None),
            _ => {
                std::thread::sleep(IDLE_POLL);
                continue;
            }
        };
        let attack = RawAttack { broker, id, will };
        let code = match kind {
            Some(FloodKind::DeepTopics) => attack.deep(&deep_filter, &deep_topic),
            _ => attack.connect().map(|(_, code)| format!("connack_{code}")),
        };
        let Ok(code) = code else { continue };
        if let Some(kind) = kind {
            ctl.count_sent(kind);
        }
        *lock(&ctl.codes).entry(code).or_default() += 1;
    }
}

/// Opens one silent connection to `broker` and holds it, the oldest dropped past [`IDLE_HELD`].
fn idle_socket(
    broker: std::net::SocketAddr,
    held: &mut std::collections::VecDeque<std::net::TcpStream>,
    ctl: &Control,
) {
    let code = match std::net::TcpStream::connect_timeout(&broker, Duration::from_secs(1)) {
        Ok(s) => {
            if held.len() >= IDLE_HELD {
                held.pop_front();
            }
            held.push_back(s);
            "idle_open"
        }
        Err(_) => "idle_refused",
    };
    ctl.count_sent(FloodKind::IdleSockets);
    *lock(&ctl.codes).entry(code.to_string()).or_default() += 1;
    // A new connection a millisecond at most: the attack is to hold them, not to open them.
    std::thread::sleep(Duration::from_millis(1));
}

/// One connection of [`connection_flood`], MQTT 3.1.1 packets written by rumqttc's encoder on a
/// bare socket.
struct RawAttack<'a> {
    broker: std::net::SocketAddr,
    id: &'a str,
    will: Option<&'a str>,
}

impl RawAttack<'_> {
    /// Connects; the socket and the CONNACK's return code.
    fn connect(&self) -> std::io::Result<(std::net::TcpStream, u8)> {
        use std::io::{Read, Write};
        let mut s = std::net::TcpStream::connect(self.broker)?;
        s.set_read_timeout(Some(Duration::from_secs(5)))?;
        let mut connect = rumqttc::Connect::new(self.id);
        connect.keep_alive = 60;
        connect.last_will = self
            .will
            .map(|t| rumqttc::LastWill::new(t, b"{}".to_vec(), rumqttc::QoS::AtMostOnce, true));
        let mut buf = bytes::BytesMut::new();
        connect.write(&mut buf).map_err(std::io::Error::other)?;
        s.write_all(&buf)?;
        let mut connack = [0u8; 4];
        s.read_exact(&mut connack)?;
        Ok((s, connack[3]))
    }

    /// Subscribes with `filter` and publishes on `topic`, retained; the SUBACK's return code,
    /// and whether the broker then closed the connection.
    fn deep(&self, filter: &str, topic: &str) -> std::io::Result<String> {
        use std::io::{Read, Write};
        let (mut s, _) = self.connect()?;
        let mut buf = bytes::BytesMut::new();
        let mut sub = rumqttc::Subscribe::new(filter, rumqttc::QoS::AtMostOnce);
        sub.pkid = 1;
        sub.write(&mut buf).map_err(std::io::Error::other)?;
        let mut publish = rumqttc::Publish::new(topic, rumqttc::QoS::AtMostOnce, b"x".to_vec());
        publish.retain = true;
        publish.write(&mut buf).map_err(std::io::Error::other)?;
        s.write_all(&buf)?;
        let mut suback = [0u8; 5];
        s.read_exact(&mut suback)?;
        let closed = matches!(s.read(&mut [0u8; 64]), Ok(0) | Err(_));
        Ok(format!(
            "suback_{}{}",
            suback[4],
            if closed { "_closed" } else { "" }
        ))
    }
}

/// The flooding client of one slice: its connection is driven by a thread of its own, and closed
/// when dropped, with whatever it had not sent yet.
struct Sender {
    client: rumqttc::v5::Client,
    stop: Arc<AtomicBool>,
}

impl Sender {
    fn connect(url: &str) -> Result<Self, BenchError> {
        let mut opts = cetratus_mct::client_options(url, "bench-flood")?;
        opts.set_max_packet_size(Some(cetratus_mct::BROKER_MAX_PACKET));
        let (client, mut conn) = rumqttc::v5::Client::new(opts, 16);
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        std::thread::spawn(move || {
            while !s.load(Ordering::Relaxed) {
                if let Ok(Err(_)) = conn.recv_timeout(Duration::from_millis(10)) {
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
        });
        Ok(Sender { client, stop })
    }
}

impl Drop for Sender {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// What the slices of one phase (the unloaded one, or one kind) add up to.
#[derive(Default)]
struct Tally {
    timing: LoopTiming,
    /// For a kind: the unloaded slices that came right before its own.
    before: LoopTiming,
    slices: u64,
    measured_us: u64,
    busy: u64,
    replies: BTreeMap<String, u64>,
}

impl Tally {
    /// The figures of a kind's phase, with `sent` messages, and whether it kept within the
    /// targets: its p99 latency within `limit` and its peak memory under 256 MiB.
    fn kind_figures(&self, sent: u64, limit: f64, peak_mib: u64) -> (serde_json::Value, bool) {
        let l = self.timing.latency.summary();
        let within = (l.p99_ns as f64) <= limit;
        let seconds = self.measured_us as f64 / 1e6;
        let figures = serde_json::json!({
            "sent": sent,
            "sent_per_s": if seconds > 0.0 { sent as f64 / seconds } else { 0.0 },
            "slices": self.slices,
            "cycles": l.count,
            "latency_p50_ns": l.p50_ns,
            "latency_p99_ns": l.p99_ns,
            "latency_max_ns": l.max_ns,
            "overruns": self.timing.overruns,
            "unloaded_before_latency_p99_ns": self.before.latency.summary().p99_ns,
            "within_limit": within,
            "peak_rss_mib": peak_mib,
            "busy": self.busy,
            "replies": self.replies,
        });
        (figures, within && peak_mib < 256)
    }
}

/// The PLC's id in a flood run.
const PLC: &str = "bench";

/// The node that [`vernadat_node`] starts.
type VernadatNode = cetratus_node::RunningNode;

/// What the node's MQTT client turned away or lost so far.
fn link_stats(node: &VernadatNode) -> cetratus_mct::LinkStats {
    node.services()
        .map(|s| s.mqtt().stats())
        .unwrap_or_default()
}

/// How a run is cut: `kinds` each flooded for `phase_us` in all, in slices of `slice_us`, the
/// node scanning every `period_us`.
struct Plan<'k> {
    phase_us: u64,
    period_us: u64,
    slice_us: u64,
    kinds: &'k [FloodKind],
}

/// Peak resident memory by phase: the unloaded slices (0), then each kind (1 + its index in
/// [`FloodKind::ALL`]), its settling included.
struct Peaks {
    by_phase: [AtomicU64; 1 + FloodKind::ALL.len()],
    /// The phase that runs now.
    phase: AtomicUsize,
}

impl Peaks {
    fn new() -> Self {
        Peaks {
            by_phase: std::array::from_fn(|_| AtomicU64::new(0)),
            phase: AtomicUsize::new(0),
        }
    }

    /// Samples the memory into the phase that runs, every 20 ms, until `done`.
    fn watch(&self, ctl: &Control) {
        while !ctl.done.load(Ordering::Relaxed) {
            self.by_phase[self.phase.load(Ordering::Relaxed)]
                .fetch_max(rss_kib(), Ordering::Relaxed);
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// The peak of phase `i`, in MiB.
    fn mib(&self, i: usize) -> u64 {
        self.by_phase[i].load(Ordering::Relaxed) / 1024
    }
}

/// A client that counts the PLC's replies on `replies` by error code. It is a client of its
/// own: the broker holds back a client that floods past its limits (and its subscriptions with
/// it).
fn replies_client(
    url: &str,
    replies: &str,
    ctl: &Arc<Control>,
) -> Result<rumqttc::v5::Client, BenchError> {
    use rumqttc::v5::mqttbytes::v5::Packet;
    use rumqttc::v5::mqttbytes::QoS;

    let opts = cetratus_mct::client_options(url, "bench-flood-replies")?;
    let (client, mut conn) = rumqttc::v5::Client::new(opts, 16);
    let ctl = ctl.clone();
    // Ends when the connection does.
    std::thread::spawn(move || {
        for ev in conn.iter() {
            if let Ok(rumqttc::v5::Event::Incoming(Packet::Publish(p))) = ev {
                let v: serde_json::Value = serde_json::from_slice(&p.payload).unwrap_or_default();
                let code = v["error"]["code"].as_str().unwrap_or("ok").to_string();
                *lock(&ctl.codes).entry(code).or_default() += 1;
            }
        }
    });
    client.subscribe(replies, QoS::AtMostOnce)?;
    Ok(client)
}

/// Starts the threads that flood the broker at `mqtt` (`url`) while `ctl` says so, until it
/// says done: the messages, the connections, the dashboard logins when `login` names an
/// account, and the one that samples the peak memory.
fn start_floods(
    mqtt: std::net::SocketAddr,
    url: String,
    replies: String,
    login: Option<(std::net::SocketAddr, String)>,
    ctl: &Arc<Control>,
    peaks: &Arc<Peaks>,
) -> Vec<std::thread::JoinHandle<()>> {
    let mut threads = Vec::new();
    let u1 = crate::update::packages().u1;
    let messages: Vec<_> = FloodKind::ALL
        .iter()
        .map(|k| k.messages(PLC, &u1))
        .collect();
    threads.push({
        let ctl = ctl.clone();
        std::thread::spawn(move || message_flood(&url, replies, &messages, &ctl))
    });
    threads.push({
        let ctl = ctl.clone();
        std::thread::spawn(move || connection_flood(mqtt, PLC, &ctl))
    });
    if let Some((addr, account)) = login {
        let ctl = ctl.clone();
        threads.push(std::thread::spawn(move || {
            login_flood(addr, &account, &ctl)
        }));
    }
    threads.push({
        let (ctl, peaks) = (ctl.clone(), peaks.clone());
        std::thread::spawn(move || peaks.watch(&ctl))
    });
    threads
}

/// Publishes the `messages` of the kind that is on (by index in [`FloodKind::ALL`]), in turn,
/// as fast as the client takes them, until `done`; commands ask for their replies on
/// `replies`.
fn message_flood(
    url: &str,
    replies: String,
    messages: &[Vec<(String, bytes::Bytes)>],
    ctl: &Control,
) {
    use rumqttc::v5::mqttbytes::v5::PublishProperties;
    use rumqttc::v5::mqttbytes::QoS;

    let props = PublishProperties {
        response_topic: Some(replies),
        correlation_data: Some(b"flood".to_vec().into()),
        ..PublishProperties::default()
    };
    let mut turn = 0usize;
    // A connection per flood slice: what a slice left unsent in the client and its socket
    // (the broker reads a client held back by its limits slowly) goes with it when the
    // slice ends, and does not flood the slices after it. The next one connects then,
    // while nothing is measured.
    let mut sender = Sender::connect(url).ok();
    let mut used = false;
    while !ctl.done.load(Ordering::Relaxed) {
        let Some((kind, list)) = ctl
            .active()
            .map(|k| (k, &messages[k.index()]))
            .filter(|(_, list)| !list.is_empty())
        else {
            if std::mem::take(&mut used) {
                drop(sender.take());
                sender = Sender::connect(url).ok();
            }
            std::thread::sleep(IDLE_POLL);
            continue;
        };
        used = true;
        if sender.is_none() {
            sender = Sender::connect(url).ok();
        }
        let Some(client) = sender.as_ref().map(|s| &s.client) else {
            std::thread::sleep(IDLE_POLL);
            continue;
        };
        let (topic, payload) = &list[turn % list.len()];
        let r = if topic.contains("/cmd/") {
            client.try_publish_with_properties(
                topic.clone(),
                QoS::AtMostOnce,
                false,
                payload.clone(),
                props.clone(),
            )
        } else {
            client.try_publish(topic.clone(), QoS::AtMostOnce, false, payload.clone())
        };
        if r.is_err() {
            // The client's queue is full: the broker reads no faster.
            std::thread::sleep(Duration::from_micros(50));
            continue;
        }
        turn = turn.wrapping_add(1);
        ctl.count_sent(kind);
    }
}

/// The scans of a flood run, slice after slice on one clock, and what the run shares with the
/// floods.
struct Run<'r> {
    node: &'r mut VernadatNode,
    ctl: &'r Control,
    peaks: &'r Peaks,
    period_us: u64,
    /// Where the next slice starts on the node's clock.
    now_base: u64,
    never: AtomicBool,
}

impl Run<'_> {
    /// What the node's MQTT client turned away or lost so far.
    fn link_stats(&self) -> cetratus_mct::LinkStats {
        link_stats(self.node)
    }

    /// One slice of `length_us`; its timing, and the length it ran.
    fn slice(&mut self, length_us: u64) -> (LoopTiming, u64) {
        use cetratus_node::periodic::run_periodic;

        let mut timing = LoopTiming::default();
        let base = self.now_base;
        let node = &mut *self.node;
        let reached = run_periodic(
            self.period_us,
            length_us,
            1.0,
            &self.never,
            &mut timing,
            |now, t| {
                node.node_mut().step(base + now, t);
                true
            },
        );
        self.now_base += reached;
        (timing, reached)
    }

    /// The round-robin of the plan's kinds, each flood slice after an unloaded one, until every
    /// kind has had its phase; the unloaded slices' tally, and each kind's (by index in
    /// [`FloodKind::ALL`]).
    fn interleave(&mut self, plan: &Plan) -> (Tally, Vec<Tally>) {
        let mut unloaded = Tally::default();
        let mut tallies: Vec<Tally> = FloodKind::ALL.iter().map(|_| Tally::default()).collect();
        let mut done_us = 0u64;
        while done_us < plan.phase_us {
            let length = plan.slice_us.min(plan.phase_us - done_us);
            for &kind in plan.kinds {
                self.peaks.phase.store(0, Ordering::Relaxed);
                let (t, reached) = self.slice(length);
                unloaded.timing.add(&t);
                unloaded.slices += 1;
                unloaded.measured_us += reached;
                let tally = &mut tallies[kind.index()];
                tally.before.add(&t);
                self.flood_slice(kind, length, tally);
            }
            done_us += length;
        }
        (unloaded, tallies)
    }

    /// One slice of `length_us` flooded with `kind`, then its settling, added to `tally`.
    fn flood_slice(&mut self, kind: FloodKind, length_us: u64, tally: &mut Tally) {
        // Replies still arriving from the kind before are nobody's.
        lock(&self.ctl.codes).clear();
        let busy0 = self.link_stats().commands_busy;
        self.peaks.phase.store(1 + kind.index(), Ordering::Relaxed);
        self.ctl.set(Some(kind));
        let (t, reached) = self.slice(length_us);
        self.ctl.set(None);
        self.slice(SETTLE_US);
        tally.timing.add(&t);
        tally.slices += 1;
        tally.measured_us += reached;
        tally.busy += self.link_stats().commands_busy - busy0;
        for (code, n) in std::mem::take(&mut *lock(&self.ctl.codes)) {
            *tally.replies.entry(code).or_default() += n;
        }
    }
}

/// The figures of the measured slices: the plan, the unloaded reference (whose p99 sets the
/// latency limit) and each kind, with whether all kept within the targets.
fn slice_figures(
    plan: &Plan,
    unloaded: &Tally,
    tallies: &[Tally],
    ctl: &Control,
    peaks: &Peaks,
) -> Figures {
    let q = unloaded.timing.latency.summary();
    let limit = 1.2 * q.p99_ns as f64 + 20_000.0;
    let mut out = Figures::new();
    let s = |k: &str| k.to_string();
    out.insert(s("method"), "interleaved".into());
    out.insert(s("period_us"), plan.period_us.into());
    out.insert(s("phase_s"), (plan.phase_us as f64 / 1e6).into());
    out.insert(s("slice_s"), (plan.slice_us as f64 / 1e6).into());
    out.insert(s("settle_s"), (SETTLE_US as f64 / 1e6).into());
    out.insert(s("unloaded_slices"), unloaded.slices.into());
    out.insert(s("unloaded_cycles"), q.count.into());
    out.insert(s("unloaded_latency_p50_ns"), q.p50_ns.into());
    out.insert(s("unloaded_latency_p99_ns"), q.p99_ns.into());
    out.insert(s("unloaded_latency_max_ns"), q.max_ns.into());
    out.insert(s("unloaded_overruns"), unloaded.timing.overruns.into());
    out.insert(s("unloaded_peak_rss_mib"), peaks.mib(0).into());
    out.insert(s("limit_ns"), limit.into());
    let mut all_within = true;
    for &kind in plan.kinds {
        let i = kind.index();
        let sent = ctl.sent[i].load(Ordering::Relaxed);
        let (figures, within) = tallies[i].kind_figures(sent, limit, peaks.mib(1 + i));
        all_within &= within;
        out.insert(kind.name().to_string(), figures);
    }
    out.insert(s("all_within_targets"), all_within.into());
    out
}

/// Runs the Vernadat node as `cetratus run` does (embedded broker, `beside` it the dashboard,
/// MQTT link) at `period_us`, and floods it with each of `kinds` for `phase_us` in all, sent
/// by clients as fast as they can. The run is cut into slices of `slice_us`, round-robin: an
/// unloaded slice, then one of the first kind, an unloaded slice, one of the second kind… until
/// every kind has had `phase_us`; after each flood slice the scans go on unmeasured for
/// [`SETTLE_US`] while what it left drains. So every kind and the unloaded reference are measured
/// over the same stretch of time, whatever the machine (or its host) does meanwhile.
///
/// Reports, per kind and for the unloaded slices, the scan latency (p50, p99, max), overruns and
/// the peak resident memory of the process, and what the flood came to (messages sent, replies
/// by code, commands answered `busy`). The process holds the flooding clients too, so its peak
/// memory is an upper bound on the PLC's. With `rt` the scan thread asks for SCHED_FIFO (as
/// `cetratus run --rt` does); the flooding clients never run real-time.
pub fn flood(
    phase_us: u64,
    period_us: u64,
    slice_us: u64,
    rt: bool,
    kinds: &[FloodKind],
    beside: Beside<'_>,
) -> Result<Figures, BenchError> {
    let slice_us = slice_us.clamp(period_us.max(1), phase_us.max(period_us.max(1)));
    let plan = Plan {
        phase_us,
        period_us,
        slice_us,
        kinds,
    };
    let mqtt = std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?;
    let mut node = vernadat_node(PLC, mqtt, period_us)?;
    let (dashboard, login_target) = beside(&format!("mqtt://{mqtt}"))?;
    let ctl = Arc::new(Control::new());
    let url = format!("mqtt://{mqtt}");
    let replies = format!("cetratus/{PLC}/reply/bench-flood");
    let replies_client = replies_client(&url, &replies, &ctl)?;
    let peaks = Arc::new(Peaks::new());
    let threads = start_floods(mqtt, url, replies, login_target, &ctl, &peaks);

    // Every thread of the node and of the floods is running by now, so only the scan thread is
    // real-time, on its CPU of its own.
    let rt_status = rt.then(|| cetratus_node::rt::request(80).to_string());
    let mut run = Run {
        node: &mut node,
        ctl: &ctl,
        peaks: &peaks,
        period_us,
        now_base: 0,
        never: AtomicBool::new(false),
    };
    // The MQTT link connected, the dashboard subscribed, the first snapshots sent.
    run.slice(SETTLE_US);
    let (unloaded, tallies) = run.interleave(&plan);
    ctl.done.store(true, Ordering::Relaxed);
    for t in threads {
        let _ = t.join();
    }
    // The machine's own wake-up latency, right after, from the scan thread (whose CPU, priority
    // and timer slack cyclictest inherits), for as long as one kind was measured (at most 30 s).
    let machine = crate::cyclictest::measure(period_us, phase_us.min(30_000_000), rt);

    let mut out = slice_figures(&plan, &unloaded, &tallies, &ctl, &peaks);
    let stats = link_stats(&node);
    let finished = node.finish()?;
    let (plc, report) = (finished.plc, finished.report);
    drop(dashboard);
    drop(replies_client);
    let s = |k: &str| k.to_string();
    out.insert(
        s("machine"),
        serde_json::to_value(machine).unwrap_or_default(),
    );
    out.insert(
        s("rt"),
        rt_status.unwrap_or_else(|| "not requested".into()).into(),
    );
    out.insert(s("primary_status"), plc.status().as_str().into());
    out.insert(
        s("dropped"),
        serde_json::json!({
            "commands_busy": stats.commands_busy,
            "commands_dropped": stats.commands_dropped,
            "mqtt_client_lost": stats.messages_lost,
            "plc_events_dropped": report.link.map_or(0, |c| c.dropped),
        }),
    );
    Ok(out)
}
