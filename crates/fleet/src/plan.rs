//! `rollout.toml`: the plan of a rollout, and the PLCs each stage picks.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use cetratus_program::duration::{parse_us, Bare};
use cetratus_proto::{Labels, Selector};
use serde::Deserialize;

/// Most bytes of a plan file.
pub const MAX_PLAN_BYTES: usize = 64 * 1024;
/// Most stages of a plan.
pub const MAX_STAGES: usize = 32;

/// Why a plan is refused.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The file cannot be read.
    #[error("{path}: cannot read the plan: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not a plan: its TOML, its keys or their types.
    #[error("{path}: {message}")]
    Schema {
        /// The file.
        path: String,
        /// What the TOML reader said, with the line.
        message: String,
    },
    /// A key's value breaks a rule of the plan.
    #[error("{path}: `{key}` {reason}")]
    Value {
        /// The file.
        path: String,
        /// The key.
        key: &'static str,
        /// What is wrong, and what to write.
        reason: String,
    },
    /// The selector picks no PLC of the fleet.
    #[error("the selector `{0}` picks no PLC of the fleet; check the labels the PLCs publish (cetratus status) or widen it")]
    EmptySelection(String),
}

/// What a failure does to the rollout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OnFailure {
    /// The PLCs mid-update are removed from quarantine or reverted in probation, and the rollout
    /// halts.
    Stop,
    /// The PLCs stay as they are, the rollout halts, and an alarm is raised.
    Hold,
}

/// One stage: how far into the selection the rollout goes, cumulatively.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Stage {
    /// The first `n` PLCs of the selection (in id order).
    Count(usize),
    /// This share of the selection, in percent, rounded up.
    Percent(u32),
    /// The PLCs of the selection that this selector picks (named canaries, a label group).
    Group(Selector),
}

/// A rollout plan, checked.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The update package, resolved against the plan's directory.
    pub package: PathBuf,
    /// The PLCs the rollout may touch.
    pub select: Selector,
    /// The cumulative stages; the first is the canary.
    pub stages: Vec<Stage>,
    /// The least time each PLC spends in quarantine, µs.
    pub quarantine_us: u64,
    /// Whether each PLC needs a passing twin verdict before its substitution.
    pub require_verdict: bool,
    /// The least time each PLC must survive in probation before the rollout accepts it, µs.
    pub probation_us: u64,
    /// How many PLCs may be mid-update at once.
    pub max_parallel: usize,
    /// What a failure does.
    pub on_failure: OnFailure,
    /// How long a PLC of the rollout may go unheard (offline, or no `state` at all) before it
    /// counts as a failure; until then the rollout waits for it, µs.
    pub silent_us: u64,
}

/// How long a PLC may go unheard when the plan does not say: 30 s.
pub const DEFAULT_SILENT_US: u64 = 30_000_000;

/// The file at `path` when it holds at most `max` bytes, `None` when it holds more. It is read
/// through a limit, so a file that never ends (a device, a pipe) costs `max` bytes at most.
pub(crate) fn read_capped(path: &Path, max: u64) -> std::io::Result<Option<Vec<u8>>> {
    use std::io::Read as _;
    let mut bytes = Vec::new();
    std::fs::File::open(path)?
        .take(max + 1)
        .read_to_end(&mut bytes)?;
    Ok((bytes.len() as u64 <= max).then_some(bytes))
}

/// `rollout.toml` as serde reads it.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    package: String,
    select: String,
    stages: Vec<String>,
    quarantine: String,
    #[serde(default)]
    require_verdict: bool,
    probation: String,
    max_parallel: usize,
    on_failure: OnFailure,
    silent: Option<String>,
}

impl Plan {
    /// Reads and checks the plan at `path`.
    pub fn load(path: &Path) -> Result<Plan, PlanError> {
        let text = Plan::read(path)?;
        let dir = path.parent().unwrap_or(Path::new("."));
        Plan::parse(&text, &path.display().to_string(), dir)
    }

    /// The text of the plan file at `path`, read through the limit of [`MAX_PLAN_BYTES`]: a
    /// larger file, or one that is not UTF-8, is refused.
    pub fn read(path: &Path) -> Result<String, PlanError> {
        let shown = path.display().to_string();
        let read = |source| PlanError::Read {
            path: shown.clone(),
            source,
        };
        let Some(bytes) = read_capped(path, MAX_PLAN_BYTES as u64).map_err(read)? else {
            return Err(PlanError::Schema {
                path: shown,
                message: format!("more than the {MAX_PLAN_BYTES} bytes a plan may have"),
            });
        };
        String::from_utf8(bytes).map_err(|e| PlanError::Schema {
            path: shown.clone(),
            message: format!(
                "not UTF-8 text (byte {}); a plan is TOML",
                e.utf8_error().valid_up_to()
            ),
        })
    }

    /// Checks the plan `text` (named `path` in messages); its package is resolved against `dir`.
    pub fn parse(text: &str, path: &str, dir: &Path) -> Result<Plan, PlanError> {
        let file: File = toml::from_str(text).map_err(|e| PlanError::Schema {
            path: path.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let bad = |key, reason: String| PlanError::Value {
            path: path.to_string(),
            key,
            reason,
        };
        let select: Selector = file
            .select
            .parse()
            .map_err(|e| bad("select", format!("{e}")))?;
        let duration = |key, text: &str| {
            parse_us(text, Bare::Refused).map_err(|e| {
                bad(
                    key,
                    format!("`{text}`: {e}; write it as \"30s\" or \"2min\""),
                )
            })
        };
        let quarantine_us = duration("quarantine", &file.quarantine)?;
        let probation_us = duration("probation", &file.probation)?;
        let silent_us = match &file.silent {
            Some(t) => match duration("silent", t)? {
                0 => {
                    return Err(bad(
                        "silent",
                        "is 0, so every PLC would fail at once; give a time such as \"30s\"".into(),
                    ))
                }
                us => us,
            },
            None => DEFAULT_SILENT_US,
        };
        if file.max_parallel == 0 {
            return Err(bad(
                "max_parallel",
                "is 0, so no PLC could ever be updated; write 1 or more".into(),
            ));
        }
        if file.package.trim().is_empty() {
            return Err(bad("package", "is empty; name the .cpkg file".into()));
        }
        let stages = stages(&file.stages).map_err(|reason| bad("stages", reason))?;
        Ok(Plan {
            package: dir.join(file.package.trim()),
            select,
            stages,
            quarantine_us,
            require_verdict: file.require_verdict,
            probation_us,
            max_parallel: file.max_parallel,
            on_failure: file.on_failure,
            silent_us,
        })
    }

    /// The PLCs of `fleet` (id and labels) that the selector picks, in id order, and the ones
    /// each stage adds to those before it: a stage that adds none is kept, empty, so that the
    /// report counts the stages of the plan. An empty selection is refused.
    pub fn stage_members(&self, fleet: &[(String, Labels)]) -> Result<Vec<Vec<String>>, PlanError> {
        let mut picked: Vec<&(String, Labels)> = fleet
            .iter()
            .filter(|(id, l)| self.select.matches(id, l))
            .collect();
        picked.sort_by(|a, b| a.0.cmp(&b.0));
        picked.dedup_by(|a, b| a.0 == b.0);
        if picked.is_empty() {
            return Err(PlanError::EmptySelection(self.select.to_string()));
        }
        let n = picked.len();
        let mut done: BTreeSet<&str> = BTreeSet::new();
        let mut out = Vec::with_capacity(self.stages.len());
        for stage in &self.stages {
            let upto: Vec<&str> = match stage {
                Stage::Count(c) => picked.iter().take(*c).map(|p| p.0.as_str()).collect(),
                Stage::Percent(p) => {
                    let k = (n * *p as usize).div_ceil(100);
                    picked.iter().take(k).map(|p| p.0.as_str()).collect()
                }
                Stage::Group(sel) => (picked.iter())
                    .filter(|(id, l)| sel.matches(id, l))
                    .map(|p| p.0.as_str())
                    .collect(),
            };
            let added: Vec<String> = (upto.into_iter())
                .filter(|id| done.insert(id))
                .map(str::to_string)
                .collect();
            out.push(added);
        }
        // The last stage takes the rollout to every PLC the selector picks.
        if let Some(last) = out.last_mut() {
            for p in &picked {
                if done.insert(&p.0) {
                    last.push(p.0.clone());
                }
            }
        }
        Ok(out)
    }
}

/// The stages as written: a count (`"1"`), a share (`"20%"`) or a selector (`"cell=press-4"`),
/// at least one and at most [`MAX_STAGES`]; counts and shares grow from stage to stage.
fn stages(texts: &[String]) -> Result<Vec<Stage>, String> {
    if texts.is_empty() || texts.len() > MAX_STAGES {
        return Err(format!(
            "has {} stages; give 1 to {MAX_STAGES}, the first the canary (e.g. [\"1\", \"20%\", \"100%\"])",
            texts.len()
        ));
    }
    let mut out = Vec::with_capacity(texts.len());
    for t in texts {
        let t = t.trim();
        let stage = if let Some(p) = t.strip_suffix('%') {
            match p.trim().parse::<u32>() {
                Ok(p @ 1..=100) => Stage::Percent(p),
                _ => return Err(format!("`{t}`: a share is 1% to 100%")),
            }
        } else if t.chars().all(|c| c.is_ascii_digit()) && !t.is_empty() {
            match t.parse::<usize>() {
                Ok(c) if c > 0 => Stage::Count(c),
                _ => return Err(format!("`{t}`: a count is 1 or more PLCs")),
            }
        } else {
            Stage::Group(t.parse().map_err(|e| format!("`{t}`: {e}"))?)
        };
        out.push(stage);
    }
    let mut last: (usize, u32) = (0, 0);
    for s in &out {
        match s {
            Stage::Count(c) if *c < last.0 => {
                return Err(format!(
                    "count {c} after {}: stages are cumulative and grow",
                    last.0
                ))
            }
            Stage::Percent(p) if *p < last.1 => {
                return Err(format!(
                    "{p}% after {}%: stages are cumulative and grow",
                    last.1
                ))
            }
            Stage::Count(c) => last.0 = *c,
            Stage::Percent(p) => last.1 = *p,
            Stage::Group(_) => {}
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
