//! The JSON payloads of every topic, as published today.
//!
//! Fields are declared in the order they appear on the wire today. Most payloads went through a
//! `serde_json::Value` before publication, which sorts keys, so most structs list their fields
//! alphabetically; `state` was serialised from a struct and keeps that struct's order. The one
//! exception is `exec_info`'s `program`, which shares [`ProgramInfo`] (name, version, hash) with
//! `state` and so comes out in that order instead of the sorted one: same JSON, other bytes.
//!
//! What a PLC is sent (a command's arguments) is read strictly: an unknown field is refused, so a
//! misspelt argument is never taken for its default. What a PLC publishes (`state`, `exec_info`,
//! `io`, `net`, `events`, replies) is read leniently: a field a newer PLC adds is passed over, and
//! an event kind it adds is kept as it is ([`crate::Open`]), so that PLCs of several versions can
//! share a broker, a dashboard and a command line.

use std::collections::BTreeMap;
use std::fmt;

use serde::de::{self, Deserializer, Visitor};
use serde::{Deserialize, Serialize, Serializer};
use serde_json::Value;

use crate::names::{
    ErrorCode, EventKind, LinkState, Open, Quality, Role, Slot, Status, SubstituteMode,
    VerdictKind, VerdictResult,
};
use crate::{ProtoError, Verb};

/// Largest command payload the PLC accepts (1 MiB); a bigger one gets `too_large`.
pub const MAX_PAYLOAD: usize = 1 << 20;

/// Longest a substitution may wait for its condition (`within_ms`): 24 h. A longer wait is
/// surely a mistake, and the microseconds of a larger number would not fit in 64 bits.
pub const MAX_WITHIN_MS: u64 = 24 * 3_600_000;

/// Why a `within` (in milliseconds) cannot be used; `None` when it can.
pub fn within_error(ms: u64) -> Option<String> {
    (ms > MAX_WITHIN_MS).then(|| {
        format!(
            "within_ms = {ms} is over the maximum of {MAX_WITHIN_MS} ms (24 h); give a shorter \
             wait, or none to wait until the candidate is removed"
        )
    })
}

/// Reads `within_ms`, refusing a value over [`MAX_WITHIN_MS`].
fn bounded_within<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u64>, D::Error> {
    let v = Option::<u64>::deserialize(d)?;
    match v.and_then(within_error) {
        Some(e) => Err(de::Error::custom(e)),
        None => Ok(v),
    }
}

/// Parses a payload of type `T`; `what` names it in the error (e.g. `state`).
pub fn decode<T: serde::de::DeserializeOwned>(
    what: &'static str,
    payload: &[u8],
) -> Result<T, ProtoError> {
    serde_json::from_slice(payload).map_err(|source| ProtoError::Payload { what, source })
}

/// Serialises a payload (compact JSON, as published).
pub fn encode<T: Serialize>(what: &'static str, payload: &T) -> Result<Vec<u8>, ProtoError> {
    serde_json::to_vec(payload).map_err(|source| ProtoError::Payload { what, source })
}

/// Deserialises any JSON value, `null` included, into `Some` (a plain `Option<Value>` would turn
/// an explicit `null` into `None` and drop it when written back).
fn some_value<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Value>, D::Error> {
    Value::deserialize(d).map(Some)
}

// ---------------------------------------------------------------------------------------------
// Signal values

/// The value of an input or output: a bool, an int or a real.
///
/// A real that is not finite is written as `null` (JSON has no NaN) and read back as NaN.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SignalValue {
    /// A bool.
    Bool(bool),
    /// An int.
    Int(i64),
    /// A real.
    Real(f64),
}

impl Serialize for SignalValue {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match *self {
            SignalValue::Bool(b) => s.serialize_bool(b),
            SignalValue::Int(i) => s.serialize_i64(i),
            SignalValue::Real(x) if x.is_finite() => s.serialize_f64(x),
            SignalValue::Real(_) => s.serialize_unit(),
        }
    }
}

impl<'de> Deserialize<'de> for SignalValue {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = SignalValue;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a bool, an integer, a number or null")
            }
            fn visit_bool<E: de::Error>(self, b: bool) -> Result<SignalValue, E> {
                Ok(SignalValue::Bool(b))
            }
            fn visit_i64<E: de::Error>(self, i: i64) -> Result<SignalValue, E> {
                Ok(SignalValue::Int(i))
            }
            fn visit_u64<E: de::Error>(self, u: u64) -> Result<SignalValue, E> {
                i64::try_from(u)
                    .map(SignalValue::Int)
                    .map_err(|_| E::custom(format!("integer {u} is out of the int range")))
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<SignalValue, E> {
                Ok(SignalValue::Real(x))
            }
            fn visit_unit<E: de::Error>(self) -> Result<SignalValue, E> {
                Ok(SignalValue::Real(f64::NAN))
            }
            fn visit_none<E: de::Error>(self) -> Result<SignalValue, E> {
                Ok(SignalValue::Real(f64::NAN))
            }
        }
        d.deserialize_any(V)
    }
}

/// Signal values by name.
pub type Signals = BTreeMap<String, SignalValue>;

// ---------------------------------------------------------------------------------------------
// state

/// A program's identity: in `state`'s `programs` and in `exec_info`'s `program`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProgramInfo {
    /// Name.
    pub name: String,
    /// Version.
    pub version: String,
    /// Hex SHA-256 of the program.
    pub hash: String,
}

/// The programs in A and B; an empty container is `null`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Programs {
    /// Container A.
    #[serde(rename = "A")]
    pub a: Option<ProgramInfo>,
    /// Container B.
    #[serde(rename = "B")]
    pub b: Option<ProgramInfo>,
}

impl Programs {
    /// The program of one container.
    pub fn get(&self, slot: Slot) -> Option<&ProgramInfo> {
        match slot {
            Slot::A => self.a.as_ref(),
            Slot::B => self.b.as_ref(),
        }
    }
}

/// Timing statistics of a duration, in nanoseconds (all zero before the first sample).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TimingSummary {
    /// Samples recorded.
    pub count: u64,
    /// The latest sample.
    pub last_ns: u64,
    /// The largest sample.
    pub max_ns: u64,
    /// The mean.
    pub mean_ns: u64,
    /// The smallest sample.
    pub min_ns: u64,
    /// The median (upper edge of its histogram bucket).
    pub p50_ns: u64,
    /// The 99th percentile (upper edge of its histogram bucket).
    pub p99_ns: u64,
}

/// The `cycle` object of `state`: the scan loop's figures.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CycleFigures {
    /// Start-to-start time of the scan loop.
    pub cycle: TimingSummary,
    /// Cycles run since start.
    pub cycles: u64,
    /// Actual start minus planned start of each cycle.
    pub latency: TimingSummary,
    /// Cycles whose body ran past the next planned start.
    pub overruns: u64,
    /// Scan time of the primary container.
    pub scan: TimingSummary,
    /// Program time, in milliseconds.
    pub time_ms: u64,
    /// `"<name> <version>"` of the update under way; `null` when none.
    pub update: Option<String>,
}

/// The `control` object of `state`: what the PLC's control plane turned away or dropped since it
/// started, so that a flood shows where it is seen and not only in the PLC's log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ControlCounters {
    /// Commands answered `busy` because a queue was full, in entries or in bytes.
    pub commands_busy: u64,
    /// Commands dropped unanswered: they came faster than they could be read.
    pub commands_dropped: u64,
    /// Events and replies of the PLC that the MQTT client had no room for.
    pub messages_lost: u64,
    /// Events and replies dropped before the MQTT client because it was behind.
    pub events_dropped: u64,
    /// `state`, `io` and `exec_info` publications skipped because the publisher was behind
    /// (the next one carries on).
    pub snapshots_skipped: u64,
}

/// The retained `state` of a PLC that is online.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct StateMsg {
    /// Always `true` here; see [`StatePayload::Offline`].
    pub online: bool,
    /// PRIMARY.
    pub primary: Slot,
    /// STATUS.
    pub status: Status,
    /// Programs in A and B.
    pub programs: Programs,
    /// The scan loop's figures.
    pub cycle: CycleFigures,
    /// What the control plane turned away or dropped; absent from PLCs older than it.
    #[serde(default)]
    pub control: ControlCounters,
    /// Present while the state directory cannot be written; absent when it can.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub persist_fault: Option<PersistFault>,
    /// The PLC's labels (`[labels]` of its local configuration), by which a selector picks it;
    /// absent when it has none.
    #[serde(default, skip_serializing_if = "crate::Labels::is_empty")]
    pub labels: crate::Labels,
    /// The update policy of its local configuration that a fleet rollout holds its plan against;
    /// absent from PLCs that predate it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub updates: Option<UpdatePolicy>,
}

/// The `updates` object of `state`: what the PLC's own `[updates]` policy enforces of every
/// update, so that a rollout plan may be checked to be at least as strict (docs/fleet.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct UpdatePolicy {
    /// The probation window after a substitution, in milliseconds of program time (0: none).
    pub probation_ms: u64,
    /// Whether a substitution needs a passing twin verdict.
    pub require_verdict: bool,
}

/// The state directory cannot be written: the PLC runs on, and tries again at every snapshot,
/// but a restart now would start from the state saved at `saved_cycle` (docs/persistence.md,
/// *When the disk fails*).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PersistFault {
    /// The last write error, in words.
    pub error: String,
    /// The cycle at which writes began to fail.
    pub since_cycle: u64,
    /// The cycle of the last state saved in this run; absent when none was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub saved_cycle: Option<u64>,
}

/// What the retained `state` topic holds: the PLC's state, or `{"online": false}` (its last
/// will, and what a clean shutdown publishes).
// Not boxed: a state message is built once per publish and moved, never stored in bulk, and a
// `Box` would only make matching on it clumsier.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StatePayload {
    /// The PLC is online.
    Online(StateMsg),
    /// `{"online": false}`.
    Offline,
}

impl StatePayload {
    /// The exact bytes of the offline message (the last will).
    pub const OFFLINE_JSON: &'static [u8] = br#"{"online":false}"#;

    /// Whether the PLC is online.
    pub fn is_online(&self) -> bool {
        matches!(self, StatePayload::Online(_))
    }
}

impl Serialize for StatePayload {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        struct Offline {
            online: bool,
        }
        match self {
            StatePayload::Online(m) => m.serialize(s),
            StatePayload::Offline => Offline { online: false }.serialize(s),
        }
    }
}

impl<'de> Deserialize<'de> for StatePayload {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = Value::deserialize(d)?;
        match v.get("online") {
            // A newer PLC may say more about going offline; this build reads the flag.
            Some(Value::Bool(false)) => Ok(StatePayload::Offline),
            _ => serde_json::from_value(v)
                .map(StatePayload::Online)
                .map_err(de::Error::custom),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// exec_info

/// A validation verdict on a candidate program.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    /// Figures that go with it, by name.
    pub figures: BTreeMap<String, f64>,
    /// Where it comes from.
    pub kind: VerdictKind,
    /// Why, in words.
    pub reasons: Vec<String>,
    /// What it says.
    pub result: VerdictResult,
}

/// `program_exec_info` of one container, as published.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExecInfo {
    /// The container.
    pub container: Slot,
    /// Scans run since it was installed.
    pub cycles: u64,
    /// No transition enabled.
    pub deadlock: bool,
    /// The stall watchdog sees a stall (the primary only); absent when false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub stall: bool,
    /// Cycles in which each output differed from the primary's (candidates only).
    pub divergence: BTreeMap<String, u64>,
    /// Drift from the primary through the projection (candidates only).
    pub drift: u64,
    /// Firings per transition id.
    pub firings: BTreeMap<String, u64>,
    /// The derived cause of the first divergence, in words (`null` when none).
    pub first_cause: Option<String>,
    /// The quality of the inputs it scanned, per field device (absent without field I/O, and
    /// from PLCs that predate it).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub input_quality: Vec<InputQuality>,
    /// The derived cause of the latest divergence, in words (`null` when none).
    pub last_cause: Option<String>,
    /// Tokens per place id.
    pub marking: BTreeMap<String, u32>,
    /// The largest drift seen.
    pub max_drift: u64,
    /// Outputs by name.
    pub outputs: Signals,
    /// Its program.
    pub program: ProgramInfo,
    /// Primary or candidate.
    pub role: Role,
    /// Scan time of this container.
    pub scan: TimingSummary,
    /// Validation verdicts.
    pub verdicts: Vec<Verdict>,
    /// A candidate's quarantine compared with the twin's divergence signature: how far it has
    /// come (absent without a signature, and from PLCs that predate it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coverage: Option<Coverage>,
    /// What the update's package declares it changes on purpose (the container that runs the
    /// update's program; absent when it declares nothing, and from PLCs that predate it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub changes: Option<DeclaredChanges>,
}

/// The changes an update's package declares it makes on purpose (docs/package-format.md,
/// *Declared changes*).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DeclaredChanges {
    /// Outputs whose values may differ from the old program's.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub outputs: Vec<String>,
    /// The least share of the old program's production it may drop to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub throughput_share: Option<f64>,
}

/// How far a quarantine's comparison with the twin's divergence signature has come
/// (docs/live-update.md, *The twin against the quarantine*).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Coverage {
    /// Cycles of the candidate compared since the signature came.
    pub cycles: u64,
    /// Outputs the twin showed diverging that the quarantine has shown diverging too.
    pub outputs_covered: u64,
    /// Outputs the twin showed diverging.
    pub outputs_expected: u64,
    /// Kinds of divergence the twin never showed.
    pub unexplained: u64,
    /// Kinds of divergence in the twin's signature.
    pub signature_kinds: u64,
}

/// What one field device's inputs were worth in the last cycle (docs/io.md, *Quality*).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputQuality {
    /// The device's name in the I/O configuration.
    pub device: String,
    /// Its connection.
    pub link: LinkState,
    /// Cycles in a row without a complete read.
    pub missed_cycles: u64,
    /// Its inputs' quality.
    pub quality: Quality,
}

/// The `exec_info` message (and the `result` of `cmd/exec_info`): `[A | null, B | null]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct ExecInfoMsg(pub [Option<ExecInfo>; 2]);

impl ExecInfoMsg {
    /// The figures of one container (`None` when it is empty).
    pub fn get(&self, slot: Slot) -> Option<&ExecInfo> {
        self.0[slot.index()].as_ref()
    }
}

// ---------------------------------------------------------------------------------------------
// io

/// The signal names of `io`, in I/O-map order (bit 0 of a sample's masks is the first name).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct IoNames {
    /// Input names.
    pub inputs: Vec<String>,
    /// Output names.
    pub outputs: Vec<String>,
}

/// The most words a [`SignalMask`] may have on the wire: 4096 signals.
pub const MAX_MASK_WORDS: usize = 128;

/// Signals as a bit mask: bit `i` of word `i / 32` is signal `i` (the signal is true, or a
/// nonzero integer). On the wire a JSON number when every set bit is below bit 53, so that
/// JavaScript reads it exactly (bit 0 is the first signal); otherwise an array of 32-bit words,
/// the first signals' word first.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SignalMask(Vec<u32>);

impl SignalMask {
    /// The mask of 64-bit words (bit `i` of word `i / 64` is signal `i`).
    pub fn from_u64_words(words: &[u64]) -> Self {
        SignalMask(
            words
                .iter()
                .flat_map(|&x| [x as u32, (x >> 32) as u32])
                .collect(),
        )
        .trimmed()
    }

    /// Signal `i`'s bit.
    pub fn get(&self, i: usize) -> bool {
        self.0.get(i / 32).is_some_and(|w| w & (1 << (i % 32)) != 0)
    }

    /// The 32-bit words, the first signals' first (trailing zero words dropped).
    pub fn words(&self) -> &[u32] {
        &self.0
    }

    fn small(&self) -> Option<u64> {
        match self.0[..] {
            [] => Some(0),
            [lo] => Some(u64::from(lo)),
            [lo, hi] if hi < 1 << 21 => Some(u64::from(lo) | u64::from(hi) << 32),
            _ => None,
        }
    }
}

impl From<u64> for SignalMask {
    fn from(v: u64) -> Self {
        SignalMask::from_u64_words(&[v])
    }
}

impl Serialize for SignalMask {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.small() {
            Some(v) => s.serialize_u64(v),
            None => self.0.serialize(s),
        }
    }
}

impl<'de> Deserialize<'de> for SignalMask {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Wire {
            Number(u64),
            Words(Vec<u32>),
        }
        match Wire::deserialize(d).map_err(|_| {
            de::Error::custom(
                "a signal mask is a number below 2^53 or an array of at most 128 32-bit words",
            )
        })? {
            Wire::Number(v) if v < 1 << 53 => Ok(SignalMask::from(v)),
            Wire::Words(w) if w.len() <= MAX_MASK_WORDS => Ok(SignalMask(w).trimmed()),
            _ => Err(de::Error::custom(
                "a signal mask is a number below 2^53 or an array of at most 128 32-bit words",
            )),
        }
    }
}

impl SignalMask {
    fn trimmed(mut self) -> Self {
        while self.0.last() == Some(&0) {
            self.0.pop();
        }
        self
    }
}

/// One cycle of the timing diagram; on the wire the array
/// `[time_ms, PRIMARY, STATUS, inputs, outputs_a | null, outputs_b | null, dispatched]`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(from = "SampleWire", into = "SampleWire")]
pub struct Sample {
    /// Program time at the cycle's start, in milliseconds.
    pub time_ms: u64,
    /// PRIMARY during the cycle.
    pub primary: Slot,
    /// STATUS during the cycle.
    pub status: Status,
    /// Inputs, as a bit mask.
    pub inputs: SignalMask,
    /// Outputs of A (`None` when empty), as a bit mask.
    pub outputs_a: Option<SignalMask>,
    /// Outputs of B (`None` when empty), as a bit mask.
    pub outputs_b: Option<SignalMask>,
    /// What reached the Dispatcher, as a bit mask.
    pub dispatched: SignalMask,
}

#[derive(Clone, Serialize, Deserialize)]
struct SampleWire(
    u64,
    Slot,
    Status,
    SignalMask,
    Option<SignalMask>,
    Option<SignalMask>,
    SignalMask,
);

impl From<SampleWire> for Sample {
    fn from(w: SampleWire) -> Self {
        Sample {
            time_ms: w.0,
            primary: w.1,
            status: w.2,
            inputs: w.3,
            outputs_a: w.4,
            outputs_b: w.5,
            dispatched: w.6,
        }
    }
}

impl From<Sample> for SampleWire {
    fn from(s: Sample) -> Self {
        SampleWire(
            s.time_ms,
            s.primary,
            s.status,
            s.inputs,
            s.outputs_a,
            s.outputs_b,
            s.dispatched,
        )
    }
}

/// The `io` message: the latest images by name and every cycle since the previous `io`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IoMsg {
    /// Outputs that reached the Dispatcher.
    pub dispatched: Signals,
    /// Inputs.
    pub inputs: Signals,
    /// Signal names in I/O-map order.
    pub names: IoNames,
    /// Outputs of A (`null` when empty).
    pub outputs_a: Option<Signals>,
    /// Outputs of B (`null` when empty).
    pub outputs_b: Option<Signals>,
    /// Every cycle since the previous message.
    pub samples: Vec<Sample>,
    /// Program time, in milliseconds.
    pub time_ms: u64,
    /// Wall clock (Unix ms, with fractions) when the message left the PLC; stamped by the MQTT
    /// side, so absent until then.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unix_ms: Option<f64>,
}

// ---------------------------------------------------------------------------------------------
// net

/// The retained `net` message: each container's net as SVG, `null` when empty.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetMsg {
    /// Container A's net.
    #[serde(rename = "A")]
    pub a: Option<String>,
    /// Container B's net.
    #[serde(rename = "B")]
    pub b: Option<String>,
}

// ---------------------------------------------------------------------------------------------
// events

/// An `events` message. Runtime events carry `cycle` and `time_us`; the control plane's own
/// (`command_rejected`, `command_received`, and `refused` from the command preparer) do not.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EventMsg {
    /// Cycle index at which it happened (runtime events only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cycle: Option<u64>,
    /// Figures that go with it, free-form; absent when `null`.
    #[serde(default, skip_serializing_if = "Value::is_null")]
    pub detail: Value,
    /// What happened, e.g. `load_accepted`, `substituted`, `command_rejected`; a kind this
    /// build does not know (a newer PLC's) is kept as it was read.
    pub kind: Open<EventKind>,
    /// In words: what, why, and what to do.
    pub message: String,
    /// Program time in microseconds (runtime events only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_us: Option<u64>,
}

// ---------------------------------------------------------------------------------------------
// replies

/// The `error` object of a failed reply.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ErrorBody {
    /// Machine-readable reason.
    pub code: ErrorCode,
    /// What was wrong and what to do.
    pub message: String,
}

/// The `result` of an accepted `load`, `substitute`, `remove`, `abort` or `reset`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Accepted {
    /// Always `true`.
    pub accepted: bool,
    /// A load's: the analysis gate's verdict on the candidate (absent for the other verbs, and
    /// from PLCs that predate it).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub verdicts: Vec<Verdict>,
}

/// A reply to a command, on the response topic (or the payload's `reply_to`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reply {
    /// The command's `correlation` field, echoed when it had one (any JSON, `null` included).
    #[serde(
        default,
        deserialize_with = "some_value",
        skip_serializing_if = "Option::is_none"
    )]
    pub correlation: Option<Value>,
    /// Why it failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorBody>,
    /// Whether the command was accepted.
    pub ok: bool,
    /// A number unique per command since the PLC started.
    pub request_id: u64,
    /// What the command produced on success: [`Accepted`], or for `exec_info` an
    /// [`ExecInfoMsg`].
    #[serde(
        default,
        deserialize_with = "some_value",
        skip_serializing_if = "Option::is_none"
    )]
    pub result: Option<Value>,
    /// The verb answered; the topic's last level as sent (at most 64 characters) when it was
    /// not a known verb, so it is text rather than a [`Verb`].
    pub verb: String,
}

impl Reply {
    /// A success answering `verb`.
    pub fn ok(verb: &str, request_id: u64, result: Option<Value>) -> Self {
        Reply {
            correlation: None,
            error: None,
            ok: true,
            request_id,
            result,
            verb: verb.to_string(),
        }
    }

    /// A failure answering `verb`.
    pub fn err(verb: &str, request_id: u64, code: ErrorCode, message: impl Into<String>) -> Self {
        Reply {
            correlation: None,
            error: Some(ErrorBody {
                code,
                message: message.into(),
            }),
            ok: false,
            request_id,
            result: None,
            verb: verb.to_string(),
        }
    }

    /// The same reply echoing the command's `correlation`.
    pub fn with_correlation(mut self, correlation: Option<Value>) -> Self {
        self.correlation = correlation;
        self
    }
}

// ---------------------------------------------------------------------------------------------
// commands

/// Arguments of `load`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadArgs {
    /// The update package file, base64 (standard alphabet).
    pub package_b64: String,
}

/// Arguments of `substitute`; every field may be left out (the CLI writes them all, `null` when
/// not given).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubstituteArgs {
    /// `keep` even with drift.
    #[serde(default)]
    pub force: bool,
    /// `retransform` (the default) or `keep`.
    #[serde(default)]
    pub mode: Option<SubstituteMode>,
    /// Wait until this predicate over the primary marking holds (guard syntax).
    #[serde(default)]
    pub when: Option<String>,
    /// Give up waiting after this many milliseconds (at most [`MAX_WITHIN_MS`]).
    #[serde(default, deserialize_with = "bounded_within")]
    pub within_ms: Option<u64>,
}

/// The arguments of `remove`, `abort`, `reset`, `exec_info`, `revert` and `accept`: none, `{}`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoArgs {}

/// A command body (what is signed in an envelope), without the reply fields: the package in
/// base64 for `load`, the arguments of `substitute`.
pub type Command = cetratus_vocab::Command<LoadArgs, SubstituteArgs>;

/// Reads the body of a `verb` command (the reply fields `reply_to`, `correlation` and `envelope`
/// already removed); unknown fields are refused.
pub fn command_from_body(verb: Verb, body: Value) -> Result<Command, ProtoError> {
    let err = |source| ProtoError::Payload {
        what: "command",
        source,
    };
    match verb {
        Verb::Load => serde_json::from_value(body).map(Command::Load).map_err(err),
        Verb::Substitute => serde_json::from_value(body)
            .map(Command::Substitute)
            .map_err(err),
        bare => {
            let NoArgs {} = serde_json::from_value(body).map_err(err)?;
            // A verb without arguments here, so `bare` has its command.
            Ok(Command::bare(bare).unwrap_or(Command::ExecInfo))
        }
    }
}

/// A command's body as JSON, as the CLI and the dashboard send it.
pub fn command_body(command: &Command) -> Value {
    let v = match command {
        Command::Load(a) => serde_json::to_value(a),
        Command::Substitute(a) => serde_json::to_value(a),
        _ => serde_json::to_value(NoArgs {}),
    };
    v.unwrap_or_else(|_| Value::Object(serde_json::Map::new()))
}

/// The fields of a command payload that say where the reply goes (MQTT 3.1.1 clients); the
/// rest of the payload is the command body, or an `envelope` that holds it signed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReplyFields {
    /// The topic to publish the reply on (the MQTT 5 response topic wins over it).
    pub reply_to: Option<String>,
    /// Any JSON value, echoed in the reply.
    pub correlation: Option<Value>,
}

impl ReplyFields {
    /// The names of the fields that are not part of a command's arguments.
    pub const META_FIELDS: [&'static str; 3] = ["reply_to", "correlation", "envelope"];

    /// Takes `reply_to` and `correlation` out of a payload object, and `envelope` with them
    /// (returned for the signature check), leaving the command's arguments.
    pub fn split(body: &mut serde_json::Map<String, Value>) -> (ReplyFields, Option<Value>) {
        let reply_to = match body.remove("reply_to") {
            Some(Value::String(s)) => Some(s),
            _ => None,
        };
        let correlation = body.remove("correlation");
        let envelope = body.remove("envelope");
        (
            ReplyFields {
                reply_to,
                correlation,
            },
            envelope,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_within_over_24_hours_is_refused_with_the_maximum_named() {
        let ok = command_from_body(
            Verb::Substitute,
            serde_json::json!({"within_ms": MAX_WITHIN_MS}),
        );
        assert!(ok.is_ok(), "{ok:?}");
        for ms in [MAX_WITHIN_MS + 1, u64::MAX / 1000 + 1, u64::MAX] {
            let e = command_from_body(Verb::Substitute, serde_json::json!({"within_ms": ms}))
                .expect_err("refused")
                .to_string();
            assert!(e.contains("within_ms") && e.contains("24 h"), "{e}");
        }
        let none = command_from_body(Verb::Substitute, serde_json::json!({"within_ms": null}));
        assert!(matches!(
            none,
            Ok(Command::Substitute(SubstituteArgs {
                within_ms: None,
                ..
            }))
        ));
    }
}
