//! The Monitor: the execution footprint of each container (`program_exec_info`), the divergence
//! between candidate and primary with its derived cause, drift, and a ring buffer of recent cycles
//! for the timing diagram.

use std::collections::BTreeMap;

use cetratus_net::TransIdx;
use cetratus_program::{Projection, Value};
use serde::Serialize;

use crate::mask::for_each_difference;
pub use crate::recent::{CycleRecord, RecentCycles};
use crate::router::MessageRouter;
use crate::signature::{CauseKey, Comparison, Divergences};
use crate::updater::value_json;
use crate::{Blocker, Container, Slot, Summary, TimingStats};

/// The derived cause of a divergence: the first transition that fired in one container and not
/// in the other, and what blocked it in the other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cause {
    /// Cycle of the divergence.
    pub cycle: u64,
    /// Program time of that cycle.
    pub time_us: u64,
    /// The container where the transition fired.
    pub fired_in: Slot,
    /// The transition, in that container's net.
    pub transition: TransIdx,
    /// Why it did not fire in the other container (places in the other container's net).
    pub blocked: Blocker,
}

/// The Monitor's running figures for one container.
#[derive(Clone, Debug, Default)]
pub struct ContainerStats {
    /// Scan time of this container alone.
    pub scan: TimingStats,
    /// Per I/O-map output: cycles in which this container's output differed from the primary's.
    pub divergent_cycles: Vec<u64>,
    /// The first divergence's cause since the container was installed.
    pub first_cause: Option<Cause>,
    /// The latest divergence's cause.
    pub last_cause: Option<Cause>,
    /// ‖Π·M_cand + Π_base − M_primary‖₁ at the last cycle (candidates only).
    pub drift: u64,
    /// The largest drift seen.
    pub max_drift: u64,
    /// `drift` was computed since the container was installed.
    pub drift_valid: bool,
    /// No transition enabled after the last scan.
    pub deadlocked: bool,
    /// The stall watchdog sees a stall (primaries only).
    pub stalled: bool,
    /// The kinds of divergence from the primary seen so far, each an output with its cause
    /// (candidates only; `signature.rs`).
    pub divergences: Divergences,
    /// The quarantine compared with a twin validation's signature, once a verdict brought one.
    pub comparison: Option<Comparison>,
}

impl ContainerStats {
    /// Fresh figures for a container whose I/O map has `outputs` outputs.
    pub fn new(outputs: usize) -> Self {
        ContainerStats {
            divergent_cycles: vec![0; outputs],
            divergences: Divergences::new(outputs),
            ..Default::default()
        }
    }

    /// Output `k` diverged in this cycle, the candidate's `scans`th, for `cause`: a kind seen
    /// for the first time is recorded, and compared with the twin's signature when there is one.
    fn diverged(&mut self, k: usize, cause: Option<CauseKey>, scans: u64) {
        if let Some(kind) = self.divergences.record(k, cause) {
            if let Some(c) = self.comparison.as_mut() {
                c.observe(kind, scans);
            }
        }
    }
}

/// The Monitor: both containers' figures and the recent cycles.
#[derive(Clone, Debug)]
pub struct Monitor {
    /// Figures of A and B.
    pub stats: [ContainerStats; 2],
    /// Recent cycles, oldest first.
    pub recent: RecentCycles,
}

impl Monitor {
    /// A monitor keeping `capacity` recent cycles for an I/O map of `inputs` inputs and
    /// `outputs` outputs (any number: the masks are as wide as the map).
    pub fn new(capacity: usize, inputs: usize, outputs: usize) -> Self {
        Monitor {
            stats: [ContainerStats::new(outputs), ContainerStats::new(outputs)],
            recent: RecentCycles::new(capacity, inputs, outputs),
        }
    }
}

/// A program's identity in reports.
#[derive(Clone, Debug, Serialize)]
pub struct ProgramId {
    /// Name.
    pub name: String,
    /// Version.
    pub version: String,
    /// Hex SHA-256 of the program.
    pub hash: String,
}

impl ProgramId {
    /// The identity of a container's program.
    pub fn of(c: &Container) -> Self {
        let p = c.program();
        ProgramId {
            name: p.name().to_string(),
            version: p.version().to_string(),
            hash: p.hash_hex().to_string(),
        }
    }
}

pub use cetratus_vocab::{Role, VerdictKind, VerdictResult};

/// What a validation found (docs/design.md §4): `{kind, result, reasons, figures}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdict {
    /// `analysis` or `twin`.
    pub kind: VerdictKind,
    /// `pass`, `fail` or `warn`.
    pub result: VerdictResult,
    /// Why, in words.
    pub reasons: Vec<String>,
    /// Figures by name.
    pub figures: BTreeMap<String, f64>,
    /// A twin verdict given in quarantine: the kinds of divergence the candidate showed on
    /// the twin, which its quarantine on the plant is compared with (`signature.rs`). Not
    /// published: the reasons say it in words.
    #[serde(skip)]
    pub signature: Option<std::sync::Arc<crate::signature::Signature>>,
}

/// `program_exec_info` of one container, as published.
#[derive(Clone, Debug, Serialize)]
pub struct ExecInfo {
    /// The container.
    pub container: Slot,
    /// Primary, candidate or shadow.
    pub role: Role,
    /// Its program.
    pub program: ProgramId,
    /// Scans run since it was installed.
    pub cycles: u64,
    /// Scan time of this container.
    pub scan: Summary,
    /// Firings per transition id.
    pub firings: BTreeMap<String, u64>,
    /// Tokens per place id.
    pub marking: BTreeMap<String, u32>,
    /// Outputs by name.
    #[serde(serialize_with = "values_by_name")]
    pub outputs: BTreeMap<String, Value>,
    /// Cycles in which each output differed from the primary's (candidates only).
    pub divergence: BTreeMap<String, u64>,
    /// The derived cause of the first divergence, in words.
    pub first_cause: Option<String>,
    /// The derived cause of the latest divergence, in words.
    pub last_cause: Option<String>,
    /// Drift from the primary through the projection (candidates only).
    pub drift: u64,
    /// The largest drift seen.
    pub max_drift: u64,
    /// No transition enabled.
    pub deadlock: bool,
    /// The stall watchdog sees a stall (the primary only); left out when false.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub stall: bool,
    /// Validation verdicts.
    pub verdicts: Vec<Verdict>,
    /// A candidate's quarantine compared with the twin's divergence signature: how far it has
    /// come (`None` without a signature).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<crate::signature::Coverage>,
    /// What the update's package declares it changes on purpose (the container that runs the
    /// update's program), signed with it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub changes: Option<cetratus_program::Changes>,
}

fn values_by_name<S: serde::Serializer>(
    m: &BTreeMap<String, Value>,
    s: S,
) -> Result<S::Ok, S::Error> {
    s.collect_map(m.iter().map(|(k, v)| (k, value_json(*v))))
}

/// What the Monitor compares in a quarantine cycle.
pub(crate) struct Pair<'a> {
    pub primary_slot: Slot,
    pub primary: &'a Container,
    pub candidate: &'a Container,
    pub to_primary: &'a [Option<TransIdx>],
    pub from_primary: &'a [Option<TransIdx>],
    pub projection: &'a Projection,
    /// The secondary is the old program on probation: the projection reads the primary.
    pub shadow: bool,
}

impl Monitor {
    /// One quarantine cycle: the candidate's drift, its divergence per signal, and the derived
    /// cause of a divergence.
    pub(crate) fn observe_quarantine(
        &mut self,
        pair: &Pair<'_>,
        router: &MessageRouter,
        cycle: u64,
        now_us: u64,
    ) {
        let p = pair.primary_slot;
        let c = p.other();
        let (pc, cc) = (pair.primary, pair.candidate);
        let quiet = pc.fired().is_empty() && cc.fired().is_empty();
        let stats = &mut self.stats[c.index()];
        // Drift only moves when a marking does.
        let drift = if quiet && stats.drift_valid {
            stats.drift
        } else if pair.shadow {
            pair.projection.drift(pc.marking(), cc.marking())
        } else {
            pair.projection.drift(cc.marking(), pc.marking())
        };
        stats.drift = drift;
        stats.drift_valid = true;
        stats.max_drift = stats.max_drift.max(drift);
        stats.deadlocked = cc.engine().deadlocked();

        // The cause of this cycle's divergence: the firing difference of this cycle, or else
        // the latest one before it.
        let fresh = if quiet {
            None
        } else {
            first_difference(pair).map(|(slot, t)| {
                let (other, other_t) = if slot == p {
                    (cc, pair.from_primary[t.index()])
                } else {
                    (pc, pair.to_primary[t.index()])
                };
                Cause {
                    cycle,
                    time_us: now_us,
                    fired_in: slot,
                    transition: t,
                    blocked: other_t.map_or(Blocker::Absent, |u| other.blocker(u)),
                }
            })
        };
        let scans = cc.scans();
        let key = fresh.or(stats.last_cause).map(|k| CauseKey {
            in_candidate: k.fired_in == c,
            transition: k.transition,
            blocked: k.blocked,
        });
        // Divergence per signal. Boolean images compare as bit masks: most cycles the two agree
        // and this is one comparison.
        let mut differs = false;
        if router.bool_outputs() {
            let (a, b) = (router.output_bits(p.index()), router.output_bits(c.index()));
            for_each_difference(a.words(), b.words(), |k| {
                stats.divergent_cycles[k] += 1;
                stats.diverged(k, key, scans);
                differs = true;
            });
        } else {
            let outs = router
                .outputs(p.index())
                .iter()
                .zip(router.outputs(c.index()));
            for (k, (a, b)) in outs.enumerate() {
                if a != b {
                    stats.divergent_cycles[k] += 1;
                    stats.diverged(k, key, scans);
                    differs = true;
                }
            }
        }
        if let Some(cause) = fresh {
            if differs || stats.last_cause.is_none() {
                stats.last_cause = Some(cause);
                if stats.first_cause.is_none() {
                    stats.first_cause = Some(cause);
                }
            }
        }
    }

    /// `program_exec_info` of both containers; `role` says what the non-primary one is.
    pub(crate) fn exec_info(
        &self,
        containers: [Option<&Container>; 2],
        primary: Slot,
        secondary_role: Role,
        io_outputs: &[String],
    ) -> [Option<ExecInfo>; 2] {
        let text = |c: &Option<Cause>| {
            c.as_ref().and_then(|cause| {
                let fired = containers[cause.fired_in.index()]?;
                let other = containers[cause.fired_in.other().index()]?;
                Some(describe_cause(cause, fired, other))
            })
        };
        [Slot::A, Slot::B].map(|slot| {
            let c = containers[slot.index()]?;
            let s = &self.stats[slot.index()];
            let net = c.program().net();
            let is_primary = slot == primary;
            Some(ExecInfo {
                container: slot,
                role: if is_primary {
                    Role::Primary
                } else {
                    secondary_role
                },
                program: ProgramId::of(c),
                cycles: c.scans(),
                scan: s.scan.summary(),
                firings: net
                    .transitions()
                    .iter()
                    .zip(c.firings())
                    .map(|(t, &n)| (t.id.clone(), n))
                    .collect(),
                marking: net
                    .places()
                    .iter()
                    .zip(c.marking())
                    .map(|(p, &m)| (p.id.clone(), m))
                    .collect(),
                outputs: c
                    .program()
                    .outputs()
                    .iter()
                    .zip(c.outputs())
                    .map(|(s, v)| (s.name.clone(), *v))
                    .collect(),
                divergence: if is_primary {
                    BTreeMap::new()
                } else {
                    io_outputs
                        .iter()
                        .zip(&s.divergent_cycles)
                        .filter(|(_, &n)| n > 0)
                        .map(|(n, &k)| (n.clone(), k))
                        .collect()
                },
                first_cause: if is_primary {
                    None
                } else {
                    text(&s.first_cause)
                },
                last_cause: if is_primary {
                    None
                } else {
                    text(&s.last_cause)
                },
                drift: if is_primary { 0 } else { s.drift },
                max_drift: if is_primary { 0 } else { s.max_drift },
                deadlock: s.deadlocked,
                stall: is_primary && s.stalled,
                verdicts: Vec::new(),
                coverage: s.comparison.as_ref().map(|k| k.progress(c.scans())),
                changes: None,
            })
        })
    }
}

/// The first transition in visiting order (priority, then declaration) that fired in one
/// container and not in the other; on a tie of rank, the primary's.
fn first_difference(pair: &Pair<'_>) -> Option<(Slot, TransIdx)> {
    let only = |a: &Container, b: &Container, map: &[Option<TransIdx>]| {
        a.fired()
            .iter()
            .copied()
            .filter(|t| !map[t.index()].is_some_and(|u| b.fired().contains(&u)))
            .min_by_key(|&t| a.program().net().rank(t))
    };
    let (pc, cc) = (pair.primary, pair.candidate);
    let primary = pair.primary_slot;
    let p = only(pc, cc, pair.from_primary).map(|t| (pc.program().net().rank(t), primary, t));
    let c = only(cc, pc, pair.to_primary).map(|t| (cc.program().net().rank(t), primary.other(), t));
    match (p, c) {
        (Some(a), Some(b)) => Some(if b.0 < a.0 { (b.1, b.2) } else { (a.1, a.2) }),
        (Some(a), None) => Some((a.1, a.2)),
        (None, Some(b)) => Some((b.1, b.2)),
        (None, None) => None,
    }
}

/// Describes a cause in words, with ids from both containers' nets.
pub fn describe_cause(cause: &Cause, fired: &Container, other: &Container) -> String {
    let t = &fired.program().net().transition(cause.transition).id;
    let (a, b) = (cause.fired_in.as_str(), cause.fired_in.other().as_str());
    let why = blocker_words(cause.blocked, other);
    format!("{t} fired in {a} only; in {b} {why}")
}

/// Why a transition did not fire in `other`, in words.
fn blocker_words(blocked: Blocker, other: &Container) -> String {
    let id = |p: cetratus_net::PlaceIdx| &other.program().net().place(p).id;
    match blocked {
        Blocker::Place(p) => format!("it was blocked by {}", id(p)),
        Blocker::Inhibitor(p) => format!("it was inhibited by {}", id(p)),
        Blocker::Capacity(p) => format!("it was blocked by the capacity of {}", id(p)),
        Blocker::Guard => "its guard was false".to_string(),
        Blocker::Conflict => "it lost a conflict to a transition of higher rank".to_string(),
        Blocker::Absent => "it does not exist".to_string(),
    }
}

/// A kind of divergence of output `output`, in words, with ids from both containers' nets:
/// `DM1: T13 fired in the candidate only; in the primary it was blocked by H`.
pub fn describe_kind(
    output: &str,
    cause: Option<CauseKey>,
    candidate: &Container,
    primary: &Container,
) -> String {
    let Some(c) = cause else {
        return format!("{output}: from the install on, before any firing differed");
    };
    let (fired, other, who, whom) = if c.in_candidate {
        (candidate, primary, "the candidate", "the primary")
    } else {
        (primary, candidate, "the primary", "the candidate")
    };
    let t = &fired.program().net().transition(c.transition).id;
    let why = blocker_words(c.blocked, other);
    format!("{output}: {t} fired in {who} only; in {whom} {why}")
}
