//! The writer thread, and the scan thread's side of it that never waits for the disk.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use cetratus_program::Program;
use cetratus_runtime::{Event, Plc, PlcSnapshot, Slot, Status, WallClock};
use serde::Serialize;

use crate::*;

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
    /// A snapshot of this run is on disk: the writer's, or the one the start committed.
    saved: AtomicBool,
    max_commit_ns: AtomicU64,
    errors: AtomicU64,
    last_error: Mutex<Option<String>>,
    /// The last write failed, and none has succeeded since.
    failing: AtomicBool,
    /// A program could not be saved: the scan thread sends its programs again.
    resend_programs: AtomicBool,
}

impl Shared {
    fn fail(&self, e: &PersistError) {
        self.errors.fetch_add(1, Ordering::Relaxed);
        if let Ok(mut g) = self.last_error.lock() {
            *g = Some(e.to_string());
        }
        self.failing.store(true, Ordering::Release);
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
    /// Refused commands counted rather than logged one by one (see [`crate::REFUSAL_BURST`]).
    pub refusals_unlogged: u64,
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
    refusals: crate::sample::RefusalSampler,
    skipped: u64,
    shared: Arc<Shared>,
    handle: Option<JoinHandle<(u64, u64)>>,
    wall: Arc<dyn WallClock>,
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
        let wall = store.wall_clock();
        let handle = std::thread::Builder::new()
            .name("cetratus-persist".into())
            .spawn(move || writer(store, rx, free_tx, s2, every))
            .map_err(|source| PersistError::Io {
                path: "(persistence thread)".into(),
                source,
            })?;
        Ok(Persister {
            wall,
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
            refusals: Default::default(),
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
        (self.shared.saved.load(Ordering::Acquire))
            .then(|| self.shared.committed_cycle.load(Ordering::Relaxed))
    }

    /// Records the snapshot of `cycle` that was committed to the store before the writer
    /// started (a start's own), so that [`Persister::committed_cycle`] names it until the
    /// writer commits one: a disk that fails at once is then reported with what it holds.
    pub fn committed_before(&self, cycle: u64) {
        self.shared.committed_cycle.store(cycle, Ordering::Relaxed);
        self.shared.saved.store(true, Ordering::Release);
    }

    /// True while the state directory cannot be written: the last write failed and none has
    /// succeeded since. Every snapshot due is a new try, so it turns false by itself once the
    /// cause is gone (docs/persistence.md, *When the disk fails*). One atomic load.
    pub fn is_failing(&self) -> bool {
        self.shared.failing.load(Ordering::Acquire)
    }

    /// The last write error, if any (never waits for the writer; `None` while it holds the lock).
    pub fn last_error(&self) -> Option<String> {
        if self.shared.errors.load(Ordering::Relaxed) == 0 {
            return None;
        }
        self.shared
            .last_error
            .try_lock()
            .ok()
            .and_then(|g| g.clone())
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
        if self.shared.resend_programs.swap(false, Ordering::AcqRel) {
            // A program could not be saved: no snapshot is committed until it is.
            self.known = [[0; 32]; 4];
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
    /// Refused commands are sampled: a burst, then one a second of program time, the rest
    /// counted in one record.
    pub fn audit(&mut self, event: &Event, who: &str) {
        // The audit log is for people, in wall time; the engine itself still never reads a clock.
        let wall = self.wall.now();
        if event.kind == cetratus_runtime::EventKind::Refused {
            match self.refusals.admit(event.time_us) {
                None => return,
                Some(0) => {}
                Some(n) => {
                    let rec = crate::sample::unlogged_record(n, event.cycle, event.time_us, wall);
                    self.audit_record(rec, event.cycle);
                }
            }
        }
        let rec = AuditRecord::of_event(event, who, wall);
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
            refusals_unlogged: self.refusals.total_unlogged(),
            ..Default::default()
        };
        let unlogged = self.refusals.take_unlogged();
        if unlogged > 0 {
            let rec = crate::sample::unlogged_record(
                unlogged,
                plc.cycles(),
                plc.now_us(),
                self.wall.now(),
            );
            let _ = self.tx.send(Msg::Audit(Box::new(rec)));
        }
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
        let mut unsaved = false;
        for m in batch.drain(..) {
            match m {
                Msg::Program(p) => {
                    if let Err(e) = store.save_program(&p) {
                        unsaved = true;
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
                        utc: rfc3339_utc(store.wall_clock().now()),
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
        if unsaved {
            // A snapshot must not name a program that is not on disk: the scan thread sends
            // the programs again, and the next snapshot is committed once they are saved.
            shared.resend_programs.store(true, Ordering::Release);
            if let Some(s) = newest.take() {
                let _ = free_tx.try_send(s);
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
                    shared.saved.store(true, Ordering::Release);
                    shared.commits.fetch_add(1, Ordering::Relaxed);
                    shared.failing.store(false, Ordering::Release);
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
