//! Scripted operator commands at program times (`run --at "10s load u1.cpkg"`): the paper's
//! experiment, replayed without anyone at the keyboard.

use cetratus_program::duration::{self, Bare};
use cetratus_program::TrustStore;
use cetratus_runtime::{Command, Plc, SubstituteMode, SubstituteRequest};

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
}

/// The verbs a script knows.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Verb {
    Load(String),
    Substitute(SubstituteMode),
    Remove,
    Abort,
    Reset,
}

/// One scripted command.
#[derive(Clone, Debug)]
struct Scripted {
    at_us: u64,
    verb: Verb,
}

/// Commands in order of their time; one is given per cycle, so that each takes effect at the
/// next cycle boundary and the next one (a substitute after a load) sees that effect.
#[derive(Clone, Debug, Default)]
pub struct Script {
    items: Vec<Scripted>,
    next: usize,
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
            let verb = match (verb, arg) {
                ("load", Some(path)) => Verb::Load(path.to_string()),
                ("load", None) => return Err(syntax("`load` needs a package file".into())),
                ("substitute", m) => Verb::Substitute(match m {
                    Some(m) => m.parse().map_err(syntax)?,
                    None => SubstituteMode::Retransform,
                }),
                ("remove", _) => Verb::Remove,
                ("abort", _) => Verb::Abort,
                ("reset", _) => Verb::Reset,
                (other, _) => {
                    return Err(syntax(format!(
                    "unknown command `{other}`; expected load, substitute, remove, abort or reset"
                )))
                }
            };
            let at_us = duration::parse_us(t, Bare::Seconds).map_err(|e| syntax(e.to_string()))?;
            v.push(Scripted { at_us, verb });
        }
        v.sort_by_key(|s| s.at_us);
        Ok(Script { items: v, next: 0 })
    }

    /// The command due at program time `now_us` (counted from `base_us`), built against `plc`:
    /// a package is read, verified and prepared here, between cycles.
    pub fn due(
        &mut self,
        plc: &Plc,
        now_us: u64,
        base_us: u64,
        trust: &TrustStore,
        allow_unsigned: bool,
    ) -> Option<Result<Command, ScriptError>> {
        let s = self.items.get(self.next)?;
        if s.at_us.saturating_add(base_us) > now_us {
            return None;
        }
        self.next += 1;
        Some(match &s.verb {
            Verb::Load(path) => std::fs::read(path)
                .map_err(|e| ScriptError::Command(format!("cannot read {path}: {e}")))
                .and_then(|bytes| {
                    plc.update_context()
                        .prepare_package(&bytes, trust, allow_unsigned, false)
                        .map(|p| Command::Load(Box::new(p)))
                        .map_err(|e| ScriptError::Command(format!("{path}: {e}")))
                }),
            Verb::Substitute(mode) => Ok(Command::Substitute(SubstituteRequest::now(*mode))),
            Verb::Remove => Ok(Command::Remove),
            Verb::Abort => Ok(Command::Abort),
            Verb::Reset => Ok(Command::Reset),
        })
    }
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
