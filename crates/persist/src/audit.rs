//! The audit log: one JSON object a line, in wall-clock time.

use std::time::SystemTime;

use cetratus_runtime::Event;
use serde::{Deserialize, Serialize};

/// A time in RFC 3339, UTC, to the millisecond.
pub fn rfc3339_utc(t: SystemTime) -> String {
    humantime::format_rfc3339_millis(t).to_string()
}

/// One line of the audit log: what happened to an update, when, who asked, and the verdict.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AuditRecord {
    /// Wall-clock time, RFC 3339 UTC.
    pub utc: String,
    /// Cycle index at which it happened.
    pub cycle: u64,
    /// Program time, microseconds.
    pub time_us: u64,
    /// Who caused it: `cli`, `mqtt:<key id>`, `mqtt:<key id>/<account>` (a dashboard operator),
    /// `plc` (the PLC itself), `local` (start-up).
    pub who: String,
    /// The event kind, e.g. `load_accepted`, `substituted`, `warm_start`, `update_discarded`.
    pub what: String,
    /// The verdict or reason, in words.
    pub message: String,
    /// Figures that go with it (drift, install time, mode).
    #[serde(default, skip_serializing_if = "serde_json::Value::is_null")]
    pub detail: serde_json::Value,
}

impl AuditRecord {
    /// The record of a PLC event.
    pub fn of_event(e: &Event, who: &str, wall: SystemTime) -> Self {
        AuditRecord {
            utc: rfc3339_utc(wall),
            cycle: e.cycle,
            time_us: e.time_us,
            who: who.to_string(),
            what: e.kind.to_string(),
            message: e.message.clone(),
            detail: serde_json::to_value(e.detail).unwrap_or(serde_json::Value::Null),
        }
    }
}

/// The audit log as read back.
#[derive(Clone, Debug, Default, Serialize)]
pub struct AuditLog {
    /// The records, oldest first.
    pub records: Vec<AuditRecord>,
    /// A last line without its newline: a record whose write a crash interrupted (never synced,
    /// so never acknowledged). Cut off when a writer next opens the log.
    pub torn_tail: Option<String>,
    /// 1-based numbers of complete lines that do not parse (the file was edited).
    pub bad_lines: Vec<usize>,
}
