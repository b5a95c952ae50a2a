//! The paper's U.1/U.2 experiment on the Vernadat cell, embedded so that it runs from any
//! directory.
//!
//! [`prepare`] writes the example into a directory, makes a demo signing key, and builds and
//! signs U.1 and U.2. [`scripted`] plays the experiment in virtual time through the node loop and
//! records every scan in which anything changed: the rows of a table like the paper's Fig. 7
//! ([`table`]) and an SVG timing diagram ([`diagram`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use cetratus_io::TwinDriver;
use cetratus_program::{
    build_package, KeyPair, PackageError, Program, ProgramError, TrustStore, Value,
};
use cetratus_runtime::trace::{Lane, LaneValue, TimingDiagram};
use cetratus_runtime::{
    Command, Event, EventKind, LoopTiming, Plc, Slot, SubstituteMode, SubstituteRequest,
};
use cetratus_twin::{Plant, Twin, TwinKind};
use serde::Serialize;

use crate::clock::MonotonicStopwatch;
use crate::gate::GatePolicy;
use crate::load::LoadPolicy;
use crate::node::{Node, NodeOptions};

/// Why the demo cannot run.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// A file of the demo directory could not be written or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A key or a package could not be made.
    #[error(transparent)]
    Package(#[from] PackageError),
    /// The example program does not load.
    #[error(transparent)]
    Program(#[from] ProgramError),
    /// The twin does not fit the program.
    #[error(transparent)]
    Io2(#[from] cetratus_io::IoError),
    /// A step of the experiment did not happen.
    #[error("{0}")]
    Experiment(String),
    /// A package of the experiment was refused.
    #[error(transparent)]
    Load(#[from] crate::load::LoadRefusal),
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> DemoError + '_ {
    move |source| DemoError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// The Vernadat example (program, U.1, U.2 and their package manifests), embedded so that the
/// demo and `cetratus bench` run from any directory.
pub const FILES: [(&str, &str); 8] = [
    (
        "vernadat.toml",
        include_str!("../../../examples/vernadat/vernadat.toml"),
    ),
    (
        "vernadat.pnml",
        include_str!("../../../examples/vernadat/vernadat.pnml"),
    ),
    (
        "u1.toml",
        include_str!("../../../examples/vernadat/u1.toml"),
    ),
    (
        "u1.pnml",
        include_str!("../../../examples/vernadat/u1.pnml"),
    ),
    (
        "u2.toml",
        include_str!("../../../examples/vernadat/u2.toml"),
    ),
    (
        "u2.pnml",
        include_str!("../../../examples/vernadat/u2.pnml"),
    ),
    (
        "u1.package.toml",
        include_str!("../../../examples/vernadat/u1.package.toml"),
    ),
    (
        "u2.package.toml",
        include_str!("../../../examples/vernadat/u2.package.toml"),
    ),
];

/// The files the demo works with.
pub struct DemoFiles {
    /// The initial program.
    pub program: PathBuf,
    /// U.1, signed.
    pub u1: Vec<u8>,
    /// U.2, signed.
    pub u2: Vec<u8>,
    /// Where U.1 was written.
    pub u1_path: PathBuf,
    /// Where U.2 was written.
    pub u2_path: PathBuf,
    /// Trusts the demo key.
    pub trust: TrustStore,
}

/// The demo's directory: `$XDG_DATA_HOME/cetratus/demo`, `~/.local/share/cetratus/demo`, or
/// `.cetratus-demo` here.
pub fn default_dir() -> PathBuf {
    crate::dirs::xdg("XDG_DATA_HOME", ".local/share").map_or_else(
        || PathBuf::from(".cetratus-demo"),
        |d| d.join("cetratus/demo"),
    )
}

/// Writes the example, makes the key and builds the packages where missing; `say` is told what
/// was made.
pub fn prepare(dir: &Path, mut say: impl FnMut(String)) -> Result<DemoFiles, DemoError> {
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    for (name, text) in FILES {
        let path = dir.join(name);
        if std::fs::read_to_string(&path).ok().as_deref() != Some(text) {
            std::fs::write(&path, text).map_err(io_err(&path))?;
        }
    }
    let key_path = dir.join("demo.key");
    let key = if key_path.exists() {
        KeyPair::load(&key_path)?
    } else {
        let k = KeyPair::generate();
        k.save(&key_path)?;
        say(format!(
            "made a demo signing key {} (id {})",
            key_path.display(),
            k.key_id()
        ));
        k
    };
    let trusted = dir.join("trusted");
    std::fs::create_dir_all(&trusted).map_err(io_err(&trusted))?;
    let pub_src = KeyPair::public_path(&key_path);
    std::fs::copy(&pub_src, trusted.join("demo.pub")).map_err(io_err(&pub_src))?;
    let trust = TrustStore::load_dir(&trusted)?;
    // Built now, as an engineer would build them: `created` is the wall clock's.
    let created = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let build = |manifest: &str, out: &str| -> Result<Vec<u8>, DemoError> {
        let (bytes, _report) = build_package(&dir.join(manifest), Some(&key), created)?;
        let path = dir.join(out);
        std::fs::write(&path, &bytes).map_err(io_err(&path))?;
        Ok(bytes)
    };
    let u1 = build("u1.package.toml", "u1.cpkg")?;
    let u2 = build("u2.package.toml", "u2.cpkg")?;
    say(format!(
        "built and signed {} and {}",
        dir.join("u1.cpkg").display(),
        dir.join("u2.cpkg").display()
    ));
    Ok(DemoFiles {
        u1_path: dir.join("u1.cpkg"),
        u2_path: dir.join("u2.cpkg"),
        program: dir.join("vernadat.toml"),
        u1,
        u2,
        trust,
    })
}

/// One scan in which anything changed.
#[derive(Debug, Serialize)]
pub struct Step {
    /// Scan index.
    pub step: u64,
    /// Virtual time at the scan's start, ms.
    pub time_ms: f64,
    /// PRIMARY.
    pub primary: Slot,
    /// STATUS.
    pub status: &'static str,
    /// Inputs by name.
    pub inputs: BTreeMap<String, bool>,
    /// Outputs of A by name, or null.
    pub outputs_a: Option<BTreeMap<String, bool>>,
    /// Outputs of B by name, or null.
    pub outputs_b: Option<BTreeMap<String, bool>>,
    /// Dispatched outputs by name.
    pub dispatched: BTreeMap<String, bool>,
    /// Marking of A by place id, or null.
    pub marking_a: Option<BTreeMap<String, u32>>,
    /// Marking of B by place id, or null.
    pub marking_b: Option<BTreeMap<String, u32>>,
}

/// The record of a scripted run.
#[derive(Debug, Serialize)]
pub struct DemoRecord {
    /// The steps.
    pub steps: Vec<Step>,
    /// The events.
    pub events: Vec<Event>,
    /// Parts finished by the twin.
    pub parts_finished: u64,
    /// Faults the twin saw.
    pub faults: Vec<String>,
    /// program_exec_info at the end of each quarantine, in order, as the wire carries it.
    pub exec_info: Vec<cetratus_proto::ExecInfoMsg>,
}

fn named(names: &[String], values: &[Value]) -> BTreeMap<String, bool> {
    names
        .iter()
        .zip(values)
        .map(|(n, v)| (n.clone(), matches!(v, Value::Bool(true))))
        .collect()
}

/// What makes a step differ from the previous one.
type StepKey = (
    Slot,
    &'static str,
    Vec<Value>,
    Vec<Option<Vec<Value>>>,
    Vec<Option<Vec<u32>>>,
);

struct Recorder {
    steps: Vec<Step>,
    last_key: Option<StepKey>,
}

impl Recorder {
    fn observe(&mut self, plc: &Plc, now_us: u64) {
        let outs: Vec<Option<Vec<Value>>> = [Slot::A, Slot::B]
            .iter()
            .map(|&s| plc.outputs_of(s).map(|o| o.to_vec()))
            .collect();
        let marks: Vec<Option<Vec<u32>>> = [Slot::A, Slot::B]
            .iter()
            .map(|&s| plc.container(s).map(|c| c.marking().to_vec()))
            .collect();
        let key = (
            plc.primary(),
            plc.status().as_str(),
            plc.inputs().to_vec(),
            outs,
            marks,
        );
        if self.last_key.as_ref() == Some(&key) {
            return;
        }
        let io_out = plc.io_outputs();
        let marking = |s: Slot| {
            plc.container(s).map(|c| {
                c.program()
                    .net()
                    .places()
                    .iter()
                    .zip(c.marking())
                    .map(|(p, &m)| (p.id.clone(), m))
                    .collect()
            })
        };
        self.steps.push(Step {
            step: plc.cycles() - 1,
            time_ms: now_us as f64 / 1e3,
            primary: plc.primary(),
            status: plc.status().as_str(),
            inputs: named(plc.io_inputs(), plc.inputs()),
            outputs_a: plc.outputs_of(Slot::A).map(|o| named(io_out, o)),
            outputs_b: plc.outputs_of(Slot::B).map(|o| named(io_out, o)),
            dispatched: named(io_out, plc.dispatched()),
            marking_a: marking(Slot::A),
            marking_b: marking(Slot::B),
        });
        self.last_key = Some(key);
    }
}

const PERIOD_US: u64 = 10_000;

struct Run {
    node: Node<TwinDriver<Twin>>,
    load: LoadPolicy,
    now: u64,
    rec: Recorder,
    events: Vec<Event>,
}

impl Run {
    fn step(&mut self) {
        let idle = LoopTiming::default();
        if let Some(ev) = self.node.step(self.now, &idle) {
            self.events.extend(ev);
        }
        self.rec.observe(self.node.plc(), self.now);
        self.now += PERIOD_US;
    }
    fn run_until(&mut self, t_us: u64) {
        while self.now < t_us {
            self.step();
        }
    }
    fn run_while(&mut self, max_us: u64, mut cond: impl FnMut(&Plc) -> bool) {
        let end = self.now + max_us;
        while self.now < end && cond(self.node.plc()) {
            self.step();
        }
    }
    fn command(&mut self, cmd: Command) -> Result<(), DemoError> {
        let (r, ev) = self.node.command(cmd);
        self.events.extend(ev);
        r.map_err(|e| DemoError::Experiment(e.to_string()))
    }
    /// Prepares and gates a package as a run's preparer does, then loads it.
    fn load(&mut self, bytes: &[u8]) -> Result<(), DemoError> {
        let ctx = self.node.plc().update_context();
        let prepared = self.load.prepare(&ctx, bytes)?;
        self.command(Command::Load(Box::new(prepared)))
    }
    fn substitute(&mut self) -> Result<(), DemoError> {
        self.command(Command::Substitute(SubstituteRequest::now(
            SubstituteMode::Retransform,
        )))?;
        self.step();
        Ok(())
    }
    fn exec_info(&self) -> cetratus_proto::ExecInfoMsg {
        crate::wire::exec_info_msg(self.node.plc())
    }
}

/// Plays the paper's experiment in virtual time; each load goes through the analysis gate
/// with `gate`, as in a run.
pub fn scripted(files: &DemoFiles, gate: GatePolicy) -> Result<DemoRecord, DemoError> {
    let program = Arc::new(Program::load(&files.program)?);
    let twin = TwinKind::Vernadat.build(1);
    let io = TwinDriver::new(twin, program.inputs(), program.outputs())?;
    let mut plc = Plc::new(program, 0, MonotonicStopwatch::boxed());
    plc.use_virtual_time(PERIOD_US);
    let load = LoadPolicy {
        trust: files.trust.clone(),
        unsigned: cetratus_program::Unsigned::Refused,
        gate,
    };
    let opts = NodeOptions {
        base_us: 0,
        load: load.clone(),
        record_trace: false,
        watch: Vec::new(),
        progress_every: None,
    };
    let mut r = Run {
        load,
        node: Node::new(plc, io, opts),
        now: 0,
        rec: Recorder {
            steps: Vec::new(),
            last_key: None,
        },
        events: Vec::new(),
    };
    let mut exec_info = Vec::new();
    r.step();
    r.run_until(10_000_000);

    // U.1 into B; quarantine until the buffer is full in A's eyes and B keeps going.
    r.load(&files.u1)?;
    r.step();
    let b = Slot::B.index();
    r.run_while(300_000_000, |plc| {
        plc.monitor().stats[b]
            .divergent_cycles
            .iter()
            .all(|&n| n == 0)
    });
    r.run_until(r.now + 10_000_000);
    exec_info.push(r.exec_info());
    r.substitute()?;
    if r.node.plc().primary() != Slot::B {
        return Err(DemoError::Experiment(format!(
            "U.1 was not substituted: {:?}",
            r.events.last()
        )));
    }
    r.run_until(r.now + 10_000_000);

    // U.2 into A with the generated transformation; quarantine over a full processing cycle, so
    // that LM1 and LM2 show in the candidate's outputs and the drift shows.
    r.load(&files.u2)?;
    r.step();
    let a = Slot::A.index();
    let lm: Vec<usize> = ["LM1", "LM2"]
        .iter()
        .filter_map(|n| r.node.plc().io_outputs().iter().position(|o| o == n))
        .collect();
    let mut seen = vec![false; lm.len()];
    let mut drift_seen = false;
    r.run_while(120_000_000, |plc| {
        if let Some(o) = plc.outputs_of(Slot::A) {
            for (s, &k) in seen.iter_mut().zip(&lm) {
                *s |= matches!(o[k], Value::Bool(true));
            }
        }
        drift_seen |= plc.monitor().stats[a].drift > 0;
        !(seen.iter().all(|&s| s) && drift_seen)
    });
    r.run_until(r.now + 5_000_000);
    exec_info.push(r.exec_info());
    r.substitute()?;
    if r.node.plc().primary() != Slot::A {
        return Err(DemoError::Experiment(format!(
            "U.2 was not substituted: {:?}",
            r.events.last()
        )));
    }
    r.run_until(r.now + 20_000_000);

    Ok(DemoRecord {
        parts_finished: r
            .node
            .io()
            .plant()
            .counters()
            .get("parts_finished")
            .unwrap_or(0),
        faults: r
            .node
            .io()
            .plant()
            .faults()
            .iter()
            .map(|f| f.to_string())
            .collect(),
        steps: r.rec.steps,
        events: r.events,
        exec_info,
    })
}

/// The SVG timing diagram of a scripted run (the paper's Fig. 7): PRIMARY and STATUS as lanes,
/// then inputs, the outputs of A and of B (absent while the container is empty) and the dispatched
/// outputs; time in seconds and in scan steps.
pub fn diagram(rec: &DemoRecord, end_ms: f64) -> TimingDiagram {
    let mut d = TimingDiagram::new(
        "Vernadat cell: U.1 then U.2, live (PRIMARY, STATUS, inputs, outputs of A and B, dispatched)",
        (end_ms * 1e3) as u64,
    );
    d.scan_period_us = Some(PERIOD_US);
    let Some(first) = rec.steps.first() else {
        return d;
    };
    let at = |s: &Step| (s.time_ms * 1e3) as u64;
    let lane = |group: &str, name: &str, pick: &dyn Fn(&Step) -> LaneValue| Lane {
        label: name.to_string(),
        group: group.to_string(),
        changes: rec.steps.iter().map(|s| (at(s), pick(s))).collect(),
    };
    let level = |v: Option<bool>| LaneValue::Level(v.unwrap_or(false));
    // An empty container has no outputs at all: drawn as absent, not as every output off.
    let of = |o: &Option<BTreeMap<String, bool>>, n: &str| {
        o.as_ref().map_or(LaneValue::Absent, |o| {
            LaneValue::Level(o.get(n).copied().unwrap_or(false))
        })
    };
    d.lanes.push(lane("update", "PRIMARY", &|s| {
        LaneValue::Text(s.primary.as_str().to_string())
    }));
    d.lanes.push(lane("update", "STATUS", &|s| {
        LaneValue::Text(s.status.to_string())
    }));
    for n in first.inputs.keys() {
        d.lanes
            .push(lane("inputs", n, &|s| level(s.inputs.get(n).copied())));
    }
    for n in first.dispatched.keys() {
        d.lanes
            .push(lane("outputs of A", n, &|s| of(&s.outputs_a, n)));
    }
    for n in first.dispatched.keys() {
        d.lanes
            .push(lane("outputs of B", n, &|s| of(&s.outputs_b, n)));
    }
    for n in first.dispatched.keys() {
        d.lanes.push(lane("dispatched", n, &|s| {
            level(s.dispatched.get(n).copied())
        }));
    }
    for e in &rec.events {
        if matches!(
            e.kind,
            EventKind::LoadAccepted | EventKind::Substituted | EventKind::QuarantineStarted
        ) {
            d.markers
                .push((e.time_us, e.kind.as_str().replace('_', " ")));
        }
    }
    d
}

fn on(m: &BTreeMap<String, bool>) -> String {
    let v: Vec<&str> = m
        .iter()
        .filter(|(_, &b)| b)
        .map(|(k, _)| k.as_str())
        .collect();
    if v.is_empty() {
        "-".into()
    } else {
        v.join(" ")
    }
}

/// The Fig. 7-like table: one row per step.
pub fn table(rec: &DemoRecord) -> String {
    let mut s = format!(
        "{:>9}  {:<3} {:<10}  {:<28} | {:<22} | {:<22} | {}\n",
        "time s", "PRI", "STATUS", "inputs", "outputs A", "outputs B", "dispatched"
    );
    for st in &rec.steps {
        let opt = |o: &Option<BTreeMap<String, bool>>| o.as_ref().map_or("(empty)".to_string(), on);
        s.push_str(&format!(
            "{:>9.2}  {:<3} {:<10}  {:<28} | {:<22} | {:<22} | {}\n",
            st.time_ms / 1e3,
            st.primary.as_str(),
            st.status,
            on(&st.inputs),
            opt(&st.outputs_a),
            opt(&st.outputs_b),
            on(&st.dispatched)
        ));
    }
    s
}
