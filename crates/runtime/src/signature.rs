//! The divergence signature of an update, and the comparison of a quarantine against it
//! (docs/live-update.md, *The twin against the quarantine*): the paper's "automatic comparison
//! of the digital twin simulation and the quarantine-mode information".
//!
//! While a candidate runs in quarantine, the Monitor puts each cycle's divergence of an output
//! down to a cause: the first transition that fired in one container and not the other, and
//! what blocked it in the other (the latest such difference, when the output goes on diverging
//! after it). A *kind* of divergence is an output with its cause. A twin validation runs the
//! candidate in quarantine on the twin and records the kinds it sees: the signature. On the
//! plant, the candidate's quarantine is compared with it kind by kind: a kind the twin never
//! showed is *unexplained*, and fails the quarantine verdict at once; the verdict passes once
//! enough cycles ran and each output the twin showed diverging has diverged at least once.
//!
//! Everything here that runs in the scan is sized when the candidate is prepared or the verdict
//! attached: recording a kind never allocates.

use std::collections::BTreeMap;
use std::sync::Arc;

use cetratus_net::TransIdx;

use crate::monitor::{describe_kind, Verdict, VerdictKind, VerdictResult};
use crate::{Blocker, Container};

/// How many kinds of divergence a candidate's record holds; past it the record is incomplete
/// (a twin signature that overflowed says so in its verdict).
pub const KINDS: usize = 256;

/// The cause a divergence is put down to: the transition that fired in one container only, and
/// what blocked it in the other. Transitions and places are indices in the two programs' nets,
/// the same wherever the same two programs run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CauseKey {
    /// The transition fired in the candidate (else in the primary).
    pub in_candidate: bool,
    /// The transition, in the net of the container where it fired.
    pub transition: TransIdx,
    /// Why it did not fire in the other container.
    pub blocked: Blocker,
}

/// One kind of divergence: an output, by its index in the I/O map, and its cause (`None`
/// before any firing differed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Kind {
    /// The output's index in the I/O map.
    pub output: u32,
    /// Its cause.
    pub cause: Option<CauseKey>,
}

/// The kinds of divergence a candidate showed, as the Monitor records them.
#[derive(Clone, Debug, Default)]
pub struct Divergences {
    kinds: Vec<Kind>,
    /// Per output, the cause last recorded: a divergence that goes on is looked up once.
    last: Vec<Option<Option<CauseKey>>>,
    overflowed: bool,
}

impl Divergences {
    /// An empty record for an I/O map of `outputs` outputs.
    pub fn new(outputs: usize) -> Self {
        Divergences {
            kinds: Vec::with_capacity(KINDS),
            last: vec![None; outputs],
            overflowed: false,
        }
    }

    /// Records that `output` diverged for `cause`; returns the kind when it was not recorded
    /// before. Never allocates.
    pub fn record(&mut self, output: usize, cause: Option<CauseKey>) -> Option<Kind> {
        let last = self.last.get_mut(output)?;
        if *last == Some(cause) {
            return None;
        }
        *last = Some(cause);
        let kind = Kind {
            output: output as u32,
            cause,
        };
        if self.kinds.contains(&kind) {
            return None;
        }
        if self.kinds.len() >= KINDS {
            self.overflowed = true;
            return None;
        }
        self.kinds.push(kind);
        Some(kind)
    }

    /// The kinds recorded, in the order they were first seen.
    pub fn kinds(&self) -> &[Kind] {
        &self.kinds
    }

    /// More kinds came than the record holds.
    pub fn overflowed(&self) -> bool {
        self.overflowed
    }
}

/// A twin validation's signature, to be compared with the quarantine on the plant: the kinds it
/// recorded with their outputs by name (the plant's I/O map may order them otherwise), and each
/// in words.
#[derive(Clone, Debug, PartialEq)]
pub struct Signature {
    /// The output's name and the cause, per kind.
    pub kinds: Vec<(String, Option<CauseKey>)>,
    /// Each kind in words, in the same order.
    pub words: Vec<String>,
    /// The record held every kind the run showed.
    pub complete: bool,
    /// The cycles the twin run covered: a quarantine that runs longer meets what the twin never
    /// simulated, and its kinds after these cycles are not judged.
    pub horizon_cycles: u64,
}

/// How far a quarantine's comparison with the twin's signature has come (`exec_info`'s
/// `coverage`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Coverage {
    /// Cycles of the candidate compared since the signature came.
    pub cycles: u64,
    /// Outputs the twin showed diverging that the quarantine has shown diverging too.
    pub outputs_covered: usize,
    /// Outputs the twin showed diverging.
    pub outputs_expected: usize,
    /// Kinds of divergence the twin never showed.
    pub unexplained: u64,
    /// Kinds of divergence in the twin's signature.
    pub signature_kinds: usize,
}

/// A quarantine compared with a signature, kept with the candidate's figures.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// The signature, for the verdict's words.
    pub signature: Arc<Signature>,
    /// Its kinds, outputs as indices of this PLC's I/O map.
    expected: Vec<Kind>,
    /// The outputs the twin showed diverging, and whether the quarantine has shown each.
    outputs: Vec<(u32, bool)>,
    /// The first kind the twin never showed, and how many there were.
    pub unexplained: Option<Kind>,
    /// Kinds the twin never showed.
    pub unexplained_count: u64,
    /// The candidate's scans when the comparison started.
    pub from_scans: u64,
    /// The candidate's scans past which the twin simulated nothing: kinds seen later are not
    /// judged.
    until_scans: u64,
    /// The verdict given last, if any.
    pub given: Option<VerdictResult>,
}

impl Comparison {
    /// Compares from the candidate's `scans` on, with `signature`'s outputs found by name in
    /// `io_outputs` (a kind whose output this PLC lacks cannot be seen, and is left out), and
    /// the kinds the candidate already showed.
    pub fn new(
        signature: Arc<Signature>,
        io_outputs: &[String],
        seen: &Divergences,
        scans: u64,
    ) -> Self {
        let expected: Vec<Kind> = signature
            .kinds
            .iter()
            .filter_map(|(name, cause)| {
                let output = io_outputs.iter().position(|n| n == name)? as u32;
                Some(Kind {
                    output,
                    cause: *cause,
                })
            })
            .collect();
        let mut outputs: Vec<(u32, bool)> = Vec::new();
        for k in &expected {
            if !outputs.iter().any(|(o, _)| *o == k.output) {
                outputs.push((k.output, false));
            }
        }
        let until_scans = scans.saturating_add(signature.horizon_cycles);
        let mut c = Comparison {
            signature,
            expected,
            outputs,
            unexplained: None,
            unexplained_count: 0,
            from_scans: scans,
            until_scans,
            given: None,
        };
        for &k in seen.kinds() {
            c.observe(k, scans);
        }
        c
    }

    /// A kind the quarantine showed for the first time, at the candidate's `scans`; past the
    /// twin's horizon it is not judged.
    pub fn observe(&mut self, kind: Kind, scans: u64) {
        if scans > self.until_scans {
            return;
        }
        if let Some(o) = self.outputs.iter_mut().find(|(o, _)| *o == kind.output) {
            o.1 = true;
        }
        if !self.expected.contains(&kind) {
            self.unexplained_count += 1;
            self.unexplained.get_or_insert(kind);
        }
    }

    /// How far the comparison has come after `scans` of the candidate, for `exec_info`.
    pub fn progress(&self, scans: u64) -> Coverage {
        let (outputs_covered, outputs_expected) = self.coverage();
        Coverage {
            cycles: scans.saturating_sub(self.from_scans),
            outputs_covered,
            outputs_expected,
            unexplained: self.unexplained_count,
            signature_kinds: self.signature.kinds.len(),
        }
    }

    /// The outputs the twin showed diverging, and how many of them the quarantine has shown.
    pub fn coverage(&self) -> (usize, usize) {
        (
            self.outputs.iter().filter(|(_, seen)| *seen).count(),
            self.outputs.len(),
        )
    }

    /// The verdict due now, when it differs from the one given: a fail at the first
    /// unexplained kind; a pass once `min_cycles` scans ran and every output the twin showed
    /// diverging has diverged.
    pub fn due(&self, scans: u64, min_cycles: u64) -> Option<VerdictResult> {
        use VerdictResult::{Fail, Pass};
        let now = if self.unexplained.is_some() {
            Fail
        } else {
            let (seen, of) = self.coverage();
            let ran = scans.saturating_sub(self.from_scans) >= min_cycles;
            if !(ran && seen == of) {
                return None;
            }
            Pass
        };
        (self.given != Some(now)).then_some(now)
    }
}

/// The quarantine verdict `result` of `cmp`, after `scans` of the candidate, with the outputs
/// named from `io_outputs` and the unexplained kind in words from the `(candidate, primary)`
/// containers.
pub(crate) fn verdict(
    cmp: &Comparison,
    result: VerdictResult,
    scans: u64,
    io_outputs: &[String],
    (candidate, primary): (&Container, &Container),
) -> Verdict {
    let (seen, of) = cmp.coverage();
    let ran = scans.saturating_sub(cmp.from_scans);
    let mut reasons = Vec::new();
    if let Some(k) = cmp.unexplained {
        let name = io_outputs
            .get(k.output as usize)
            .map_or("?", String::as_str);
        reasons.push(format!(
            "unexplained divergence: {}; the twin never showed it (its signature holds {} kinds{})",
            describe_kind(name, k.cause, candidate, primary),
            cmp.signature.kinds.len(),
            if cmp.signature.complete {
                ""
            } else {
                ", and is incomplete"
            }
        ));
    } else {
        reasons.push(format!(
            "in {ran} cycles the quarantine showed {seen} of the {of} outputs the twin showed diverging, each as the twin did, and no divergence the twin did not show"
        ));
    }
    let mut figures = BTreeMap::new();
    figures.insert("cycles".to_string(), ran as f64);
    figures.insert("outputs_covered".to_string(), seen as f64);
    figures.insert("outputs_expected".to_string(), of as f64);
    figures.insert("unexplained".to_string(), cmp.unexplained_count as f64);
    figures.insert(
        "signature_kinds".to_string(),
        cmp.signature.kinds.len() as f64,
    );
    Verdict {
        kind: VerdictKind::Quarantine,
        result,
        reasons,
        figures,
        signature: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cause(t: u32) -> Option<CauseKey> {
        Some(CauseKey {
            in_candidate: true,
            transition: TransIdx(t),
            blocked: Blocker::Guard,
        })
    }

    #[test]
    fn a_kind_is_recorded_once_and_a_divergence_that_goes_on_is_not_looked_up_again() {
        let mut d = Divergences::new(3);
        assert!(d.record(1, cause(4)).is_some());
        assert!(d.record(1, cause(4)).is_none());
        assert!(d.record(1, cause(5)).is_some());
        assert!(d.record(1, cause(4)).is_none(), "seen before");
        assert!(d.record(9, cause(4)).is_none(), "no such output");
        assert_eq!(d.kinds().len(), 2);
        let before = d.kinds.capacity();
        for k in 0..400 {
            d.record(k % 3, cause(k as u32));
        }
        assert!(d.overflowed());
        assert_eq!(d.kinds().len(), KINDS);
        assert_eq!(d.kinds.capacity(), before, "never grew");
    }

    #[test]
    fn a_kind_the_twin_never_showed_fails_and_coverage_decides_a_pass() {
        let names = ["A".to_string(), "B".to_string()];
        let sig = Arc::new(Signature {
            kinds: vec![("B".into(), cause(1))],
            words: vec!["B: T".into()],
            complete: true,
            horizon_cycles: 1_000,
        });
        let mut c = Comparison::new(sig.clone(), &names, &Divergences::new(2), 10);
        assert_eq!(c.due(500, 100), None, "B has not diverged yet");
        c.observe(
            Kind {
                output: 1,
                cause: cause(1),
            },
            20,
        );
        assert_eq!(c.due(50, 100), None, "too few cycles");
        assert_eq!(c.due(110, 100), Some(VerdictResult::Pass));
        c.given = Some(VerdictResult::Pass);
        assert_eq!(c.due(200, 100), None, "given already");
        c.observe(
            Kind {
                output: 0,
                cause: cause(2),
            },
            2_000,
        );
        assert_eq!(
            c.due(2_000, 100),
            None,
            "past the twin's horizon: not judged"
        );
        c.observe(
            Kind {
                output: 0,
                cause: cause(1),
            },
            200,
        );
        assert_eq!(c.due(200, 100), Some(VerdictResult::Fail));
        assert_eq!(c.unexplained_count, 1);
    }
}
