//! The node loop: one cycle of a PLC node, the same for `run` and `demo`, in virtual or real time.
//!
//! Each cycle, on the scan thread: the commands that are ready (from MQTT through the preparer,
//! or from a script), the scan, the trace and the invariant check, the events (to the audit log,
//! to MQTT and to the echo), the publication, and a snapshot offered to the persistence writer.
//! Nothing here blocks: every other party is behind a bounded queue used with `try_send`.

use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{sync_channel, SyncSender};
use std::thread::JoinHandle;

use cetratus_persist::{PersistStats, Persister};
use cetratus_runtime::trace::Trace;
use cetratus_runtime::{
    Clock, Command, CommandError, Dispatcher, Event, EventKind, LoopTiming, Plc, Provider, Status,
    SubstituteMode, SubstituteRequest, VirtualClock,
};

use crate::link::{ControlLink, LinkCounters};
use crate::overruns::OverrunWatch;
use crate::periodic::run_periodic;
use crate::script::{Pace, Script, ScriptError};
use crate::validate::{self, AutoSubstitute, Start, ValidationMode, ValidationPolicy, Validator};
use cetratus_io::TwinDriver;
use cetratus_twin::Twin;

/// What the node tells the operator, printed by the caller on a thread of its own (the scan
/// thread never writes to a terminal).
#[derive(Debug)]
pub enum Echo {
    /// An event of the PLC.
    Event(Event),
    /// Every `progress_every` cycles: the cycle count and the last committed snapshot's cycle.
    Progress {
        /// Cycles run.
        cycle: u64,
        /// Cycle of the last committed snapshot.
        committed: Option<u64>,
    },
}

/// How a node runs.
pub struct NodeOptions {
    /// Program time at which this run starts (after a warm start, past the last committed cycle).
    pub base_us: u64,
    /// What the script's loads accept: keys, unsigned packages, the analysis gate.
    pub load: crate::load::LoadPolicy,
    /// Record the I/O trace (`--trace`, `--svg`).
    pub record_trace: bool,
    /// Program variables the trace records too (`--watch`).
    pub watch: Vec<String>,
    /// Echo [`Echo::Progress`] every this many cycles.
    pub progress_every: Option<u64>,
}

/// What [`Node::with_observer`] is given.
type Observer = Box<dyn FnMut(&Plc) + Send>;

/// Most faults a run's report keeps; the count of the rest is still reported.
const MAX_FAULTS: usize = 100;

/// A PLC node: the PLC, its I/O, and what is connected to it.
pub struct Node<IO> {
    plc: Plc,
    io: IO,
    opts: NodeOptions,
    persister: Option<Persister>,
    link: Option<ControlLink>,
    script: Script,
    trace: Option<Trace>,
    /// The watched variables' values of the cycle, one per watched name, filled in place.
    watched: Vec<cetratus_program::Value>,
    faults: Vec<String>,
    faults_dropped: u64,
    echo: Option<(SyncSender<Echo>, JoinHandle<()>)>,
    echo_dropped: u64,
    /// Set while the state directory cannot be written.
    persist_fault: Option<cetratus_proto::PersistFault>,
    script_error: Option<ScriptError>,
    timing: LoopTiming,
    pace: Pace,
    overruns: OverrunWatch,
    /// The real-time loop's period in wall-clock ns (the program's period over the speed).
    wall_period_ns: u64,
    observer: Option<Observer>,
    validation: Option<NodeValidation<IO>>,
}

/// The node's twin validation: the thread, and how to fork the twin of this kind of I/O.
struct NodeValidation<IO> {
    validator: Validator,
    fork: fn(&IO) -> Option<Twin>,
    period_us: u64,
    auto: Option<AutoSubstitute>,
    // Program time of the next validation during probation.
    revalidate_at: Option<u64>,
}

/// What a node leaves when it stops.
pub struct NodeReport {
    /// Declared invariants the primary broke, and the alarms (primary fault, deadlock), with
    /// their program times.
    pub faults: Vec<String>,
    /// Faults beyond the first hundred.
    pub faults_dropped: u64,
    /// What the persistence writer did.
    pub persist: Option<PersistStats>,
    /// The I/O trace, when recorded.
    pub trace: Option<Trace>,
    /// Cycle time, latency and overruns (real time).
    pub timing: LoopTiming,
    /// Echo lines dropped because the printer was behind.
    pub echo_dropped: u64,
    /// What the MQTT side dropped because the client was behind (with MQTT only).
    pub link: Option<LinkCounters>,
}

impl<IO: Provider + Dispatcher> Node<IO> {
    /// A node around `plc` and its I/O.
    pub fn new(plc: Plc, io: IO, opts: NodeOptions) -> Self {
        let trace = opts.record_trace.then(|| {
            Trace::new(plc.io_inputs().to_vec(), plc.io_outputs().to_vec())
                .watching(opts.watch.clone())
        });
        let watched = vec![cetratus_program::Value::Bool(false); opts.watch.len()];
        Node {
            plc,
            io,
            opts,
            persister: None,
            link: None,
            script: Script::default(),
            trace,
            watched,
            faults: Vec::new(),
            faults_dropped: 0,
            echo: None,
            echo_dropped: 0,
            persist_fault: None,
            script_error: None,
            timing: LoopTiming::default(),
            pace: Pace::Virtual,
            overruns: OverrunWatch::default(),
            wall_period_ns: 0,
            observer: None,
            validation: None,
        }
    }

    /// Validates every update on twins (docs/live-update.md, *Twin validation*): when it enters
    /// quarantine and again when it is substituted into probation, on a thread of its own; the
    /// verdict goes to the PLC. `fork` forks the twin of this I/O (fork mode).
    pub fn with_validation(
        mut self,
        policy: ValidationPolicy,
        period_us: u64,
        fork: fn(&IO) -> Option<Twin>,
    ) -> Self {
        if policy.mode != ValidationMode::Off {
            self.validation = Some(NodeValidation {
                validator: Validator::start(policy),
                fork,
                period_us,
                auto: None,
                revalidate_at: None,
            });
        }
        self
    }

    /// Starts a validation when the cycle's events put an update into quarantine or probation,
    /// and again on a fork of the state of the moment every `revalidate_us` of the probation
    /// window; hands a finished verdict to the PLC (a failing one in probation reverts). In
    /// virtual time it waits for the verdict, so that it lands at the same cycle on every run.
    fn validation_step(&mut self, events: &[Event], now: u64) {
        let Some(v) = self.validation.as_mut() else {
            return;
        };
        let policy = v.validator.policy;
        // Commissioning starts fresh twins from initial markings: run again, it would only say
        // the same. Forks of the state of the moment are what the window is watched with.
        if events.iter().any(|e| e.kind == EventKind::ProbationStarted) {
            v.revalidate_at = (policy.revalidate_us > 0 && policy.mode == ValidationMode::Fork)
                .then(|| now + policy.revalidate_us);
        }
        if self.plc.status() != Status::Probation {
            v.revalidate_at = None;
        }
        let again = v.revalidate_at.is_some_and(|t| now >= t);
        let due = again
            || events.iter().any(|e| {
                e.kind == EventKind::QuarantineStarted || e.kind == EventKind::ProbationStarted
            });
        let mut submitted = false;
        if due {
            let start = match policy.mode {
                ValidationMode::Commission(kind) => Some(Start::Commission(kind)),
                ValidationMode::Fork => (v.fork)(&self.io).map(|t| Start::fork(&self.plc, t)),
                ValidationMode::Off => None,
            };
            if let Some(job) =
                start.and_then(|s| validate::job_for(&self.plc, s, policy, v.period_us))
            {
                submitted = v.validator.submit(job);
            }
            // A job that could not be handed over (one waits already) is tried again next cycle.
            if again && submitted {
                v.revalidate_at = Some(now + policy.revalidate_us);
            }
        }
        let done = if submitted && self.pace == Pace::Virtual {
            v.validator.wait_done()
        } else {
            v.validator.try_done()
        };
        let attached = done.is_some_and(|d| self.plc.add_verdict(&d.program_hash, d.verdict));
        // A quarantine verdict comes from the PLC itself, in the cycle's events.
        if !attached && !events.iter().any(|e| e.kind == EventKind::Verdict) {
            return;
        }
        // Substitutes by itself only a load that an allowed operator key signed, once the
        // verdicts allow it: the twin's, and the quarantine's when the twin brought a signature.
        let key = self.link.as_ref().and_then(|l| l.load_key());
        let allowed = v
            .auto
            .as_ref()
            .zip(key)
            .is_some_and(|(a, k)| a.keys.iter().any(|x| x == k));
        if allowed
            && self.plc.status() == Status::Quarantine
            && self.plc.verdicts_allow_substitution()
        {
            let who = format!("auto:{}", key.unwrap_or_default());
            let r = self.plc.command(Command::Substitute(SubstituteRequest::now(
                SubstituteMode::Retransform,
            )));
            let ev = self.plc.drain_events();
            self.events(ev, &who, true);
            let _ = r;
        }
    }

    /// `auto_substitute = "on-pass"`: substitutes a candidate whose twin verdict passes, when an
    /// operator key of `auto` signed its load. Needs [`Node::with_validation`] first.
    pub fn with_auto_substitute(mut self, auto: Option<AutoSubstitute>) -> Self {
        if let Some(v) = self.validation.as_mut() {
            v.auto = auto;
        }
        self
    }

    /// Keeps the state in a directory, through its writer.
    pub fn with_persister(mut self, p: Persister) -> Self {
        self.persister = Some(p);
        self
    }

    /// Connects the node to MQTT.
    pub fn with_link(mut self, link: ControlLink) -> Self {
        self.link = Some(link);
        self
    }

    /// Gives scripted commands; their packages must be signed by the keys of the options.
    pub fn with_script(mut self, script: Script) -> Self {
        self.script = script.trusting(self.opts.load.clone());
        self
    }

    /// Calls `observe` on the scan thread after every cycle, with the PLC as the cycle left it
    /// (the Modbus server's status registers). It must not block: use `try_lock`/`try_send`.
    pub fn with_observer(mut self, observe: impl FnMut(&Plc) + Send + 'static) -> Self {
        self.observer = Some(Box::new(observe));
        self
    }

    /// Whether a scripted load that is due but not prepared yet is waited for (virtual time,
    /// the default) or applied when ready (real time). [`Node::run_virtual`] and
    /// [`Node::run_realtime`] set it.
    pub fn set_pace(&mut self, pace: Pace) {
        self.pace = pace;
    }

    /// Echoes events, progress and warnings to `print`, on a thread of its own.
    pub fn with_echo(mut self, mut print: impl FnMut(Echo) + Send + 'static) -> Self {
        let (tx, rx) = sync_channel::<Echo>(1024);
        let handle = std::thread::Builder::new()
            .name("cetratus-echo".into())
            .spawn(move || {
                while let Ok(e) = rx.recv() {
                    print(e);
                }
            })
            .expect("spawn the echo thread");
        self.echo = Some((tx, handle));
        self
    }

    /// The PLC.
    pub fn plc(&self) -> &Plc {
        &self.plc
    }

    /// The I/O.
    pub fn io(&self) -> &IO {
        &self.io
    }

    /// The I/O, to act on the plant (press a button of a twin).
    pub fn io_mut(&mut self) -> &mut IO {
        &mut self.io
    }

    fn echo(&mut self, e: Echo) {
        if let Some((tx, _)) = &self.echo {
            if tx.try_send(e).is_err() {
                self.echo_dropped += 1;
            }
        }
    }

    /// Echoes, audits and publishes events caused by `who`.
    fn events(&mut self, events: Vec<Event>, who: &str, publish: bool) -> Vec<Event> {
        for e in &events {
            if let Some(p) = self.persister.as_mut() {
                p.audit(e, who);
            }
            if e.kind.is_alarm() {
                self.fault(format!("{:.3}s: {}", e.time_us as f64 / 1e6, e.message));
            }
        }
        if publish {
            if let Some(link) = self.link.as_mut() {
                link.queue_events(&events);
            }
        }
        if self.echo.is_some() {
            for e in &events {
                self.echo(Echo::Event(e.clone()));
            }
        }
        events
    }

    fn fault(&mut self, f: String) {
        if self.faults.len() < MAX_FAULTS {
            self.faults.push(f);
        } else {
            self.faults_dropped += 1;
        }
    }

    /// Gives the PLC a command between cycles, as the operator at the machine (`cli` in the
    /// audit log). Returns the events it caused.
    pub fn command(&mut self, cmd: Command) -> (Result<(), CommandError>, Vec<Event>) {
        let r = self.plc.command(cmd);
        let ev = self.plc.drain_events();
        (r, self.events(ev, "cli", true))
    }

    /// One cycle at program time `now_us` (counted from this run's start). Returns the cycle's
    /// events, or `None` when a scripted command could not be built (the run stops; see
    /// [`Node::finish`]).
    /// `timing` is the real-time loop's figures so far, for the publication.
    pub fn step(&mut self, now_us: u64, timing: &LoopTiming) -> Option<Vec<Event>> {
        let now = now_us + self.opts.base_us;
        if let Some(link) = self.link.as_mut() {
            let who = link.take_commands(&mut self.plc);
            let ev = self.plc.drain_events();
            if !ev.is_empty() {
                let who = who.unwrap_or_else(|| "mqtt".into());
                self.events(ev, &who, true);
            }
        }
        let due = self
            .script
            .due(&self.plc, now, self.opts.base_us, self.pace);
        match due {
            None => {}
            Some(Ok(cmd)) => {
                let _ = self.command(cmd);
            }
            Some(Err(e)) => {
                self.script_error = Some(e);
                return None;
            }
        }
        if self.pace == Pace::Real {
            let candidate = self.candidate_share();
            if let Some(why) = self.overruns.cycle(timing.overruns, candidate) {
                self.plc.fault_candidate(&why);
            }
        }
        self.plc.cycle(now, &mut self.io);
        if let Some(t) = self.trace.as_mut() {
            let k = self.plc.primary_container();
            // Filled in place: a watched run allocates nothing per cycle.
            for (v, n) in self.watched.iter_mut().zip(&t.watched_names) {
                *v = k.watch(n).unwrap_or(cetratus_program::Value::Bool(false));
            }
            t.observe_watched(
                self.plc.cycles() - 1,
                now,
                self.plc.inputs(),
                self.plc.dispatched(),
                &self.watched,
            );
        }
        if let Some(observe) = self.observer.as_mut() {
            observe(&self.plc);
        }
        let k = self.plc.primary_container();
        if let Err(v) = k.program().check_invariants(k.marking()) {
            self.fault(format!("{:.3}s: {v}", now as f64 / 1e6));
        }
        let ev = self.plc.drain_events();
        self.validation_step(&ev, now);
        let ev = self.events(ev, "plc", false);
        if let Some(link) = self.link.as_mut() {
            link.after_cycle(&self.plc, &ev, timing, now);
        }
        if let Some(p) = self.persister.as_mut() {
            p.offer(&self.plc);
            let progress = self
                .opts
                .progress_every
                .filter(|&n| n > 0 && self.plc.cycles().is_multiple_of(n))
                .map(|_| p.committed_cycle());
            if let Some(committed) = progress {
                let cycle = self.plc.cycles();
                self.echo(Echo::Progress { cycle, committed });
            }
            self.persist_health(now);
        }
        drop(self.plc.take_retired());
        Some(ev)
    }

    /// Raises `persist_failed` when the state directory stops taking writes and
    /// `persist_recovered` when it takes them again, and keeps `state` saying which
    /// (docs/persistence.md, *When the disk fails*). One atomic load a cycle otherwise.
    fn persist_health(&mut self, now: u64) {
        let Some(p) = self.persister.as_ref() else {
            return;
        };
        let failing = p.is_failing();
        if failing == self.persist_fault.is_some() {
            return;
        }
        let cycle = self.plc.cycles();
        let (kind, message, fault) = if failing {
            let error = p.last_error().unwrap_or_else(|| "a write failed".into());
            let saved_cycle = p.committed_cycle();
            let saved = saved_cycle.map_or("none saved in this run".into(), |c| {
                format!("the last saved is of cycle {c}")
            });
            let message = format!(
                "the state directory cannot be written ({error}); the PLC runs on, but a restart now would \
                 start from the state saved before ({saved}); free space or mend the directory: \
                 every snapshot tries again"
            );
            let fault = cetratus_proto::PersistFault {
                error,
                since_cycle: cycle,
                saved_cycle,
            };
            (EventKind::PersistFailed, message, Some(fault))
        } else {
            let message = "the state directory takes writes again; the state is saved as before";
            (EventKind::PersistRecovered, message.to_string(), None)
        };
        self.persist_fault = fault.clone();
        if let Some(link) = self.link.as_mut() {
            link.set_persist_fault(fault);
        }
        let event = Event {
            cycle,
            time_us: now,
            kind,
            message,
            detail: None,
        };
        self.events(vec![event], "local", true);
    }

    /// While a candidate is in quarantine, the part of the wall-clock period its last scan took.
    fn candidate_share(&self) -> Option<f64> {
        if self.plc.status() != Status::Quarantine {
            return None;
        }
        let slot = self.plc.primary().other();
        let took_ns = self.plc.monitor().stats[slot.index()].scan.summary_last();
        Some(took_ns as f64 / self.wall_period_ns.max(1) as f64)
    }

    /// Runs cycles every `period_us` of virtual time until `until_us`. Returns the time reached.
    pub fn run_virtual(&mut self, period_us: u64, until_us: u64) -> u64 {
        let (mut clock, idle) = (VirtualClock::new(), LoopTiming::default());
        self.pace = Pace::Virtual;
        while clock.now_us() < until_us && self.step(clock.now_us(), &idle).is_some() {
            clock.advance_us(period_us);
        }
        clock.now_us()
    }

    /// Runs cycles in real time at absolute deadlines until `until_us` of program time or `stop`;
    /// `speed` program seconds per wall second. Returns the program time reached.
    pub fn run_realtime(
        &mut self,
        period_us: u64,
        until_us: u64,
        speed: f64,
        stop: &AtomicBool,
    ) -> u64 {
        let mut timing = std::mem::take(&mut self.timing);
        self.pace = Pace::Real;
        // As the loop takes it: a speed that is not a positive number runs at 1.
        let wall_speed = if speed.is_finite() && speed > 0.0 {
            speed
        } else {
            1.0
        };
        self.wall_period_ns = (period_us as f64 * 1e3 / wall_speed) as u64;
        let reached = run_periodic(period_us, until_us, speed, stop, &mut timing, |now, t| {
            self.step(now, t).is_some()
        });
        self.timing = timing;
        reached
    }

    /// Stops everything connected (the last snapshot is committed) and returns the PLC, its I/O
    /// and the report; or the error of a scripted command that stopped the run.
    pub fn finish(mut self) -> Result<(Plc, IO, NodeReport), ScriptError> {
        let persist = self.persister.take().map(|p| p.stop(&self.plc));
        let link = self.link.take().map(|link| {
            let counters = link.counters();
            link.stop();
            counters
        });
        if let Some((tx, handle)) = self.echo.take() {
            drop(tx);
            let _ = handle.join();
        }
        if let Some(e) = self.script_error.take() {
            return Err(e);
        }
        let report = NodeReport {
            faults: self.faults,
            faults_dropped: self.faults_dropped,
            persist,
            trace: self.trace,
            timing: self.timing,
            echo_dropped: self.echo_dropped,
            link,
        };
        Ok((self.plc, self.io, report))
    }
}

impl Node<TwinDriver<Twin>> {
    /// [`Node::with_validation`] for a node on an in-process twin, which fork mode forks.
    pub fn with_twin_validation(self, policy: ValidationPolicy, period_us: u64) -> Self {
        self.with_validation(policy, period_us, |io| Some(io.plant().clone()))
    }
}
