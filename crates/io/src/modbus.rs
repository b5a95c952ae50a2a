//! The Modbus TCP client of one field device, on an I/O thread of its own (tokio-modbus).
//!
//! Each cycle the scan thread wakes it after dispatch: it writes the outputs when they changed,
//! after a reconnect, and at least every `rewrite_every` cycles (the device's communication
//! watchdog), then reads the inputs for the next cycle's start. Every request has the device's
//! timeout; a timeout or a broken connection drops the connection, and it is made again with
//! exponential backoff. An exception response keeps the connection and counts the cycle as
//! missed. Whatever the device answers is checked for length before it is decoded.

use std::net::{SocketAddr, ToSocketAddrs};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use cetratus_program::Value;
use tokio_modbus::client::sync::{self, Context, Reader, Writer};
use tokio_modbus::Slave;

use crate::address::Table;
use crate::config::{Device, Transport};
use crate::field::{lock, Kick, LinkState, Shared};
use crate::map::FieldMap;

/// The longest error text kept for a device.
const MAX_ERROR: usize = 200;

/// Once cycles wake the thread, it polls on its own only after this long without one (a scan
/// that stopped). A poll at the cycle period, restarted after each exchange, would fire in every
/// cycle whose wake-up comes a little later than the last one's: at the moment the scan thread
/// wakes, competing with it for the CPU, for an exchange the cycle's own wake-up repeats.
const IDLE_POLL: Duration = Duration::from_secs(1);

/// One device's I/O thread.
pub(crate) struct DeviceThread {
    index: usize,
    dev: Device,
    map: Arc<FieldMap>,
    shared: Arc<Mutex<Shared>>,
    poll: Duration,
    // Per served range, the bits or registers last read or to write; reused.
    bits: Vec<Vec<bool>>,
    regs: Vec<Vec<u16>>,
    outputs: Vec<Value>,
}

/// What a request came to.
enum Outcome {
    Ok,
    /// The device answered with an exception: the connection stays.
    Exception(String),
    /// Timeout or a broken connection: the connection is dropped.
    Broken(String),
}

fn outcome<T>(r: tokio_modbus::Result<T>, what: &str) -> Result<T, Outcome> {
    match r {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(code)) => Err(Outcome::Exception(format!("{what}: exception {code:?}"))),
        Err(e) => Err(Outcome::Broken(format!("{what}: {e}"))),
    }
}

impl DeviceThread {
    pub(crate) fn new(
        index: usize,
        dev: Device,
        map: Arc<FieldMap>,
        shared: Arc<Mutex<Shared>>,
        period_us: u64,
    ) -> Self {
        let bits = dev
            .ranges
            .iter()
            .map(|r| {
                if r.table.is_bits() {
                    vec![false; r.len() as usize]
                } else {
                    Vec::new()
                }
            })
            .collect();
        let regs = dev
            .ranges
            .iter()
            .map(|r| {
                if r.table.is_bits() {
                    Vec::new()
                } else {
                    vec![0; r.len() as usize]
                }
            })
            .collect();
        let outputs = map.safe_outputs.clone();
        DeviceThread {
            index,
            dev,
            map,
            shared,
            poll: Duration::from_micros(period_us.clamp(1_000, 1_000_000)),
            bits,
            regs,
            outputs,
        }
    }

    fn resolve(&self) -> Result<SocketAddr, String> {
        let Transport::ModbusTcp(a) = &self.dev.transport;
        a.to_socket_addrs()
            .map_err(|e| format!("cannot resolve {a}: {e}"))?
            .next()
            .ok_or_else(|| format!("{a} resolves to no address"))
    }

    fn connect(&self) -> Result<Context, String> {
        let addr = self.resolve()?;
        let timeout = Duration::from_micros(self.dev.timeout_us);
        sync::tcp::connect_slave_with_timeout(addr, Slave(self.dev.unit), Some(timeout))
            .map_err(|e| format!("cannot connect to {addr}: {e}"))
    }

    fn report(&self, f: impl FnOnce(&mut crate::field::DeviceStatus)) {
        let mut s = lock(&self.shared);
        f(&mut s.devices[self.index]);
    }

    /// Runs until told to stop or the scan side is gone; the last thing it does is write the
    /// safe outputs to the device, if connected.
    pub(crate) fn run(mut self, kicks: Receiver<Kick>) {
        let (min, max) = (
            Duration::from_micros(self.dev.reconnect_us.0),
            Duration::from_micros(self.dev.reconnect_us.1),
        );
        let mut backoff = min;
        let mut next_attempt = Instant::now();
        let mut ctx: Option<Context> = None;
        let mut connected_once = false;
        let mut written_gen = 0u64;
        let mut since_write = 0u32;
        let mut rewrite = true;
        // Before the first cycle the thread polls at the period (the first input image).
        let mut driven = false;
        loop {
            let wait = if driven { IDLE_POLL } else { self.poll };
            let stop = match kicks.recv_timeout(wait) {
                Ok(Kick::Cycle) => {
                    driven = true;
                    false
                }
                Err(RecvTimeoutError::Timeout) => false,
                Ok(Kick::Stop) | Err(RecvTimeoutError::Disconnected) => true,
            };
            if ctx.is_none() {
                // Stopping with no connection: there is nobody to give the safe values to.
                if stop {
                    return;
                }
                if Instant::now() < next_attempt {
                    continue;
                }
                match self.connect() {
                    Ok(c) => {
                        backoff = min;
                        rewrite = true;
                        let again = connected_once;
                        connected_once = true;
                        self.report(|s| {
                            s.link = LinkState::Up;
                            s.reconnects += u64::from(again);
                        });
                        ctx = Some(c);
                    }
                    Err(e) => {
                        next_attempt = Instant::now() + backoff;
                        backoff = (backoff * 2).min(max);
                        self.report(|s| {
                            s.link = LinkState::Down;
                            s.errors += 1;
                            s.last_error = Some(truncate(e));
                        });
                        continue;
                    }
                }
            }
            let Some(c) = ctx.as_mut() else { continue };
            let result = if stop {
                // The safe values the scan side set before it sent the stop.
                self.outputs.clone_from(&lock(&self.shared).outputs);
                self.write(c)
            } else {
                since_write = since_write.saturating_add(1);
                let due = {
                    let s = lock(&self.shared);
                    if !Arc::ptr_eq(&s.map, &self.map) {
                        // A live update added signals: serve their channels from now on.
                        self.map = s.map.clone();
                    }
                    let due = rewrite
                        || s.outputs_gen != written_gen
                        || since_write >= self.dev.rewrite_every;
                    if due {
                        self.outputs.clone_from(&s.outputs);
                        written_gen = s.outputs_gen;
                    }
                    due
                };
                let w = if due { self.write(c) } else { Outcome::Ok };
                if matches!(w, Outcome::Ok) {
                    if due {
                        rewrite = false;
                        since_write = 0;
                    }
                    self.read(c)
                } else {
                    w
                }
            };
            match result {
                Outcome::Ok => {}
                Outcome::Exception(e) => self.report(|s| {
                    s.exceptions += 1;
                    s.last_error = Some(truncate(e));
                }),
                Outcome::Broken(e) => {
                    ctx = None;
                    next_attempt = Instant::now() + backoff;
                    self.report(|s| {
                        s.link = LinkState::Down;
                        s.errors += 1;
                        s.last_error = Some(truncate(e));
                    });
                }
            }
            if stop {
                return;
            }
        }
    }

    /// Writes every output range of the device, one request per range.
    fn write(&mut self, c: &mut Context) -> Outcome {
        let order = self.dev.word_order;
        let mut any = false;
        for (r, range) in self.dev.ranges.iter().enumerate() {
            if !matches!(range.table, Table::Coils | Table::HoldingRegisters) {
                continue;
            }
            for ch in self
                .map
                .outputs
                .iter()
                .filter(|ch| ch.on.is_some_and(|o| o.0 == self.index && o.1 == r))
            {
                let (_, _, pos) = ch.on.unwrap_or_default();
                let v = self.outputs[ch.signal];
                if range.table.is_bits() {
                    self.bits[r][pos] = matches!(v, Value::Bool(true));
                } else {
                    let w = ch.address.width() as usize;
                    ch.encode_regs(v, order, &mut self.regs[r][pos..pos + w]);
                }
            }
            let at = range.offset as u16;
            let done = if range.table.is_bits() {
                outcome(c.write_multiple_coils(at, &self.bits[r]), "write coils")
            } else {
                outcome(
                    c.write_multiple_registers(at, &self.regs[r]),
                    "write holding registers",
                )
            };
            if let Err(o) = done {
                return o;
            }
            any = true;
        }
        if any {
            self.report(|s| s.writes += 1);
        }
        Outcome::Ok
    }

    /// Reads every input range; on success, decodes the device's input channels into the image.
    fn read(&mut self, c: &mut Context) -> Outcome {
        let mut any = false;
        for r in 0..self.dev.ranges.len() {
            let range = self.dev.ranges[r];
            let (at, n) = (range.offset as u16, range.len() as u16);
            let got = match range.table {
                Table::DiscreteInputs => {
                    outcome(c.read_discrete_inputs(at, n), "read discrete inputs")
                        .map(|v| self.store_bits(r, v))
                }
                Table::InputRegisters => {
                    outcome(c.read_input_registers(at, n), "read input registers")
                        .map(|v| self.store_regs(r, v))
                }
                Table::Coils | Table::HoldingRegisters => continue,
            };
            match got {
                Ok(true) => any = true,
                Ok(false) => {
                    return Outcome::Exception(format!(
                        "{} {at}: the device answered a wrong number of values",
                        range.table.name()
                    ))
                }
                Err(o) => return o,
            }
        }
        let order = self.dev.word_order;
        let mut s = lock(&self.shared);
        for ch in &self.map.inputs {
            let Some((d, r, pos)) = ch.on else { continue };
            if d != self.index {
                continue;
            }
            s.inputs[ch.signal] = if self.dev.ranges[r].table.is_bits() {
                Value::Bool(self.bits[r][pos])
            } else {
                let w = ch.address.width() as usize;
                ch.decode_regs(&self.regs[r][pos..pos + w], order)
            };
        }
        let st = &mut s.devices[self.index];
        st.reads += 1;
        if !any {
            // A device with only outputs: a read of nothing is a successful cycle.
            st.link = LinkState::Up;
        }
        Outcome::Ok
    }

    fn store_bits(&mut self, r: usize, v: Vec<bool>) -> bool {
        // A device may pad bits to a whole byte; fewer than asked is an error.
        if v.len() < self.bits[r].len() {
            return false;
        }
        let n = self.bits[r].len();
        self.bits[r].copy_from_slice(&v[..n]);
        true
    }

    fn store_regs(&mut self, r: usize, v: Vec<u16>) -> bool {
        if v.len() != self.regs[r].len() {
            return false;
        }
        self.regs[r].copy_from_slice(&v);
        true
    }
}

fn truncate(mut s: String) -> String {
    if s.len() > MAX_ERROR {
        let mut end = MAX_ERROR;
        while !s.is_char_boundary(end) {
            end -= 1;
        }
        s.truncate(end);
    }
    s
}
