//! Field I/O: the double-buffered process image between the scan thread and the I/O threads.
//!
//! Each field device has an I/O thread of its own ([`crate::modbus`]) that does all the network
//! work. The threads and the scan meet in one shared image behind a mutex that is only ever held
//! to copy a few values. The scan thread never waits for it: it uses `try_lock`, and when an I/O
//! thread holds it, the scan keeps its own copy of the inputs (the front buffer) and offers its
//! outputs again in the next cycle. It wakes the I/O threads after dispatch with `try_send` on
//! a queue of one. Nothing a device sends causes work on the scan thread beyond copying the
//! decoded values of the channels the configuration declares.
//!
//! Staleness is counted by the scan, in cycles: a device that has not completed a read since the
//! last cycle has missed it. After `stale_after` missed cycles its inputs follow the device's
//! policy: hold the last values, take the safe values, or fault (safe values in, safe values out,
//! until the run is restarted).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use cetratus_program::{Signal, Value};
use cetratus_runtime::{Dispatcher, Inadmissible, IoAdmission, Provider};
use serde::Serialize;

use crate::config::{Device, IoConfig, StalePolicy};
use crate::map::FieldMap;
use crate::IoError;

pub use cetratus_vocab::{LinkState, Quality};

/// The figures of one device, for the run summary, exec_info and the dashboard.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DeviceStatus {
    /// The device's name.
    pub name: String,
    /// Its inputs' quality in the last cycle.
    pub quality: Quality,
    /// Its connection.
    pub link: LinkState,
    /// Cycles in a row without a complete read.
    pub missed_cycles: u64,
    /// Complete reads.
    pub reads: u64,
    /// Requests that failed or timed out.
    pub errors: u64,
    /// Modbus exception responses.
    pub exceptions: u64,
    /// Connections made after the first.
    pub reconnects: u64,
    /// Output writes.
    pub writes: u64,
    /// The last error, for people.
    pub last_error: Option<String>,
}

/// The image the I/O threads and the scan thread share.
#[derive(Debug)]
pub(crate) struct Shared {
    /// The inputs as the devices last read them (I/O-map order).
    pub inputs: Vec<Value>,
    /// Per device: complete reads so far, and what the thread reports.
    pub devices: Vec<DeviceStatus>,
    /// The outputs to write (I/O-map order) and their generation, bumped on change.
    pub outputs: Vec<Value>,
    pub outputs_gen: u64,
    /// The field map; replaced (not changed) when a live update adds signals, and taken by each
    /// I/O thread at its next cycle.
    pub map: Arc<FieldMap>,
}

/// Locks the shared image from an I/O thread; a panic elsewhere does not stop the I/O.
pub(crate) fn lock(shared: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    shared.lock().unwrap_or_else(|p| p.into_inner())
}

/// What the scan thread tells an I/O thread.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kick {
    /// A cycle was dispatched: write the outputs if due, then read the inputs for the next.
    Cycle,
    /// Write the safe outputs and stop.
    Stop,
}

/// Reads every device's figures, quality included, from another thread than the scan's (the
/// publisher of `exec_info`): it locks the image for the copy, and the scan never waits for it.
#[derive(Clone)]
pub struct StatusReader(Arc<Mutex<Shared>>);

impl StatusReader {
    /// Every device's figures as of the last cycle.
    pub fn read(&self) -> Vec<DeviceStatus> {
        lock(&self.0).devices.clone()
    }
}

/// The field I/O of a node: a [`Provider`] and a [`Dispatcher`] over the process image.
pub struct FieldIo {
    map: Arc<FieldMap>,
    config: IoConfig,
    devices: Vec<Device>,
    shared: Arc<Mutex<Shared>>,
    front: Vec<Value>,
    seen: Vec<u64>,
    missed: Vec<u64>,
    quality: Vec<Quality>,
    last_out: Vec<Value>,
    // What the outputs go to in the I/O's safe state (a stale device under `fault`, a stop):
    // the PLC's safe values, as it last gave them.
    safe_out: Vec<Value>,
    out_pending: bool,
    fault: bool,
    // The PLC's I/O is in its safe state because another input source (the OPC UA server's
    // clients) went stale under `fault`.
    safe_state: bool,
    contended: u64,
    kicks: Vec<SyncSender<Kick>>,
    threads: Vec<JoinHandle<()>>,
    stopped: Arc<AtomicBool>,
}

impl FieldIo {
    /// Starts one I/O thread per device of `config`. `period_us` is how often a thread polls
    /// when no cycle wakes it (before the first scan).
    pub fn start(config: &IoConfig, map: FieldMap, period_us: u64) -> Result<FieldIo, IoError> {
        let map = Arc::new(map);
        let shared = Arc::new(Mutex::new(Shared {
            inputs: map.safe_inputs.clone(),
            devices: config
                .devices
                .iter()
                .map(|d| DeviceStatus {
                    name: d.name.clone(),
                    quality: Quality::Initial,
                    link: LinkState::Connecting,
                    missed_cycles: 0,
                    reads: 0,
                    errors: 0,
                    exceptions: 0,
                    reconnects: 0,
                    writes: 0,
                    last_error: None,
                })
                .collect(),
            outputs: map.safe_outputs.clone(),
            outputs_gen: 1,
            map: map.clone(),
        }));
        let stopped = Arc::new(AtomicBool::new(false));
        let mut kicks = Vec::new();
        let mut threads = Vec::new();
        for (d, dev) in config.devices.iter().enumerate() {
            let (tx, rx) = sync_channel(1);
            let worker = crate::modbus::DeviceThread::new(
                d,
                dev.clone(),
                map.clone(),
                shared.clone(),
                period_us,
            );
            let handle = std::thread::Builder::new()
                .name(format!("cetratus-io-{d}"))
                .spawn(move || worker.run(rx))
                .map_err(|e| IoError::Thread(e.to_string()))?;
            kicks.push(tx);
            threads.push(handle);
        }
        let n = config.devices.len();
        Ok(FieldIo {
            front: map.safe_inputs.clone(),
            last_out: map.safe_outputs.clone(),
            safe_out: map.safe_outputs.clone(),
            map,
            config: config.clone(),
            devices: config.devices.clone(),
            shared,
            seen: vec![0; n],
            missed: vec![0; n],
            quality: vec![Quality::Initial; n],
            out_pending: false,
            fault: false,
            safe_state: false,
            contended: 0,
            kicks,
            threads,
            stopped,
        })
    }

    /// What lets a live update use signals the running program does not: those on a channel a
    /// device serves (asked away from the scan thread).
    pub fn admission(&self) -> Arc<FieldAdmission> {
        Arc::new(FieldAdmission {
            config: self.config.clone(),
            shared: self.shared.clone(),
        })
    }

    /// Serves signals appended to the I/O map (at the install of an update that
    /// [`FieldAdmission`] admitted): their channels join the map, the inputs start at their
    /// safe values, and every I/O thread takes the new map at its next cycle. On the scan
    /// thread, at that install's cycle boundary only: it builds the new map and locks the image
    /// for the copy (an I/O thread holds it only to copy values, never across a request).
    pub fn grow(&mut self, inputs: &[Signal], outputs: &[Signal]) -> Result<(), IoError> {
        let mut map = (*self.map).clone();
        map.extend(&self.config, inputs, outputs)?;
        let map = Arc::new(map);
        self.front.resize(map.safe_inputs.len(), Value::Bool(false));
        self.front[self.map.safe_inputs.len()..]
            .copy_from_slice(&map.safe_inputs[self.map.safe_inputs.len()..]);
        self.last_out.clone_from(&map.safe_outputs);
        let n = self.safe_out.len();
        self.safe_out.extend_from_slice(&map.safe_outputs[n..]);
        self.out_pending = true;
        {
            let mut s = lock(&self.shared);
            let n = s.inputs.len();
            s.inputs.extend_from_slice(&map.safe_inputs[n..]);
            let n = s.outputs.len();
            s.outputs.extend_from_slice(&map.safe_outputs[n..]);
            s.outputs_gen += 1;
            s.map = map.clone();
        }
        self.map = map;
        Ok(())
    }

    /// The field map bound so far (grown by live updates).
    pub fn map(&self) -> &FieldMap {
        &self.map
    }

    /// Waits (before the first scan, never in one) until every device that serves an input has
    /// completed a read, or `timeout_us` passes. Returns the devices still missing, whose inputs
    /// start at their safe values.
    pub fn wait_first_image(&self, timeout_us: u64) -> Vec<String> {
        let deadline = Instant::now() + Duration::from_micros(timeout_us);
        let needed: Vec<usize> = (0..self.devices.len())
            .filter(|&d| {
                self.map
                    .inputs
                    .iter()
                    .any(|c| c.on.is_some_and(|o| o.0 == d))
            })
            .collect();
        loop {
            let missing: Vec<String> = {
                let s = lock(&self.shared);
                needed
                    .iter()
                    .filter(|&&d| s.devices[d].reads == 0)
                    .map(|&d| self.devices[d].name.clone())
                    .collect()
            };
            if missing.is_empty() || Instant::now() >= deadline {
                return missing;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Every device's figures (off the scan thread: it locks the image).
    pub fn status(&self) -> Vec<DeviceStatus> {
        let mut s = lock(&self.shared).devices.clone();
        for (d, st) in s.iter_mut().enumerate() {
            st.quality = self.quality[d];
            st.missed_cycles = self.missed[d];
        }
        s
    }

    /// A reader of every device's figures for another thread.
    pub fn status_reader(&self) -> StatusReader {
        StatusReader(self.shared.clone())
    }

    /// Whether a device with the `fault` policy went stale: the field I/O is in its safe state.
    pub fn faulted(&self) -> bool {
        self.fault
    }

    /// Puts the field I/O in its safe state for a fault of another input source: safe values in,
    /// safe values out, latched until the run is restarted, as under its own `fault`.
    pub fn enter_safe_state(&mut self) {
        self.safe_state = true;
    }

    /// Whether the field I/O is in its safe state, for its own fault or another source's.
    pub fn in_safe_state(&self) -> bool {
        self.fault || self.safe_state
    }

    /// Cycles in which the scan found the image held by an I/O thread and kept its copy.
    pub fn contended(&self) -> u64 {
        self.contended
    }

    /// Writes the safe outputs to every connected device and stops the I/O threads (Ctrl-C,
    /// SIGTERM, the end of a run). Waits for them: this is not the scan thread.
    pub fn stop(&mut self) {
        if self.stopped.swap(true, Ordering::SeqCst) {
            return;
        }
        {
            let mut s = lock(&self.shared);
            s.outputs.clone_from(&self.safe_out);
            s.outputs_gen += 1;
        }
        for k in &self.kicks {
            let _ = k.send(Kick::Stop);
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }

    /// Takes the inputs the devices read, counts missed cycles and grades each device's
    /// quality, under one `try_lock` of the image: the same lock shows the quality to readers
    /// on other threads (a cycle in which an I/O thread holds the image shows it one cycle late).
    fn take_inputs(&mut self) {
        match self.shared.try_lock() {
            Ok(mut s) => {
                for (d, st) in s.devices.iter().enumerate() {
                    if st.reads != self.seen[d] {
                        self.seen[d] = st.reads;
                        self.missed[d] = 0;
                    } else {
                        self.missed[d] = self.missed[d].saturating_add(1);
                    }
                }
                for c in &self.map.inputs {
                    self.front[c.signal] = s.inputs[c.signal];
                }
                self.fault |= grade(&self.devices, &self.seen, &self.missed, &mut self.quality);
                for (d, st) in s.devices.iter_mut().enumerate() {
                    st.quality = self.quality[d];
                    st.missed_cycles = self.missed[d];
                }
            }
            Err(TryLockError::WouldBlock) => {
                self.contended += 1;
                self.fault |= grade(&self.devices, &self.seen, &self.missed, &mut self.quality);
            }
            Err(TryLockError::Poisoned(p)) => {
                let s = p.into_inner();
                for c in &self.map.inputs {
                    self.front[c.signal] = s.inputs[c.signal];
                }
                self.fault |= grade(&self.devices, &self.seen, &self.missed, &mut self.quality);
            }
        }
    }
}

/// Each device's quality from its reads seen and cycles missed; true when a device with the
/// `fault` policy is stale.
fn grade(devices: &[Device], seen: &[u64], missed: &[u64], quality: &mut [Quality]) -> bool {
    let mut fault = false;
    for (d, dev) in devices.iter().enumerate() {
        quality[d] = if seen[d] == 0 {
            Quality::Initial
        } else if missed[d] <= 1 {
            // A read that lands just after a cycle start is on time for the next one.
            Quality::Good
        } else if missed[d] < u64::from(dev.stale_after) {
            Quality::Late
        } else {
            fault |= dev.stale == StalePolicy::Fault;
            Quality::Stale
        };
    }
    fault
}

/// Admits the signals of a live update that a device of the I/O configuration serves.
pub struct FieldAdmission {
    config: IoConfig,
    shared: Arc<Mutex<Shared>>,
}

impl IoAdmission for FieldAdmission {
    fn admit(&self, inputs: &[Signal], outputs: &[Signal]) -> Result<(), Inadmissible> {
        let refused = |e: IoError| Inadmissible(e.to_string());
        let mut map = (*lock(&self.shared).map).clone();
        let (ins, outs) = (map.inputs.len(), map.outputs.len());
        map.extend(&self.config, inputs, outputs).map_err(refused)?;
        // The PLC's Modbus server shows them too, below its own entries.
        if self.config.server.is_some() {
            for c in &map.inputs[ins..] {
                crate::server::fits_server(c, true).map_err(refused)?;
            }
            for c in &map.outputs[outs..] {
                crate::server::fits_server(c, false).map_err(refused)?;
            }
        }
        Ok(())
    }
}

impl Provider for FieldIo {
    fn io_map_grew(&mut self, inputs: &[Signal], outputs: &[Signal]) {
        // Admitted away from the scan thread against the same map: this does not fail unless
        // the configuration changed under it, and then the new signals stay unserved.
        let _ = self.grow(inputs, outputs);
    }

    fn read_inputs(&mut self, _now_us: u64, inputs: &mut [Value]) {
        self.take_inputs();
        for c in &self.map.inputs {
            // An input no device serves comes from the twin or from the server's clients.
            let Some((d, _, _)) = c.on else { continue };
            let Some(slot) = inputs.get_mut(c.signal) else {
                continue;
            };
            let use_safe = self.fault
                || self.safe_state
                || self.quality[d] == Quality::Initial
                || (self.quality[d] == Quality::Stale
                    && self.devices[d].stale != StalePolicy::Hold);
            *slot = if use_safe {
                self.map.safe_inputs[c.signal]
            } else {
                self.front[c.signal]
            };
        }
    }
}

impl Dispatcher for FieldIo {
    fn safe_outputs(&mut self, safe: &[Value]) {
        // Of the map's length once it grew (the router and the field grow at the same install).
        if safe.len() == self.safe_out.len() {
            self.safe_out.copy_from_slice(safe);
        }
    }

    fn write_outputs(&mut self, _now_us: u64, outputs: &[Value]) {
        let wanted: &[Value] = if self.in_safe_state() {
            &self.safe_out
        } else {
            outputs
        };
        if self.out_pending || wanted != &self.last_out[..] {
            if let Ok(mut s) = self.shared.try_lock() {
                let n = s.outputs.len().min(wanted.len());
                s.outputs[..n].copy_from_slice(&wanted[..n]);
                s.outputs_gen += 1;
                let m = self.last_out.len().min(wanted.len());
                self.last_out[..m].copy_from_slice(&wanted[..m]);
                self.out_pending = false;
            } else {
                self.out_pending = true;
                self.contended += 1;
            }
        }
        for k in &self.kicks {
            // A thread still busy with the last cycle is not queued a second one.
            if let Err(TrySendError::Disconnected(_)) = k.try_send(Kick::Cycle) {}
        }
    }
}

impl Drop for FieldIo {
    fn drop(&mut self) {
        self.stop();
    }
}
