//! The PLC's state as persisted, and the warm start that resumes it (docs/design.md §4).

use std::sync::Arc;

use cetratus_net::Tokens;
use cetratus_program::st::RetainedSt;
use cetratus_program::{Program, Type, Value};
use serde::{Deserialize, Serialize};

use crate::clock::Stopwatch;
use crate::error::WarmStartError;
use crate::event::EventKind;
use crate::plc::Plc;
use crate::updater::value_json;
use crate::{Container, Slot, Status};

/// The state of one container, as persisted.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct ContainerSnapshot {
    /// Hex SHA-256 of its program.
    pub program_hash: String,
    /// The marking.
    pub marking: Vec<Tokens>,
    /// When each place went from empty to marked.
    pub place_since_us: Vec<Option<u64>>,
    /// The variables, as JSON scalars.
    pub variables: Vec<serde_json::Value>,
    /// The S/R latches.
    pub latches: Vec<bool>,
    /// The RETAIN variables of the program's Structured Text (docs/st.md, *Restarts*).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub st_retained: Vec<RetainedSt>,
}

/// Everything a warm start needs, written by the persistence thread.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct PlcSnapshot {
    /// Cycle index of the snapshot.
    pub cycle: u64,
    /// Program time of the snapshot.
    pub time_us: u64,
    /// PRIMARY ("A"/"B").
    pub primary: Option<Slot>,
    /// STATUS.
    pub status: Option<Status>,
    /// Containers A and B.
    pub containers: [Option<ContainerSnapshot>; 2],
    /// The update under way, in words.
    pub update: Option<String>,
}

impl Plc {
    /// Copies the state into `snap`, reusing its buffers.
    pub fn snapshot_into(&self, snap: &mut PlcSnapshot) {
        snap.cycle = self.cycles();
        snap.time_us = self.now_us();
        snap.primary = Some(self.primary());
        snap.status = Some(self.status());
        for slot in [Slot::A, Slot::B] {
            let i = slot.index();
            match self.container(slot) {
                None => snap.containers[i] = None,
                Some(c) => {
                    let s = snap.containers[i].get_or_insert_with(Default::default);
                    let hash = c.program().hash_hex();
                    // Reuses the buffer: no allocation once the hash is known.
                    if s.program_hash != hash {
                        s.program_hash.clear();
                        s.program_hash.push_str(hash);
                    }
                    s.marking.clear();
                    s.marking.extend_from_slice(c.marking());
                    s.place_since_us.clear();
                    s.place_since_us.extend_from_slice(c.place_since_us());
                    s.variables.clear();
                    s.variables
                        .extend(c.variables().iter().map(|v| value_json(*v)));
                    s.latches.clear();
                    s.latches.extend_from_slice(c.latches());
                    c.st_retained_into(&mut s.st_retained);
                }
            }
        }
        snap.update = self
            .update_meta()
            .map(|m| format!("{} {}", m.name, m.version));
    }

    /// A warm start: the saved PRIMARY resumes its last committed marking, timers, variables and
    /// latches; an update that was under way is discarded, with an event (docs/design.md §4). A PLC that
    /// was in fault comes back in fault. `program` finds a program by its hash; `io_program`
    /// defines the I/O map.
    pub fn warm_start(
        snap: &PlcSnapshot,
        program: impl Fn(&str) -> Option<Arc<Program>>,
        io_program: Arc<Program>,
        stopwatch: Box<dyn Stopwatch>,
    ) -> Result<Plc, WarmStartError> {
        let primary = snap.primary.ok_or(WarmStartError::NoPrimary)?;
        let cs = snap.containers[primary.index()]
            .as_ref()
            .ok_or(WarmStartError::NoPrimaryProgram)?;
        let prog = program(&cs.program_hash).ok_or_else(|| WarmStartError::MissingProgram {
            hash: cs.program_hash.clone(),
        })?;
        if cs.marking.len() != prog.net().num_places() {
            return Err(WarmStartError::Shape {
                saved: cs.marking.len(),
                program: prog.name().to_string(),
                places: prog.net().num_places(),
            });
        }
        if let Err(v) = prog.check_invariants(&cs.marking) {
            return Err(WarmStartError::Invariant(v.to_string()));
        }
        let now = snap.time_us;
        let mut container =
            Container::with_state(prog.clone(), &cs.marking, &cs.place_since_us, now)
                .map_err(|e| WarmStartError::Net(e.to_string()))?;
        let vars: Vec<Value> = prog
            .variables()
            .iter()
            .zip(&cs.variables)
            .map(|(s, j)| match s.ty {
                Type::Bool => Value::Bool(j.as_bool().unwrap_or(false)),
                Type::Int => Value::Int(j.as_i64().unwrap_or(0)),
                Type::Real => Value::Real(j.as_f64().unwrap_or(0.0)),
            })
            .collect();
        container.restore_retained(&vars, &cs.latches);
        // The program is the one saved (its hash), so every saved RETAIN variable is there,
        // unless the file was damaged or edited.
        let not_restored = container.restore_st_retained(&cs.st_retained);
        container.resume_without_entry();
        let image = container.inputs().to_vec();
        let mut plc = Plc::bare(container, primary, now, &io_program, stopwatch);
        plc.stall.warm_started();
        let i = primary.index();
        let core = plc.core_mut();
        core.router
            .attach_by_name(i, &prog, &image)
            .map_err(WarmStartError::MissingInput)?;
        core.log.cycle = snap.cycle;
        if snap.status == Some(Status::Fault) {
            plc.enter_fault();
        }
        let core = plc.core_mut();
        core.log.push(
            EventKind::WarmStart,
            format!(
                "warm start: PRIMARY = {} resumes {} {} at cycle {} ({:.3} s){}",
                primary.as_str(),
                prog.name(),
                prog.version(),
                snap.cycle,
                now as f64 / 1e6,
                not_restored_note(&not_restored)
            ),
            None,
        );
        let update = snap.update.as_deref().unwrap_or("unnamed");
        if snap.status == Some(Status::Probation) {
            core.log.push(
                EventKind::Accepted,
                format!("the update on probation at the crash ({update}) is final: its shadow was not kept"),
                None,
            );
        }
        if matches!(snap.status, Some(Status::Setup) | Some(Status::Quarantine)) {
            core.log.push(
                EventKind::UpdateDiscarded,
                format!("the update under way at the crash ({update}) is discarded; load it again"),
                None,
            );
        }
        if snap.status == Some(Status::Fault) {
            core.log.push(
                EventKind::PrimaryFault,
                "the PLC was in fault when it stopped; it stays in fault until an operator resets"
                    .into(),
                None,
            );
        }
        Ok(plc)
    }
}

/// What a warm start says of saved RETAIN variables it could not restore: empty when there are
/// none, else their count and the first eight names.
fn not_restored_note(names: &[String]) -> String {
    if names.is_empty() {
        return String::new();
    }
    let shown: Vec<&str> = names.iter().take(8).map(String::as_str).collect();
    let more = if names.len() > 8 { ", …" } else { "" };
    format!(
        "; WARNING: {} saved RETAIN variable(s) of its Structured Text could not be restored \
         (another size, or a STRING longer than its capacity: the state file was damaged or \
         edited) and start from their initial values: {}{more}",
        names.len(),
        shown.join(", ")
    )
}
