//! The rollout's state directory: `rollout.json` (the [`Record`], replaced whole at every
//! change, so a crash leaves the old one or the new one), `rollout.log` (a line per step, never
//! rewritten), `lock` (held by the process that runs the rollout: the lock ends with the
//! process, however it ends) and `request` (an operator's pause, resume or abort, for the
//! process that holds the lock).

use std::fs::{File, OpenOptions};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use rustix::fs::{flock, FlockOperation};
use rustix::io::Errno;

use crate::record::Record;
use crate::rollout::Request;
use crate::FleetError;

/// Most bytes of `rollout.json` that are read; a larger one is not the rollout's.
const MAX_RECORD_BYTES: u64 = 16 << 20;

/// Whether this process runs a rollout: a second is refused at once.
static RUNNING: AtomicBool = AtomicBool::new(false);

/// The state directory, held: this process runs its rollout.
#[derive(Debug)]
pub struct Journal {
    dir: PathBuf,
    _lock: File,
    log: File,
}

impl Drop for Journal {
    fn drop(&mut self) {
        RUNNING.store(false, Ordering::SeqCst);
    }
}

impl Journal {
    /// Takes the directory (made when missing) for this process: refused when this process
    /// already runs a rollout, or another process holds the directory.
    pub fn hold(dir: &Path) -> Result<Journal, FleetError> {
        if RUNNING.swap(true, Ordering::SeqCst) {
            return Err(FleetError::Busy(
                "this process already runs a rollout; wait for it to end, or abort it".into(),
            ));
        }
        let held = Self::lock(dir);
        if held.is_err() {
            RUNNING.store(false, Ordering::SeqCst);
        }
        held
    }

    fn lock(dir: &Path) -> Result<Journal, FleetError> {
        let io = |e: std::io::Error| FleetError::Io(dir.display().to_string(), e);
        std::fs::create_dir_all(dir).map_err(io)?;
        let mut lock = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .read(true)
            .open(dir.join("lock"))
            .map_err(io)?;
        match flock(&lock, FlockOperation::NonBlockingLockExclusive) {
            Ok(()) => {}
            Err(e) if e == Errno::WOULDBLOCK => {
                let pid = std::fs::read_to_string(dir.join("lock")).unwrap_or_default();
                return Err(FleetError::Busy(format!(
                    "a rollout process (pid {}) runs on {}; follow it with `cetratus rollout status`, \
                     or pause or abort it",
                    pid.trim(),
                    dir.display()
                )));
            }
            Err(e) => return Err(io(e.into())),
        }
        lock.set_len(0).map_err(io)?;
        write!(lock, "{}", std::process::id()).map_err(io)?;
        let log = OpenOptions::new()
            .create(true)
            .append(true)
            .open(dir.join("rollout.log"))
            .map_err(io)?;
        Ok(Journal {
            dir: dir.to_path_buf(),
            _lock: lock,
            log,
        })
    }

    /// Replaces `rollout.json` with `record`, whole.
    pub fn save(&self, record: &Record) -> Result<(), FleetError> {
        let io = |e: std::io::Error| FleetError::Io(self.dir.display().to_string(), e);
        let text =
            serde_json::to_vec_pretty(record).map_err(|e| FleetError::Encode(e.to_string()))?;
        let tmp = self.dir.join("rollout.json.new");
        let mut f = File::create(&tmp).map_err(io)?;
        f.write_all(&text).map_err(io)?;
        f.sync_all().map_err(io)?;
        std::fs::rename(&tmp, self.dir.join("rollout.json")).map_err(io)
    }

    /// Appends `line` to `rollout.log`, after the wall-clock time in Unix seconds (to the
    /// millisecond).
    pub fn log(&mut self, line: &str) {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        let _ = writeln!(self.log, "{now:.3} {line}");
    }

    /// The operator's request waiting in `request`, taken (the file is removed).
    pub fn take_request(&self) -> Option<Request> {
        let path = self.dir.join("request");
        let text = crate::plan::read_capped(&path, 64).ok().flatten();
        let _ = std::fs::remove_file(&path);
        parse_request(String::from_utf8_lossy(&text?).trim())
    }
}

fn parse_request(text: &str) -> Option<Request> {
    match text {
        "pause" => Some(Request::Pause),
        "resume" => Some(Request::Resume),
        "abort" => Some(Request::Abort),
        _ => None,
    }
}

/// Reads `rollout.json` of `dir` without holding it (for `status`).
pub fn read(dir: &Path) -> Result<Record, FleetError> {
    let path = dir.join("rollout.json");
    let shown = path.display().to_string();
    let io = |e: std::io::Error| FleetError::Io(shown.clone(), e);
    let text = match crate::plan::read_capped(&path, MAX_RECORD_BYTES) {
        Ok(Some(text)) => text,
        Ok(None) => {
            return Err(FleetError::Record {
                path: shown,
                reason: format!("more than the {MAX_RECORD_BYTES} bytes a rollout's record has"),
            })
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(FleetError::NoRollout(dir.display().to_string()))
        }
        Err(e) => return Err(io(e)),
    };
    serde_json::from_slice(&text).map_err(|e| FleetError::Record {
        path: shown,
        reason: e.to_string(),
    })
}

/// Whether a process holds `dir` (runs its rollout).
pub fn held(dir: &Path) -> bool {
    let Ok(f) = OpenOptions::new()
        .read(true)
        .write(true)
        .open(dir.join("lock"))
    else {
        return false;
    };
    match flock(&f, FlockOperation::NonBlockingLockShared) {
        Ok(()) => {
            let _ = flock(&f, FlockOperation::Unlock);
            false
        }
        Err(_) => true,
    }
}

/// Leaves `request` for the process that runs the rollout of `dir`.
pub fn ask(dir: &Path, request: Request) -> Result<(), FleetError> {
    let io = |e: std::io::Error| FleetError::Io(dir.display().to_string(), e);
    let word = match request {
        Request::Pause => "pause",
        Request::Resume => "resume",
        Request::Abort => "abort",
    };
    let tmp = dir.join("request.new");
    std::fs::write(&tmp, word).map_err(io)?;
    std::fs::rename(&tmp, dir.join("request")).map_err(io)
}
