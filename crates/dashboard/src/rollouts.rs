//! The fleet page's rollouts (docs/fleet.md): the same rollout `cetratus rollout` runs, in a
//! thread of the dashboard's process, started, paused, resumed and aborted by logged-in
//! operators. The plans it may start are the `*.toml` files of one directory, named by file
//! name only; its record lives in one state directory, so `cetratus rollout status` reads it
//! too. Every change is pushed to the browsers as a `rollout` event.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use cetratus_fleet::run::{self, Options};
use cetratus_fleet::{journal, FleetError, LinkConfig, Request};
use serde_json::{json, Value};
use tokio::sync::broadcast;

use crate::hub::Push;

/// Most plans the page lists.
const MAX_PLANS: usize = 200;

/// Where the page's rollouts come from and go.
#[derive(Clone)]
pub struct RolloutConfig {
    /// The directory of plans (`*.toml`) the page may start; each names its package.
    pub plans: PathBuf,
    /// The rollouts' state directory.
    pub state_dir: PathBuf,
    /// The broker connection of a rollout; each run names the account that asked.
    pub link: LinkConfig,
}

impl std::fmt::Debug for RolloutConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RolloutConfig")
            .field("plans", &self.plans)
            .field("state_dir", &self.state_dir)
            .finish_non_exhaustive()
    }
}

/// Why the page's request about a rollout is refused: the HTTP status and what to do.
pub(crate) struct Refusal(pub u16, pub String);

/// The page's rollouts: at most one runs, in its own thread.
pub(crate) struct Rollouts {
    config: Option<RolloutConfig>,
    thread: Mutex<Option<JoinHandle<()>>>,
    error: Arc<Mutex<Option<String>>>,
    push: broadcast::Sender<Push>,
}

impl Rollouts {
    pub(crate) fn new(config: Option<RolloutConfig>, push: broadcast::Sender<Push>) -> Self {
        Rollouts {
            config,
            thread: Mutex::new(None),
            error: Arc::new(Mutex::new(None)),
            push,
        }
    }

    fn running(&self) -> bool {
        let t = self.thread.lock().unwrap_or_else(|p| p.into_inner());
        t.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// What the page shows: the plans, whether a rollout runs, its report, the last error.
    pub(crate) fn status(&self) -> Value {
        let Some(c) = &self.config else {
            return json!({ "enabled": false });
        };
        let report = journal::read(&c.state_dir).ok().map(|r| r.report());
        let error = self.error.lock().unwrap_or_else(|p| p.into_inner()).clone();
        json!({
            "enabled": true,
            "plans": plans(&c.plans),
            "running": self.running(),
            "report": report,
            "error": error,
        })
    }

    /// Starts the plan named `name` (a file name of the plans' directory) for `account`.
    pub(crate) fn start(&self, name: &str, account: &str) -> Result<(), Refusal> {
        let c = self.enabled()?;
        if !plans(&c.plans).iter().any(|p| p == name) {
            return Err(Refusal(
                404,
                format!(
                    "no plan `{}` in the plans' directory; choose one the page lists",
                    name.escape_debug()
                ),
            ));
        }
        let path = c.plans.join(name);
        self.spawn(account, move |o| run::start(&path, o).map(|_| ()))
    }

    /// Pauses, resumes or aborts: asks the running rollout, or acts on the recorded one.
    pub(crate) fn request(&self, r: Request, account: &str) -> Result<(), Refusal> {
        let c = self.enabled()?;
        let dir = c.state_dir.clone();
        if self.running() {
            return journal::ask(&dir, r).map_err(|e| Refusal(500, e.to_string()));
        }
        match r {
            Request::Pause => run::pause(&dir)
                .map(|_| self.changed())
                .map_err(|e| Refusal(409, e.to_string())),
            Request::Resume => self.spawn(account, |o| run::resume(o).map(|_| ())),
            Request::Abort => self.spawn(account, |o| run::abort(o).map(|_| ())),
        }
    }

    fn enabled(&self) -> Result<&RolloutConfig, Refusal> {
        self.config.as_ref().ok_or_else(|| {
            Refusal(
                404,
                "this dashboard runs no rollouts; start it with `--plans DIR`".into(),
            )
        })
    }

    /// Runs `body` in the rollout's thread, unless one runs.
    fn spawn(
        &self,
        account: &str,
        body: impl FnOnce(Options) -> Result<(), FleetError> + Send + 'static,
    ) -> Result<(), Refusal> {
        let c = self.enabled()?;
        let mut thread = self.thread.lock().unwrap_or_else(|p| p.into_inner());
        if thread.as_ref().is_some_and(|t| !t.is_finished()) {
            return Err(Refusal(
                409,
                "a rollout runs already; pause or abort it first".into(),
            ));
        }
        let mut link = c.link.clone();
        link.account = Some(account.to_string());
        let push = self.push.clone();
        let options = Options {
            link,
            state_dir: c.state_dir.clone(),
            discover: Duration::from_secs(2),
            progress: Box::new(move |record, _| {
                let _ = push.send(Push::Rollout(Arc::new(record.report())));
            }),
        };
        let error = self.error.clone();
        *error.lock().unwrap_or_else(|p| p.into_inner()) = None;
        let push = self.push.clone();
        let t = std::thread::Builder::new()
            .name("cetratus-rollout".into())
            .spawn(move || {
                if let Err(e) = body(options) {
                    *error.lock().unwrap_or_else(|p| p.into_inner()) = Some(e.to_string());
                }
                let _ = push.send(Push::RolloutEnded);
            })
            .map_err(|e| Refusal(500, format!("cannot start the rollout's thread: {e}")))?;
        *thread = Some(t);
        Ok(())
    }

    fn changed(&self) {
        let _ = self.push.send(Push::RolloutEnded);
    }
}

/// The plans of `dir`: the names of its `*.toml` files whose names are plain (letters, digits,
/// `.`, `_`, `-`), sorted, at most [`MAX_PLANS`].
fn plans(dir: &Path) -> Vec<String> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut out: Vec<String> = entries
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| plain_plan_name(n))
        .take(MAX_PLANS * 4)
        .collect();
    out.sort();
    out.truncate(MAX_PLANS);
    out
}

/// Whether `name` is a plan's file name the page may start: `*.toml`, at most 128 bytes of
/// letters, digits, `.`, `_` and `-`, not starting with `.`.
fn plain_plan_name(name: &str) -> bool {
    name.len() <= 128
        && name.ends_with(".toml")
        && !name.starts_with('.')
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_plain_toml_file_names_are_plans() {
        for good in ["rollout.toml", "line-1_u1.v2.toml"] {
            assert!(plain_plan_name(good), "{good}");
        }
        for bad in [
            "../rollout.toml",
            "/etc/passwd",
            ".hidden.toml",
            "a b.toml",
            "rollout.txt",
            "x/../y.toml",
            "rollout.toml\0",
        ] {
            assert!(!plain_plan_name(bad), "{bad}");
        }
        assert!(!plain_plan_name(&format!("{}.toml", "a".repeat(130))));
    }
}
