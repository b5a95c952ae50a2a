//! Scripted operator commands at program times (`run --at "10s load u1.cpkg"`): the paper's
//! experiment, replayed without anyone at the keyboard.
//!
//! A scripted package is read, verified and built on a thread of its own (the script's
//! preparer), never on the scan thread: a package of a million places takes seconds to build.
//! A load is prepared when it is due, against the primary and its marking at that cycle
//! boundary: the analysis gate starts from the marking the install transforms. When it is due:
//! * in virtual time ([`Pace::Virtual`]) the loop waits for its preparation, so it is applied at
//!   the cycle its time names, however long the preparation took: a virtual run is the same
//!   every time;
//! * in real time ([`Pace::Real`]) the scan goes on, and the load is applied at the first cycle
//!   boundary at or after its time at which it is ready.
//!
//! Either way the install itself happens at a cycle boundary, within stateTransTimeout (the
//! runtime's `Updater`).

use std::sync::mpsc::{sync_channel, Receiver, SyncSender};

use crate::load::LoadPolicy;
use cetratus_program::duration::{self, Bare};
use cetratus_runtime::{
    Command, Plc, PreparedUpdate, SubstituteMode, SubstituteRequest, UpdateContext,
};
use cetratus_vocab::Verb as Name;

/// Why a script cannot be run.
#[derive(Debug, thiserror::Error)]
pub enum ScriptError {
    /// An item is not `TIME VERB [ARG]`.
    #[error("--at `{item}`: {reason}")]
    Syntax {
        /// The item as written.
        item: String,
        /// What is wrong, and an example.
        reason: String,
    },
    /// A command's argument cannot be used.
    #[error("{0}")]
    Command(String),
    /// A scripted load was refused.
    #[error("{path}: {refusal}")]
    Load {
        /// The package file.
        path: String,
        /// Why it does not load.
        refusal: Box<crate::load::LoadRefusal>,
    },
}

/// A scripted command: a load names its package file, a substitution its mode.
type Verb = cetratus_vocab::Command<String, SubstituteMode>;

/// One scripted command.
#[derive(Clone, Debug)]
struct Scripted {
    at_us: u64,
    verb: Verb,
}

/// How the loop treats a scripted load that is due but not yet prepared.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Pace {
    /// Virtual time: wait for the preparation, so the load takes effect at its own cycle.
    #[default]
    Virtual,
    /// Real time: go on scanning, and apply the load at the first boundary once it is ready.
    Real,
}

/// A package to prepare: the script item, the file, and the running PLC's context.
struct Job {
    item: usize,
    path: String,
    ctx: UpdateContext,
}

/// A prepared package (or why it cannot be), and the primary it was prepared against.
struct Done {
    item: usize,
    base: [u8; 32],
    result: Result<PreparedUpdate, ScriptError>,
}

/// The script's preparer thread, started with the first load to prepare.
struct Preparer {
    jobs: SyncSender<Job>,
    done: Receiver<Done>,
    // At most one job at a time; `true` while it runs.
    busy: bool,
    // The newest result, until it is used or found stale.
    ready: Option<Done>,
}

impl Preparer {
    fn start(policy: LoadPolicy) -> Self {
        let (jobs, job_rx) = sync_channel::<Job>(1);
        let (done_tx, done) = sync_channel::<Done>(1);
        // Detached: it ends when the script (and so `jobs`) is dropped, after the job under way.
        let _ = std::thread::Builder::new()
            .name("cetratus-script".into())
            .spawn(move || {
                crate::rt::normal();
                while let Ok(Job { item, path, ctx }) = job_rx.recv() {
                    // The analysis gate, here on the script's thread as on the MQTT
                    // preparer's: never on the scan thread.
                    let result = policy
                        .prepare_file(&ctx, std::path::Path::new(&path))
                        .map_err(|refusal| ScriptError::Load {
                            path: path.clone(),
                            refusal: Box::new(refusal),
                        });
                    let base = ctx.primary.hash();
                    if done_tx.send(Done { item, base, result }).is_err() {
                        return;
                    }
                }
            });
        Preparer {
            jobs,
            done,
            busy: false,
            ready: None,
        }
    }

    /// Takes a finished job's result, waiting for it when `wait`.
    fn collect(&mut self, wait: bool) {
        if !self.busy {
            return;
        }
        let got = if wait {
            self.done.recv().ok()
        } else {
            self.done.try_recv().ok()
        };
        if let Some(d) = got {
            self.busy = false;
            self.ready = Some(d);
        } else if wait {
            // The thread is gone (it could not be started): nothing more will come.
            self.busy = false;
        }
    }

    /// The result for `item` prepared against the primary `base`, if there is one.
    fn take(&mut self, item: usize, base: [u8; 32]) -> Option<Result<PreparedUpdate, ScriptError>> {
        match &self.ready {
            Some(d) if d.item == item && d.base == base => self.ready.take().map(|d| d.result),
            _ => None,
        }
    }

    /// Starts preparing `item` against the running PLC, unless a job runs or its result for
    /// this primary is there already.
    fn ensure(&mut self, item: usize, path: &str, plc: &Plc) {
        let base = plc.primary_program().hash();
        let fresh = matches!(&self.ready, Some(d) if d.item == item && d.base == base);
        if self.busy || fresh {
            return;
        }
        self.ready = None;
        let job = Job {
            item,
            path: path.to_string(),
            ctx: plc.update_context(),
        };
        self.busy = self.jobs.try_send(job).is_ok();
    }
}

/// Commands in order of their time; one is given per cycle, so that each takes effect at the
/// next cycle boundary and the next one (a substitute after a load) sees that effect.
#[derive(Default)]
pub struct Script {
    items: Vec<Scripted>,
    next: usize,
    preparer: Option<Preparer>,
    policy: LoadPolicy,
}

impl std::fmt::Debug for Script {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Script")
            .field("items", &self.items)
            .field("next", &self.next)
            .finish()
    }
}

impl Script {
    /// Parses `TIME VERB [ARG]` items: `10s load PKG`, `60s substitute [keep|retransform]`,
    /// `70s remove`, `70s abort`, `80s reset`.
    pub fn parse(items: &[String]) -> Result<Script, ScriptError> {
        let mut v = Vec::new();
        for item in items {
            let syntax = |reason: String| ScriptError::Syntax {
                item: item.clone(),
                reason,
            };
            let mut parts = item.split_whitespace();
            let (Some(t), Some(verb)) = (parts.next(), parts.next()) else {
                return Err(syntax(
                    "expected a time and a command, e.g. `10s load u1.cpkg`".into(),
                ));
            };
            let arg = parts.next();
            let verb = match (verb.parse(), arg) {
                (Ok(Name::Load), Some(path)) => Verb::Load(path.to_string()),
                (Ok(Name::Load), None) => return Err(syntax("`load` needs a package file".into())),
                (Ok(Name::Substitute), m) => Verb::Substitute(match m {
                    Some(m) => m
                        .parse()
                        .map_err(|e: cetratus_runtime::UnknownName| syntax(e.to_string()))?,
                    None => SubstituteMode::Retransform,
                }),
                (Ok(Name::ExecInfo), _) => {
                    return Err(syntax(
                        "`exec_info` is a query, not a command; `cetratus exec-info` asks a \
                         running PLC"
                            .into(),
                    ))
                }
                (Ok(bare), _) => Verb::bare(bare).ok_or_else(|| syntax(bare.to_string()))?,
                (Err(e), _) => return Err(syntax(e.to_string())),
            };
            let at_us = duration::parse_us(t, Bare::Seconds).map_err(|e| syntax(e.to_string()))?;
            v.push(Scripted { at_us, verb });
        }
        v.sort_by_key(|s| s.at_us);
        Ok(Script {
            items: v,
            next: 0,
            preparer: None,
            policy: LoadPolicy::default(),
        })
    }

    /// The keys a scripted package must be signed with (and whether unsigned ones are taken).
    /// Starts the preparer thread when the script loads a package: here, before the run, so that
    /// it does not inherit the scan thread's real-time priority (`--rt`).
    pub fn trusting(mut self, policy: LoadPolicy) -> Self {
        if self.items.iter().any(|s| matches!(s.verb, Verb::Load(_))) {
            self.preparer = Some(Preparer::start(policy.clone()));
        }
        self.policy = policy;
        self
    }

    /// The command due at program time `now_us` (counted from `base_us`), built against `plc`.
    /// A package is prepared on the script's preparer thread; see [`Pace`] for what happens when
    /// it is due before it is ready. Costs the scan thread a comparison of hashes per cycle.
    pub fn due(
        &mut self,
        plc: &Plc,
        now_us: u64,
        base_us: u64,
        pace: Pace,
    ) -> Option<Result<Command, ScriptError>> {
        let Script {
            items,
            next,
            preparer,
            policy,
        } = self;
        let s = items.get(*next)?;
        let due = s.at_us.saturating_add(base_us) <= now_us;
        // Every verb but a load is ready as it is; a load is prepared below.
        let plain = s
            .verb
            .as_ref()
            .try_map(|_| Err(()), |mode| Ok(SubstituteRequest::now(*mode)));
        if let Ok(c) = plain {
            return due.then(|| {
                *next += 1;
                Ok(c)
            });
        }
        let Verb::Load(path) = &s.verb else {
            return None;
        };
        let item = *next;
        let prep = preparer.get_or_insert_with(|| Preparer::start(policy.clone()));
        if !due {
            // Not prepared ahead: the analysis gate starts from the marking the install will
            // transform, the primary's at the boundary the load is due at.
            prep.collect(false);
            return None;
        }
        let base = plc.primary_program().hash();
        loop {
            prep.collect(pace == Pace::Virtual);
            if let Some(result) = prep.take(item, base) {
                *next += 1;
                return Some(result.map(|p| Command::Load(Box::new(p))));
            }
            // Not prepared, or prepared against a primary that has changed since.
            prep.ensure(item, path, plc);
            match pace {
                Pace::Real => return None,
                Pace::Virtual if prep.busy => continue,
                Pace::Virtual => {
                    *next += 1;
                    return Some(Err(ScriptError::Command(format!(
                        "{path}: the package could not be prepared (the script's preparer \
                         thread did not start)"
                    ))));
                }
            }
        }
    }
}

/// A `--press BUTTON@TIME` that cannot be given: the press as written, and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("--press {press}: {reason}")]
pub struct PressError {
    /// The press as written.
    pub press: String,
    /// What is wrong: the time, or a button the twin does not have.
    pub reason: String,
}

/// Presses the twin's buttons as `--press BUTTON@TIME` asks (a bare button is pressed at 0 s),
/// times counted from `base_us`. Given no press, a plant gets its own start presses
/// ([`cetratus_twin::Plant::start_presses`]: the Festo station's RESET at 100 ms and START at
/// 500 ms), so that it runs as it does for an operator.
pub fn press_buttons(
    plant: &mut dyn cetratus_twin::Plant,
    presses: &[String],
    base_us: u64,
) -> Result<(), PressError> {
    if presses.is_empty() {
        for &(button, at_us) in plant.start_presses() {
            plant
                .press(button, at_us.saturating_add(base_us))
                .map_err(|e| PressError {
                    press: button.to_string(),
                    reason: e.to_string(),
                })?;
        }
    }
    for p in presses {
        let failed = |reason: String| PressError {
            press: p.clone(),
            reason,
        };
        let (button, at) = p.split_once('@').unwrap_or((p.as_str(), "0s"));
        let at_us = duration::parse_us(at, Bare::Seconds).map_err(|e| failed(e.to_string()))?;
        plant
            .press(button, at_us.saturating_add(base_us))
            .map_err(|e| failed(e.to_string()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn items_are_sorted_by_time_and_checked() {
        let s = Script::parse(&["60s substitute keep".into(), "10s load u1.cpkg".into()]).unwrap();
        assert_eq!(s.items[0].verb, Verb::Load("u1.cpkg".into()));
        assert_eq!(s.items[1].verb, Verb::Substitute(SubstituteMode::Keep));
        for bad in [
            "10s",
            "10s launch",
            "soon load x",
            "10s load",
            "5s substitute sideways",
        ] {
            let e = Script::parse(&[bad.to_string()]).unwrap_err().to_string();
            assert!(e.starts_with(&format!("--at `{bad}`")), "{e}");
        }
    }
}
