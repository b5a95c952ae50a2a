//! A node assembled in one place. [`NodeSpec`] is what `cetratus run`, `cetratus demo` and the
//! benches ask for: the program, the plant, the time, MQTT and the state directory.
//! [`NodeSpec::start`] decides everything else, in this order:
//! 1. the plant I/O ([`crate::plant`]): the twin, the field devices with the PLC's Modbus
//!    server, the PLC's OPC UA server;
//! 2. MQTT and its companion (the dashboard) ([`crate::services`]), whose ports are taken before
//!    anything is written, so that a start that cannot bind leaves no trace;
//! 3. the PLC, warm from its state directory or fresh;
//! 4. the node: its script, twin validation, the drivers' observers, persistence, the MQTT link.
//!
//! What a person should read about the start comes out as [`Notice`]s, which the caller prints;
//! nothing here writes to a terminal.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use cetratus_io::plant::{PlantIo, PlantReport};
use cetratus_persist::Persister;
use cetratus_program::{Program, TrustStore, Unsigned};
use cetratus_runtime::{Event, Limits, Plc};
use cetratus_twin::TwinKind;

use crate::clock::MonotonicStopwatch;
use crate::config::{ConfigError, LocalConfig};
use crate::load::LoadPolicy;
use crate::plant::{Opening, PlantSpec};
use crate::script::{PressError, Script, ScriptError};
use crate::services::{MqttSpec, Services};
use crate::{Echo, Node, NodeOptions, NodeReport};

/// Something a person should read about a node's start, printed by the caller.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Notice {
    /// What a person needs even from a quiet caller: where a service the node started is
    /// reached, what a cold start discarded, whether real-time scheduling was granted.
    Note(String),
    /// What the node was started with (a quiet caller leaves it out).
    Info(String),
    /// Something that went less well than asked, and what it means for the run.
    Warning(String),
}

/// Where [`NodeSpec::start`] says its [`Notice`]s.
pub type Say<'a> = &'a mut dyn FnMut(Notice);

/// The clock a node runs on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TimeMode {
    /// Virtual time: as fast as the machine goes, deterministic; no MQTT, no field I/O.
    Virtual,
    /// Real time at `speed` program seconds per wall second; `rt` asks for SCHED_FIFO and
    /// mlockall (a warning where refused).
    Real {
        /// Program seconds per wall second.
        speed: f64,
        /// Ask for real-time scheduling.
        rt: bool,
    },
}

impl TimeMode {
    /// Program seconds per wall second: 1 for virtual time, and for a speed that is not a
    /// positive number.
    pub fn speed(self) -> f64 {
        match self {
            TimeMode::Real { speed, .. } if speed.is_finite() && speed > 0.0 => speed,
            _ => 1.0,
        }
    }
}

/// Where a node keeps its state.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum StateDir {
    /// In real time, `$XDG_STATE_HOME/cetratus/<program name>`; in virtual time nowhere (a
    /// simulation keeps no state unless asked to).
    #[default]
    Default,
    /// In this directory.
    At(PathBuf),
    /// Nowhere: every start is a cold start.
    Nowhere,
}

/// A node to start: what its caller chooses. [`NodeSpec::new`] gives the defaults of a bare
/// `cetratus run` on that program and plant.
pub struct NodeSpec {
    /// The program.
    pub program: Arc<Program>,
    /// The PLC's id: names its MQTT topics and its OPC UA nodes.
    pub plc_id: String,
    /// The local configuration.
    pub local: LocalConfig,
    /// The plant.
    pub plant: PlantSpec,
    /// Virtual or real time.
    pub time: TimeMode,
    /// The scan period, instead of the program's.
    pub period_us: Option<u64>,
    /// MQTT, for a node that is watched and commanded (real time only).
    pub mqtt: Option<MqttSpec>,
    /// Where the state is kept.
    pub state: StateDir,
    /// Start afresh: the saved state is ignored and replaced.
    pub cold: bool,
    /// The package keys, instead of the local configuration's.
    pub trust: Option<TrustStore>,
    /// Accept unsigned packages even if the local configuration does not.
    pub allow_unsigned: bool,
    /// Scripted operator commands.
    pub script: Script,
    /// Record the I/O trace.
    pub record_trace: bool,
    /// Program variables the trace records too.
    pub watch: Vec<String>,
    /// Echo progress every this many cycles.
    pub progress_every: Option<u64>,
    /// Where events, progress and warnings are echoed, on a thread of their own.
    pub echo: Option<Box<dyn FnMut(Echo) + Send>>,
}

/// Why a node does not start: what is wrong, and what to do.
#[derive(Debug, thiserror::Error)]
pub enum SpecError {
    /// The local configuration refuses the run.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A driver could not be built or started.
    #[error(transparent)]
    Io(#[from] cetratus_io::IoError),
    /// The twin refuses its settings.
    #[error("--twin {kind}: {error}")]
    Twin {
        /// The twin.
        kind: TwinKind,
        /// Why.
        error: cetratus_twin::TwinError,
    },
    /// A simulation without a twin.
    #[error(
        "a virtual run needs a plant: add --twin vernadat or --twin festo, or --replay TRACE.csv"
    )]
    VirtualNeedsTwin,
    /// A simulation with network I/O.
    #[error("{file}: a virtual run cannot use network I/O (its time runs faster than any device's); run in real time, or leave --io out")]
    VirtualNetworkIo {
        /// The I/O configuration.
        file: String,
    },
    /// The twin and the OPC UA clients would both provide the inputs.
    #[error("{file}: [opcua] inputs = true and --twin {twin} would both provide the inputs; an input has one source: leave out --twin, or inputs = true")]
    TwoInputSources {
        /// The I/O configuration.
        file: String,
        /// The twin.
        twin: TwinKind,
    },
    /// The program's signals do not fit the I/O configuration.
    #[error("the program does not fit the I/O configuration {file}: {error}")]
    DoesNotFit {
        /// The I/O configuration.
        file: String,
        /// Why.
        error: cetratus_io::IoError,
    },
    /// One of the PLC's servers did not start.
    #[error("the {what} server of {file}: {error}")]
    Server {
        /// Which server.
        what: &'static str,
        /// The I/O configuration.
        file: String,
        /// Why.
        error: cetratus_io::IoError,
    },
    /// An OPC UA user's password hash is not an argon2 hash.
    #[error("{at}: the password hash of `{user}` is not an argon2 hash ({error}); make one with `cetratus hash-password`")]
    PasswordHash {
        /// Where the user is declared.
        at: String,
        /// The user.
        user: String,
        /// Why.
        error: cetratus_mct::password::PasswordError,
    },
    /// This build has no OPC UA server.
    #[error("{file}: [opcua] asks for the PLC's OPC UA server, and this build of Cetratus has none (it was built without the `opcua` feature); remove the section, or use a full build")]
    NoOpcUa {
        /// The I/O configuration.
        file: String,
    },
    /// No twin and no I/O.
    #[error("nothing to run against: give --twin vernadat|festo, --io IO.toml, or both (or an [io] section in the local configuration)")]
    NoPlant,
    /// A button press that cannot be given.
    #[error(transparent)]
    Press(#[from] PressError),
    /// `--replay` beside a twin or field I/O: the inputs would have two sources.
    #[error("--replay gives the inputs of every scan; leave out --twin and --io")]
    ReplayAndPlant,
    /// The replay file was refused.
    #[error(transparent)]
    Replay(#[from] cetratus_io::replay::ReplayError),
    /// `--press` without a twin.
    #[error("--press needs a twin; with field I/O, press the machine's own buttons")]
    PressNeedsTwin,
    /// MQTT did not start.
    #[error(transparent)]
    Mqtt(#[from] cetratus_mct::MctError),
    /// The companion (the dashboard) did not start.
    #[error("{0}")]
    Companion(Box<dyn std::error::Error + Send + Sync>),
    /// The state directory cannot be used.
    #[error("the state directory {dir}: {error}")]
    State {
        /// The directory.
        dir: PathBuf,
        /// Why.
        error: cetratus_persist::PersistError,
    },
}

/// The PLC a node starts with, and what its start left.
struct Opened {
    plc: Plc,
    persister: Option<Persister>,
    events: Vec<Event>,
    dir: Option<PathBuf>,
}

impl NodeSpec {
    /// A real-time node on `program` and `plant` with the local configuration `local`: no MQTT,
    /// state in the default directory, no script.
    pub fn new(program: Arc<Program>, plc_id: &str, local: LocalConfig, plant: PlantSpec) -> Self {
        NodeSpec {
            program,
            plc_id: plc_id.to_string(),
            local,
            plant,
            time: TimeMode::Real {
                speed: 1.0,
                rt: false,
            },
            period_us: None,
            mqtt: None,
            state: StateDir::Default,
            cold: false,
            trust: None,
            allow_unsigned: false,
            script: Script::default(),
            record_trace: false,
            watch: Vec::new(),
            progress_every: None,
            echo: None,
        }
    }

    /// The scan period: the one asked for, or the program's.
    pub fn period(&self) -> u64 {
        self.period_us
            .map_or(self.program.scan_period().as_micros() as u64, |p| p.max(1))
    }

    /// What loads accept: the keys (the spec's, or the configuration's), unsigned packages,
    /// the analysis gate.
    pub fn load_policy(&self) -> LoadPolicy {
        LoadPolicy {
            trust: self
                .trust
                .clone()
                .unwrap_or_else(|| self.local.trust.clone()),
            unsigned: Unsigned::allowed_if(self.allow_unsigned || self.local.allow_unsigned),
            gate: self.local.gate,
        }
    }

    /// Starts the node (see the module doc for the order); `say` hears what a person should
    /// read about it.
    pub fn start(mut self, say: Say<'_>) -> Result<RunningNode, SpecError> {
        let period_us = self.period();
        let load = self.load_policy();
        say(Notice::Info(self.describe_config(&load)));
        let virtual_time = self.time == TimeMode::Virtual;
        let mut io = crate::plant::open(
            &self.plant,
            &Opening {
                program: &self.program,
                local_io: self.local.io.as_ref(),
                virtual_time,
                period_us,
                plc_id: &self.plc_id,
            },
            say,
        )?;
        self.local.check_validation(io.plant().is_some())?;
        let services = match self.mqtt.take().filter(|_| !virtual_time) {
            Some(m) => Some(crate::services::start(m, &self.plc_id, &self.local, say)?),
            None => None,
        };
        let mut opened = self.open_plc(period_us, say)?;
        self.set_time(&mut opened.plc, period_us);
        // Program time resumes after the last committed cycle; the script and the presses
        // count from the start of this run.
        let base_us = if opened.plc.cycles() > 0 {
            opened.plc.now_us().saturating_add(period_us)
        } else {
            0
        };
        press(&mut io, &self.plant.presses, base_us)?;
        if let Some(a) = io.admission() {
            opened.plc.set_io_admission(a);
        }
        Ok(self.assemble(opened, io, services, load, base_us, period_us))
    }

    /// One line on what loads and commands accept.
    fn describe_config(&self, load: &LoadPolicy) -> String {
        let commands = if self.local.operators.is_some() {
            "signed commands required"
        } else {
            "no operator keys (commands need no signature)"
        };
        let unsigned = if self.allow_unsigned || self.local.allow_unsigned {
            "ACCEPTED"
        } else {
            "refused"
        };
        format!(
            "configuration {}: {} trusted package keys, {commands}, unsigned packages {unsigned}",
            self.local.dir.display(),
            load.trust.len(),
        )
    }

    /// The PLC: warm from its state directory, or fresh.
    fn open_plc(&self, period_us: u64, say: Say<'_>) -> Result<Opened, SpecError> {
        let dir = match (&self.state, self.time) {
            (StateDir::At(d), _) => Some(d.clone()),
            (StateDir::Default, TimeMode::Real { .. }) => crate::state::default_dir(&self.program),
            (StateDir::Default, TimeMode::Virtual) | (StateDir::Nowhere, _) => None,
        };
        let Some(dir) = dir else {
            if self.cold {
                say(Notice::Info(
                    "cold start: no state directory, nothing saved is used".into(),
                ));
            }
            let mut plc = Plc::new(self.program.clone(), 0, MonotonicStopwatch::boxed());
            let events = plc.drain_events();
            return Ok(Opened {
                plc,
                persister: None,
                events,
                dir: None,
            });
        };
        let s = crate::state::open(
            &dir,
            &self.program,
            self.cold,
            period_us,
            MonotonicStopwatch::boxed(),
        )
        .map_err(|error| SpecError::State {
            dir: dir.clone(),
            error,
        })?;
        for n in s.notes {
            say(Notice::Note(n));
        }
        say(Notice::Info(format!(
            "state: {} (a snapshot every {} cycles; see docs/persistence.md)",
            dir.display(),
            s.persister.config().every_cycles
        )));
        Ok(Opened {
            plc: s.plc,
            persister: Some(s.persister),
            events: s.events,
            dir: Some(dir),
        })
    }

    /// Virtual time, the scan period asked for, and the limits of the configuration.
    fn set_time(&self, plc: &mut Plc, period_us: u64) {
        if self.time == TimeMode::Virtual {
            plc.use_virtual_time(period_us);
        } else if self.period_us.is_some() {
            plc.set_limits(Limits::for_period_us(period_us));
        }
        plc.set_limits(self.local.limits(plc.limits()));
    }

    /// The node around the PLC and its I/O, with everything the spec connects to it.
    fn assemble(
        self,
        opened: Opened,
        io: PlantIo,
        services: Option<(cetratus_mct::MctLink, Services)>,
        load: LoadPolicy,
        base_us: u64,
        period_us: u64,
    ) -> RunningNode {
        let opts = NodeOptions {
            base_us,
            load: load.clone(),
            record_trace: self.record_trace,
            watch: self.watch.clone(),
            progress_every: self.progress_every,
        };
        let observer = io.observer();
        let quality = io.quality_reader();
        let mut node = Node::new(opened.plc, io, opts)
            .with_script(self.script)
            .with_validation(self.local.validation, period_us, |io| io.plant().cloned())
            .with_auto_substitute(self.local.auto_substitute.clone());
        if let Some(observe) = observer {
            node = node.with_observer(observe);
        }
        if let Some(p) = opened.persister {
            node = node.with_persister(p);
        }
        if let Some(echo) = self.echo {
            node = node.with_echo(echo);
        }
        let services = match services {
            Some((link, s)) => {
                let speed = self.time.speed();
                let own = crate::link::OwnFacts {
                    labels: self.local.labels.clone(),
                    updates: cetratus_proto::UpdatePolicy {
                        probation_ms: self.local.probation_us / 1000,
                        require_verdict: self.local.require_verdict,
                    },
                };
                let mut link =
                    crate::services::control_link(link, node.plc(), load, (speed, period_us), own);
                if let Some(q) = quality {
                    link.set_input_quality(q);
                }
                node = node.with_link(link);
                Some(s)
            }
            None => None,
        };
        RunningNode {
            node,
            services,
            start_events: opened.events,
            state_dir: opened.dir,
            period_us,
            time: self.time,
        }
    }
}

/// A started node: run it, then finish it.
pub struct RunningNode {
    node: Node<PlantIo>,
    services: Option<Services>,
    start_events: Vec<Event>,
    state_dir: Option<PathBuf>,
    period_us: u64,
    time: TimeMode,
}

/// What a node leaves when it is finished.
pub struct Finished {
    /// The PLC as the last cycle left it.
    pub plc: Plc,
    /// The plant I/O, stopped.
    pub io: PlantIo,
    /// What the node saw.
    pub report: NodeReport,
    /// What the plant says.
    pub plant: PlantReport,
}

impl RunningNode {
    /// The node.
    pub fn node(&self) -> &Node<PlantIo> {
        &self.node
    }

    /// The node, to step it by hand (the benches do).
    pub fn node_mut(&mut self) -> &mut Node<PlantIo> {
        &mut self.node
    }

    /// The events of the start (a warm start's restore, a cold start), already audited.
    pub fn start_events(&self) -> &[Event] {
        &self.start_events
    }

    /// The state directory, when the node keeps its state.
    pub fn state_dir(&self) -> Option<&std::path::Path> {
        self.state_dir.as_deref()
    }

    /// The scan period.
    pub fn period_us(&self) -> u64 {
        self.period_us
    }

    /// MQTT and its companion, when the node has them.
    pub fn services(&self) -> Option<&Services> {
        self.services.as_ref()
    }

    /// Runs until `until_us` of program time, or until `stop` in real time. Real time asks for
    /// real-time scheduling first when the spec did, and at the end takes the field to its safe
    /// values before anything else is shut down. Returns the program time reached.
    pub fn run(&mut self, until_us: u64, stop: &AtomicBool, say: Say<'_>) -> u64 {
        let TimeMode::Real { rt, .. } = self.time else {
            return self.node.run_virtual(self.period_us, until_us);
        };
        if rt {
            let status = crate::rt::request(80);
            for w in &status.warnings {
                say(Notice::Warning(w.clone()));
            }
            say(Notice::Note(format!("real time: {status}")));
        }
        let speed = self.time.speed();
        let reached = self
            .node
            .run_realtime(self.period_us, until_us, speed, stop);
        self.node.io_mut().stop();
        reached
    }

    /// Stops everything connected (the last snapshot is committed, MQTT and its companion
    /// stop) and returns what the node leaves; or the error of a scripted command that stopped
    /// the run.
    pub fn finish(self) -> Result<Finished, ScriptError> {
        let finished = self.node.finish();
        if let Some(s) = self.services {
            s.stop();
        }
        let (plc, io, report) = finished?;
        let plant = io.report();
        Ok(Finished {
            plc,
            io,
            report,
            plant,
        })
    }
}

/// Presses the twin's buttons (`BUTTON@TIME`, program time from `base_us`); the twin's own start
/// presses when none are given (the Festo station's RESET and START).
fn press(io: &mut PlantIo, presses: &[String], base_us: u64) -> Result<(), SpecError> {
    match io.plant_mut() {
        Some(t) => Ok(crate::script::press_buttons(t, presses, base_us)?),
        None if presses.is_empty() => Ok(()),
        None => Err(SpecError::PressNeedsTwin),
    }
}
