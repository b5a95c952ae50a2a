//! Running a rollout: `start` checks the plan against the fleet the broker shows and records
//! it; `resume` takes a recorded rollout up again (after a crash, or to carry on after a
//! pause); `abort` and `pause` act on a rollout that runs in another process by a request in
//! its state directory, or run it themselves when none does. Each drives one loop: take in what
//! the broker says, move the rollout on, save its record, then send its commands, so that a
//! crash after a send never forgets the send.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use cetratus_program::package;
use cetratus_proto::Labels;

use crate::journal::{self, Journal};
use crate::link::{Link, LinkConfig};
use crate::plan::read_capped;
use crate::record::{Outcome, Record, Target};
use crate::rollout::{Request, Rollout};
use crate::view::View;
use crate::{FleetError, Plan};

/// Most bytes of a package file a rollout reads.
pub const MAX_PACKAGE_BYTES: u64 = 64 << 20;
/// How often the rollout looks at the fleet, its requests and its clock.
const TICK: Duration = Duration::from_millis(100);

/// Called with the record and the new log lines after each change.
pub type Progress = Box<dyn FnMut(&Record, &[String]) + Send>;

/// What every run needs besides the plan or the record.
pub struct Options {
    /// The broker, and who the rollout is on it.
    pub link: LinkConfig,
    /// The state directory.
    pub state_dir: PathBuf,
    /// How long to listen to the broker before the fleet counts as seen.
    pub discover: Duration,
    /// Called with the record and the new log lines after each change.
    pub progress: Progress,
}

/// Starts the rollout of the plan at `plan_path`, and drives it to its end.
pub fn start(plan_path: &Path, o: Options) -> Result<Record, FleetError> {
    let shown = plan_path.display().to_string();
    let plan_text = Plan::read(plan_path)?;
    let plan_dir = plan_path.parent().unwrap_or(Path::new("."));
    let plan = Plan::parse(&plan_text, &shown, plan_dir)?;
    let (bytes, target) = read_package(&plan.package)?;
    let journal = Journal::hold(&o.state_dir)?;
    if let Ok(old) = journal::read(&o.state_dir) {
        if !old.outcome.ended() {
            return Err(FleetError::Busy(format!(
                "rollout {} in {} has not ended ({}); resume it or abort it, or give another --state-dir",
                old.id,
                o.state_dir.display(),
                old.outcome.as_str()
            )));
        }
    }
    let link = Link::connect(o.link, &bytes)?;
    let mut view = View::new(link.reply_leaf());
    listen(&link, &mut view, o.discover)?;
    let stages = check_fleet(&plan, &target, &view)?;
    let name = plan_path
        .file_stem()
        .map_or("rollout".into(), |s| s.to_string_lossy().into_owned());
    let id = format!("{name}-{}", cetratus_mct::unix_now());
    let record = Record::new(id, (&shown, &plan_text), target, stages);
    journal.save(&record)?;
    drive(journal, link, view, Rollout::new(plan, record), o.progress)
}

/// Takes the rollout recorded in the state directory up again and drives it to its end; one
/// that has ended is returned as it is.
pub fn resume(o: Options) -> Result<Record, FleetError> {
    let journal = Journal::hold(&o.state_dir)?;
    let record = journal::read(&o.state_dir)?;
    if record.outcome.ended() {
        return Ok(record);
    }
    let (plan, bytes) = recorded_plan(&record)?;
    let link = Link::connect(o.link, &bytes)?;
    let mut view = View::new(link.reply_leaf());
    listen(&link, &mut view, o.discover)?;
    let mut rollout = Rollout::new(plan, record);
    rollout.request(Request::Resume);
    drive(journal, link, view, rollout, o.progress)
}

/// Aborts the rollout of the state directory: asks the process that runs it, or, when none
/// does, removes or reverts its PLCs mid-update itself. `None` when another process does it.
pub fn abort(o: Options) -> Result<Option<Record>, FleetError> {
    if journal::held(&o.state_dir) {
        journal::ask(&o.state_dir, Request::Abort)?;
        return Ok(None);
    }
    let journal = Journal::hold(&o.state_dir)?;
    let record = journal::read(&o.state_dir)?;
    if record.outcome == Outcome::Done || record.outcome == Outcome::Aborted {
        return Ok(Some(record));
    }
    let (plan, bytes) = recorded_plan(&record)?;
    let link = Link::connect(o.link, &bytes)?;
    let mut view = View::new(link.reply_leaf());
    listen(&link, &mut view, o.discover)?;
    let mut rollout = Rollout::new(plan, record);
    rollout.record.outcome = Outcome::Running;
    rollout.request(Request::Abort);
    drive(journal, link, view, rollout, o.progress).map(Some)
}

/// Pauses the rollout of `dir`: asks the process that runs it, or records the pause for the
/// next `resume`. Whether a running process was asked.
pub fn pause(dir: &Path) -> Result<bool, FleetError> {
    if journal::held(dir) {
        journal::ask(dir, Request::Pause)?;
        return Ok(true);
    }
    let journal = Journal::hold(dir)?;
    let mut record = journal::read(dir)?;
    if !record.outcome.ended() {
        record.paused = true;
        journal.save(&record)?;
    }
    Ok(false)
}

/// The plan a record started with, and its package, which must be the same file.
fn recorded_plan(record: &Record) -> Result<(Plan, Vec<u8>), FleetError> {
    let path = Path::new(&record.plan_file);
    let dir = path.parent().unwrap_or(Path::new("."));
    let plan = Plan::parse(&record.plan_text, &record.plan_file, dir)?;
    let (bytes, target) = read_package(&plan.package)?;
    if target.file_sha256 != record.target.file_sha256 {
        return Err(FleetError::Package {
            path: plan.package.display().to_string(),
            reason: "it is not the file the rollout started with (its SHA-256 changed); \
                     abort this rollout and start a new one for the new package"
                .into(),
        });
    }
    Ok((plan, bytes))
}

/// Reads the package and what the rollout needs of its manifest (its signature is the PLCs' to
/// check).
fn read_package(path: &Path) -> Result<(Vec<u8>, Target), FleetError> {
    let shown = path.display().to_string();
    let bad = |reason: String| FleetError::Package {
        path: shown.clone(),
        reason,
    };
    let Some(bytes) = read_capped(path, MAX_PACKAGE_BYTES).map_err(|e| bad(e.to_string()))? else {
        return Err(bad(format!(
            "more than the {MAX_PACKAGE_BYTES} bytes a package may have"
        )));
    };
    let info = package::inspect(&bytes).map_err(|e| bad(e.to_string()))?;
    let target = Target {
        update: format!("{} {}", info.meta.name, info.meta.version),
        program_hash: info.program.hash_hex().to_string(),
        base_hash: info.meta.base_program_hash.clone(),
        may_differ: info.meta.changes.outputs.clone(),
        file_sha256: info.hash_hex.clone(),
    };
    Ok((bytes, target))
}

/// Takes in what the broker says for `wait`.
fn listen(link: &Link, view: &mut View, wait: Duration) -> Result<(), FleetError> {
    let end = Instant::now() + wait;
    loop {
        let left = end.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Ok(());
        }
        if let Some(m) = link.recv(left)? {
            view.take(
                &m.plc,
                &m.leaf,
                &m.payload,
                m.correlation.as_deref(),
                Instant::now(),
            );
        }
    }
}

/// The stages' PLCs of the fleet the view shows, once the plan holds for each: every PLC of the
/// selection has a probation window the plan's fits in, and one at least runs the package's
/// base program (or already its new one).
fn check_fleet(plan: &Plan, target: &Target, view: &View) -> Result<Vec<Vec<String>>, FleetError> {
    let fleet: Vec<(String, Labels)> = (view.all())
        .filter_map(|(id, s)| {
            Some((
                id.clone(),
                s.state.as_ref().filter(|_| s.online)?.labels.clone(),
            ))
        })
        .collect();
    let stages = plan.stage_members(&fleet)?;
    let mut runs_base = false;
    for id in stages.iter().flatten() {
        let Some(seen) = view.get(id) else { continue };
        if let Some(why) = crate::rollout::window_too_short(plan.probation_us, seen) {
            return Err(FleetError::Refused(format!("{id}: {why}")));
        }
        let primary = seen.primary_hash().unwrap_or("");
        runs_base |= primary == target.base_hash || primary == target.program_hash;
    }
    if !runs_base {
        return Err(FleetError::Refused(format!(
            "no PLC the selector `{}` picks runs the package's base program {} (or its new one); \
             check the package against `cetratus status` of the PLCs",
            plan.select,
            target.base_hash.get(..12).unwrap_or(&target.base_hash)
        )));
    }
    Ok(stages)
}

/// The loop: take in, move on, save, send; until the rollout ends.
fn drive(
    mut journal: Journal,
    link: Link,
    mut view: View,
    mut rollout: Rollout,
    mut progress: Progress,
) -> Result<Record, FleetError> {
    view.watch(rollout.record.plcs.keys().cloned());
    let mut saved = rollout.record.clone();
    loop {
        listen(&link, &mut view, TICK)?;
        if let Some(r) = journal.take_request() {
            rollout.request(r);
        }
        let now = Instant::now();
        let orders = rollout.tick(&view, now);
        for o in &orders {
            rollout.log.push(format!("{}: {} sent", o.plc, o.verb));
        }
        if rollout.record != saved || !orders.is_empty() {
            journal.save(&rollout.record)?;
            saved = rollout.record.clone();
        }
        for o in orders {
            let correlation = crate::link::correlation(o.verb);
            link.send(&o.plc, o.verb, &correlation)?;
            view.sent(&o.plc, o.verb, correlation, now);
        }
        if !rollout.log.is_empty() {
            let lines = std::mem::take(&mut rollout.log);
            for l in &lines {
                journal.log(l);
            }
            progress(&rollout.record, &lines);
        }
        if rollout.record.outcome.ended() {
            link.close();
            return Ok(rollout.record);
        }
    }
}
