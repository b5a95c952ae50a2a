//! Twin validation on the real PLC and the real twins, in virtual time: U.1 forked from a running
//! Vernadat cell passes; a candidate that stalls, or that slows machine 2 down, fails unless its
//! package says it changes throughput; F.1 commissioned on fresh Festo twins passes; a verdict
//! that fails during probation reverts.

use std::path::Path;
use std::sync::Arc;

use cetratus_io::TwinDriver;
use cetratus_node::validate::{self, Start, ValidationMode, ValidationPolicy};
use cetratus_program::{build_package, Program, TrustStore};
use cetratus_runtime::{
    Command, EventKind, ManualStopwatch, Plc, RevertReason, Slot, Status, SubstituteMode,
    SubstituteRequest, VerdictResult,
};
use cetratus_twin::{Twin, TwinKind, VernadatCell, VernadatParams};

const VERNADAT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/vernadat");
const FESTO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/festo");
const PERIOD: u64 = 10_000;

fn workshop(example: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("a temporary directory");
    for entry in std::fs::read_dir(example).expect("the example") {
        let path = entry.expect("an entry").path();
        if path.extension().is_some_and(|e| e == "toml" || e == "pnml") {
            let name = path.file_name().expect("a name");
            std::fs::copy(&path, dir.path().join(name)).expect("copy");
        }
    }
    dir
}

/// Replaces `from` by `to` in `file` of the workshop.
fn edit(dir: &Path, file: &str, from: &str, to: &str) {
    let text = std::fs::read_to_string(dir.join(file)).expect("the file");
    assert!(text.contains(from), "{from} in {file}");
    std::fs::write(dir.join(file), text.replace(from, to)).expect("write");
}

struct Cell {
    plc: Plc,
    io: TwinDriver<Twin>,
    now: u64,
}

impl Cell {
    fn new(program: Arc<Program>) -> Self {
        let io = TwinDriver::new(
            TwinKind::Vernadat.build(1),
            program.inputs(),
            program.outputs(),
        )
        .expect("the signals match");
        let mut plc = Plc::new(program, 0, Box::new(ManualStopwatch::new()));
        plc.use_virtual_time(PERIOD);
        Cell { plc, io, now: 0 }
    }
    fn run_for(&mut self, us: u64) {
        let end = self.now + us;
        while self.now < end {
            self.plc.cycle(self.now, &mut self.io);
            drop(self.plc.take_retired());
            self.now += PERIOD;
        }
    }
    fn load(&mut self, dir: &Path, manifest: &str) {
        let (bytes, _) =
            build_package(&dir.join(manifest), None, 1_700_000_000).expect("the package builds");
        let p = self
            .plc
            .update_context()
            .prepare_package(
                &bytes,
                &TrustStore::empty(),
                cetratus_program::Unsigned::Allowed,
                cetratus_program::OtherBase::Refused,
            )
            .expect("prepared");
        self.plc
            .command(Command::Load(Box::new(p)))
            .expect("accepted");
        self.run_for(PERIOD);
        assert_eq!(self.plc.status(), Status::Quarantine);
    }
    /// The validation of the update under way, forked now.
    fn fork_job(&self, policy: ValidationPolicy) -> validate::Job {
        let start = Start::fork(&self.plc, self.io.plant().clone());
        validate::job_for(&self.plc, start, policy, PERIOD).expect("an update under way")
    }
}

fn policy(horizon_s: u64) -> ValidationPolicy {
    ValidationPolicy {
        mode: ValidationMode::Fork,
        horizon_us: horizon_s * 1_000_000,
        ..ValidationPolicy::default()
    }
}

/// `manifest` of the workshop `dir` built unsigned into a package file beside it; its path.
fn package_file(dir: &Path, manifest: &str) -> std::path::PathBuf {
    let (bytes, _) = build_package(&dir.join(manifest), None, 1_700_000_000).expect("it builds");
    let pkg = dir.join(manifest.replace(".package.toml", ".cpkg"));
    std::fs::write(&pkg, bytes).expect("write");
    pkg
}

/// A node in virtual time: `program` against `twin`, its limits changed by `tune`, the
/// scripted commands `script`, unsigned loads allowed, and twin validation by `policy`.
fn validated_node(
    program: Arc<Program>,
    twin: Twin,
    tune: impl FnOnce(&mut cetratus_runtime::Limits),
    script: &[String],
    policy: ValidationPolicy,
) -> cetratus_node::Node<TwinDriver<Twin>> {
    use cetratus_node::script::Script;
    use cetratus_node::{Node, NodeOptions};

    let io = TwinDriver::new(twin, program.inputs(), program.outputs()).expect("signals match");
    let mut plc = Plc::new(program, 0, Box::new(ManualStopwatch::new()));
    plc.use_virtual_time(PERIOD);
    let mut limits = plc.limits();
    tune(&mut limits);
    plc.set_limits(limits);
    let opts = NodeOptions {
        base_us: 0,
        load: cetratus_node::load::LoadPolicy {
            trust: TrustStore::empty(),
            unsigned: cetratus_program::Unsigned::Allowed,
            gate: Default::default(),
        },
        record_trace: false,
        watch: Vec::new(),
        progress_every: None,
    };
    Node::new(plc, io, opts)
        .with_script(Script::parse(script).expect("script"))
        .with_twin_validation(policy, PERIOD)
}

/// Steps `node` from 0 until `until_us` of virtual time, or until `done` holds of the events
/// so far; the events.
fn run_node(
    node: &mut cetratus_node::Node<TwinDriver<Twin>>,
    until_us: u64,
    done: impl Fn(&[cetratus_runtime::Event]) -> bool,
) -> Vec<cetratus_runtime::Event> {
    let idle = cetratus_runtime::LoopTiming::default();
    let mut events = Vec::new();
    let mut now = 0;
    while now < until_us && !done(&events) {
        events.extend(node.step(now, &idle).expect("a cycle"));
        now += PERIOD;
    }
    events
}

#[test]
fn u1_forked_from_a_running_cell_passes_over_ten_minutes_of_plant_time() {
    let dir = workshop(VERNADAT);
    let mut cell = Cell::new(Arc::new(
        Program::load(&dir.path().join("vernadat.toml")).expect("program"),
    ));
    cell.run_for(20_000_000);
    cell.load(dir.path(), "u1.package.toml");
    let before = (cell.plc.cycles(), cell.io.plant().clone());
    let v = validate::validate(&cell.fork_job(ValidationPolicy {
        mode: ValidationMode::Fork,
        ..ValidationPolicy::default()
    }));
    assert_eq!(v.result, VerdictResult::Pass, "{v:?}");
    assert!(
        v.reasons.is_empty(),
        "neither run had trouble on its fork: {v:?}"
    );
    assert_eq!(v.figures["horizon_s"], 600.0);
    let (base, cand) = (v.figures["parts_baseline"], v.figures["parts_candidate"]);
    assert!(
        (60.0..=76.0).contains(&base),
        "M2 bounds 10 min at 75 parts: {base}"
    );
    // The candidate's run starts two cycles later (install, switch): a part may fall on either
    // side of the horizon.
    assert!(
        cand + 1.0 >= base,
        "two more buffer slots make as many parts: {cand} < {base}"
    );
    assert_eq!(
        (cell.plc.cycles(), cell.io.plant().clone()),
        before,
        "the PLC and its twin are untouched"
    );
}

#[test]
fn a_candidate_that_stalls_on_its_fork_fails_with_the_stall() {
    let dir = workshop(VERNADAT);
    edit(
        dir.path(),
        "u1.toml",
        "T11 = \"FCM1\"",
        "T11 = \"FCM1 && P11.t >= 3600s\"",
    );
    let mut cell = Cell::new(Arc::new(
        Program::load(&dir.path().join("vernadat.toml")).expect("program"),
    ));
    cell.run_for(5_000_000);
    cell.load(dir.path(), "u1.package.toml");
    let v = validate::validate(&cell.fork_job(policy(120)));
    assert_eq!(v.result, VerdictResult::Fail, "{v:?}");
    let text = v.reasons.join("\n");
    assert!(text.contains("stall_alarm"), "{text}");
    assert!(
        text.contains("throughput"),
        "it makes nothing either: {text}"
    );
}

#[test]
fn a_candidate_that_slows_machine_2_fails_on_throughput_unless_its_package_says_so() {
    let dir = workshop(VERNADAT);
    // M2 is loaded 5 s after the robot brought the part: 12 s a part instead of 8.
    edit(
        dir.path(),
        "u1.toml",
        "T21 = \"FCM2\"",
        "T21 = \"FCM2 && P22.t >= 5s\"",
    );
    let mut cell = Cell::new(Arc::new(
        Program::load(&dir.path().join("vernadat.toml")).expect("program"),
    ));
    cell.run_for(5_000_000);
    cell.load(dir.path(), "u1.package.toml");
    let v = validate::validate(&cell.fork_job(policy(300)));
    assert_eq!(v.result, VerdictResult::Fail, "{v:?}");
    assert!(v.figures["throughput_share"] < 0.8, "{v:?}");
    assert!(
        v.reasons.join("\n").contains("below the 90 % required"),
        "{v:?}"
    );

    edit(
        dir.path(),
        "u1.package.toml",
        "base = \"vernadat.toml\"",
        "base = \"vernadat.toml\"\nchanges_throughput = true",
    );
    let mut cell = Cell::new(Arc::new(
        Program::load(&dir.path().join("vernadat.toml")).expect("program"),
    ));
    cell.run_for(5_000_000);
    cell.load(dir.path(), "u1.package.toml");
    let v = validate::validate(&cell.fork_job(policy(300)));
    assert_eq!(v.result, VerdictResult::Pass, "{v:?}");
    assert!(v.reasons.join("\n").contains("may drop to 0 %"), "{v:?}");
}

#[test]
fn f1_commissioned_on_fresh_festo_twins_passes() {
    let dir = workshop(FESTO);
    let base = Arc::new(Program::load(&dir.path().join("festo.toml")).expect("program"));
    let (bytes, _) =
        build_package(&dir.path().join("f1.package.toml"), None, 1_700_000_000).expect("F.1");
    let plc = Plc::new(base.clone(), 0, Box::new(ManualStopwatch::new()));
    plc.update_context()
        .prepare_package(
            &bytes,
            &TrustStore::empty(),
            cetratus_program::Unsigned::Allowed,
            cetratus_program::OtherBase::Refused,
        )
        .expect("F.1 fits the Festo program");
    let pkg = cetratus_program::UpdatePackage::verify(
        &bytes,
        &TrustStore::empty(),
        cetratus_program::Unsigned::Allowed,
    )
    .expect("verifies");
    let update = pkg
        .resolve(&base, cetratus_program::OtherBase::Refused)
        .expect("resolves");
    let job = validate::Job {
        baseline: base,
        update,
        baseline_slot: Slot::A,
        on_probation: false,
        start: Start::Commission(TwinKind::Festo),
        period_us: PERIOD,
        policy: ValidationPolicy {
            mode: ValidationMode::Commission(TwinKind::Festo),
            horizon_us: 300_000_000,
            ..ValidationPolicy::default()
        },
    };
    let v = validate::validate(&job);
    assert_eq!(v.result, VerdictResult::Pass, "{v:?}");
    assert!(v.figures["parts_baseline"] >= 50.0, "{v:?}");
}

#[test]
fn a_failing_verdict_during_probation_reverts_at_the_next_cycle() {
    let dir = workshop(VERNADAT);
    edit(
        dir.path(),
        "u1.toml",
        "T21 = \"FCM2\"",
        "T21 = \"FCM2 && P22.t >= 5s\"",
    );
    let mut cell = Cell::new(Arc::new(
        Program::load(&dir.path().join("vernadat.toml")).expect("program"),
    ));
    let mut limits = cell.plc.limits();
    limits.probation_us = 600_000_000;
    cell.plc.set_limits(limits);
    cell.run_for(5_000_000);
    cell.load(dir.path(), "u1.package.toml");
    cell.plc
        .command(Command::Substitute(SubstituteRequest::now(
            SubstituteMode::Retransform,
        )))
        .expect("substitute");
    cell.run_for(PERIOD);
    assert_eq!(cell.plc.status(), Status::Probation);
    let job = cell.fork_job(policy(300));
    assert!(job.on_probation);
    let hash = job.update.program.hash();
    let v = validate::validate(&job);
    assert_eq!(v.result, VerdictResult::Fail, "{v:?}");
    let _ = cell.plc.drain_events();
    assert!(cell.plc.add_verdict(&hash, v));
    let detected = cell.plc.cycles();
    cell.run_for(PERIOD);
    let events = cell.plc.drain_events();
    let reverted = events
        .iter()
        .find(|e| e.kind == EventKind::Reverted)
        .unwrap_or_else(|| panic!("{events:#?}"));
    assert!(
        matches!(
            reverted.detail,
            Some(cetratus_runtime::EventDetail::Revert {
                reason: RevertReason::Verdict,
                detected_cycle,
                ..
            }) if detected_cycle == detected
        ),
        "{reverted:?}"
    );
    assert_eq!(cell.plc.primary(), Slot::A);
}

/// The verdict of a fork taken at any cycle, as a real-time run takes it at a cycle it does not
/// choose: U.1 loaded at 24 instants a prime number of cycles apart (over two minutes of the
/// cell, across its buffer filling up) passes over two minutes of plant time at every one. Over
/// one minute it does not: that holds 6 to 8 parts, and U.1, which keeps M1 going where the old
/// program blocks it at a full buffer, is a part behind at some phases (docs/live-update.md).
#[test]
fn u1_forked_at_any_cycle_passes_over_two_minutes_of_plant_time() {
    let dir = workshop(VERNADAT);
    let mut cell = Cell::new(Arc::new(
        Program::load(&dir.path().join("vernadat.toml")).expect("program"),
    ));
    cell.run_for(3_000_000);
    let mut failed = Vec::new();
    for _ in 0..24 {
        cell.run_for(503 * PERIOD);
        cell.load(dir.path(), "u1.package.toml");
        let v = validate::validate(&cell.fork_job(policy(120)));
        if v.result != VerdictResult::Pass {
            failed.push(format!("fork at {:.2} s: {v:?}", cell.now as f64 / 1e6));
        }
        cell.plc.command(Command::Abort).expect("abort");
        cell.run_for(PERIOD);
        assert_eq!(cell.plc.status(), Status::Idle);
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

/// The two runs of a fork start at the same cycle boundary: the baseline runs on through the two
/// cycles the candidate's install and substitution take. U.1 does what the old program does
/// until the buffer fills, so over the first 20 s their outputs agree cycle for cycle (before,
/// the candidate's run was two cycles late, and every output edge counted as divergent).
#[test]
fn both_runs_of_a_fork_start_at_the_same_cycle() {
    let dir = workshop(VERNADAT);
    let mut cell = Cell::new(Arc::new(
        Program::load(&dir.path().join("vernadat.toml")).expect("program"),
    ));
    for _ in 0..5 {
        cell.run_for(139 * PERIOD);
        cell.load(dir.path(), "u1.package.toml");
        let v = validate::validate(&cell.fork_job(policy(20)));
        assert_eq!(v.result, VerdictResult::Pass, "{v:?}");
        assert!(v.figures["parts_baseline"] >= 2.0, "{v:?}");
        assert_eq!(v.figures["divergent_cycles"], 0.0, "{v:?}");
        assert_eq!(v.figures["parts_candidate"], v.figures["parts_baseline"]);
        cell.plc.command(Command::Abort).expect("abort");
        cell.run_for(PERIOD);
    }
}

/// A fork continues the edge detection of the PLC it forks: with T11 = `rise(FCM1)` in both
/// programs, a fork whose first cycle is the one in which FCM1 rises sees the rise. Before, a
/// forked PLC had no past and its first scan saw no edge: T11 never fired, CM1 stayed on, and
/// the fork stalled.
#[test]
fn a_fork_taken_just_before_an_edge_sees_it() {
    let dir = workshop(VERNADAT);
    for file in ["vernadat.toml", "u1.toml"] {
        edit(dir.path(), file, "T11 = \"FCM1\"", "T11 = \"rise(FCM1)\"");
    }
    let program = Arc::new(Program::load(&dir.path().join("vernadat.toml")).expect("program"));
    let fcm1 = program
        .inputs()
        .iter()
        .position(|s| s.name == "FCM1")
        .expect("FCM1");
    // The cycle at which FCM1 first rises, from a run of its own (the cell is deterministic).
    let mut probe = Cell::new(program.clone());
    while !matches!(
        probe.plc.inputs()[fcm1],
        cetratus_program::Value::Bool(true)
    ) {
        probe.run_for(PERIOD);
    }
    let rise_us = probe.now - PERIOD;
    // The same cell, loaded so that the fork's first cycle is that one.
    let mut cell = Cell::new(program);
    cell.run_for(rise_us - PERIOD);
    cell.load(dir.path(), "u1.package.toml");
    assert_eq!(cell.now, rise_us);
    assert!(matches!(
        cell.plc.inputs()[fcm1],
        cetratus_program::Value::Bool(false)
    ));
    let v = validate::validate(&cell.fork_job(policy(60)));
    assert_eq!(v.result, VerdictResult::Pass, "{v:?}");
    assert!(
        v.reasons.is_empty(),
        "the baseline has no trouble either: {v:?}"
    );
}

/// A node on the cell validates a new primary again every `revalidate` of its probation window,
/// on a fork of the state of the moment. This candidate stops fetching parts from the buffer once
/// four wait there: the forks of the first moments do not reach that within their horizon and
/// pass; a later one does, fails, and the PLC reverts to the old program for it.
#[test]
fn during_probation_validation_runs_again_and_a_later_failing_verdict_reverts() {
    use cetratus_runtime::Event;

    let dir = workshop(VERNADAT);
    edit(
        dir.path(),
        "u1.toml",
        "T20 = \"SB\"",
        "T20 = \"SB && B < 4\"",
    );
    let pkg = package_file(dir.path(), "u1.package.toml");
    let program = Arc::new(Program::load(&dir.path().join("vernadat.toml")).expect("program"));
    let mut node = validated_node(
        program,
        TwinKind::Vernadat.build(1),
        |l| l.probation_us = 600_000_000,
        &[
            format!("2s load {}", pkg.display()),
            "3s substitute".to_string(),
        ],
        ValidationPolicy {
            revalidate_us: 5_000_000,
            ..policy(10)
        },
    );
    let events = run_node(&mut node, 300_000_000, |e| {
        e.iter().any(|e| e.kind == EventKind::Reverted)
    });
    let probation = events
        .iter()
        .position(|e| e.kind == EventKind::ProbationStarted)
        .unwrap_or_else(|| panic!("{events:#?}"));
    let verdicts: Vec<&Event> = events[probation..]
        .iter()
        .filter(|e| e.kind == EventKind::Verdict && e.message.starts_with("twin"))
        .collect();
    let text = |v: &[&Event]| {
        v.iter()
            .map(|e| format!("{:.2} s {}", e.time_us as f64 / 1e6, e.message))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert!(verdicts.len() >= 3, "{}", text(&verdicts));
    assert!(
        verdicts[..verdicts.len() - 1]
            .iter()
            .all(|e| e.message.contains(": pass")),
        "{}",
        text(&verdicts)
    );
    let last = verdicts.last().expect("a verdict");
    assert!(last.message.contains(": fail"), "{}", text(&verdicts));
    // Verdicts of the window come every 5 s of program time.
    for w in verdicts.windows(2) {
        assert_eq!(
            w[1].time_us - w[0].time_us,
            5_000_000,
            "{}",
            text(&verdicts)
        );
    }
    let reverted = events
        .iter()
        .find(|e| e.kind == EventKind::Reverted)
        .unwrap_or_else(|| panic!("no revert: {}", text(&verdicts)));
    assert!(
        matches!(
            reverted.detail,
            Some(cetratus_runtime::EventDetail::Revert {
                reason: RevertReason::Verdict,
                ..
            })
        ),
        "{reverted:?}"
    );
    let (plc, _, _) = node.finish().expect("finish");
    assert_eq!(plc.primary(), Slot::A);
}

#[test]
fn a_candidate_with_a_new_output_on_a_field_channel_is_validated_on_its_fork() {
    // The cell's twin is the plant; a field device takes a beacon's output at %QX1.0 (nobody
    // answers at its address: the admission reads the configuration, not the device).
    let dir = workshop(VERNADAT);
    let u1 = dir.path().join("u1.toml");
    let mut text = std::fs::read_to_string(&u1).expect("u1.toml");
    text.push_str("\n[[output]]\nname = \"BEACON\"\ntype = \"bool\"\naddress = \"%QX1.0\"\n\n[[action]]\nplace = \"P12\"\nqualifier = \"N\"\ntarget = \"BEACON\"\n");
    std::fs::write(&u1, text).expect("write u1.toml");
    let program = Arc::new(Program::load(&dir.path().join("vernadat.toml")).expect("program"));
    let config = cetratus_io::config::IoConfig::parse(
        "io.toml",
        "[[device]]\nname = \"beacons\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:1\"\nserves = [{ from = \"%QX1.0\", to = \"%QX1.7\" }]\n",
    )
    .expect("the configuration");
    let map = cetratus_io::map::FieldMap::bind(&config, program.inputs(), program.outputs(), true)
        .expect("the program fits");
    let field = cetratus_io::field::FieldIo::start(&config, map, PERIOD).expect("the I/O thread");
    let mut cell = Cell::new(program);
    cell.plc.set_io_admission(field.admission());
    cell.run_for(5_000_000);
    cell.load(dir.path(), "u1.package.toml");
    assert_eq!(
        cell.plc.io_outputs().last().map(String::as_str),
        Some("BEACON"),
        "the install added the beacon to the I/O map"
    );
    let v = validate::validate(&cell.fork_job(policy(120)));
    assert_eq!(v.result, VerdictResult::Pass, "{v:?}");
    drop(field);
}

/// The paper's U.2 adds 3 s of lubrication a part: on the twin it makes about 72 % of U.1's
/// parts, below the node's 90 %. Its package declares its lubrication outputs and that its
/// production may drop to 65 % (`[changes]`, signed with it), and passes against that; without
/// the declaration the same program fails on throughput.
#[test]
fn u2_passes_with_its_declared_changes_and_fails_without_them() {
    let dir = workshop(VERNADAT);
    let verdict = |dir: &Path| {
        let mut cell = Cell::new(Arc::new(
            Program::load(&dir.join("u1.toml")).expect("program"),
        ));
        cell.run_for(5_000_000);
        cell.load(dir, "u2.package.toml");
        validate::validate(&cell.fork_job(ValidationPolicy {
            mode: ValidationMode::Fork,
            ..ValidationPolicy::default()
        }))
    };
    let v = verdict(dir.path());
    assert_eq!(v.result, VerdictResult::Pass, "{v:?}");
    let share = v.figures["throughput_share"];
    assert!((0.65..0.9).contains(&share), "{v:?}");
    assert!(v.figures["declared_divergent_cycles.LM1"] > 0.0, "{v:?}");
    assert!(v.reasons.join("\n").contains("may drop to 65 %"), "{v:?}");
    let text = std::fs::read_to_string(dir.path().join("u2.package.toml")).expect("manifest");
    let start = text.find("[changes]").expect("U.2 declares its changes");
    let end = start + text[start..].find("\n\n").expect("the section ends");
    std::fs::write(
        dir.path().join("u2.package.toml"),
        format!("{}{}", &text[..start], &text[end..]),
    )
    .expect("write");
    let v = verdict(dir.path());
    assert_eq!(v.result, VerdictResult::Fail, "{v:?}");
    assert!(
        v.reasons.join("\n").contains("below the 90 % required"),
        "{v:?}"
    );
}

/// The paper's last step, the twin against the quarantine: U.1, its guard of T22 replaced by
/// `t22`, is validated in commission mode on a fresh twin of the model (ten minutes), and then
/// runs in quarantine on `plant` for `for_s` seconds (no substitution). Returns the events.
fn u1_quarantined_on(plant: VernadatParams, t22: &str, for_s: u64) -> Vec<cetratus_runtime::Event> {
    let dir = workshop(VERNADAT);
    edit(
        dir.path(),
        "u1.toml",
        "T22 = \"FPM2\"",
        &format!("T22 = \"{t22}\""),
    );
    let pkg = package_file(dir.path(), "u1.package.toml");
    let program = Arc::new(Program::load(&dir.path().join("vernadat.toml")).expect("program"));
    let twin = Twin::Vernadat(VernadatCell::new(plant, 1).expect("valid parameters"));
    let mut node = validated_node(
        program,
        twin,
        |_| {},
        &[format!("2s load {}", pkg.display())],
        ValidationPolicy {
            mode: ValidationMode::Commission(TwinKind::Vernadat),
            ..ValidationPolicy::default()
        },
    );
    run_node(&mut node, for_s * 1_000_000, |_| false)
}

fn verdicts<'e>(events: &'e [cetratus_runtime::Event], kind: &str) -> Vec<&'e str> {
    events
        .iter()
        .filter(|e| e.kind == EventKind::Verdict && e.message.starts_with(kind))
        .map(|e| e.message.as_str())
        .collect()
}

/// A plant that is not the model: its machine 2 takes 24 s where the twin's takes 6. The
/// candidate is U.1 with a timeout bug: it unloads M2 when M2 says it is finished *or* after
/// 10 s (`T22 = "FPM2 || P21.t >= 10s"`). On the twin the machine is always done first, so the
/// candidate passes there and its signature holds only U.1's buffer; on the slow plant it
/// unloads a part mid-cut (T22 fires in the candidate only; in the primary its guard is false),
/// which the twin never showed: the quarantine verdict fails and names it. Without the
/// comparison it would have passed. The same candidate on a plant like the model, and plain
/// U.1 on the slow plant, pass.
#[test]
fn a_candidate_that_passed_on_the_twin_fails_in_quarantine_on_a_plant_the_twin_did_not_model() {
    let slow = VernadatParams {
        m2_machining_us: 24_000_000,
        ..VernadatParams::default()
    };
    let timeout = "FPM2 || P21.t >= 10s";
    let events = u1_quarantined_on(slow.clone(), timeout, 120);
    let twin = verdicts(&events, "twin");
    assert!(twin.len() == 1 && twin[0].contains(": pass"), "{twin:#?}");
    let q = verdicts(&events, "quarantine");
    let fail = q
        .iter()
        .find(|m| m.contains(": fail"))
        .unwrap_or_else(|| panic!("no failing quarantine verdict: {q:#?}"));
    assert!(fail.contains("unexplained divergence"), "{fail}");
    assert!(fail.contains("T22 fired in the candidate only"), "{fail}");
    assert!(fail.contains("the twin never showed it"), "{fail}");

    for (plant, t22) in [(VernadatParams::default(), timeout), (slow, "FPM2")] {
        let events = u1_quarantined_on(plant, t22, 120);
        let q = verdicts(&events, "quarantine");
        assert!(
            !q.is_empty() && q.iter().all(|m| m.contains(": pass")),
            "{t22}: {q:#?}"
        );
    }
}

/// The paper's U.2 with `require_verdict = true`, validated on a fork of the plant: its package
/// declares its lubrication outputs and its slower production, the twin verdict passes against
/// them, the quarantine shows the divergences the twin showed and nothing else, and the
/// substitution asked for once the quarantine has run its course is taken.
#[test]
fn u2_with_its_declared_changes_is_substituted_where_a_verdict_is_required() {
    let dir = workshop(VERNADAT);
    let pkg = package_file(dir.path(), "u2.package.toml");
    let program = Arc::new(Program::load(&dir.path().join("u1.toml")).expect("program"));
    let mut node = validated_node(
        program,
        TwinKind::Vernadat.build(1),
        |l| l.require_verdict = true,
        &[
            format!("2s load {}", pkg.display()),
            "150s substitute".to_string(),
        ],
        policy(120),
    );
    let events = run_node(&mut node, 160_000_000, |_| false);
    let said: Vec<String> = events
        .iter()
        .filter(|e| {
            matches!(
                e.kind,
                EventKind::Verdict | EventKind::Substituted | EventKind::Refused
            )
        })
        .map(|e| format!("{:.1} s {}: {}", e.time_us as f64 / 1e6, e.kind, e.message))
        .collect();
    assert!(
        events.iter().any(|e| e.kind == EventKind::Substituted),
        "{said:#?}"
    );
    let q = verdicts(&events, "quarantine");
    assert!(
        !q.is_empty() && q.iter().all(|m| m.contains(": pass")),
        "{said:#?}"
    );
}
