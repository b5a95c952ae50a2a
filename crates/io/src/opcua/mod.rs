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
pub mod probe;
mod security;
mod space;
pub mod twin_client;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};
use std::thread::JoinHandle;

use cetratus_program::{Program, Signal, Type, Value};
use cetratus_runtime::{Dispatcher, Plc, Provider, Slot, Status};

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
    /// Substitutions after which the nodes followed the new program.
    pub model_changes: u64,
}

#[derive(Default)]
pub(crate) struct Counters {
    pub published: AtomicU64,
    pub writes: AtomicU64,
    pub refused_writes: AtomicU64,
    pub refused_connections: AtomicU64,
    pub model_changes: AtomicU64,
}

impl Counters {
    fn read(&self) -> OpcUaCounters {
        OpcUaCounters {
            published: self.published.load(Ordering::Relaxed),
            writes: self.writes.load(Ordering::Relaxed),
            refused_writes: self.refused_writes.load(Ordering::Relaxed),
            refused_connections: self.refused_connections.load(Ordering::Relaxed),
            model_changes: self.model_changes.load(Ordering::Relaxed),
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
            held: safe_inputs,
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

impl Provider for OpcUaServer {
    fn read_inputs(&mut self, _now_us: u64, inputs: &mut [Value]) {
        if !self.provides_inputs {
            return;
        }
        match try_lock(&self.shared.written) {
            Some(w) => {
                let n = self.held.len().min(w.values.len());
                self.held[..n].copy_from_slice(&w.values[..n]);
            }
            None => self.contended += 1,
        }
        let n = inputs.len().min(self.held.len());
        inputs[..n].copy_from_slice(&self.held[..n]);
    }
}

impl Dispatcher for OpcUaServer {
    fn write_outputs(&mut self, _now_us: u64, _outputs: &[Value]) {
        // The outputs are published with the rest of the cycle, by the Publisher.
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
        copy_into(&mut im.outputs, plc.dispatched());
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
