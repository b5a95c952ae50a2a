//! How an accepted command ends: the `events` kinds that complete each verb, or end it without
//! its effect. The reply to a command only says that the PLC accepted it; what it causes happens
//! at a cycle boundary (docs/live-update.md), and the `events` topic says how it went. The CLI
//! and the dashboard both read this one table.

use serde::Serialize;

use crate::Verb;

/// How an event ends an accepted command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Ending {
    /// The command took effect (`quarantine_started`, `substituted`, `removed`, …).
    Done,
    /// The command ended without its effect: refused at the cycle boundary, its condition given
    /// up, or the update it acted on ended otherwise.
    Failed,
}

const LOAD: &[(&str, Ending)] = &[
    ("quarantine_started", Ending::Done),
    ("state_trans_timeout", Ending::Failed),
    ("transform_refused", Ending::Failed),
    ("refused", Ending::Failed),
    ("aborted", Ending::Failed),
    ("update_discarded", Ending::Failed),
];

const SUBSTITUTE: &[(&str, Ending)] = &[
    ("substituted", Ending::Done),
    ("refused", Ending::Failed),
    ("substitute_timeout", Ending::Failed),
    ("candidate_fault", Ending::Failed),
    ("removed", Ending::Failed),
    ("aborted", Ending::Failed),
    ("update_discarded", Ending::Failed),
];

impl Verb {
    /// The event kinds that end an accepted command of this verb, and how. Empty for
    /// `exec_info`, whose reply is its whole outcome.
    pub fn endings(self) -> &'static [(&'static str, Ending)] {
        match self {
            Verb::Load => LOAD,
            Verb::Substitute => SUBSTITUTE,
            Verb::Remove => &[("removed", Ending::Done)],
            Verb::Abort => &[("aborted", Ending::Done)],
            Verb::Reset => &[("reset", Ending::Done)],
            Verb::ExecInfo => &[],
            // Probation can also end by itself before the command's boundary: a revert the PLC
            // decided ends an `accept`, the window's end ends a `revert`.
            Verb::Revert => &[("reverted", Ending::Done), ("accepted", Ending::Failed)],
            Verb::Accept => &[("accepted", Ending::Done), ("reverted", Ending::Failed)],
        }
    }

    /// How an event of kind `kind` ends an accepted command of this verb; `None` when it does not.
    pub fn ending(self, kind: &str) -> Option<Ending> {
        self.endings()
            .iter()
            .find(|(k, _)| *k == kind)
            .map(|&(_, e)| e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_verb_but_exec_info_has_exactly_one_kind_that_completes_it() {
        for v in Verb::ALL {
            let done = v
                .endings()
                .iter()
                .filter(|(_, e)| *e == Ending::Done)
                .count();
            assert_eq!(done, usize::from(v != Verb::ExecInfo), "{v}");
        }
        assert_eq!(Verb::Substitute.ending("substituted"), Some(Ending::Done));
        assert_eq!(
            Verb::Substitute.ending("substitute_timeout"),
            Some(Ending::Failed)
        );
        assert_eq!(Verb::Substitute.ending("load_accepted"), None);
    }
}
