//! What `cetratus state` reports: the saved state checked against its rules.

use cetratus_program::Program;
use cetratus_runtime::{ContainerSnapshot, PlcSnapshot, Role, Slot, Status};
use serde::Serialize;

use crate::*;

/// A stored program, as `cetratus state` lists it.
#[derive(Clone, Debug, Default, Serialize)]
pub struct StoredProgram {
    /// Its hash.
    pub hash: String,
    /// Its name.
    pub name: String,
    /// Its version.
    pub version: String,
    /// Why it does not load, if it does not.
    pub problem: Option<String>,
}

/// One container of the saved state, resolved against its program.
#[derive(Clone, Debug, Serialize)]
pub struct ContainerReport {
    /// A or B.
    pub slot: Slot,
    /// Primary or candidate.
    pub role: Role,
    /// Program name and version, when it loads.
    pub program: String,
    /// Its hash.
    pub program_hash: String,
    /// The marking by place id, in declaration order.
    pub marking: Vec<(String, u64)>,
    /// The first declared invariant the marking breaks, if any.
    pub violation: Option<String>,
}

/// What `cetratus state` reports about a state directory.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Inspection {
    /// The directory.
    pub dir: String,
    /// `state.json`, when there is one and it parses.
    pub state: Option<StateFile>,
    /// The containers of the saved state.
    pub containers: Vec<ContainerReport>,
    /// Every declared invariant holds in every saved marking.
    pub invariants_hold: bool,
    /// What a warm start would do, in words.
    pub warm_start: String,
    /// The stored programs.
    pub programs: Vec<StoredProgram>,
    /// How many audit records there are in all.
    pub audit_records: usize,
    /// The last audit records (and a torn tail, if any).
    pub audit: AuditLog,
    /// No problem was found.
    pub consistent: bool,
    /// What is wrong, each in words.
    pub problems: Vec<String>,
}

/// The rules a committed snapshot obeys: a PRIMARY whose container holds a stored program of the
/// right size; a second container exactly when a candidate is in quarantine; an update named
/// exactly when one is under way; every declared invariant holding.
pub(crate) fn check_snapshot(store: &StateStore, snap: &PlcSnapshot, ins: &mut Inspection) {
    let problems = &mut ins.problems;
    let Some(primary) = snap.primary else {
        problems.push("the saved state has no PRIMARY".into());
        return;
    };
    let status = snap.status.unwrap_or(Status::Idle);
    if snap.containers[primary.index()].is_none() {
        problems.push(format!(
            "the PRIMARY container {} is empty",
            primary.as_str()
        ));
    }
    let other = snap.containers[primary.other().index()].is_some();
    if other != (status == Status::Quarantine) {
        problems.push(format!(
            "half-applied update: STATUS is {} but container {} {}",
            status.as_str(),
            primary.other().as_str(),
            if other { "holds a program" } else { "is empty" }
        ));
    }
    let under_way = matches!(status, Status::Setup | Status::Quarantine);
    if snap.update.is_some() != under_way {
        problems.push(format!(
            "STATUS is {} but the update under way is {:?}",
            status.as_str(),
            snap.update
        ));
    }
    let mut holds = true;
    for slot in [Slot::A, Slot::B] {
        let Some(cs) = &snap.containers[slot.index()] else {
            continue;
        };
        let role = if slot == primary {
            Role::Primary
        } else {
            Role::Candidate
        };
        let mut rep = ContainerReport {
            slot,
            role,
            program: String::new(),
            program_hash: cs.program_hash.clone(),
            marking: Vec::new(),
            violation: None,
        };
        match store.load_program(&cs.program_hash) {
            Ok(p) => {
                rep.program = format!("{} {}", p.name(), p.version());
                if let Some(problem) = shape_problem(&p, cs) {
                    problems.push(format!("container {}: {problem}", slot.as_str()));
                    holds = false;
                } else {
                    rep.marking = p
                        .net()
                        .places()
                        .iter()
                        .zip(&cs.marking)
                        .map(|(pl, &m)| (pl.id.clone(), u64::from(m)))
                        .collect();
                    if let Err(v) = p.check_invariants(&cs.marking) {
                        holds = false;
                        rep.violation = Some(v.to_string());
                        problems.push(format!("container {}: {v}", slot.as_str()));
                    }
                }
            }
            Err(e) => {
                holds = false;
                problems.push(format!("container {}: {e}", slot.as_str()));
            }
        }
        ins.containers.push(rep);
    }
    ins.invariants_hold = holds;
    let resumes = ins
        .containers
        .iter()
        .find(|c| c.role == Role::Primary)
        .map_or(String::new(), |c| c.program.clone());
    ins.warm_start = format!(
        "PRIMARY = {} resumes {} at cycle {} ({:.3} s){}{}",
        primary.as_str(),
        resumes,
        snap.cycle,
        snap.time_us as f64 / 1e6,
        if under_way {
            format!(
                "; the update under way ({}) is discarded",
                snap.update.as_deref().unwrap_or("unnamed")
            )
        } else {
            String::new()
        },
        if status == Status::Fault {
            "; it stays in fault until reset"
        } else {
            ""
        }
    );
}

fn shape_problem(p: &Program, cs: &ContainerSnapshot) -> Option<String> {
    let np = p.net().num_places();
    if cs.marking.len() != np || cs.place_since_us.len() != np {
        return Some(format!(
            "the marking has {} places and {} timers, but the program has {np} places",
            cs.marking.len(),
            cs.place_since_us.len()
        ));
    }
    if cs.variables.len() != p.variables().len() {
        return Some(format!(
            "{} variables saved, but the program declares {}",
            cs.variables.len(),
            p.variables().len()
        ));
    }
    None
}
