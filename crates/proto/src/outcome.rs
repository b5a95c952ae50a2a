//! How an accepted command ends: the `events` kinds that complete each verb, or end it without
//! its effect. The reply to a command only says that the PLC accepted it; what it causes happens
//! at a cycle boundary (docs/live-update.md), and the `events` topic says how it went. The CLI
//! and the dashboard both read this one table.

use serde::Serialize;

use cetratus_vocab::{EventKind, Open};

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

const LOAD: &[(EventKind, Ending)] = &[
    (EventKind::QuarantineStarted, Ending::Done),
    (EventKind::StateTransTimeout, Ending::Failed),
    (EventKind::TransformRefused, Ending::Failed),
    (EventKind::Refused, Ending::Failed),
    (EventKind::Aborted, Ending::Failed),
    (EventKind::UpdateDiscarded, Ending::Failed),
];

const SUBSTITUTE: &[(EventKind, Ending)] = &[
    (EventKind::Substituted, Ending::Done),
    (EventKind::Refused, Ending::Failed),
    (EventKind::SubstituteTimeout, Ending::Failed),
    (EventKind::CandidateFault, Ending::Failed),
    (EventKind::Removed, Ending::Failed),
    (EventKind::Aborted, Ending::Failed),
    (EventKind::UpdateDiscarded, Ending::Failed),
];

/// The event kinds that end an accepted command of `verb`, and how. Empty for `exec_info`,
/// whose reply is its whole outcome.
pub fn endings(verb: Verb) -> &'static [(EventKind, Ending)] {
    match verb {
        Verb::Load => LOAD,
        Verb::Substitute => SUBSTITUTE,
        Verb::Remove => &[(EventKind::Removed, Ending::Done)],
        Verb::Abort => &[(EventKind::Aborted, Ending::Done)],
        Verb::Reset => &[(EventKind::Reset, Ending::Done)],
        Verb::ExecInfo => &[],
        // Probation can also end by itself before the command's boundary: a revert the PLC
        // decided ends an `accept`, the window's end ends a `revert`.
        // An operator's revert that finds no marking agreeing with the plant is refused.
        Verb::Revert => &[
            (EventKind::Reverted, Ending::Done),
            (EventKind::Refused, Ending::Failed),
            (EventKind::Accepted, Ending::Failed),
        ],
        Verb::Accept => &[
            (EventKind::Accepted, Ending::Done),
            (EventKind::Reverted, Ending::Failed),
        ],
    }
}

/// How an event of kind `kind` ends an accepted command of `verb`; `None` when it does not (a
/// kind this build does not know never does).
pub fn ending(verb: Verb, kind: &Open<EventKind>) -> Option<Ending> {
    let kind = kind.known()?;
    endings(verb)
        .iter()
        .find(|(k, _)| *k == kind)
        .map(|&(_, e)| e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_verb_but_exec_info_has_exactly_one_kind_that_completes_it() {
        for &v in Verb::ALL {
            let done = endings(v)
                .iter()
                .filter(|(_, e)| *e == Ending::Done)
                .count();
            assert_eq!(done, usize::from(v != Verb::ExecInfo), "{v}");
        }
        let kind = |k: EventKind| Open::Known(k);
        let sub = Verb::Substitute;
        assert_eq!(
            ending(sub, &kind(EventKind::Substituted)),
            Some(Ending::Done)
        );
        assert_eq!(
            ending(sub, &kind(EventKind::SubstituteTimeout)),
            Some(Ending::Failed)
        );
        assert_eq!(ending(sub, &kind(EventKind::LoadAccepted)), None);
        assert_eq!(ending(sub, &Open::Other("substituted2".into())), None);
    }
}
