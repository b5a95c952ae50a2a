//! The state directory: atomic snapshots, content-addressed programs, the audit log file.

use std::collections::HashSet;
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use cetratus_program::Program;
use cetratus_runtime::{PlcSnapshot, WallClock};
use nix::fcntl::{Flock, FlockArg};
use serde::{Deserialize, Serialize};

use crate::inspect::check_snapshot;
use crate::*;

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

/// Opens (creating, mode 0600) a file of the state directory: only the PLC's user reads what it
/// holds, and only it may take the lock.
fn private_file(path: &Path, options: &mut OpenOptions) -> Result<File, PersistError> {
    use std::os::unix::fs::OpenOptionsExt;
    options.mode(0o600).open(path).map_err(io_err(path))
}

/// Refuses a state directory (or its `programs/`) that others may write, or that another user
/// owns (root aside): whoever may write it decides what the next warm start runs as PRIMARY.
fn check_private(dir: &Path) -> Result<(), PersistError> {
    let meta = std::fs::metadata(dir).map_err(io_err(dir))?;
    let shown = dir.display().to_string();
    let (why, fix) = match exposure(&meta) {
        None => return Ok(()),
        Some(Exposure::OwnedByOther { owner, me }) => (
            format!("belongs to user {owner}, not to this process's user {me}"),
            format!("run `chown {me} {shown}` or give this PLC a --state-dir of its own"),
        ),
        Some(Exposure::WritableByOthers { mode }) => (
            format!("is writable by its group or others (mode {mode:o})"),
            format!("run `chmod go-w {shown}`"),
        ),
    };
    Err(PersistError::NotPrivate {
        path: shown,
        why,
        fix,
    })
}

/// Creates `dir` and its parents as needed, each new one mode 0700.
fn create_private_dir(dir: &Path) -> Result<(), PersistError> {
    use std::os::unix::fs::DirBuilderExt;
    std::fs::DirBuilder::new()
        .recursive(true)
        .mode(0o700)
        .create(dir)
        .map_err(io_err(dir))
}

/// Writes `bytes` to `dir/name` so that a crash leaves either the old file or the new one.
fn write_atomic(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), PersistError> {
    let tmp = dir.join(format!("{name}.tmp"));
    let target = dir.join(name);
    let mut f = private_file(
        &tmp,
        OpenOptions::new().write(true).create(true).truncate(true),
    )?;
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
    wall: Arc<dyn WallClock>,
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
        Self::open_with_clock(dir, Arc::new(SystemWallClock))
    }

    /// [`StateStore::open`], with the wall clock that stamps its records.
    pub fn open_with_clock(dir: &Path, wall: Arc<dyn WallClock>) -> Result<Self, PersistError> {
        let programs = dir.join(PROGRAMS_DIR);
        create_private_dir(&programs)?;
        check_private(dir)?;
        check_private(&programs)?;
        let lock_path = dir.join(LOCK_FILE);
        let lock_file = private_file(
            &lock_path,
            OpenOptions::new().create(true).truncate(false).write(true),
        )?;
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
            wall: wall.clone(),
        };
        store.seq = match store.load_state() {
            Ok(Some(s)) => s.seq,
            _ => 0,
        };
        let torn = store.open_audit()?;
        if let Some(tail) = torn {
            store.append_audit(&AuditRecord {
                utc: rfc3339_utc(wall.now()),
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
            wall: Arc::new(SystemWallClock),
        })
    }

    /// The wall clock that stamps its records.
    pub fn wall_clock(&self) -> Arc<dyn WallClock> {
        self.wall.clone()
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn open_audit(&mut self) -> Result<Option<String>, PersistError> {
        let path = self.dir.join(AUDIT_FILE);
        let mut f = private_file(
            &path,
            OpenOptions::new()
                .create(true)
                .truncate(false)
                .read(true)
                .append(true),
        )?;
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
        let size = std::fs::metadata(&path).map_or(0, |m| m.len());
        if size > MAX_STATE_BYTES {
            return Err(PersistError::Malformed {
                path: path.display().to_string(),
                reason: format!(
                    "{size} bytes, more than the {MAX_STATE_BYTES} a state file may have"
                ),
            });
        }
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
        let state: StateFile =
            serde_json::from_value(head).map_err(|e| PersistError::Malformed {
                path: path.display().to_string(),
                reason: e.to_string(),
            })?;
        let counters = [
            ("seq", state.seq),
            ("cycle", state.snapshot.cycle),
            ("time_us", state.snapshot.time_us),
        ];
        if let Some(&(field, value)) = counters.iter().find(|(_, v)| *v > MAX_COUNTER) {
            return Err(PersistError::Counter {
                path: path.display().to_string(),
                field,
                value,
            });
        }
        Ok(Some(state))
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
        // `seq` was read through `load_state`, so far below the top; saturating all the same.
        let seq = self.seq.saturating_add(1);
        self.buf.clear();
        let file = StateFileRef {
            format: STATE_FORMAT,
            seq,
            written_utc: rfc3339_utc(self.wall.now()),
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
    pub(crate) fn write_audit(&mut self, rec: &AuditRecord) -> Result<(), PersistError> {
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

    pub(crate) fn sync_audit(&mut self) -> Result<(), PersistError> {
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
