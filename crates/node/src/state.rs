//! Where a node keeps its state, and how it starts from it (docs/persistence.md).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use cetratus_persist::{
    self as persist, AuditRecord, PersistConfig, PersistError, PersistFigures, Persister,
    StateStore,
};
use cetratus_program::Program;
use cetratus_runtime::{Event, Plc, Slot, Stopwatch};

/// The default state directory of a program: `$XDG_STATE_HOME/cetratus/<program name>`, or
/// `~/.local/state/cetratus/<program name>`, the name made a file name
/// ([`Program::file_stem`]).
pub fn default_dir(program: &Program) -> Option<PathBuf> {
    let base = crate::dirs::xdg("XDG_STATE_HOME", ".local/state")?;
    Some(base.join("cetratus").join(program.file_stem()))
}

/// A PLC started from a state directory, with its writer.
pub struct Started {
    /// The PLC, warm or cold.
    pub plc: Plc,
    /// The writer thread of the directory.
    pub persister: Persister,
    /// The start-up events, already in the audit log.
    pub events: Vec<Event>,
    /// What an operator should read about the start, line by line.
    pub notes: Vec<String>,
}

/// Opens the state directory and starts the PLC from it (warm, or cold when `cold` or when
/// nothing is saved). Before the first scan the start is made durable: the programs, a first
/// snapshot and the start-up records of the audit log are written synchronously, so a crash at
/// any later instant warm starts from this run, never from what a cold start discarded.
pub fn open(
    dir: &Path,
    program: &Arc<Program>,
    cold: bool,
    period_us: u64,
    stopwatch: Box<dyn Stopwatch>,
) -> Result<Started, PersistError> {
    let mut store = StateStore::open(dir)?;
    let wall = store.wall_clock();
    let saved = if cold {
        store.load_state().ok().flatten()
    } else {
        None
    };
    let mut plc = persist::start(&store, program.clone(), cold, stopwatch)?;
    let now = wall.now();
    let mut notes = Vec::new();
    if cold {
        let message = match &saved {
            Some(s) => format!(
                "cold start: the saved state in {} is ignored (cycle {}, PRIMARY {}, {})",
                dir.display(),
                s.snapshot.cycle,
                s.snapshot.primary.map_or("?", |p| p.as_str()),
                s.snapshot.status.map_or("?", |st| st.as_str())
            ),
            None => format!(
                "cold start: the saved state in {} is ignored (there was none)",
                dir.display()
            ),
        };
        store.append_audit(&AuditRecord {
            utc: persist::rfc3339_utc(now),
            cycle: 0,
            time_us: 0,
            who: "cli".into(),
            what: "cold_start_requested".into(),
            message: message.clone(),
            detail: serde_json::Value::Null,
        })?;
        notes.push(message);
    }
    let events = plc.drain_events();
    for e in &events {
        store.append_audit(&AuditRecord::of_event(e, "local", now))?;
    }
    for slot in [Slot::A, Slot::B] {
        if let Some(c) = plc.container(slot) {
            store.save_program(c.program())?;
        }
    }
    let config = PersistConfig::for_period_us(period_us);
    let mut snap = Default::default();
    plc.snapshot_into(&mut snap);
    store.commit(
        &snap,
        &PersistFigures {
            every_cycles: config.every_cycles,
            ..Default::default()
        },
    )?;
    let persister = Persister::start(store, config)?;
    persister.committed_before(snap.cycle);
    Ok(Started {
        plc,
        persister,
        events,
        notes,
    })
}
