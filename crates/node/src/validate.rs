//! Twin validation (docs/live-update.md, *Twin validation*): the candidate and the program it
//! replaces run ahead side by side, each on its own twin, in virtual time over a horizon, and a
//! verdict says whether the candidate may drive the plant.
//!
//! * **fork**: the PLC runs against an in-process twin. The twin is forked at its current state
//!   and the PLC's state is taken as a snapshot; the baseline resumes the program that drives the
//!   plant now, the candidate run resumes it too and takes the update through its install and a
//!   retransform substitution at once, as the PLC would.
//! * **commission**: any PLC whose configuration names a twin model. Both programs start from
//!   their initial markings on fresh twins.
//!
//! A verdict passes when the candidate causes no twin fault, no primary fault, no deadlock alarm
//! and no stall alarm, and its throughput (the twin's production counter) is at least the
//! configured share of the baseline's, or the share the package declares it may drop to. Output
//! divergence is reported per output, marked where the package declares it. Both runs are the real `Plc` on the real twin, so a
//! verdict is deterministic for a given state. Runs on a thread of the node, never the scan
//! thread.

use std::collections::BTreeMap;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::sync::Arc;
use std::time::Instant;

use cetratus_io::TwinDriver;
use cetratus_program::{Program, ResolvedUpdate, Value};
use cetratus_runtime::mask::Mask;
use cetratus_runtime::signature::Signature;
use cetratus_runtime::{
    Command, Dispatcher, EventKind, IoAdmission, ManualStopwatch, Plc, PlcSnapshot, Slot, Status,
    SubstituteMode, SubstituteRequest, Verdict, VerdictKind, VerdictResult,
};
use cetratus_twin::{Plant, Twin, TwinKind};

/// Where the twins of a validation come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ValidationMode {
    /// No twin validation.
    #[default]
    Off,
    /// Fork the in-process twin the PLC runs against.
    Fork,
    /// Fresh twins of this kind, both programs from their initial markings.
    Commission(TwinKind),
}

/// The twin validation's settings (`[updates]` of the local configuration).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValidationPolicy {
    /// Fork, commission or off.
    pub mode: ValidationMode,
    /// Plant time each run covers, µs.
    pub horizon_us: u64,
    /// The least share of the baseline's production the candidate must reach.
    pub throughput_share: f64,
    /// During probation (fork mode), a validation starts again on a fork of the state of the
    /// moment every this much program time, µs, while the window lasts; 0: once, at the
    /// substitution.
    pub revalidate_us: u64,
}

/// `auto_substitute = "on-pass"`: the operator key ids whose loads the PLC substitutes by itself
/// when the twin verdict in quarantine passes.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct AutoSubstitute {
    /// Key ids (`cetratus package keygen` prints them; the `key-id` line of a `.pub` file).
    pub keys: Vec<String>,
}

/// `[updates] revalidate` when absent: ten seconds, six fresh verdicts in the default minute of
/// probation.
pub const DEFAULT_REVALIDATE_US: u64 = 10_000_000;

impl Default for ValidationPolicy {
    fn default() -> Self {
        ValidationPolicy {
            mode: ValidationMode::Off,
            horizon_us: 600_000_000,
            throughput_share: 0.9,
            revalidate_us: DEFAULT_REVALIDATE_US,
        }
    }
}

/// What a validation starts from.
pub enum Start {
    /// Fork mode: the PLC's state and its twin, forked now.
    Fork {
        /// The PLC's state at the fork.
        snapshot: Box<PlcSnapshot>,
        /// The twin, forked at the same moment.
        twin: Box<Twin>,
        /// What the PLC dispatched in its last cycle, by output name: what the twin was last
        /// told, which the forks' drivers start from.
        dispatched: Vec<(String, bool)>,
        /// What the PLC read in its last cycle, by input name: the forks' edge detection
        /// continues from it.
        read: Vec<(String, Value)>,
    },
    /// Commission mode: fresh twins of this kind.
    Commission(TwinKind),
}

impl Start {
    /// Fork mode: `plc`'s state, what it dispatched and read in its last cycle, and `twin`, the
    /// plant it runs against, forked at the same moment (after a cycle).
    pub fn fork(plc: &Plc, twin: Twin) -> Start {
        let mut snapshot = Box::<PlcSnapshot>::default();
        plc.snapshot_into(&mut snapshot);
        let dispatched = plc
            .io_outputs()
            .iter()
            .zip(plc.dispatched())
            .map(|(n, v)| (n.clone(), matches!(v, Value::Bool(true))))
            .collect();
        let read = plc
            .io_inputs()
            .iter()
            .cloned()
            .zip(plc.inputs().iter().copied())
            .collect();
        Start::Fork {
            snapshot,
            twin: Box::new(twin),
            dispatched,
            read,
        }
    }
}

/// One validation to run: the baseline program, the update, and where to start.
pub struct Job {
    /// The program the update replaces (the baseline).
    pub baseline: Arc<Program>,
    /// The update, resolved against the baseline.
    pub update: ResolvedUpdate,
    /// In fork mode, the slot of the PLC that runs the baseline now, and whether the update is
    /// already primary (probation): then the candidate run resumes the new primary as it is.
    pub baseline_slot: Slot,
    /// The update is already primary (probation).
    pub on_probation: bool,
    /// Fork or commission.
    pub start: Start,
    /// Period of the scans, µs.
    pub period_us: u64,
    /// Horizon and throughput share.
    pub policy: ValidationPolicy,
}

/// What one run on a twin came to.
#[derive(Debug, Default)]
struct RunFigures {
    produced: u64,
    twin_faults: Vec<String>,
    alarms: Vec<String>,
}

/// Runs `plc` on `twin` for the horizon from `from_us`, gathering what the verdict needs, and
/// calling `each` with the dispatched outputs of every cycle.
fn run(
    plc: &mut Plc,
    io: &mut TwinDriver<Twin>,
    from_us: u64,
    job: &Job,
    mut each: impl FnMut(&[cetratus_program::Value]),
) -> RunFigures {
    let counter = io.plant().production_counter();
    let produced0 = io.plant().counters().get(counter).unwrap_or(0);
    let faults0 = io.plant().faults().len();
    let mut f = RunFigures::default();
    let end = from_us.saturating_add(job.policy.horizon_us);
    let mut now = from_us;
    while now < end {
        plc.cycle(now, io);
        each(plc.dispatched());
        for e in plc.drain_events() {
            if matches!(
                e.kind,
                EventKind::PrimaryFault | EventKind::DeadlockAlarm | EventKind::StallAlarm
            ) && f.alarms.len() < 4
            {
                f.alarms.push(format!(
                    "{} at {:.1} s: {}",
                    e.kind,
                    now.saturating_sub(from_us) as f64 / 1e6,
                    e.message
                ));
            }
        }
        drop(plc.take_retired());
        now += job.period_us;
    }
    f.produced = io
        .plant()
        .counters()
        .get(counter)
        .unwrap_or(0)
        .saturating_sub(produced0);
    f.twin_faults = io.plant().faults()[faults0.min(io.plant().faults().len())..]
        .iter()
        .take(4)
        .map(|x| x.to_string())
        .collect();
    f
}

/// A PLC resumed from `snap` with `slot` as PRIMARY, in virtual time.
fn resume(
    snap: &PlcSnapshot,
    slot: Slot,
    programs: &[&Arc<Program>],
    period_us: u64,
) -> Option<Plc> {
    let mut s = snap.clone();
    s.primary = Some(slot);
    s.status = Some(Status::Idle);
    let hash = s.containers[slot.index()].as_ref()?.program_hash.clone();
    let program = programs.iter().find(|p| p.hash_hex() == hash)?;
    let mut plc = Plc::warm_start(
        &s,
        |h| {
            programs
                .iter()
                .find(|p| p.hash_hex() == h)
                .map(|p| (*p).clone())
        },
        (*program).clone(),
        Box::new(ManualStopwatch::new()),
    )
    .ok()?;
    plc.use_virtual_time(period_us);
    plc.set_io_admission(Arc::new(ForkOutputs));
    let _ = plc.drain_events();
    Some(plc)
}

/// Continues `plc`'s edge detection from what the forked PLC read in its last cycle, by name.
fn continue_inputs(plc: &mut Plc, read: &[(String, Value)]) {
    let image: Vec<Value> = plc
        .io_inputs()
        .iter()
        .zip(plc.inputs())
        .map(|(n, v)| read.iter().find(|(m, _)| m == n).map_or(*v, |(_, x)| *x))
        .collect();
    plc.continue_inputs_from(&image);
}

/// What a fork admits of a candidate's new signals: outputs, which the node's field devices
/// take and the twin of the fork ignores, as the plant ignores outputs it has no actuator for;
/// no new inputs, which the twin cannot provide (a node whose twin is the plant refuses them
/// too).
struct ForkOutputs;

impl IoAdmission for ForkOutputs {
    fn admit(
        &self,
        inputs: &[cetratus_program::Signal],
        _outputs: &[cetratus_program::Signal],
    ) -> Result<(), cetratus_runtime::Inadmissible> {
        match inputs.first() {
            Some(s) => Err(cetratus_runtime::Inadmissible(format!(
                "the twin of the validation cannot provide the new input `{}`",
                s.name
            ))),
            None => Ok(()),
        }
    }
}

/// Takes `plc` through the install of `update` and a retransform substitution, as the PLC would:
/// two cycles. Returns why it did not get there.
fn apply_update(
    plc: &mut Plc,
    io: &mut TwinDriver<Twin>,
    update: &ResolvedUpdate,
    now: &mut u64,
    period_us: u64,
) -> Result<(), String> {
    let prepared = plc
        .update_context()
        .prepare(update.clone())
        .map_err(|e| e.to_string())?;
    plc.command(Command::Load(Box::new(prepared)))
        .map_err(|e| e.to_string())?;
    plc.cycle(*now, io);
    *now += period_us;
    plc.command(Command::Substitute(SubstituteRequest::now(
        SubstituteMode::Retransform,
    )))
    .map_err(|e| e.to_string())?;
    plc.cycle(*now, io);
    *now += period_us;
    let events = plc.drain_events();
    drop(plc.take_retired());
    if events.iter().any(|e| e.kind == EventKind::Substituted) {
        Ok(())
    } else {
        Err(events
            .iter()
            .rev()
            .find(|e| {
                matches!(
                    e.kind,
                    EventKind::Refused
                        | EventKind::TransformRefused
                        | EventKind::StateTransTimeout
                        | EventKind::CandidateFault
                )
            })
            .map_or("the update did not take".to_string(), |e| e.message.clone()))
    }
}

/// Runs a validation and returns its verdict.
pub fn validate(job: &Job) -> Verdict {
    let t0 = Instant::now();
    let mut pair = match Pair::set_up(job) {
        Ok(pair) => pair,
        Err(reason) => return failed(reason),
    };
    // In quarantine the baseline's run carries the candidate in quarantine beside it, as the
    // plant will: what the Monitor puts its divergences down to is the signature.
    let watching = !job.on_probation && watch_candidate(&mut pair.base, job);
    let mut outputs: Vec<Mask> =
        Vec::with_capacity((job.policy.horizon_us / job.period_us.max(1)) as usize);
    let bits = Mask::of;
    let b = run(&mut pair.base, &mut pair.base_io, pair.from, job, |d| {
        outputs.push(bits(d))
    });
    let signature = watching
        .then(|| pair.base.divergence_signature())
        .flatten()
        .map(|s| {
            Arc::new(Signature {
                horizon_cycles: job.policy.horizon_us / job.period_us.max(1),
                ..s
            })
        });
    // The candidate's outputs by name against the baseline's: one it adds is compared with off.
    let names = pair.cand.io_outputs().to_vec();
    let in_base: Vec<Option<usize>> = names
        .iter()
        .map(|n| pair.base.io_outputs().iter().position(|m| m == n))
        .collect();
    let mut per_output = vec![0u64; names.len()];
    let mut i = 0usize;
    let mut divergent = 0u64;
    let c = run(
        &mut pair.cand,
        &mut pair.cand_io,
        pair.cand_from,
        job,
        |d| {
            let Some(base) = outputs.get(i) else {
                return;
            };
            let mut differs = false;
            for (j, v) in d.iter().enumerate() {
                let theirs = in_base[j].is_some_and(|k| base.get(k));
                if matches!(v, Value::Bool(true)) != theirs {
                    per_output[j] += 1;
                    differs = true;
                }
            }
            divergent += u64::from(differs);
            i += 1;
        },
    );
    let diverged: Vec<(String, u64)> = names
        .into_iter()
        .zip(per_output)
        .filter(|(_, n)| *n > 0)
        .collect();
    let mut v = verdict(job, &b, &c, (divergent, &diverged), t0);
    if let Some(sig) = &signature {
        v.figures
            .insert("signature_kinds".into(), sig.kinds.len() as f64);
    }
    v.signature = signature;
    v
}

/// Puts the candidate into quarantine beside the baseline `base`, whose I/O admits the outputs
/// it adds (the twin ignores them); false when it does not take.
fn watch_candidate(base: &mut Plc, job: &Job) -> bool {
    base.set_io_admission(Arc::new(ForkOutputs));
    let Ok(prepared) = base.update_context().prepare(job.update.clone()) else {
        return false;
    };
    base.command(Command::Load(Box::new(prepared))).is_ok()
}

/// A validation that cannot run both programs says why, and does not pass.
fn failed(reason: String) -> Verdict {
    Verdict {
        kind: VerdictKind::Twin,
        result: VerdictResult::Fail,
        reasons: vec![reason],
        figures: BTreeMap::new(),
        signature: None,
    }
}

/// The baseline and the candidate, each a PLC on its twin's driver, at the cycle boundary where
/// the comparison starts.
struct Pair {
    base: Plc,
    base_io: TwinDriver<Twin>,
    /// Program time of the baseline's first compared cycle, µs.
    from: u64,
    cand: Plc,
    cand_io: TwinDriver<Twin>,
    /// Program time of the candidate's first compared cycle, µs.
    cand_from: u64,
}

impl Pair {
    /// Sets both runs up from `job.start`; in fork mode the candidate takes the update first, as
    /// the PLC would. `Err` says why the validation cannot run.
    fn set_up(job: &Job) -> Result<Pair, String> {
        let (mut base, base_twin, mut cand, cand_twin, from) = starting_plcs(job)?;
        let candidate = &job.update.program;
        let driver = |twin: Twin, p: &Program| TwinDriver::new(twin, p.inputs(), p.outputs());
        // Each driver follows the I/O map of its PLC: the program it started with.
        let cand_map = match job.start {
            Start::Fork { .. } if !job.on_probation => &job.baseline,
            _ => candidate,
        };
        let (Ok(mut base_io), Ok(mut cand_io)) = (
            driver(base_twin, &job.baseline),
            driver(cand_twin, cand_map),
        ) else {
            return Err("the programs' signals do not match the twin's".into());
        };
        // A new driver has told the plant nothing yet; it starts from what the PLC last
        // dispatched, or the fork's first step would read as every command withdrawn at once.
        if let Start::Fork {
            snapshot,
            dispatched,
            ..
        } = &job.start
        {
            for (io, program) in [(&mut base_io, &job.baseline), (&mut cand_io, cand_map)] {
                let values: Vec<Value> = program
                    .outputs()
                    .iter()
                    .map(|o| Value::Bool(dispatched.iter().any(|(n, on)| *n == o.name && *on)))
                    .collect();
                io.write_outputs(snapshot.time_us, &values);
            }
        }
        let mut cand_from = from;
        if matches!(job.start, Start::Fork { .. }) && !job.on_probation {
            apply_update(
                &mut cand,
                &mut cand_io,
                &job.update,
                &mut cand_from,
                job.period_us,
            )
            .map_err(|why| format!("the update does not take on the fork: {why}"))?;
        }
        // Both runs start at the same cycle boundary: the baseline runs on through the cycles
        // the candidate's install and substitution took (the old program drove the plant in
        // them on both forks), so that the same plant time is compared, cycle for cycle.
        let mut from = from;
        while from < cand_from {
            base.cycle(from, &mut base_io);
            let _ = base.drain_events();
            drop(base.take_retired());
            from += job.period_us;
        }
        Ok(Pair {
            base,
            base_io,
            from,
            cand,
            cand_io,
            cand_from,
        })
    }
}

/// The baseline PLC and its twin, the candidate PLC and its twin, and the program time both
/// start from: forks of the running PLC's state and plant, or fresh ones in commission mode.
fn starting_plcs(job: &Job) -> Result<(Plc, Twin, Plc, Twin, u64), String> {
    let candidate = &job.update.program;
    let programs = [&job.baseline, candidate];
    match &job.start {
        Start::Fork {
            snapshot,
            twin,
            read,
            ..
        } => {
            let from = snapshot.time_us.saturating_add(job.period_us);
            let Some(mut base) = resume(snapshot, job.baseline_slot, &programs, job.period_us)
            else {
                return Err("the PLC's state could not be resumed on a fork".into());
            };
            let cand_slot = if job.on_probation {
                job.baseline_slot.other()
            } else {
                job.baseline_slot
            };
            let Some(mut cand) = resume(snapshot, cand_slot, &programs, job.period_us) else {
                return Err("the candidate's state could not be resumed on a fork".into());
            };
            continue_inputs(&mut base, read);
            continue_inputs(&mut cand, read);
            Ok((base, (**twin).clone(), cand, (**twin).clone(), from))
        }
        Start::Commission(kind) => {
            let mut base = Plc::new(job.baseline.clone(), 0, Box::new(ManualStopwatch::new()));
            base.use_virtual_time(job.period_us);
            let mut cand = Plc::new(candidate.clone(), 0, Box::new(ManualStopwatch::new()));
            cand.use_virtual_time(job.period_us);
            let mut twins = [kind.build(1), kind.build(1)];
            for t in &mut twins {
                // A station that needs its buttons gets them as `cetratus run` gives them; its
                // own start presses name buttons it has.
                let _ = crate::script::press_buttons(t, &[], 0);
            }
            let [a, b] = twins;
            Ok((base, a, cand, b, 0))
        }
    }
}

/// The verdict on the candidate's run `c` against the baseline's `b`: the candidate's own
/// trouble decides it; the rest is reported so that an operator can weigh it (the cycles each
/// output diverged, apart for those the package declares it changes).
fn verdict(
    job: &Job,
    b: &RunFigures,
    c: &RunFigures,
    (divergent, diverged): (u64, &[(String, u64)]),
    t0: Instant,
) -> Verdict {
    let share = if b.produced == 0 {
        1.0
    } else {
        c.produced as f64 / b.produced as f64
    };
    let mut reasons = failures(job, b, c, share);
    let passed = reasons.is_empty();
    if let Some(d) = job.update.meta.declared_share() {
        reasons.push(format!(
            "the package declares that its production may drop to {:.0} % of the old program's: judged against that",
            d * 100.0
        ));
    }

    if !b.twin_faults.is_empty() || !b.alarms.is_empty() {
        reasons.push(format!(
            "the program it replaces also had trouble on its fork: {}",
            b.twin_faults
                .iter()
                .chain(&b.alarms)
                .cloned()
                .collect::<Vec<_>>()
                .join("; ")
        ));
    }
    let mut figures = BTreeMap::new();
    figures.insert("horizon_s".into(), job.policy.horizon_us as f64 / 1e6);
    figures.insert("parts_baseline".into(), b.produced as f64);
    figures.insert("parts_candidate".into(), c.produced as f64);
    figures.insert("throughput_share".into(), share);
    figures.insert("divergent_cycles".into(), divergent as f64);
    // Per output that diverged: `divergent_cycles.OUT`, or `declared_divergent_cycles.OUT` for
    // one the package declares it changes.
    for (name, n) in diverged {
        let key = if job.update.meta.may_differ(name) {
            "declared_divergent_cycles"
        } else {
            "divergent_cycles"
        };
        figures.insert(format!("{key}.{name}"), *n as f64);
    }
    figures.insert("twin_faults".into(), c.twin_faults.len() as f64);
    figures.insert("alarms".into(), c.alarms.len() as f64);
    figures.insert("validation_ms".into(), t0.elapsed().as_secs_f64() * 1e3);
    Verdict {
        kind: VerdictKind::Twin,
        result: if passed {
            VerdictResult::Pass
        } else {
            VerdictResult::Fail
        },
        reasons,
        figures,
        signature: None,
    }
}

/// Why the candidate may not drive the plant, if at all: its twin faults and alarms, and a
/// production below the share the package declares it may drop to, or else the node's `share`.
fn failures(job: &Job, b: &RunFigures, c: &RunFigures, share: f64) -> Vec<String> {
    let mut reasons = Vec::new();
    for f in &c.twin_faults {
        reasons.push(format!("twin fault: {f}"));
    }
    for a in &c.alarms {
        reasons.push(a.clone());
    }
    // The package's own declaration, signed with it, takes the place of the node's share.
    let required = job
        .update
        .meta
        .declared_share()
        .unwrap_or(job.policy.throughput_share);
    if share < required {
        reasons.push(format!(
            "throughput: the candidate produced {} parts in {:.0} s of plant time, {:.0} % of the {} of the program it replaces, below the {:.0} % required",
            c.produced,
            job.policy.horizon_us as f64 / 1e6,
            share * 100.0,
            b.produced,
            required * 100.0
        ));
        // A part is the unit of production: over a horizon that holds few, where a part is at
        // its end decides more than the program does.
        if (b.produced as f64) * (1.0 - required) < 1.0 {
            reasons.push(format!(
                "the horizon holds only {} parts of the program it replaces, so one part is {:.0} % of its production: a longer horizon judges throughput rather than the phase",
                b.produced,
                100.0 / b.produced as f64
            ));
        }
    }
    reasons
}

/// A finished validation: the verdict and the program it is about.
pub struct Done {
    /// [`Program::hash`] of the update's program.
    pub program_hash: [u8; 32],
    /// The verdict.
    pub verdict: Verdict,
}

/// The node's validation thread: one job at a time; a job that comes while one runs replaces
/// the one waiting.
pub struct Validator {
    jobs: SyncSender<Job>,
    done: Receiver<Done>,
    /// The settings.
    pub policy: ValidationPolicy,
}

impl Validator {
    /// Starts the thread.
    pub fn start(policy: ValidationPolicy) -> Self {
        let (jobs, rx) = sync_channel::<Job>(1);
        let (tx, done) = sync_channel::<Done>(4);
        let _ = std::thread::Builder::new()
            .name("cetratus-validate".into())
            .spawn(move || {
                crate::rt::normal();
                while let Ok(job) = rx.recv() {
                    let verdict = validate(&job);
                    let program_hash = job.update.program.hash();
                    if tx
                        .send(Done {
                            program_hash,
                            verdict,
                        })
                        .is_err()
                    {
                        return;
                    }
                }
            });
        Validator { jobs, done, policy }
    }

    /// Hands a job over without waiting; false when one is already waiting.
    pub fn submit(&self, job: Job) -> bool {
        self.jobs.try_send(job).is_ok()
    }

    /// A finished validation, if any, without waiting.
    pub fn try_done(&self) -> Option<Done> {
        self.done.try_recv().ok()
    }

    /// Waits for a finished validation (virtual time: a run is deterministic only when the
    /// verdict comes at a cycle the run decides).
    pub fn wait_done(&self) -> Option<Done> {
        self.done.recv().ok()
    }
}

/// The job that validates the update under way on `plc`, starting from `start`.
pub fn job_for(plc: &Plc, start: Start, policy: ValidationPolicy, period_us: u64) -> Option<Job> {
    let update = plc.resolved_update()?;
    let on_probation = plc.status() == Status::Probation;
    let baseline_slot = if on_probation {
        plc.primary().other()
    } else {
        plc.primary()
    };
    let baseline = plc.container(baseline_slot)?.program().clone();
    Some(Job {
        baseline,
        update,
        baseline_slot,
        on_probation,
        start,
        period_us,
        policy,
    })
}
