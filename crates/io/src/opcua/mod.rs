//! The PLC's OPC UA server (async-opcua), beside its Modbus server: the process image, PRIMARY,
//! STATUS, the primary's marking and the exec_info figures for SCADA and HMIs, and, when the I/O
//! configuration says so, the program's inputs written by an OPC UA client (a twin host, the
//! paper's virtual commissioning). docs/io.md, *The PLC's OPC UA server*.
//!
//! The namespace is `urn:cetratus`; every node has a string id under `<plc>`:
//! `<plc>.PRIMARY`, `<plc>.STATUS`, `<plc>.Inputs.<signal>`, `<plc>.Outputs.<signal>`,
//! `<plc>.Marking.<place>` and `<plc>.ExecInfo.<figure>`.
//!
//! The scan never waits for it. After each cycle the scan thread copies what the cycle left
//! into a shared [`Image`] with `try_lock` (buffers sized at start: no allocation), and wakes the
//! server's thread with a `Notify` (which never blocks). The server's thread copies the image out
//! and sets the nodes that changed, so subscriptions are sampled at the cycle. Clients' writes of
//! inputs land in a second buffer that the scan takes with `try_lock` at the cycle start; in a
//! cycle in which the server's thread holds either buffer, the scan keeps what it had.
//!
//! The server runs on a thread of its own with its own tokio runtime. A front listener counts TCP
//! connections and closes those beyond `max_connections` at once; async-opcua limits sessions.

pub mod config;
mod front;
mod limit;
pub mod pki;
pub mod probe;
mod security;
mod space;
pub mod twin_client;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};
use std::thread::JoinHandle;

use cetratus_program::{Program, Signal, Type, Value};
use cetratus_runtime::{Dispatcher, Plc, Provider, Slot, Status};

use crate::config::StalePolicy;
use crate::field::{DeviceStatus, LinkState, Quality};
use crate::IoError;
pub use config::OpcUaConfig;

/// The namespace URI of every Cetratus node.
pub const NAMESPACE: &str = "urn:cetratus";

/// Checks a user's password against its hash; given by the caller, which owns the one password
/// module of the workspace. Slow on purpose: it is called on a blocking thread.
pub type PasswordCheck = Arc<dyn Fn(&str, &[u8]) -> bool + Send + Sync>;

/// What a cycle left, as the scan thread publishes it.
#[derive(Debug)]
pub(crate) struct Image {
    /// Bumped by every publication.
    pub generation: u64,
    pub inputs: Vec<Value>,
    pub outputs: Vec<Value>,
    pub primary: Slot,
    pub status: Status,
    pub cycles: u64,
    pub drift: Option<u64>,
    pub scan_ns: u64,
    pub firings: u64,
    /// The primary's program; replaced only when the primary changes.
    pub program: Arc<Program>,
    /// The primary's marking, in its program's place order.
    pub marking: Vec<u32>,
}

/// What the server did.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct OpcUaCounters {
    /// Cycles published to the nodes.
    pub published: u64,
    /// Input writes accepted.
    pub writes: u64,
    /// Writes refused by the server's own checks (wrong type, an array, an empty value).
    pub refused_writes: u64,
    /// TCP connections closed at once because the limit was reached.
    pub refused_connections: u64,
    /// Substitutions after which the nodes followed the new program, and live updates that
    /// added signals.
    pub model_changes: u64,
    /// Password logins accepted.
    pub logins: u64,
    /// Password logins refused after the check (a wrong name or password).
    pub failed_logins: u64,
    /// Password logins refused unchecked, because they came too fast.
    pub refused_logins: u64,
}

#[derive(Default)]
pub(crate) struct Counters {
    pub published: AtomicU64,
    pub writes: AtomicU64,
    pub refused_writes: AtomicU64,
    pub refused_connections: AtomicU64,
    pub model_changes: AtomicU64,
    pub logins: AtomicU64,
    pub failed_logins: AtomicU64,
    pub refused_logins: AtomicU64,
}

impl Counters {
    fn read(&self) -> OpcUaCounters {
        OpcUaCounters {
            published: self.published.load(Ordering::Relaxed),
            writes: self.writes.load(Ordering::Relaxed),
            refused_writes: self.refused_writes.load(Ordering::Relaxed),
            refused_connections: self.refused_connections.load(Ordering::Relaxed),
            model_changes: self.model_changes.load(Ordering::Relaxed),
            logins: self.logins.load(Ordering::Relaxed),
            failed_logins: self.failed_logins.load(Ordering::Relaxed),
            refused_logins: self.refused_logins.load(Ordering::Relaxed),
        }
    }
}

/// What the scan thread and the server's thread share.
pub(crate) struct Shared {
    pub image: Mutex<Image>,
    /// The inputs as clients last wrote them (I/O-map order), when OPC UA provides them.
    pub written: Mutex<Written>,
    pub wake: tokio::sync::Notify,
    pub counters: Counters,
    /// The quality of the written inputs, as the scan last counted it (for other threads).
    pub quality: AtomicU8,
    /// Cycles in a row without a write, as the scan last counted them.
    pub missed: AtomicU64,
    /// Set once the inputs went stale under the `fault` policy: the Outputs nodes show the
    /// outputs' safe values until the run is restarted.
    pub fault: AtomicBool,
    /// The outputs' safe values, shown under a fault: those the PLC last gave (the driving
    /// program's, and the held ones of the outputs it lacks).
    pub safe_outputs: Mutex<Vec<Value>>,
    /// Signals appended to the I/O map by a live update, for the server's thread to add as
    /// nodes: the inputs, then the outputs.
    pub grown: Mutex<Vec<(SignalNode, bool)>>,
}

fn quality_code(q: Quality) -> u8 {
    match q {
        Quality::Initial => 0,
        Quality::Good => 1,
        Quality::Late => 2,
        Quality::Stale => 3,
    }
}

fn quality_of(code: u8) -> Quality {
    match code {
        0 => Quality::Initial,
        1 => Quality::Good,
        2 => Quality::Late,
        _ => Quality::Stale,
    }
}

/// The inputs clients wrote.
pub(crate) struct Written {
    pub values: Vec<Value>,
    /// Per input: written at least once.
    pub seen: Vec<bool>,
}

pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn try_lock<T>(m: &Mutex<T>) -> Option<MutexGuard<'_, T>> {
    match m.try_lock() {
        Ok(g) => Some(g),
        Err(TryLockError::Poisoned(p)) => Some(p.into_inner()),
        Err(TryLockError::WouldBlock) => None,
    }
}

/// One signal as a node.
#[derive(Clone, Debug)]
pub(crate) struct SignalNode {
    pub name: String,
    pub ty: Type,
}

/// The PLC's OPC UA server, seen from the scan thread: a [`Provider`] of the inputs clients
/// write (when the configuration says they provide them), and the [`Publisher`] of each cycle.
pub struct OpcUaServer {
    shared: Arc<Shared>,
    addr: SocketAddr,
    url: String,
    provides_inputs: bool,
    held: Vec<Value>,
    safe_inputs: Vec<Value>,
    stale: StalePolicy,
    stale_after: u64,
    last_writes: u64,
    written_once: bool,
    missed: u64,
    quality: Quality,
    fault: bool,
    // The PLC's I/O is in its safe state because a field device went stale under `fault`.
    safe_state: bool,
    // The PLC's safe outputs, and whether the shared copy still lacks them (the server's thread
    // held it when they changed).
    safe_out: Vec<Value>,
    safe_pending: bool,
    contended: u64,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

/// The scan's side of the nodes, for the node to call after each cycle.
pub struct Publisher {
    shared: Arc<Shared>,
}

/// What the server needs from the run to start.
pub struct Start<'a> {
    /// The `<plc>` of every node id.
    pub plc: &'a str,
    /// The program at start.
    pub program: &'a Arc<Program>,
    /// The I/O map's inputs.
    pub inputs: &'a [Signal],
    /// The I/O map's outputs.
    pub outputs: &'a [Signal],
    /// The users' password check (security `sign-and-encrypt` with users).
    pub passwords: Option<PasswordCheck>,
}

fn safe(s: &Signal) -> Value {
    s.safe.unwrap_or(s.ty.zero())
}

impl OpcUaServer {
    /// Builds the address space and starts serving it as `config` says.
    pub fn start(config: &OpcUaConfig, run: Start<'_>) -> Result<OpcUaServer, IoError> {
        if run.plc.is_empty() || run.plc.contains('.') {
            return Err(IoError::Listen {
                addr: config.url.clone(),
                reason: format!("the PLC id `{}` cannot name OPC UA nodes (it is empty or has a dot); give --plc a name without dots", run.plc),
            });
        }
        let safe_inputs: Vec<Value> = run.inputs.iter().map(safe).collect();
        let places = run.program.net().places().len();
        let image = Image {
            generation: 0,
            inputs: safe_inputs.clone(),
            outputs: run.outputs.iter().map(safe).collect(),
            primary: Slot::A,
            status: Status::Idle,
            cycles: 0,
            drift: None,
            scan_ns: 0,
            firings: 0,
            program: run.program.clone(),
            marking: Vec::with_capacity(places.max(64) * 4),
        };
        let shared = Arc::new(Shared {
            image: Mutex::new(image),
            written: Mutex::new(Written {
                seen: vec![false; safe_inputs.len()],
                values: safe_inputs.clone(),
            }),
            wake: tokio::sync::Notify::new(),
            counters: Counters::default(),
            quality: AtomicU8::new(quality_code(Quality::Initial)),
            missed: AtomicU64::new(0),
            fault: AtomicBool::new(false),
            safe_outputs: Mutex::new(run.outputs.iter().map(safe).collect()),
            grown: Mutex::new(Vec::new()),
        });
        let layout = space::Layout {
            plc: run.plc.to_string(),
            inputs: run
                .inputs
                .iter()
                .map(|s| SignalNode {
                    name: s.name.clone(),
                    ty: s.ty,
                })
                .collect(),
            outputs: run
                .outputs
                .iter()
                .map(|s| SignalNode {
                    name: s.name.clone(),
                    ty: s.ty,
                })
                .collect(),
            writable_inputs: config.inputs,
        };
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel();
        let (ready_tx, ready_rx) = std::sync::mpsc::sync_channel(1);
        let thread = {
            let (config, shared, passwords) = (config.clone(), shared.clone(), run.passwords);
            std::thread::Builder::new()
                .name("cetratus-opcua".into())
                .spawn(move || {
                    let rt = match tokio::runtime::Builder::new_current_thread()
                        .enable_all()
                        .build()
                    {
                        Ok(rt) => rt,
                        Err(e) => {
                            let _ = ready_tx.send(Err(IoError::Thread(e.to_string())));
                            return;
                        }
                    };
                    rt.block_on(space::serve(
                        config, layout, shared, passwords, ready_tx, stop_rx,
                    ));
                })
                .map_err(|e| IoError::Thread(e.to_string()))?
        };
        let addr = match ready_rx.recv() {
            Ok(Ok(a)) => a,
            Ok(Err(e)) => {
                let _ = thread.join();
                return Err(e);
            }
            Err(_) => {
                let _ = thread.join();
                return Err(IoError::Thread("the OPC UA server's thread ended".into()));
            }
        };
        Ok(OpcUaServer {
            url: format!("opc.tcp://{addr}"),
            addr,
            shared,
            provides_inputs: config.inputs,
            held: safe_inputs.clone(),
            safe_inputs,
            stale: config.stale,
            stale_after: u64::from(config.stale_after),
            last_writes: 0,
            written_once: false,
            missed: 0,
            quality: Quality::Initial,
            fault: false,
            safe_state: false,
            safe_out: Vec::new(),
            safe_pending: false,
            contended: 0,
            stop: Some(stop_tx),
            thread: Some(thread),
        })
    }

    /// Where it listens.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Its endpoint URL, with the port it got.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Whether OPC UA clients provide the program's inputs.
    pub fn provides_inputs(&self) -> bool {
        self.provides_inputs
    }

    /// Waits (before the first scan, never in one) until clients have written every input once,
    /// or `timeout_us` passes; whether they did.
    pub fn wait_first_image(&self, timeout_us: u64) -> bool {
        let deadline = std::time::Instant::now() + std::time::Duration::from_micros(timeout_us);
        loop {
            if lock(&self.shared.written).seen.iter().all(|&s| s) {
                return true;
            }
            if std::time::Instant::now() >= deadline {
                return false;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
    }

    /// What it did.
    pub fn counters(&self) -> OpcUaCounters {
        self.shared.counters.read()
    }

    /// The quality of the inputs OPC UA clients write, as a device's (docs/io.md, *Quality*);
    /// `None` when they provide no inputs.
    pub fn status(&self) -> Option<DeviceStatus> {
        self.provides_inputs
            .then(|| status_of(&self.shared, self.quality, self.missed))
    }

    /// Reads [`OpcUaServer::status`] from another thread than the scan's.
    pub fn status_reader(&self) -> Option<impl Fn() -> DeviceStatus + Send + Sync + 'static> {
        let shared = self.shared.clone();
        self.provides_inputs.then_some(move || {
            status_of(
                &shared,
                quality_of(shared.quality.load(Ordering::Relaxed)),
                shared.missed.load(Ordering::Relaxed),
            )
        })
    }

    /// Whether the inputs went stale under the `fault` policy.
    pub fn faulted(&self) -> bool {
        self.fault
    }

    /// Puts the server in the PLC's safe state for a field device's fault: the written inputs
    /// give way to their safe values and the Outputs nodes show the safe outputs, latched.
    pub fn enter_safe_state(&mut self) {
        self.safe_state = true;
        self.shared.fault.store(true, Ordering::Relaxed);
    }

    /// Whether the server is in the PLC's safe state, for its clients' fault or a device's.
    pub fn in_safe_state(&self) -> bool {
        self.fault || self.safe_state
    }

    fn push_safe_outputs(&mut self) {
        if let Some(mut s) = try_lock(&self.shared.safe_outputs) {
            copy_into(&mut s, &self.safe_out);
            self.safe_pending = false;
        }
    }

    /// Cycles in which the server's thread held the written inputs and the scan kept its copy.
    pub fn contended(&self) -> u64 {
        self.contended
    }

    /// The publisher of each cycle, for the node to call after each cycle.
    pub fn publisher(&self) -> Publisher {
        Publisher {
            shared: self.shared.clone(),
        }
    }

    /// Closes every session and stops the thread.
    pub fn stop(&mut self) {
        if let Some(tx) = self.stop.take() {
            let _ = tx.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for OpcUaServer {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The figures of the OPC UA clients as the source of the inputs, in a device's terms: `link` is
/// `up` while they write in time, `reads` counts the writes accepted, `errors` those refused.
fn status_of(shared: &Shared, quality: Quality, missed: u64) -> DeviceStatus {
    let c = shared.counters.read();
    DeviceStatus {
        name: "opcua".into(),
        quality,
        link: match quality {
            Quality::Initial => LinkState::Connecting,
            Quality::Good | Quality::Late => LinkState::Up,
            Quality::Stale => LinkState::Down,
        },
        missed_cycles: missed,
        reads: c.writes,
        errors: c.refused_writes,
        exceptions: 0,
        reconnects: 0,
        writes: 0,
        last_error: (quality == Quality::Stale)
            .then(|| format!("no OPC UA client wrote an input for {missed} cycles")),
    }
}

impl OpcUaServer {
    /// Counts the cycles since a client last wrote an input (an atomic load: no lock), and
    /// grades them as a device's reads (docs/io.md, *Quality*).
    fn count_cycle(&mut self) {
        let writes = self.shared.counters.writes.load(Ordering::Relaxed);
        if writes != self.last_writes {
            self.last_writes = writes;
            self.written_once = true;
            self.missed = 0;
        } else {
            self.missed = self.missed.saturating_add(1);
        }
        // A client that writes only what changed keeps the inputs alive with a keep-alive: a
        // quiet spell shorter than half of `stale_after` is good, beyond it late.
        self.quality = if !self.written_once {
            Quality::Initial
        } else if self.missed < self.stale_after.div_ceil(2) {
            Quality::Good
        } else if self.missed < self.stale_after {
            Quality::Late
        } else {
            if self.stale == StalePolicy::Fault && !self.fault {
                self.fault = true;
                self.shared.fault.store(true, Ordering::Relaxed);
            }
            Quality::Stale
        };
        self.shared
            .quality
            .store(quality_code(self.quality), Ordering::Relaxed);
        self.shared.missed.store(self.missed, Ordering::Relaxed);
    }
}

impl Provider for OpcUaServer {
    fn io_map_grew(&mut self, inputs: &[Signal], outputs: &[Signal]) {
        // At an install's cycle boundary only: the new nodes are the server thread's work. The
        // new inputs come from the field (OPC UA clients write only the inputs of the start), so
        // the written inputs stay as they are.
        let node = |s: &Signal, input| {
            (
                SignalNode {
                    name: s.name.clone(),
                    ty: s.ty,
                },
                input,
            )
        };
        lock(&self.shared.safe_outputs).extend(outputs.iter().map(safe));
        lock(&self.shared.grown).extend(
            inputs
                .iter()
                .map(|s| node(s, true))
                .chain(outputs.iter().map(|s| node(s, false))),
        );
        self.shared.wake.notify_one();
    }

    fn read_inputs(&mut self, _now_us: u64, inputs: &mut [Value]) {
        if !self.provides_inputs {
            return;
        }
        self.count_cycle();
        match try_lock(&self.shared.written) {
            Some(w) => {
                let n = self.held.len().min(w.values.len());
                self.held[..n].copy_from_slice(&w.values[..n]);
            }
            None => self.contended += 1,
        }
        let use_safe = self.fault
            || self.safe_state
            || (self.quality == Quality::Stale && self.stale != StalePolicy::Hold);
        let from = if use_safe {
            &self.safe_inputs
        } else {
            &self.held
        };
        let n = inputs.len().min(from.len());
        inputs[..n].copy_from_slice(&from[..n]);
    }
}

impl Dispatcher for OpcUaServer {
    fn safe_outputs(&mut self, safe: &[Value]) {
        copy_into(&mut self.safe_out, safe);
        self.safe_pending = true;
        self.push_safe_outputs();
    }

    fn write_outputs(&mut self, _now_us: u64, _outputs: &[Value]) {
        // The outputs are published with the rest of the cycle, by the Publisher; only safe
        // values the server's thread kept from the last offer are offered again.
        if self.safe_pending {
            self.push_safe_outputs();
        }
    }
}

fn copy_into<T: Copy>(to: &mut Vec<T>, from: &[T]) {
    if to.len() == from.len() {
        to.copy_from_slice(from);
    } else {
        to.clear();
        to.extend_from_slice(from);
    }
}

impl Publisher {
    /// Publishes what the cycle left; skipped in a cycle in which the server's thread holds the
    /// image (the next cycle publishes). Never blocks and, while the primary's program keeps its
    /// places, never allocates.
    pub fn show(&mut self, plc: &Plc) {
        let Some(mut im) = try_lock(&self.shared.image) else {
            return;
        };
        copy_into(&mut im.inputs, plc.inputs());
        if self.shared.fault.load(Ordering::Relaxed) {
            if let Some(safe) = try_lock(&self.shared.safe_outputs) {
                copy_into(&mut im.outputs, &safe);
            }
        } else {
            copy_into(&mut im.outputs, plc.dispatched());
        }
        im.primary = plc.primary();
        im.status = plc.status();
        im.cycles = plc.cycles();
        im.drift = plc.drift();
        let k = plc.primary_container();
        im.scan_ns = plc.monitor().stats[plc.primary().index()]
            .scan
            .summary_last();
        im.firings = k.firings().iter().sum();
        if !Arc::ptr_eq(&im.program, k.program()) {
            im.program = k.program().clone();
        }
        copy_into(&mut im.marking, k.marking());
        im.generation = im.generation.wrapping_add(1);
        drop(im);
        self.shared.wake.notify_one();
    }
}
