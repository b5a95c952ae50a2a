//! The Monitor: the execution footprint of each container (`program_exec_info`), the divergence
//! between candidate and primary with its derived cause, drift, and a ring buffer of recent cycles
//! for the timing diagram.

use std::collections::{BTreeMap, VecDeque};

use cetratus_net::TransIdx;
use serde::Serialize;

use crate::{Blocker, Container, Summary, TimingStats};

/// A program container: A or B.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, serde::Deserialize)]
pub enum Slot {
    /// Container A (PRIMARY at boot).
    A,
    /// Container B.
    B,
}

impl Slot {
    /// The other container.
    pub fn other(self) -> Slot {
        match self {
            Slot::A => Slot::B,
            Slot::B => Slot::A,
        }
    }
    /// 0 for A, 1 for B.
    pub fn index(self) -> usize {
        match self {
            Slot::A => 0,
            Slot::B => 1,
        }
    }
    /// "A" or "B".
    pub fn name(self) -> &'static str {
        match self {
            Slot::A => "A",
            Slot::B => "B",
        }
    }
}

impl std::str::FromStr for Slot {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "A" | "a" => Ok(Slot::A),
            "B" | "b" => Ok(Slot::B),
            other => Err(format!("unknown container `{other}`; expected A or B")),
        }
    }
}

/// STATUS: whether an update is under way (DESIGN §4), or the PLC is in fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// No update under way.
    Idle,
    /// A package was accepted; the state transformation runs at the next cycle boundary.
    Setup,
    /// Both containers run; only PRIMARY's outputs are dispatched.
    Quarantine,
    /// The primary faulted: safe outputs until an operator resets.
    Fault,
}

impl Status {
    /// The lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Status::Idle => "idle",
            Status::Setup => "setup",
            Status::Quarantine => "quarantine",
            Status::Fault => "fault",
        }
    }
}

/// The derived cause of a divergence: the first transition that fired in one container and not
/// in the other, and what blocked it in the other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cause {
    /// Cycle of the divergence.
    pub cycle: u64,
    /// Program time of that cycle.
    pub time_us: u64,
    /// The container where the transition fired.
    pub fired_in: Slot,
    /// The transition, in that container's net.
    pub transition: TransIdx,
    /// Why it did not fire in the other container (places in the other container's net).
    pub blocked: Blocker,
}

/// One cycle as the timing diagram needs it; signals as bit masks in I/O-map order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CycleRecord {
    /// Cycle index.
    pub cycle: u64,
    /// Program time at the cycle's start.
    pub time_us: u64,
    /// PRIMARY during the cycle.
    pub primary: Slot,
    /// STATUS during the cycle.
    pub status: Status,
    /// Inputs.
    pub inputs: u64,
    /// Outputs of container A (`None` when empty).
    pub outputs_a: Option<u64>,
    /// Outputs of container B (`None` when empty).
    pub outputs_b: Option<u64>,
    /// What reached the Dispatcher.
    pub dispatched: u64,
}

/// The Monitor's running figures for one container.
#[derive(Clone, Debug, Default)]
pub struct ContainerStats {
    /// Scan time of this container alone.
    pub scan: TimingStats,
    /// Per I/O-map output: cycles in which this container's output differed from the primary's.
    pub divergent_cycles: Vec<u64>,
    /// The first divergence's cause since the container was installed.
    pub first_cause: Option<Cause>,
    /// The latest divergence's cause.
    pub last_cause: Option<Cause>,
    /// ‖Π·M_cand + Π_base − M_primary‖₁ at the last cycle (candidates only).
    pub drift: u64,
    /// The largest drift seen.
    pub max_drift: u64,
    /// `drift` was computed since the container was installed.
    pub drift_valid: bool,
    /// No transition enabled after the last scan.
    pub deadlocked: bool,
}

impl ContainerStats {
    /// Fresh figures for a container whose I/O map has `outputs` outputs.
    pub fn new(outputs: usize) -> Self {
        ContainerStats {
            divergent_cycles: vec![0; outputs],
            ..Default::default()
        }
    }
}

/// The Monitor: both containers' figures and the recent cycles.
#[derive(Clone, Debug)]
pub struct Monitor {
    /// Figures of A and B.
    pub stats: [ContainerStats; 2],
    /// Recent cycles, oldest first.
    pub recent: VecDeque<CycleRecord>,
    capacity: usize,
}

impl Monitor {
    /// A monitor keeping `capacity` recent cycles for an I/O map of `outputs` outputs.
    pub fn new(capacity: usize, outputs: usize) -> Self {
        Monitor {
            stats: [ContainerStats::new(outputs), ContainerStats::new(outputs)],
            recent: VecDeque::with_capacity(capacity),
            capacity: capacity.max(1),
        }
    }

    /// Appends a cycle, dropping the oldest when full (no allocation once full).
    pub fn record(&mut self, r: CycleRecord) {
        if self.recent.len() == self.capacity {
            self.recent.pop_front();
        }
        self.recent.push_back(r);
    }
}

/// A program's identity in reports.
#[derive(Clone, Debug, Serialize)]
pub struct ProgramId {
    /// Name.
    pub name: String,
    /// Version.
    pub version: String,
    /// Hex SHA-256 of the program.
    pub hash: String,
}

impl ProgramId {
    /// The identity of a container's program.
    pub fn of(c: &Container) -> Self {
        let p = c.program();
        ProgramId {
            name: p.name().to_string(),
            version: p.version().to_string(),
            hash: p.hash_hex().to_string(),
        }
    }
}

/// `program_exec_info` of one container, as published.
#[derive(Clone, Debug, Serialize)]
pub struct ExecInfo {
    /// The container.
    pub container: Slot,
    /// "primary" or "candidate".
    pub role: &'static str,
    /// Its program.
    pub program: ProgramId,
    /// Scans run since it was installed.
    pub cycles: u64,
    /// Scan time of this container.
    pub scan: Summary,
    /// Firings per transition id.
    pub firings: BTreeMap<String, u64>,
    /// Tokens per place id.
    pub marking: BTreeMap<String, u32>,
    /// Outputs by name.
    pub outputs: BTreeMap<String, serde_json::Value>,
    /// Cycles in which each output differed from the primary's (candidates only).
    pub divergence: BTreeMap<String, u64>,
    /// The derived cause of the first divergence, in words.
    pub first_cause: Option<String>,
    /// The derived cause of the latest divergence, in words.
    pub last_cause: Option<String>,
    /// Drift from the primary through the projection (candidates only).
    pub drift: u64,
    /// The largest drift seen.
    pub max_drift: u64,
    /// No transition enabled.
    pub deadlock: bool,
    /// Validation verdicts (filled by the validation issue; empty for now).
    pub verdicts: Vec<String>,
}

/// Describes a cause in words, with ids from both containers' nets.
pub fn describe_cause(cause: &Cause, fired: &Container, other: &Container) -> String {
    let t = &fired.program().net().transition(cause.transition).id;
    let (a, b) = (cause.fired_in.name(), cause.fired_in.other().name());
    let why = match cause.blocked {
        Blocker::Place(p) => format!("it was blocked by {}", other.program().net().place(p).id),
        Blocker::Inhibitor(p) => {
            format!("it was inhibited by {}", other.program().net().place(p).id)
        }
        Blocker::Capacity(p) => format!(
            "it was blocked by the capacity of {}",
            other.program().net().place(p).id
        ),
        Blocker::Guard => "its guard was false".to_string(),
        Blocker::Conflict => "it lost a conflict to a transition of higher rank".to_string(),
        Blocker::Absent => "it does not exist".to_string(),
    };
    format!("{t} fired in {a} only; in {b} {why}")
}
