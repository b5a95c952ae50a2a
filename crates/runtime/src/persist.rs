//! Persistence of the PLC's state: the state directory and the writer thread that fills it.
//!
//! A state directory holds everything a warm start needs (DESIGN §4), in files that a crash at any
//! instant leaves consistent:
//!
//! ```text
//! DIR/state.json              the last committed PlcSnapshot: PRIMARY, STATUS, markings, timers,
//!                             retained variables and latches; replaced atomically (write a
//!                             temporary file, fsync, rename, fsync the directory)
//! DIR/programs/<hash>.toml    every program a snapshot refers to, content-addressed by
//! DIR/programs/<hash>.pnml    Program::hash_hex; written before any snapshot that names it
//! DIR/audit.jsonl             append-only log of update operations, one JSON object a line
//! DIR/lock                    held (flock) by the one process that writes the directory
//! ```
//!
//! [`StateStore`] is the directory. [`Persister`] owns one on a writer thread fed through bounded
//! channels: the scan thread offers a snapshot every few cycles with `try_send` and never waits
//! for the disk. `docs/persistence.md` derives how many scans a crash can lose.

use std::collections::HashSet;
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use cetratus_program::Program;
use nix::fcntl::{Flock, FlockArg};
use serde::{Deserialize, Serialize};

use crate::monitor::{Slot, Status};
use crate::plc::{ContainerSnapshot, Event, Plc, PlcSnapshot};

/// The `format` of `state.json` this version writes and reads.
pub const STATE_FORMAT: &str = "cetratus-state/1";
const STATE_FILE: &str = "state.json";
const AUDIT_FILE: &str = "audit.jsonl";
const PROGRAMS_DIR: &str = "programs";
const LOCK_FILE: &str = "lock";

/// Everything that can go wrong with a state directory (this module's own error type: the
/// scan engine's [`crate::RuntimeError`] never meets a disk).
#[derive(Debug, thiserror::Error)]
pub enum PersistError {
    /// A file or directory could not be read, written or synced.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// Another process holds the state directory.
    #[error("{dir} is in use by another cetratus process (its lock file is held); stop that process, or give this one another --state-dir")]
    Locked {
        /// The directory.
        dir: String,
    },
    /// `state.json` is not valid JSON of the right shape.
    #[error("{path}: not a Cetratus state file: {reason}; start with --cold to replace it (the programs and the audit log are kept)")]
    Malformed {
        /// The file.
        path: String,
        /// What serde said.
        reason: String,
    },
    /// `state.json` is in a format this version does not read.
    #[error("{path}: state format `{found}`, but this version reads `{STATE_FORMAT}`; start with --cold to replace it")]
    Format {
        /// The file.
        path: String,
        /// The format the file gives.
        found: String,
    },
    /// A program hash is not 64 lowercase hex digits (so it cannot name a file here).
    #[error("`{hash}` is not a program hash (64 lowercase hex digits); the state file was edited or damaged")]
    BadHash {
        /// The text given.
        hash: String,
    },
    /// A program the state refers to is not in the directory.
    #[error("program {hash} is not in {dir}/programs; the state directory lost a file; start with --cold")]
    ProgramMissing {
        /// Its hash.
        hash: String,
        /// The state directory.
        dir: String,
    },
    /// A stored program does not load.
    #[error("{path}: the stored program does not load: {reason}")]
    Program {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// The saved state does not fit the program given on the command line (the I/O map).
    #[error("{dir}: cannot warm start: {reason}; start with --cold to replace the saved state")]
    WarmStart {
        /// The state directory.
        dir: String,
        /// Why.
        reason: String,
    },
    /// A stored program loads, but to another hash than its name: the files were altered.
    #[error("program file {path} loads to hash {got}, not the {hash} its name says; it was altered; start with --cold")]
    ProgramMismatch {
        /// The hash its name gives.
        hash: String,
        /// The hash it loads to.
        got: String,
        /// The file.
        path: String,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> PersistError + '_ {
    move |source| PersistError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// A time in RFC 3339, UTC, to the millisecond.
pub fn rfc3339_utc(t: SystemTime) -> String {
    let d = t.duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO);
    let secs = d.as_secs();
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // Howard Hinnant's days-to-civil algorithm: no dependency for one date format.
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{:03}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60,
        d.subsec_millis()
    )
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
    /// Who caused it: `cli`, `mqtt:<key id>`, `plc` (the PLC itself), `local` (start-up).
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
            detail: e.detail.clone(),
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

/// How the persister was configured and how it kept up, as recorded in `state.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PersistFigures {
    /// A snapshot is offered every this many cycles (and at every change of PRIMARY or STATUS).
    pub every_cycles: u64,
    /// The longest commit so far in this process (write, fsync, rename, fsync), microseconds.
    pub max_commit_us: u64,
    /// Snapshots this process committed before this one.
    pub commits: u64,
}

/// `state.json`: a snapshot and how it was written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StateFile {
    /// [`STATE_FORMAT`].
    pub format: String,
    /// Increases by one with every commit to this directory.
    pub seq: u64,
    /// When it was written, RFC 3339 UTC.
    pub written_utc: String,
    /// The writer's figures.
    #[serde(default)]
    pub persist: PersistFigures,
    /// The PLC's state.
    pub snapshot: PlcSnapshot,
}

#[derive(Serialize)]
struct StateFileRef<'a> {
    format: &'a str,
    seq: u64,
    written_utc: String,
    persist: &'a PersistFigures,
    snapshot: &'a PlcSnapshot,
}

/// True when `hash` can be a [`Program::hash_hex`] (and so names a file safely).
pub fn is_program_hash(hash: &str) -> bool {
    hash.len() == 64
        && hash
            .bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

/// Writes `bytes` to `dir/name` so that a crash leaves either the old file or the new one.
fn write_atomic(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), PersistError> {
    let tmp = dir.join(format!("{name}.tmp"));
    let target = dir.join(name);
    let mut f = File::create(&tmp).map_err(io_err(&tmp))?;
    f.write_all(bytes).map_err(io_err(&tmp))?;
    // The data must be on disk before the rename makes it visible, or a crash could leave a
    // renamed but empty file.
    f.sync_all().map_err(io_err(&tmp))?;
    drop(f);
    std::fs::rename(&tmp, &target).map_err(io_err(&target))?;
    sync_dir(dir)
}

/// Makes a rename or a new file in `dir` durable.
fn sync_dir(dir: &Path) -> Result<(), PersistError> {
    File::open(dir)
        .and_then(|d| d.sync_all())
        .map_err(io_err(dir))
}

/// A state directory.
pub struct StateStore {
    dir: PathBuf,
    // Held while this value lives; the kernel releases it when the process dies, even by SIGKILL.
    _lock: Option<Flock<File>>,
    audit: Option<File>,
    seq: u64,
    buf: Vec<u8>,
    saved: HashSet<String>,
}

impl std::fmt::Debug for StateStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StateStore")
            .field("dir", &self.dir)
            .field("seq", &self.seq)
            .finish()
    }
}

impl StateStore {
    /// Opens `dir` for writing, creating it: takes its lock, removes temporary files a crash left,
    /// and cuts a torn last line off the audit log (a record never synced, so never acknowledged;
    /// the cut is itself logged).
    pub fn open(dir: &Path) -> Result<Self, PersistError> {
        let programs = dir.join(PROGRAMS_DIR);
        std::fs::create_dir_all(&programs).map_err(io_err(&programs))?;
        let lock_path = dir.join(LOCK_FILE);
        let lock_file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&lock_path)
            .map_err(io_err(&lock_path))?;
        let lock = Flock::lock(lock_file, FlockArg::LockExclusiveNonblock).map_err(|_| {
            PersistError::Locked {
                dir: dir.display().to_string(),
            }
        })?;
        for d in [dir.to_path_buf(), programs] {
            let entries = std::fs::read_dir(&d).map_err(io_err(&d))?;
            for entry in entries.flatten() {
                let p = entry.path();
                if p.extension().is_some_and(|e| e == "tmp") {
                    // Left by a crash between write and rename: never part of the state.
                    let _ = std::fs::remove_file(&p);
                }
            }
        }
        let mut store = StateStore {
            dir: dir.to_path_buf(),
            _lock: Some(lock),
            audit: None,
            seq: 0,
            buf: Vec::with_capacity(4096),
            saved: HashSet::new(),
        };
        store.seq = match store.load_state() {
            Ok(Some(s)) => s.seq,
            _ => 0,
        };
        let torn = store.open_audit()?;
        if let Some(tail) = torn {
            store.append_audit(&AuditRecord {
                utc: rfc3339_utc(SystemTime::now()),
                cycle: 0,
                time_us: 0,
                who: "local".into(),
                what: "audit_repaired".into(),
                message: format!(
                    "the audit log ended in a torn record ({} bytes, written when the process died and never synced); it was cut off",
                    tail.len()
                ),
                detail: serde_json::json!({ "torn": tail }),
            })?;
        }
        Ok(store)
    }

    /// Opens `dir` to read it only (`cetratus state`): no lock, nothing created or repaired.
    pub fn open_read_only(dir: &Path) -> Result<Self, PersistError> {
        std::fs::metadata(dir).map_err(io_err(dir))?;
        Ok(StateStore {
            dir: dir.to_path_buf(),
            _lock: None,
            audit: None,
            seq: 0,
            buf: Vec::new(),
            saved: HashSet::new(),
        })
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn open_audit(&mut self) -> Result<Option<String>, PersistError> {
        let path = self.dir.join(AUDIT_FILE);
        let mut f = OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .append(true)
            .open(&path)
            .map_err(io_err(&path))?;
        let mut bytes = Vec::new();
        f.read_to_end(&mut bytes).map_err(io_err(&path))?;
        let keep = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        let torn = if keep < bytes.len() {
            let tail = String::from_utf8_lossy(&bytes[keep..]).into_owned();
            // Appending after a torn line would glue the next record onto it.
            f.set_len(keep as u64).map_err(io_err(&path))?;
            f.sync_all().map_err(io_err(&path))?;
            Some(tail)
        } else {
            None
        };
        f.seek(SeekFrom::End(0)).map_err(io_err(&path))?;
        if bytes.is_empty() {
            sync_dir(&self.dir)?;
        }
        self.audit = Some(f);
        Ok(torn)
    }

    /// Reads `state.json`; `None` when there is none (a first start).
    pub fn load_state(&self) -> Result<Option<StateFile>, PersistError> {
        let path = self.dir.join(STATE_FILE);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(io_err(&path)(e)),
        };
        let head: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| PersistError::Malformed {
                path: path.display().to_string(),
                reason: e.to_string(),
            })?;
        let format = head.get("format").and_then(|f| f.as_str()).unwrap_or("");
        if format != STATE_FORMAT {
            return Err(PersistError::Format {
                path: path.display().to_string(),
                found: format.to_string(),
            });
        }
        serde_json::from_value(head)
            .map(Some)
            .map_err(|e| PersistError::Malformed {
                path: path.display().to_string(),
                reason: e.to_string(),
            })
    }

    /// The snapshot of `state.json`, if there is one.
    pub fn load_snapshot(&self) -> Result<Option<PlcSnapshot>, PersistError> {
        Ok(self.load_state()?.map(|s| s.snapshot))
    }

    fn program_paths(&self, hash: &str) -> (PathBuf, PathBuf) {
        let d = self.dir.join(PROGRAMS_DIR);
        (
            d.join(format!("{hash}.toml")),
            d.join(format!("{hash}.pnml")),
        )
    }

    /// True when the program is stored (both files present; not verified).
    pub fn has_program(&self, hash: &str) -> bool {
        let (t, n) = self.program_paths(hash);
        is_program_hash(hash) && t.is_file() && n.is_file()
    }

    /// Stores a program under its hash, once per process (idempotent). The files are read back and
    /// must load to the same hash, so a snapshot never refers to a program that cannot come back.
    pub fn save_program(&mut self, program: &Program) -> Result<(), PersistError> {
        let hash = program.hash_hex().to_string();
        if self.saved.contains(&hash) {
            return Ok(());
        }
        let dir = self.dir.join(PROGRAMS_DIR);
        let pnml = cetratus_net::pnml::write_string(program.net());
        // The net first: a .toml without its .pnml is never mistaken for a stored program.
        write_atomic(&dir, &format!("{hash}.pnml"), pnml.as_bytes())?;
        write_atomic(&dir, &format!("{hash}.toml"), program.source().as_bytes())?;
        self.load_program(&hash)?;
        self.saved.insert(hash);
        Ok(())
    }

    /// Loads a stored program and checks that it is the one its hash names.
    pub fn load_program(&self, hash: &str) -> Result<Arc<Program>, PersistError> {
        if !is_program_hash(hash) {
            return Err(PersistError::BadHash {
                hash: hash.to_string(),
            });
        }
        let (toml_path, pnml_path) = self.program_paths(hash);
        let read = |p: &Path| match std::fs::read_to_string(p) {
            Ok(t) => Ok(t),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                Err(PersistError::ProgramMissing {
                    hash: hash.to_string(),
                    dir: self.dir.display().to_string(),
                })
            }
            Err(e) => Err(io_err(p)(e)),
        };
        let toml_text = read(&toml_path)?;
        let pnml_text = read(&pnml_path)?;
        let pnml_label = pnml_path.display().to_string();
        let net = cetratus_net::pnml::read_str(&pnml_text, &pnml_label).map_err(|e| {
            PersistError::Program {
                path: pnml_label.clone(),
                reason: e.to_string(),
            }
        })?;
        let label = toml_path.display().to_string();
        let program =
            Program::from_sources(&toml_text, &label, net).map_err(|e| PersistError::Program {
                path: label.clone(),
                reason: e.to_string(),
            })?;
        let got = program.hash_hex().to_string();
        if got != hash {
            return Err(PersistError::ProgramMismatch {
                hash: hash.to_string(),
                got,
                path: label,
            });
        }
        Ok(Arc::new(program))
    }

    /// Hashes of the stored programs, sorted.
    pub fn program_hashes(&self) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(self.dir.join(PROGRAMS_DIR))
            .into_iter()
            .flatten()
            .flatten()
            .filter_map(|e| {
                let name = e.file_name().into_string().ok()?;
                let hash = name.strip_suffix(".toml")?;
                is_program_hash(hash).then(|| hash.to_string())
            })
            .collect();
        v.sort();
        v
    }

    /// Replaces `state.json` atomically with `snap`. Every program it names must have been saved
    /// by this store first.
    pub fn commit(
        &mut self,
        snap: &PlcSnapshot,
        figures: &PersistFigures,
    ) -> Result<u64, PersistError> {
        for cs in snap.containers.iter().flatten() {
            if !self.saved.contains(&cs.program_hash) {
                return Err(PersistError::ProgramMissing {
                    hash: cs.program_hash.clone(),
                    dir: self.dir.display().to_string(),
                });
            }
        }
        let seq = self.seq + 1;
        self.buf.clear();
        let file = StateFileRef {
            format: STATE_FORMAT,
            seq,
            written_utc: rfc3339_utc(SystemTime::now()),
            persist: figures,
            snapshot: snap,
        };
        serde_json::to_writer(&mut self.buf, &file).map_err(|e| PersistError::Io {
            path: self.dir.join(STATE_FILE).display().to_string(),
            source: e.into(),
        })?;
        self.buf.push(b'\n');
        write_atomic(&self.dir, STATE_FILE, &self.buf)?;
        self.seq = seq;
        Ok(seq)
    }

    /// Appends one record to the audit log and syncs it.
    pub fn append_audit(&mut self, rec: &AuditRecord) -> Result<(), PersistError> {
        self.write_audit(rec)?;
        self.sync_audit()
    }

    // Writes without syncing: the writer thread syncs once per batch, before it commits a
    // snapshot, so the log never lags behind the state it explains.
    fn write_audit(&mut self, rec: &AuditRecord) -> Result<(), PersistError> {
        let path = self.dir.join(AUDIT_FILE);
        if self.audit.is_none() {
            self.open_audit()?;
        }
        let Some(f) = self.audit.as_mut() else {
            return Ok(());
        };
        let mut line = serde_json::to_vec(rec).map_err(|e| PersistError::Io {
            path: path.display().to_string(),
            source: e.into(),
        })?;
        line.push(b'\n');
        // One write call per record, so a crash tears at most the last line.
        f.write_all(&line).map_err(io_err(&path))
    }

    fn sync_audit(&mut self) -> Result<(), PersistError> {
        let path = self.dir.join(AUDIT_FILE);
        match self.audit.as_mut() {
            Some(f) => f.sync_data().map_err(io_err(&path)),
            None => Ok(()),
        }
    }

    /// Reads the audit log, tolerating a torn last line (reported in [`AuditLog::torn_tail`]).
    pub fn read_audit(&self) -> Result<AuditLog, PersistError> {
        let path = self.dir.join(AUDIT_FILE);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(AuditLog::default()),
            Err(e) => return Err(io_err(&path)(e)),
        };
        let mut log = AuditLog::default();
        let complete = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        if complete < bytes.len() {
            log.torn_tail = Some(String::from_utf8_lossy(&bytes[complete..]).into_owned());
        }
        for (i, line) in bytes[..complete].split(|&b| b == b'\n').enumerate() {
            if line.is_empty() {
                continue;
            }
            match serde_json::from_slice::<AuditRecord>(line) {
                Ok(r) => log.records.push(r),
                Err(_) => log.bad_lines.push(i + 1),
            }
        }
        Ok(log)
    }

    /// Checks the directory the way a warm start would, and reports what it finds.
    pub fn inspect(&self, audit_tail: usize) -> Inspection {
        let mut ins = Inspection {
            dir: self.dir.display().to_string(),
            ..Default::default()
        };
        match self.load_state() {
            Ok(Some(s)) => {
                check_snapshot(self, &s.snapshot, &mut ins);
                ins.state = Some(s);
            }
            Ok(None) => ins.warm_start = "no saved state: the next start is a cold start".into(),
            Err(e) => ins.problems.push(e.to_string()),
        }
        for hash in self.program_hashes() {
            ins.programs.push(match self.load_program(&hash) {
                Ok(p) => StoredProgram {
                    hash,
                    name: p.name().to_string(),
                    version: p.version().to_string(),
                    problem: None,
                },
                Err(e) => StoredProgram {
                    hash,
                    name: String::new(),
                    version: String::new(),
                    problem: Some(e.to_string()),
                },
            });
        }
        match self.read_audit() {
            Ok(mut log) => {
                ins.audit_records = log.records.len();
                if !log.bad_lines.is_empty() {
                    ins.problems.push(format!(
                        "audit.jsonl: lines {:?} do not parse",
                        log.bad_lines
                    ));
                }
                let skip = log.records.len().saturating_sub(audit_tail);
                log.records.drain(..skip);
                ins.audit = log;
            }
            Err(e) => ins.problems.push(e.to_string()),
        }
        ins.consistent = ins.problems.is_empty();
        ins
    }
}

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
#[derive(Clone, Debug, Default, Serialize)]
pub struct ContainerReport {
    /// A or B.
    pub slot: String,
    /// `primary` or `candidate`.
    pub role: String,
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
fn check_snapshot(store: &StateStore, snap: &PlcSnapshot, ins: &mut Inspection) {
    let problems = &mut ins.problems;
    let Some(primary) = snap.primary else {
        problems.push("the saved state has no PRIMARY".into());
        return;
    };
    let status = snap.status.unwrap_or(Status::Idle);
    if snap.containers[primary.index()].is_none() {
        problems.push(format!("the PRIMARY container {} is empty", primary.name()));
    }
    let other = snap.containers[primary.other().index()].is_some();
    if other != (status == Status::Quarantine) {
        problems.push(format!(
            "half-applied update: STATUS is {} but container {} {}",
            status.name(),
            primary.other().name(),
            if other { "holds a program" } else { "is empty" }
        ));
    }
    let under_way = matches!(status, Status::Setup | Status::Quarantine);
    if snap.update.is_some() != under_way {
        problems.push(format!(
            "STATUS is {} but the update under way is {:?}",
            status.name(),
            snap.update
        ));
    }
    let mut holds = true;
    for slot in [Slot::A, Slot::B] {
        let Some(cs) = &snap.containers[slot.index()] else {
            continue;
        };
        let role = if slot == primary {
            "primary"
        } else {
            "candidate"
        };
        let mut rep = ContainerReport {
            slot: slot.name().into(),
            role: role.into(),
            program_hash: cs.program_hash.clone(),
            ..Default::default()
        };
        match store.load_program(&cs.program_hash) {
            Ok(p) => {
                rep.program = format!("{} {}", p.name(), p.version());
                if let Some(problem) = shape_problem(&p, cs) {
                    problems.push(format!("container {}: {problem}", slot.name()));
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
                        problems.push(format!("container {}: {v}", slot.name()));
                    }
                }
            }
            Err(e) => {
                holds = false;
                problems.push(format!("container {}: {e}", slot.name()));
            }
        }
        ins.containers.push(rep);
    }
    ins.invariants_hold = holds;
    let resumes = ins
        .containers
        .iter()
        .find(|c| c.role == "primary")
        .map_or(String::new(), |c| c.program.clone());
    ins.warm_start = format!(
        "PRIMARY = {} resumes {} at cycle {} ({:.3} s){}{}",
        primary.name(),
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

/// Starts a PLC from a state directory: a warm start from its snapshot when it has one and `cold`
/// is false, otherwise a cold start with `program`. The start-up events are left in the PLC's
/// event queue, and a cold start that replaces a saved state adds one saying so.
pub fn start(store: &StateStore, program: Arc<Program>, cold: bool) -> Result<Plc, PersistError> {
    let saved = if cold {
        None
    } else {
        store.load_state()?.map(|s| s.snapshot)
    };
    let Some(snap) = saved else {
        return Ok(Plc::new(program, 0));
    };
    // Loaded first so that a missing or altered program is reported as such, not as "absent".
    let mut found: Vec<Arc<Program>> = Vec::new();
    if let Some(p) = snap.primary {
        if let Some(cs) = &snap.containers[p.index()] {
            found.push(store.load_program(&cs.program_hash)?);
        }
    }
    Plc::warm_start(
        &snap,
        |h| found.iter().find(|p| p.hash_hex() == h).cloned(),
        program,
    )
    .map_err(|reason| PersistError::WarmStart {
        dir: store.dir.display().to_string(),
        reason,
    })
}

/// How the [`Persister`] works.
#[derive(Clone, Copy, Debug)]
pub struct PersistConfig {
    /// Offer a snapshot every this many cycles; PRIMARY or STATUS changing offers one at once.
    pub every_cycles: u64,
    /// Snapshot buffers in circulation: one filling, one queued, one being written.
    pub buffers: usize,
    /// Room in the queue to the writer (snapshots, programs and audit records).
    pub queue: usize,
}

impl PersistConfig {
    /// The default: a snapshot every 50 ms of program time, at least every cycle.
    pub fn for_period_us(period_us: u64) -> Self {
        PersistConfig {
            every_cycles: (DEFAULT_INTERVAL_US / period_us.max(1)).max(1),
            buffers: 3,
            queue: 256,
        }
    }

    /// The most cycles a crash can lose (docs/persistence.md) when a commit takes at most
    /// `commit_ns` and a cycle at least `cycle_ns` of wall time.
    pub fn loss_bound_cycles(&self, commit_ns: u64, cycle_ns: u64) -> u64 {
        let w = commit_ns.div_ceil(cycle_ns.max(1));
        self.every_cycles + 3 * w + 1
    }
}

/// Program time between two snapshots by default.
pub const DEFAULT_INTERVAL_US: u64 = 50_000;

enum Msg {
    Program(Arc<Program>),
    Snapshot(Box<PlcSnapshot>),
    Audit(Box<AuditRecord>),
    Dropped { audit: u64, at_cycle: u64 },
    Stop,
}

#[derive(Default)]
struct Shared {
    commits: AtomicU64,
    committed_cycle: AtomicU64,
    max_commit_ns: AtomicU64,
    errors: AtomicU64,
    last_error: Mutex<Option<String>>,
}

impl Shared {
    fn fail(&self, e: &PersistError) {
        self.errors.fetch_add(1, Ordering::Relaxed);
        if let Ok(mut g) = self.last_error.lock() {
            *g = Some(e.to_string());
        }
    }
}

/// What the writer did, when it stopped.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PersistStats {
    /// Snapshots committed.
    pub commits: u64,
    /// Snapshots offered but superseded in the queue by a newer one before they were written.
    pub coalesced: u64,
    /// Cycles at which a snapshot was due but no buffer was free (the writer was behind).
    pub skipped: u64,
    /// Audit records dropped because the queue was full.
    pub audit_dropped: u64,
    /// The longest commit, microseconds.
    pub max_commit_us: u64,
    /// Write errors.
    pub errors: u64,
    /// The last error, in words.
    pub last_error: Option<String>,
}

/// The scan thread's side of persistence: offers snapshots and audit records to a writer thread
/// and never waits for it.
pub struct Persister {
    tx: SyncSender<Msg>,
    free_rx: Receiver<Box<PlcSnapshot>>,
    // Boxed so a snapshot travels through the channels as a pointer and `Msg` stays small.
    #[allow(clippy::vec_box)]
    free: Vec<Box<PlcSnapshot>>,
    config: PersistConfig,
    last_cycle: Option<u64>,
    last_state: Option<(Slot, Status)>,
    // Hashes the writer has been sent, newest last; a fixed ring so the check never allocates.
    known: [[u8; 32]; 4],
    known_next: usize,
    audit_dropped: u64,
    audit_dropped_unreported: u64,
    skipped: u64,
    shared: Arc<Shared>,
    handle: Option<JoinHandle<(u64, u64)>>,
}

impl Persister {
    /// Starts the writer thread on `store`. Programs already saved by the store are known to it.
    pub fn start(store: StateStore, config: PersistConfig) -> Result<Self, PersistError> {
        let (tx, rx) = sync_channel::<Msg>(config.queue.max(4));
        let buffers = config.buffers.max(2);
        let (free_tx, free_rx) = sync_channel::<Box<PlcSnapshot>>(buffers);
        let shared = Arc::new(Shared::default());
        let s2 = shared.clone();
        let every = config.every_cycles;
        let handle = std::thread::Builder::new()
            .name("cetratus-persist".into())
            .spawn(move || writer(store, rx, free_tx, s2, every))
            .map_err(|source| PersistError::Io {
                path: "(persistence thread)".into(),
                source,
            })?;
        Ok(Persister {
            tx,
            free_rx,
            free: (0..buffers).map(|_| Box::default()).collect(),
            config,
            last_cycle: None,
            last_state: None,
            known: [[0; 32]; 4],
            known_next: 0,
            audit_dropped: 0,
            audit_dropped_unreported: 0,
            skipped: 0,
            shared,
            handle: Some(handle),
        })
    }

    /// The configuration.
    pub fn config(&self) -> PersistConfig {
        self.config
    }

    /// Cycle count of the last committed snapshot, if any.
    pub fn committed_cycle(&self) -> Option<u64> {
        (self.shared.commits.load(Ordering::Relaxed) > 0)
            .then(|| self.shared.committed_cycle.load(Ordering::Relaxed))
    }

    /// The last write error since the previous call, if any (never waits for the writer).
    pub fn take_error(&self) -> Option<String> {
        if self.shared.errors.load(Ordering::Relaxed) == 0 {
            return None;
        }
        self.shared
            .last_error
            .try_lock()
            .ok()
            .and_then(|mut g| g.take())
    }

    fn ensure_programs(&mut self, plc: &Plc) -> bool {
        for slot in [Slot::A, Slot::B] {
            let Some(c) = plc.container(slot) else {
                continue;
            };
            let h = c.program().hash();
            if self.known.contains(&h) {
                continue;
            }
            match self.tx.try_send(Msg::Program(c.program().clone())) {
                Ok(()) => {
                    self.known[self.known_next] = h;
                    self.known_next = (self.known_next + 1) % self.known.len();
                }
                // No snapshot may name a program the writer has not been given.
                Err(_) => return false,
            }
        }
        true
    }

    /// Called by the scan thread once per cycle, after the cycle: snapshots the PLC when one is
    /// due (every `every_cycles`, or PRIMARY or STATUS changed) and a buffer is free. Never blocks;
    /// allocates nothing in steady state.
    pub fn offer(&mut self, plc: &Plc) {
        while let Ok(b) = self.free_rx.try_recv() {
            self.free.push(b);
        }
        let state = (plc.primary(), plc.status());
        let due = self.last_state != Some(state)
            || self
                .last_cycle
                .is_none_or(|c| plc.cycles() >= c + self.config.every_cycles);
        if !due {
            return;
        }
        if !self.ensure_programs(plc) {
            self.skipped += 1;
            return;
        }
        let Some(mut buf) = self.free.pop() else {
            self.skipped += 1;
            return;
        };
        plc.snapshot_into(&mut buf);
        match self.tx.try_send(Msg::Snapshot(buf)) {
            Ok(()) => {
                self.last_cycle = Some(plc.cycles());
                self.last_state = Some(state);
            }
            Err(TrySendError::Full(Msg::Snapshot(b)))
            | Err(TrySendError::Disconnected(Msg::Snapshot(b))) => {
                self.free.push(b);
                self.skipped += 1;
            }
            Err(_) => {}
        }
    }

    /// Logs an event in the audit log, caused by `who`. Never blocks: when the queue is full the
    /// record is dropped and counted, and the count is logged as soon as there is room.
    pub fn audit(&mut self, event: &Event, who: &str) {
        // The audit log is for people, in wall time; the engine itself still never reads a clock.
        let rec = AuditRecord::of_event(event, who, SystemTime::now());
        self.audit_record(rec, event.cycle);
    }

    /// Logs a record built by the caller (start-up records, operator notes).
    pub fn audit_record(&mut self, rec: AuditRecord, cycle: u64) {
        if self.audit_dropped_unreported > 0 {
            let n = self.audit_dropped_unreported;
            if self
                .tx
                .try_send(Msg::Dropped {
                    audit: n,
                    at_cycle: cycle,
                })
                .is_ok()
            {
                self.audit_dropped_unreported = 0;
            }
        }
        if self.tx.try_send(Msg::Audit(Box::new(rec))).is_err() {
            self.audit_dropped += 1;
            self.audit_dropped_unreported += 1;
        }
    }

    /// Takes a last snapshot of `plc`, waits for the writer to commit it and everything queued,
    /// and stops the writer.
    pub fn stop(mut self, plc: &Plc) -> PersistStats {
        let mut stats = PersistStats {
            skipped: self.skipped,
            audit_dropped: self.audit_dropped,
            ..Default::default()
        };
        // Off the scan loop now: blocking sends are fine, and nothing may be lost.
        let mut programs_ok = true;
        for slot in [Slot::A, Slot::B] {
            if let Some(c) = plc.container(slot) {
                programs_ok &= self.tx.send(Msg::Program(c.program().clone())).is_ok();
            }
        }
        if self.audit_dropped_unreported > 0 {
            let _ = self.tx.send(Msg::Dropped {
                audit: self.audit_dropped_unreported,
                at_cycle: plc.cycles(),
            });
        }
        if programs_ok {
            let mut buf = self.free.pop().unwrap_or_default();
            plc.snapshot_into(&mut buf);
            let _ = self.tx.send(Msg::Snapshot(buf));
        }
        let _ = self.tx.send(Msg::Stop);
        if let Some(h) = self.handle.take() {
            match h.join() {
                Ok((coalesced, max_ns)) => {
                    stats.coalesced = coalesced;
                    stats.max_commit_us = max_ns / 1000;
                }
                Err(_) => stats.last_error = Some("the persistence thread panicked".into()),
            }
        }
        stats.commits = self.shared.commits.load(Ordering::Relaxed);
        stats.errors = self.shared.errors.load(Ordering::Relaxed);
        if let Ok(mut g) = self.shared.last_error.lock() {
            stats.last_error = stats.last_error.take().or(g.take());
        }
        stats
    }
}

/// The writer thread: takes whatever is queued, saves programs and audit records in order, syncs
/// the log, then commits the newest snapshot of the batch (older ones are superseded).
fn writer(
    mut store: StateStore,
    rx: Receiver<Msg>,
    free_tx: SyncSender<Box<PlcSnapshot>>,
    shared: Arc<Shared>,
    every_cycles: u64,
) -> (u64, u64) {
    let mut batch: Vec<Msg> = Vec::with_capacity(64);
    let mut figures = PersistFigures {
        every_cycles,
        ..Default::default()
    };
    let mut coalesced = 0u64;
    let mut max_ns = 0u64;
    while let Ok(first) = rx.recv() {
        batch.push(first);
        while let Ok(m) = rx.try_recv() {
            batch.push(m);
        }
        let mut newest: Option<Box<PlcSnapshot>> = None;
        let mut stop = false;
        let mut logged = false;
        for m in batch.drain(..) {
            match m {
                Msg::Program(p) => {
                    if let Err(e) = store.save_program(&p) {
                        shared.fail(&e);
                    }
                }
                Msg::Audit(r) => {
                    logged = true;
                    if let Err(e) = store.write_audit(&r) {
                        shared.fail(&e);
                    }
                }
                Msg::Dropped { audit, at_cycle } => {
                    logged = true;
                    let rec = AuditRecord {
                        utc: rfc3339_utc(SystemTime::now()),
                        cycle: at_cycle,
                        time_us: 0,
                        who: "local".into(),
                        what: "audit_dropped".into(),
                        message: format!("{audit} audit records were dropped because the persistence queue was full"),
                        detail: serde_json::json!({ "dropped": audit }),
                    };
                    if let Err(e) = store.write_audit(&rec) {
                        shared.fail(&e);
                    }
                }
                Msg::Snapshot(s) => {
                    if let Some(old) = newest.replace(s) {
                        coalesced += 1;
                        let _ = free_tx.try_send(old);
                    }
                }
                Msg::Stop => stop = true,
            }
        }
        if logged {
            if let Err(e) = store.sync_audit() {
                shared.fail(&e);
            }
        }
        if let Some(s) = newest {
            let t = Instant::now();
            match store.commit(&s, &figures) {
                Ok(_) => {
                    let ns = t.elapsed().as_nanos() as u64;
                    max_ns = max_ns.max(ns);
                    figures.max_commit_us = max_ns / 1000;
                    figures.commits += 1;
                    shared.max_commit_ns.store(max_ns, Ordering::Relaxed);
                    shared.committed_cycle.store(s.cycle, Ordering::Relaxed);
                    shared.commits.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) => shared.fail(&e),
            }
            let _ = free_tx.try_send(s);
        }
        if stop {
            break;
        }
    }
    (coalesced, max_ns)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example(name: &str) -> Arc<Program> {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/vernadat")
            .join(name);
        Arc::new(Program::load(&path).expect("the example loads"))
    }

    fn tmp() -> PathBuf {
        static N: AtomicU64 = AtomicU64::new(0);
        let d = std::env::temp_dir().join(format!(
            "cetratus-persist-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn rfc3339_matches_known_dates() {
        assert_eq!(rfc3339_utc(UNIX_EPOCH), "1970-01-01T00:00:00.000Z");
        let t = UNIX_EPOCH + Duration::from_millis(951_782_400_123);
        assert_eq!(rfc3339_utc(t), "2000-02-29T00:00:00.123Z");
    }

    #[test]
    fn program_round_trips_by_hash() {
        let d = tmp();
        let mut store = StateStore::open(&d).expect("open");
        for name in ["vernadat.toml", "u1.toml", "u2.toml"] {
            let p = example(name);
            store.save_program(&p).expect("save");
            let back = store.load_program(p.hash_hex()).expect("load");
            assert_eq!(back.hash_hex(), p.hash_hex());
        }
        assert_eq!(store.program_hashes().len(), 3);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn altered_program_is_refused() {
        let d = tmp();
        let mut store = StateStore::open(&d).expect("open");
        let p = example("vernadat.toml");
        store.save_program(&p).expect("save");
        let h = p.hash_hex();
        let path = d.join(PROGRAMS_DIR).join(format!("{h}.toml"));
        let text = std::fs::read_to_string(&path).expect("read");
        std::fs::write(&path, format!("{text}\n# edited\n")).expect("write");
        assert!(matches!(
            store.load_program(h),
            Err(PersistError::ProgramMismatch { .. })
        ));
        assert!(matches!(
            store.load_program("../x"),
            Err(PersistError::BadHash { .. })
        ));
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn commit_is_atomic_and_a_torn_temporary_file_is_ignored() {
        let d = tmp();
        let p = example("vernadat.toml");
        let plc = Plc::new(p.clone(), 0);
        let mut snap = PlcSnapshot::default();
        plc.snapshot_into(&mut snap);
        {
            let mut store = StateStore::open(&d).expect("open");
            assert!(matches!(
                store.commit(&snap, &PersistFigures::default()),
                Err(PersistError::ProgramMissing { .. })
            ));
            store.save_program(&p).expect("save");
            assert_eq!(
                store
                    .commit(&snap, &PersistFigures::default())
                    .expect("commit"),
                1
            );
        }
        // A crash in the middle of the next commit leaves a torn temporary file.
        std::fs::write(d.join("state.json.tmp"), b"{\"format\":\"cetratus-st").expect("write");
        let store = StateStore::open(&d).expect("reopen");
        assert!(!d.join("state.json.tmp").exists());
        let back = store.load_state().expect("load").expect("a state");
        assert_eq!(back.seq, 1);
        assert_eq!(back.snapshot, snap);
        let ins = store.inspect(10);
        assert!(ins.consistent, "{:?}", ins.problems);
        assert!(ins.invariants_hold);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn the_lock_keeps_a_second_writer_out() {
        let d = tmp();
        let _a = StateStore::open(&d).expect("open");
        assert!(matches!(
            StateStore::open(&d),
            Err(PersistError::Locked { .. })
        ));
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn audit_reader_tolerates_a_torn_last_line_and_the_writer_cuts_it() {
        let d = tmp();
        let rec = |what: &str| AuditRecord {
            utc: rfc3339_utc(SystemTime::now()),
            cycle: 1,
            time_us: 10,
            who: "cli".into(),
            what: what.into(),
            message: "m".into(),
            detail: serde_json::Value::Null,
        };
        {
            let mut store = StateStore::open(&d).expect("open");
            store.append_audit(&rec("load_accepted")).expect("append");
            store
                .append_audit(&rec("quarantine_started"))
                .expect("append");
        }
        let mut f = OpenOptions::new()
            .append(true)
            .open(d.join(AUDIT_FILE))
            .expect("open");
        f.write_all(b"{\"utc\":\"2026-").expect("write");
        drop(f);
        let ro = StateStore::open_read_only(&d).expect("open");
        let log = ro.read_audit().expect("read");
        assert_eq!(log.records.len(), 2);
        assert_eq!(log.torn_tail.as_deref(), Some("{\"utc\":\"2026-"));
        let mut store = StateStore::open(&d).expect("reopen");
        store.append_audit(&rec("substituted")).expect("append");
        let log = store.read_audit().expect("read");
        assert!(log.torn_tail.is_none());
        assert!(log.bad_lines.is_empty());
        let whats: Vec<&str> = log.records.iter().map(|r| r.what.as_str()).collect();
        assert_eq!(
            whats,
            [
                "load_accepted",
                "quarantine_started",
                "audit_repaired",
                "substituted"
            ]
        );
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn persister_commits_and_a_warm_start_resumes() {
        struct Still;
        impl crate::Provider for Still {
            fn read_inputs(&mut self, _now_us: u64, _inputs: &mut [cetratus_program::Value]) {}
        }
        impl crate::Dispatcher for Still {
            fn write_outputs(&mut self, _now_us: u64, _outputs: &[cetratus_program::Value]) {}
        }
        let d = tmp();
        let p = example("vernadat.toml");
        let mut plc = Plc::new(p.clone(), 0);
        let store = StateStore::open(&d).expect("open");
        let config = PersistConfig::for_period_us(10_000);
        let mut per = Persister::start(store, config).expect("start");
        for e in plc.drain_events() {
            per.audit(&e, "local");
        }
        for k in 0..50u64 {
            plc.cycle(k * 10_000, &mut Still);
            per.offer(&plc);
        }
        let stats = per.stop(&plc);
        assert!(stats.commits >= 1, "{stats:?}");
        assert_eq!(stats.errors, 0, "{stats:?}");
        let store = StateStore::open(&d).expect("reopen");
        let snap = store.load_snapshot().expect("load").expect("a snapshot");
        assert_eq!(snap.cycle, 50);
        let mut warm = start(&store, p.clone(), false).expect("warm start");
        assert_eq!(warm.cycles(), 50);
        assert_eq!(warm.drain_events()[0].kind, "warm_start");
        let cold = start(&store, p, true).expect("cold start");
        assert_eq!(cold.cycles(), 0);
        let log = store.read_audit().expect("audit");
        assert_eq!(log.records[0].what, "cold_start");
        let _ = std::fs::remove_dir_all(&d);
    }
}
