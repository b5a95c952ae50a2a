//! The latest picture of every PLC seen on the broker: what a browser needs when it connects.
//!
//! Nothing here touches the network or a clock (the receive time is passed in), so the state
//! keeping is tested without a broker.
//!
//! Anyone on the broker can publish under any PLC id, so what is kept is bounded in bytes, not
//! only in messages: a message over its kind's limit ([`Kind::max_bytes`]) is refused before it
//! is parsed; each PLC keeps at most [`IO_HISTORY_BYTES`] of `io` and [`EVENT_HISTORY_BYTES`] of
//! events, oldest dropped first; and the whole fleet at most [`FLEET_BYTES`], taken back from the
//! PLC that holds the most. Bytes are those a parsed message takes in memory
//! ([`value_bytes`], an estimate), and every message refused or dropped is counted
//! ([`Fleet::dropped`]).
//!
//! What is kept is decoded with the protocol's own types ([`Payload`]): a message that is not
//! the payload its topic carries is refused, and a field a newer PLC adds is passed over.

use std::collections::{BTreeMap, VecDeque};

use cetratus_proto::{parse_topic, EventMsg, ExecInfoMsg, IoMsg, Leaf, NetMsg, StatePayload};
use serde::Serialize;
use serde_json::Value;

/// How many `io` samples are kept per PLC: 1024 at the default 500 ms period is about 8 minutes,
/// more than the 60 s the timing diagram shows, so a browser that connects late still gets a full
/// diagram at once.
pub const IO_HISTORY: usize = 1024;

/// How many bytes of `io` are kept per PLC: the runtime's `io` carries the Monitor's ring
/// buffer since the last publish (hundreds of samples at high speed), so a count alone would let
/// one PLC hold tens of megabytes and send them to every browser that connects.
pub const IO_HISTORY_BYTES: usize = 4 << 20;

/// How many events are kept per PLC for a browser that connects later.
pub const EVENT_HISTORY: usize = 200;

/// How many bytes of events are kept per PLC.
pub const EVENT_HISTORY_BYTES: usize = 1 << 20;

/// How many bytes the whole fleet keeps: past it the PLC that holds the most gives back its
/// oldest history, then its drawings and figures (never its `state`).
pub const FLEET_BYTES: usize = 64 << 20;

/// How many PLC ids are kept at most: anyone on the broker can invent ids, and the dashboard must
/// not grow without bound because of it.
pub const MAX_PLCS: usize = 1000;

/// Which topic a message came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// `state` (retained).
    State,
    /// `exec_info`.
    ExecInfo,
    /// `io`.
    Io,
    /// `events`.
    Event,
    /// `net` (retained).
    Net,
}

impl Kind {
    /// The SSE event name.
    pub fn name(self) -> &'static str {
        match self {
            Kind::State => "state",
            Kind::ExecInfo => "exec_info",
            Kind::Io => "io",
            Kind::Event => "event",
            Kind::Net => "net",
        }
    }

    /// The largest message of this kind that is taken, in bytes as received. A PLC's `state`
    /// and events are a few hundred bytes; `exec_info` and `net` grow with the net (a marking
    /// per place, an SVG drawing), `io` with the samples since the last publish.
    pub fn max_bytes(self) -> usize {
        match self {
            Kind::State => 64 << 10,
            Kind::Event => 64 << 10,
            Kind::Io => 1 << 20,
            Kind::ExecInfo => 4 << 20,
            Kind::Net => 4 << 20,
        }
    }

    fn from_leaf(leaf: Leaf) -> Option<Kind> {
        match leaf {
            Leaf::State => Some(Kind::State),
            Leaf::ExecInfo => Some(Kind::ExecInfo),
            Leaf::Io => Some(Kind::Io),
            Leaf::Events => Some(Kind::Event),
            Leaf::Net => Some(Kind::Net),
            Leaf::Cmd(_) => None,
        }
    }
}

/// A message of a PLC, decoded with the protocol's types; sent on to the browsers as the PLC
/// wrote it.
// Not boxed: one is kept per message, already bounded in bytes as its JSON, and moved, never
// stored in bulk beside smaller ones of its kind.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Payload {
    /// `state`.
    State(StatePayload),
    /// `exec_info`: `[A | null, B | null]`.
    ExecInfo(ExecInfoMsg),
    /// `io`.
    Io(IoMsg),
    /// `events`.
    Event(EventMsg),
    /// `net`.
    Net(NetMsg),
}

impl Payload {
    /// Reads the JSON of a `kind` message as its protocol type.
    fn decode(kind: Kind, v: Value) -> Result<Payload, serde_json::Error> {
        Ok(match kind {
            Kind::State => Payload::State(serde_json::from_value(v)?),
            Kind::ExecInfo => Payload::ExecInfo(serde_json::from_value(v)?),
            Kind::Io => Payload::Io(serde_json::from_value(v)?),
            Kind::Event => Payload::Event(serde_json::from_value(v)?),
            Kind::Net => Payload::Net(serde_json::from_value(v)?),
        })
    }
}

/// A payload with the time the dashboard received it (Unix milliseconds), so the browser can
/// measure MQTT → DOM latency.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stamped {
    /// When the MQTT message arrived at the dashboard, Unix ms.
    pub recv_ms: f64,
    /// The payload.
    pub data: Payload,
    /// What it takes in memory ([`value_bytes`]).
    #[serde(skip)]
    pub bytes: usize,
}

/// About how many bytes a JSON value takes in memory: its strings, plus a fixed cost per value
/// and per key. An estimate, used to bound what is kept; it walks the value, once, when it
/// arrives.
pub fn value_bytes(v: &Value) -> usize {
    const NODE: usize = 32;
    NODE + match v {
        Value::Null | Value::Bool(_) | Value::Number(_) => 0,
        Value::String(s) => s.len(),
        Value::Array(a) => a.iter().map(value_bytes).sum(),
        Value::Object(o) => o.iter().map(|(k, v)| NODE + k.len() + value_bytes(v)).sum(),
    }
}

/// One change, as pushed to the browsers.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Update {
    /// The PLC id.
    pub plc: String,
    /// Which topic.
    #[serde(skip)]
    pub kind: Kind,
    /// When it arrived, Unix ms.
    pub recv_ms: f64,
    /// The payload; `None` when an empty retained message cleared what was kept.
    pub data: Option<Payload>,
    /// What the payload takes in memory ([`value_bytes`]).
    #[serde(skip)]
    pub bytes: usize,
    /// Whether this message made the PLC list change (a new id, or `online` changed).
    #[serde(skip)]
    pub list_changed: bool,
}

/// What the dashboard knows about one PLC.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PlcView {
    /// The latest `state`.
    pub state: Option<Stamped>,
    /// The latest `exec_info`, as the pair `[A, B]` ([`ExecInfoMsg`]): container A's figures, then
    /// B's, each `null` when the container is empty.
    pub exec_info: Option<Stamped>,
    /// The latest `net`, as `{"A": "<svg…>"|null, "B": …}`.
    pub net: Option<Stamped>,
    /// The latest `io` samples, oldest first.
    pub io: VecDeque<Stamped>,
    /// The latest events, oldest first.
    pub events: VecDeque<Stamped>,
    /// Bytes of `io` kept.
    #[serde(skip)]
    io_bytes: usize,
    /// Bytes of events kept.
    #[serde(skip)]
    event_bytes: usize,
    /// Bytes kept in all.
    #[serde(skip)]
    bytes: usize,
}

impl PlcView {
    /// Whether the PLC's last `state` said it is online (false before any `state`).
    pub fn online(&self) -> bool {
        let state = self.state.as_ref().map(|s| &s.data);
        matches!(state, Some(Payload::State(StatePayload::Online(_))))
    }

    /// Bytes this PLC keeps.
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    fn slot(&mut self, kind: Kind) -> Option<&mut Option<Stamped>> {
        match kind {
            Kind::State => Some(&mut self.state),
            Kind::ExecInfo => Some(&mut self.exec_info),
            Kind::Net => Some(&mut self.net),
            Kind::Io | Kind::Event => None,
        }
    }

    /// Replaces the latest value of a kind; returns the bytes it gave back.
    fn set_latest(&mut self, kind: Kind, value: Option<Stamped>) -> usize {
        let added = value.as_ref().map_or(0, |v| v.bytes);
        let old = self
            .slot(kind)
            .and_then(|slot| std::mem::replace(slot, value))
            .map_or(0, |v| v.bytes);
        self.bytes = self.bytes - old + added;
        old
    }

    /// Adds to a history and drops its oldest entries past the PLC's bounds; returns the number
    /// of entries dropped and their bytes.
    fn push_history(&mut self, kind: Kind, item: Stamped) -> (u64, usize) {
        let (q, held, max_len, max_bytes) = match kind {
            Kind::Io => (
                &mut self.io,
                &mut self.io_bytes,
                IO_HISTORY,
                IO_HISTORY_BYTES,
            ),
            _ => (
                &mut self.events,
                &mut self.event_bytes,
                EVENT_HISTORY,
                EVENT_HISTORY_BYTES,
            ),
        };
        *held += item.bytes;
        self.bytes += item.bytes;
        q.push_back(item);
        let (mut n, mut freed) = (0, 0);
        // The newest is always kept: it is no larger than its kind's limit.
        while (q.len() > max_len || *held > max_bytes) && q.len() > 1 {
            if let Some(old) = q.pop_front() {
                *held -= old.bytes;
                self.bytes -= old.bytes;
                freed += old.bytes;
                n += 1;
            }
        }
        (n, freed)
    }

    /// Gives back the oldest history entry, or else the larger of the drawings and the figures
    /// (the `state` is kept: it is small and says whether the PLC is online). Returns the bytes
    /// given back, 0 when there is nothing left to give.
    fn evict_one(&mut self) -> usize {
        let oldest_io = self.io.front().map(|s| s.recv_ms);
        let oldest_event = self.events.front().map(|s| s.recv_ms);
        let from_io = match (oldest_io, oldest_event) {
            (Some(a), Some(b)) => a <= b,
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (None, None) => {
                let net = self.net.as_ref().map_or(0, |s| s.bytes);
                let info = self.exec_info.as_ref().map_or(0, |s| s.bytes);
                let kind = if net >= info {
                    Kind::Net
                } else {
                    Kind::ExecInfo
                };
                return self.set_latest(kind, None);
            }
        };
        let (q, held) = if from_io {
            (&mut self.io, &mut self.io_bytes)
        } else {
            (&mut self.events, &mut self.event_bytes)
        };
        let freed = q.pop_front().map_or(0, |s| s.bytes);
        *held -= freed;
        self.bytes -= freed;
        freed
    }
}

/// What the fleet refused or dropped since it started.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Dropped {
    /// Messages over their kind's limit, refused unread.
    pub too_large: u64,
    /// Entries dropped to keep a PLC's histories within their bounds.
    pub history: u64,
    /// Entries and values dropped to keep the fleet within [`FLEET_BYTES`].
    pub fleet: u64,
}

/// Why a message was not taken.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Ignored {
    /// Not under `cetratus/<plc-id>/`, or a leaf the dashboard does not show (commands, replies).
    NotOurs,
    /// The payload is not the JSON the topic carries; the reason says what was wrong.
    Malformed(String),
    /// [`MAX_PLCS`] ids are known already.
    TooManyPlcs,
    /// The message is larger than its kind's limit ([`Kind::max_bytes`]).
    TooLarge {
        /// Its kind.
        kind: Kind,
        /// Its size.
        bytes: usize,
    },
}

/// Every PLC seen, by id.
#[derive(Clone, Debug, Default)]
pub struct Fleet {
    plcs: BTreeMap<String, PlcView>,
    bytes: usize,
    dropped: Dropped,
}

/// One PLC in the list the browsers choose from.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Listed {
    /// The PLC id.
    pub id: String,
    /// Whether its last `state` said it is online.
    pub online: bool,
}

/// One PLC on the fleet page.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Row {
    /// The PLC id.
    pub id: String,
    /// Whether its last `state` said it is online.
    pub online: bool,
    /// PRIMARY, when online.
    pub primary: Option<&'static str>,
    /// STATUS, when online.
    pub status: Option<&'static str>,
    /// PRIMARY's program, `"<name> <version>"`.
    pub program: Option<String>,
    /// Its labels.
    pub labels: cetratus_proto::Labels,
}

/// Everything a browser needs to draw one PLC at once.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Snapshot<'a> {
    /// The PLC id.
    pub plc: &'a str,
    /// The latest `state`.
    pub state: Option<&'a Stamped>,
    /// The latest `exec_info`.
    pub exec_info: Option<&'a Stamped>,
    /// The latest `net`.
    pub net: Option<&'a Stamped>,
    /// The kept `io` samples, oldest first.
    pub io: &'a VecDeque<Stamped>,
    /// The kept events, oldest first.
    pub events: &'a VecDeque<Stamped>,
}

/// The history of a PLC that is not known.
static NO_HISTORY: VecDeque<Stamped> = VecDeque::new();

impl Fleet {
    /// An empty fleet.
    pub fn new() -> Self {
        Fleet::default()
    }

    /// Takes one MQTT message received at `recv_ms` (Unix ms). Returns the change to push to the
    /// browsers. An empty payload on a retained topic (the broker's way of deleting a retained
    /// message) clears what was kept.
    pub fn apply(&mut self, topic: &str, payload: &[u8], recv_ms: f64) -> Result<Update, Ignored> {
        let (plc, leaf) = parse_topic(topic).map_err(|_| Ignored::NotOurs)?;
        let kind = Kind::from_leaf(leaf).ok_or(Ignored::NotOurs)?;
        let plc = plc.as_str();
        if payload.len() > kind.max_bytes() {
            self.dropped.too_large += 1;
            return Err(Ignored::TooLarge {
                kind,
                bytes: payload.len(),
            });
        }
        let value: Value = if payload.is_empty() {
            Value::Null
        } else {
            serde_json::from_slice(payload)
                .map_err(|e| Ignored::Malformed(format!("{topic}: not JSON: {e}")))?
        };
        let bytes = if value.is_null() {
            0
        } else {
            value_bytes(&value)
        };
        let data = match value {
            Value::Null => None,
            v => Some(
                Payload::decode(kind, v)
                    .map_err(|e| Ignored::Malformed(format!("{topic}: not its payload: {e}")))?,
            ),
        };
        let is_new = !self.plcs.contains_key(plc);
        if is_new && self.plcs.len() >= MAX_PLCS {
            return Err(Ignored::TooManyPlcs);
        }
        if data.is_none() && matches!(kind, Kind::Io | Kind::Event) {
            return Err(Ignored::Malformed(format!("{topic}: empty payload")));
        }
        let view = self.plcs.entry(plc.to_string()).or_default();
        let was_online = view.online();
        let before = view.bytes;
        let stamped = data.clone().map(|data| Stamped {
            recv_ms,
            data,
            bytes,
        });
        match (kind, stamped) {
            (Kind::State | Kind::ExecInfo | Kind::Net, stamped) => {
                view.set_latest(kind, stamped);
            }
            (Kind::Io | Kind::Event, Some(stamped)) => {
                let (n, _) = view.push_history(kind, stamped);
                self.dropped.history += n;
            }
            (Kind::Io | Kind::Event, None) => {}
        }
        let online = view.online();
        self.bytes = self.bytes + view.bytes - before;
        self.keep_within(FLEET_BYTES, plc);
        let list_changed = is_new || was_online != online;
        Ok(Update {
            plc: plc.to_string(),
            kind,
            recv_ms,
            data,
            bytes,
            list_changed,
        })
    }

    /// Gives back bytes, from the PLC that holds the most, until the fleet holds at most `limit`.
    /// `newest` (the PLC just written) gives back last, so what just arrived is kept.
    fn keep_within(&mut self, limit: usize, newest: &str) {
        while self.bytes > limit {
            let victim = self
                .plcs
                .iter()
                .filter(|(id, v)| id.as_str() != newest && v.bytes > 0)
                .max_by_key(|(_, v)| v.bytes)
                .map_or_else(|| newest.to_string(), |(id, _)| id.clone());
            let Some(view) = self.plcs.get_mut(&victim) else {
                return;
            };
            let freed = view.evict_one();
            if freed == 0 {
                // Only `state`s are left: they are bounded by the number of PLCs.
                return;
            }
            self.bytes -= freed;
            self.dropped.fleet += 1;
        }
    }

    /// Bytes the whole fleet keeps.
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    /// What was refused or dropped so far.
    pub fn dropped(&self) -> Dropped {
        self.dropped
    }

    /// One row per PLC for the fleet page, in id order: what its last `state` says.
    pub fn rows(&self) -> Vec<Row> {
        let row = |(id, v): (&String, &PlcView)| {
            let state = match v.state.as_ref().map(|s| &s.data) {
                Some(Payload::State(StatePayload::Online(s))) => Some(s),
                _ => None,
            };
            Row {
                id: id.clone(),
                online: state.is_some(),
                primary: state.map(|s| s.primary.as_str()),
                status: state.map(|s| s.status.as_str()),
                program: state
                    .and_then(|s| s.programs.get(s.primary))
                    .map(|p| format!("{} {}", p.name, p.version)),
                labels: state.map(|s| s.labels.clone()).unwrap_or_default(),
            }
        };
        self.plcs.iter().map(row).collect()
    }

    /// The PLC ids with their `online` flag, in id order.
    pub fn list(&self) -> Vec<Listed> {
        let listed = |(id, v): (&String, &PlcView)| Listed {
            id: id.clone(),
            online: v.online(),
        };
        self.plcs.iter().map(listed).collect()
    }

    /// What is known about one PLC.
    pub fn get(&self, plc: &str) -> Option<&PlcView> {
        self.plcs.get(plc)
    }

    /// Everything a browser needs to draw one PLC at once.
    pub fn snapshot<'a>(&'a self, plc: &'a str) -> Snapshot<'a> {
        let view = self.plcs.get(plc);
        Snapshot {
            plc,
            state: view.and_then(|v| v.state.as_ref()),
            exec_info: view.and_then(|v| v.exec_info.as_ref()),
            net: view.and_then(|v| v.net.as_ref()),
            io: view.map_or(&NO_HISTORY, |v| &v.io),
            events: view.map_or(&NO_HISTORY, |v| &v.events),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cetratus_proto::{Slot, StateMsg, Status};
    use serde_json::json;

    /// A payload the running PLC published (the protocol's golden files).
    fn golden(name: &str) -> Value {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../proto/tests/golden")
            .join(name);
        let text = std::fs::read_to_string(&path).expect("a golden file");
        serde_json::from_str(&text).expect("golden JSON")
    }

    fn bytes(v: &Value) -> Vec<u8> {
        v.to_string().into_bytes()
    }

    fn state(primary: &str, status: &str) -> Vec<u8> {
        let mut v = golden("state.json");
        v["primary"] = json!(primary);
        v["status"] = json!(status);
        bytes(&v)
    }

    /// An `io` message whose `time_ms` is `t`, with a field of `pad` bytes this build ignores.
    fn io(t: u64, pad: usize) -> Vec<u8> {
        let mut v = golden("io.json");
        v["time_ms"] = json!(t);
        v["samples"] = json!([]);
        if pad > 0 {
            v["pad"] = json!("x".repeat(pad));
        }
        bytes(&v)
    }

    fn event(cycle: u64, message: &str) -> Vec<u8> {
        bytes(&json!({"kind": "x", "message": message, "cycle": cycle}))
    }

    fn state_msg(s: Option<&Stamped>) -> Option<&StateMsg> {
        match s.map(|s| &s.data) {
            Some(Payload::State(StatePayload::Online(m))) => Some(m),
            _ => None,
        }
    }

    fn io_time(s: Option<&Stamped>) -> Option<u64> {
        match s.map(|s| &s.data) {
            Some(Payload::Io(m)) => Some(m.time_ms),
            _ => None,
        }
    }

    fn event_cycle(s: Option<&Stamped>) -> Option<u64> {
        match s.map(|s| &s.data) {
            Some(Payload::Event(e)) => e.cycle,
            _ => None,
        }
    }

    fn listed(id: &str, online: bool) -> Listed {
        Listed {
            id: id.into(),
            online,
        }
    }

    #[test]
    fn state_message_creates_the_plc_and_is_kept() {
        let mut f = Fleet::new();
        let u = f
            .apply("cetratus/cell1/state", &state("A", "idle"), 1.0)
            .expect("taken");
        assert_eq!(u.plc, "cell1");
        assert_eq!(u.kind, Kind::State);
        assert!(u.list_changed);
        let v = f.get("cell1").expect("kept");
        let m = state_msg(v.state.as_ref()).expect("an online state");
        assert_eq!((m.primary, m.status), (Slot::A, Status::Idle));
        assert!(v.online());
        assert_eq!(f.list(), [listed("cell1", true)]);
    }

    #[test]
    fn later_state_replaces_earlier_and_list_changes_only_on_online_flip() {
        let mut f = Fleet::new();
        f.apply("cetratus/c/state", &state("A", "idle"), 1.0)
            .expect("taken");
        let u = f
            .apply("cetratus/c/state", &state("A", "quarantine"), 2.0)
            .expect("taken");
        assert!(!u.list_changed);
        let u = f
            .apply("cetratus/c/state", br#"{"online": false}"#, 3.0)
            .expect("taken");
        assert!(u.list_changed);
        assert_eq!(f.list(), [listed("c", false)]);
    }

    #[test]
    fn io_history_is_bounded_and_keeps_the_newest() {
        let mut f = Fleet::new();
        for i in 0..IO_HISTORY + 10 {
            f.apply("cetratus/c/io", &io(i as u64, 0), i as f64)
                .expect("taken");
        }
        let io = &f.get("c").expect("kept").io;
        assert_eq!(io.len(), IO_HISTORY);
        assert_eq!(io_time(io.front()), Some(10));
        assert_eq!(io_time(io.back()), Some(IO_HISTORY as u64 + 9));
    }

    #[test]
    fn io_history_is_bounded_in_bytes_too() {
        let mut f = Fleet::new();
        for i in 0..100 {
            f.apply("cetratus/c/io", &io(i, 100_000), 0.0)
                .expect("taken");
        }
        let v = f.get("c").expect("kept");
        // A field this build passes over still counts: the bound is on what arrived.
        let held: usize = v.io.iter().map(|s| s.bytes).sum();
        assert!(held <= IO_HISTORY_BYTES, "{held}");
        let each = v.io.back().map_or(1, |s| s.bytes);
        assert!(v.io.len() + 1 >= IO_HISTORY_BYTES / each, "{}", v.io.len());
        assert_eq!(io_time(v.io.back()), Some(99));
    }

    #[test]
    fn events_are_bounded() {
        let mut f = Fleet::new();
        for i in 0..EVENT_HISTORY + 5 {
            f.apply("cetratus/c/events", &event(i as u64, "m"), 0.0)
                .expect("taken");
        }
        assert_eq!(f.get("c").expect("kept").events.len(), EVENT_HISTORY);
    }

    #[test]
    fn a_message_over_its_kinds_limit_is_refused_unread_and_counted() {
        let mut f = Fleet::new();
        for kind in ["state", "events", "io", "exec_info", "net"] {
            let topic = format!("cetratus/c/{kind}");
            let (_, leaf) = parse_topic(&topic).expect("a topic");
            let limit = Kind::from_leaf(leaf).expect("a kind").max_bytes();
            // Not even JSON: refused for its size before anything reads it.
            let big = vec![b'x'; limit + 1];
            assert!(
                matches!(f.apply(&topic, &big, 0.0), Err(Ignored::TooLarge { bytes, .. }) if bytes == limit + 1),
                "{kind}"
            );
        }
        assert_eq!(f.dropped().too_large, 5);
        assert!(f.get("c").is_none(), "nothing was kept");
    }

    #[test]
    fn events_are_bounded_in_bytes_and_keep_the_newest() {
        let mut f = Fleet::new();
        let pad = "e".repeat(50_000);
        for i in 0..100 {
            f.apply("cetratus/c/events", &event(i, &pad), i as f64)
                .expect("taken");
        }
        let v = f.get("c").expect("kept");
        let held: usize = v.events.iter().map(|s| s.bytes).sum();
        assert!(held <= EVENT_HISTORY_BYTES, "{held}");
        assert!(
            v.events.len() >= EVENT_HISTORY_BYTES / 50_200,
            "{}",
            v.events.len()
        );
        assert_eq!(event_cycle(v.events.back()), Some(99));
        assert_eq!(
            f.dropped().history as usize + v.events.len(),
            100,
            "every event is kept or counted"
        );
    }

    #[test]
    fn the_fleet_is_bounded_in_bytes_and_the_biggest_plc_gives_back_first() {
        let mut f = Fleet::new();
        f.apply("cetratus/good/state", &state("A", "idle"), 0.0)
            .expect("taken");
        let net = bytes(&json!({"A": "n".repeat(3 << 20), "B": null}));
        let mut info = golden("exec_info.json");
        info[0]["first_cause"] = json!("m".repeat(3 << 20));
        let info = bytes(&info);
        // Many ids, each with a drawing and figures of 3 MiB: far more than the fleet keeps.
        for i in 0..40 {
            f.apply(&format!("cetratus/x{i}/net"), &net, 1.0)
                .expect("taken");
            f.apply(&format!("cetratus/x{i}/exec_info"), &info, 1.0)
                .expect("taken");
            assert!(f.bytes() <= FLEET_BYTES, "{} after {i}", f.bytes());
        }
        let held: usize = f.plcs.values().map(PlcView::bytes).sum();
        assert_eq!(held, f.bytes(), "the count agrees with what is kept");
        assert!(f.dropped().fleet > 0);
        // The small PLC kept its state; the newest drawing is there.
        assert!(f.get("good").is_some_and(PlcView::online));
        assert!(f.get("x39").and_then(|v| v.net.as_ref()).is_some());
    }

    #[test]
    fn a_retained_net_replaced_many_times_holds_only_the_latest() {
        let mut f = Fleet::new();
        for i in 0..50 {
            let net = json!({"A": format!("{i}{}", "n".repeat(2 << 20)), "B": null});
            f.apply("cetratus/c/net", &bytes(&net), 0.0).expect("taken");
        }
        assert!(f.bytes() < 3 << 20, "{}", f.bytes());
        f.apply("cetratus/c/net", b"", 1.0).expect("taken");
        assert_eq!(f.bytes(), 0);
    }

    #[test]
    fn exec_info_is_the_protocols_pair_and_nothing_else() {
        let mut f = Fleet::new();
        let u = f
            .apply(
                "cetratus/c/exec_info",
                &bytes(&golden("exec_info.json")),
                0.0,
            )
            .expect("taken");
        let Some(Payload::ExecInfo(pair)) = &u.data else {
            panic!("exec_info: {:?}", u.data);
        };
        assert!(pair.get(Slot::A).is_some() && pair.get(Slot::B).is_none());
        let sent = serde_json::to_value(&u.data).expect("JSON");
        assert_eq!(
            sent,
            golden("exec_info.json"),
            "the browser gets it as written"
        );
        for other in [
            br#"{"A": {"cycles": 2}, "B": null}"#.as_slice(),
            b"[1]",
            b"[{\"cycles\": 1}, null]",
        ] {
            assert!(
                matches!(
                    f.apply("cetratus/c/exec_info", other, 0.0),
                    Err(Ignored::Malformed(_))
                ),
                "{}",
                String::from_utf8_lossy(other)
            );
        }
    }

    #[test]
    fn commands_replies_and_foreign_topics_are_not_ours() {
        let mut f = Fleet::new();
        for t in [
            "cetratus/c/cmd/load",
            "other/c/state",
            "cetratus/state",
            "cetratus/c/state/extra",
        ] {
            assert_eq!(f.apply(t, b"{}", 0.0), Err(Ignored::NotOurs), "{t}");
        }
        assert!(f.list().is_empty());
    }

    #[test]
    fn malformed_payload_is_refused_without_creating_the_plc() {
        let mut f = Fleet::new();
        for (topic, payload) in [
            ("cetratus/c/state", b"not json".as_slice()),
            ("cetratus/c/io", b"[1,2]"),
            ("cetratus/c/state", br#"{"online": true, "primary": "C"}"#),
            ("cetratus/c/events", b"{}"),
        ] {
            assert!(
                matches!(f.apply(topic, payload, 0.0), Err(Ignored::Malformed(_))),
                "{topic}"
            );
        }
        assert!(f.get("c").is_none());
    }

    #[test]
    fn empty_retained_payload_clears_the_kept_net() {
        let mut f = Fleet::new();
        f.apply("cetratus/c/net", br#"{"A": "<svg/>", "B": null}"#, 0.0)
            .expect("taken");
        assert!(f.get("c").and_then(|v| v.net.as_ref()).is_some());
        let u = f.apply("cetratus/c/net", b"", 1.0).expect("taken");
        assert_eq!(u.data, None);
        assert!(f.get("c").and_then(|v| v.net.as_ref()).is_none());
    }

    #[test]
    fn snapshot_holds_everything_for_one_plc() {
        let mut f = Fleet::new();
        f.apply("cetratus/c/state", &state("B", "idle"), 5.0)
            .expect("taken");
        f.apply("cetratus/c/io", &io(1, 0), 6.0).expect("taken");
        let s = serde_json::to_value(f.snapshot("c")).expect("JSON");
        assert_eq!(s["plc"], json!("c"));
        assert_eq!(s["state"]["recv_ms"], json!(5.0));
        assert_eq!(s["state"]["data"]["primary"], json!("B"));
        assert_eq!(s["io"][0]["data"]["time_ms"], json!(1));
        assert_eq!(s["exec_info"], Value::Null);
        let unknown = serde_json::to_value(f.snapshot("unknown")).expect("JSON");
        assert_eq!(unknown["io"], json!([]));
    }

    #[test]
    fn the_number_of_plcs_is_bounded() {
        let mut f = Fleet::new();
        let e = event(0, "m");
        for i in 0..MAX_PLCS {
            f.apply(&format!("cetratus/p{i}/events"), &e, 0.0)
                .expect("taken");
        }
        assert_eq!(
            f.apply("cetratus/one-too-many/events", &e, 0.0),
            Err(Ignored::TooManyPlcs)
        );
        // Known PLCs still update.
        assert!(f.apply("cetratus/p0/events", &e, 0.0).is_ok());
    }

    #[test]
    fn plc_ids_that_cannot_be_topic_levels_are_not_ours() {
        let mut f = Fleet::new();
        for bad in [
            "cetratus//state",
            "cetratus/a+b/state",
            "cetratus/a\nb/state",
        ] {
            assert_eq!(f.apply(bad, b"{}", 0.0), Err(Ignored::NotOurs), "{bad:?}");
        }
        let long = format!("cetratus/{}/state", "x".repeat(257));
        assert_eq!(f.apply(&long, b"{}", 0.0), Err(Ignored::NotOurs));
    }
}
