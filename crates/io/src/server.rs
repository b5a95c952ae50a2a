//! The PLC's own Modbus TCP server (like OpenPLC's slave): the process image for HMIs and SCADA,
//! and read-only status registers (docs/io.md, *The PLC's Modbus server*).
//!
//! It is the [`bank`](crate::bank) server with a write policy. Every signal with an address is
//! shown at its place in OpenPLC's default map; clients may write only the program's `%M` inputs
//! and the inputs marked `hmi_writable` (at a mirror, since Modbus cannot write a discrete input
//! or an input register), and only from the configuration's `write_from` addresses. Everything
//! else is answered with an exception by the server's own thread.
//!
//! The scan meets the bank as it meets the field's process image: with `try_lock` only. At the
//! cycle start it takes what HMIs wrote and shows the inputs the program gets; after dispatch it
//! shows the outputs; after the cycle, PRIMARY, STATUS, the cycle counter and the drift. When a
//! client holds the bank (for the microseconds of one request), the scan keeps the values it took
//! last and shows the image again next cycle. What a client sends never causes more work on the
//! scan thread than copying the declared channels.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};

use cetratus_program::Value;
use cetratus_runtime::{Dispatcher, Plc, Provider, Status};

use crate::address::{Area, Table};
use crate::bank::{lock, Bank, BankCounters, BankServer, ServeOptions, Writable, WriteFrom};
use crate::config::{ServerConfig, WordOrder};
use crate::map::{Channel, FieldMap};
use crate::IoError;

/// Where the server's own entries start in every table: status registers (input registers) and
/// the mirrors through which HMIs write inputs (coils and holding registers). Signals live below.
pub const SERVER_AREA: u32 = 8192;

/// Input register of PRIMARY: 0 for container A, 1 for B.
pub const REG_PRIMARY: u16 = SERVER_AREA as u16;
/// Input register of STATUS: 0 idle, 1 setup, 2 quarantine, 3 probation, 4 fault.
pub const REG_STATUS: u16 = REG_PRIMARY + 1;
/// Four input registers, high word first: cycles run.
pub const REG_CYCLES: u16 = REG_PRIMARY + 2;
/// Two input registers, high word first: the candidate's drift in quarantine (saturated).
pub const REG_DRIFT: u16 = REG_PRIMARY + 6;
/// Input register: 1 while a drift is measured (a candidate in quarantine), else 0.
pub const REG_DRIFT_VALID: u16 = REG_PRIMARY + 8;
/// Status registers.
const STATUS_LEN: usize = 9;

/// Where a value lives in the server's tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Place {
    table: Table,
    at: usize,
}

/// One shown signal.
#[derive(Clone, Debug)]
struct Shown {
    channel: Channel,
    /// Where clients read it.
    shown: Place,
    /// Where clients write it, for a writable input.
    written: Option<Place>,
}

/// The server of a run, seen from the scan thread: a [`Provider`] of what HMIs write, and a
/// [`Dispatcher`] that shows the outputs.
pub struct ImageServer {
    bank: Arc<Mutex<Bank>>,
    server: BankServer,
    inputs: Vec<Shown>,
    outputs: Vec<Shown>,
    /// The last values taken from the bank, per input (I/O-map order), for the cycles in which a
    /// client holds it.
    held: Vec<Value>,
    contended: u64,
}

/// The scan's side of the status registers, given to the node to call after each cycle.
pub struct StatusBoard {
    bank: Arc<Mutex<Bank>>,
}

fn place_of(c: &Channel) -> Place {
    let (table, at) = c.address.default_location();
    Place {
        table,
        at: at as usize,
    }
}

fn table_mut(b: &mut Bank, t: Table) -> TableMut<'_> {
    match t {
        Table::DiscreteInputs => TableMut::Bits(&mut b.discrete_inputs),
        Table::Coils => TableMut::Bits(&mut b.coils),
        Table::InputRegisters => TableMut::Regs(&mut b.input_registers),
        Table::HoldingRegisters => TableMut::Regs(&mut b.holding_registers),
    }
}

enum TableMut<'a> {
    Bits(&'a mut [bool]),
    Regs(&'a mut [u16]),
}

/// The server's tables speak OpenPLC's word order: the high word first.
const ORDER: WordOrder = WordOrder::HighFirst;

fn show(b: &mut Bank, s: &Shown, p: Place, v: Value) {
    let w = s.channel.address.width() as usize;
    match table_mut(b, p.table) {
        TableMut::Bits(t) => {
            if let Some(x) = t.get_mut(p.at) {
                *x = matches!(v, Value::Bool(true));
            }
        }
        TableMut::Regs(t) => {
            if let Some(x) = t.get_mut(p.at..p.at + w) {
                s.channel.encode_regs(v, ORDER, x);
            }
        }
    }
}

fn take(b: &mut Bank, s: &Shown, p: Place) -> Option<Value> {
    let w = s.channel.address.width() as usize;
    match table_mut(b, p.table) {
        TableMut::Bits(t) => t.get(p.at).map(|&x| Value::Bool(x)),
        TableMut::Regs(t) => t
            .get(p.at..p.at + w)
            .map(|x| s.channel.decode_regs(x, ORDER)),
    }
}

fn grow<T: Clone>(v: &mut Vec<T>, len: usize, zero: T) {
    if v.len() < len {
        v.resize(len, zero);
    }
}

fn try_bank(bank: &Mutex<Bank>) -> Option<MutexGuard<'_, Bank>> {
    match bank.try_lock() {
        Ok(g) => Some(g),
        Err(TryLockError::Poisoned(p)) => Some(p.into_inner()),
        Err(TryLockError::WouldBlock) => None,
    }
}

/// Where a client reads an input, and writes it when the configuration lets HMIs write it.
fn shown_input(c: &Channel) -> Shown {
    let shown = place_of(c);
    let written = if c.address.area == Area::Memory {
        Some(shown)
    } else if c.hmi_writable {
        Some(Place {
            table: if c.address.size == crate::address::Size::Bit {
                Table::Coils
            } else {
                Table::HoldingRegisters
            },
            at: SERVER_AREA as usize + shown.at,
        })
    } else {
        None
    };
    Shown {
        channel: c.clone(),
        shown,
        written,
    }
}

/// Where a client reads an output.
fn shown_output(c: &Channel) -> Shown {
    Shown {
        channel: c.clone(),
        shown: place_of(c),
        written: None,
    }
}

/// Refuses a signal among the server's own entries.
fn below_server_area(s: &Shown) -> Result<(), IoError> {
    let end = s.shown.at + s.channel.address.width() as usize;
    if end > SERVER_AREA as usize {
        return Err(IoError::Unmapped {
            signal: s.channel.name.clone(),
            why: format!(
                "{} is {} {}, but the Modbus server keeps the entries from {SERVER_AREA} on for its status registers and for HMI writes; give the signal a lower address, or remove [server]",
                s.channel.address,
                s.shown.table.name(),
                s.shown.at
            ),
        });
    }
    Ok(())
}

/// Whether the PLC's Modbus server can show channel `c` (an input when `input`): refused when
/// its entries are among the server's own (asked when a live update adds it).
pub(crate) fn fits_server(c: &Channel, input: bool) -> Result<(), IoError> {
    below_server_area(&if input {
        shown_input(c)
    } else {
        shown_output(c)
    })
}

/// Grows `bank`'s tables (and their writable flags) to hold `s`.
fn lay_out(bank: &mut Bank, s: &Shown) {
    for p in std::iter::once(s.shown).chain(s.written) {
        let end = p.at + s.channel.address.width() as usize;
        match p.table {
            Table::DiscreteInputs => grow(&mut bank.discrete_inputs, end, false),
            Table::Coils => grow(&mut bank.coils, end, false),
            Table::InputRegisters => {}
            Table::HoldingRegisters => grow(&mut bank.holding_registers, end, 0),
        }
    }
    if let Some(w) = bank.writable.as_mut() {
        grow(&mut w.coils, bank.coils.len(), false);
        grow(
            &mut w.holding_registers,
            bank.holding_registers.len(),
            false,
        );
    }
}

impl ImageServer {
    /// Lays out the image of `map` and starts serving it as `config` says.
    pub fn start(config: &ServerConfig, map: &FieldMap) -> Result<ImageServer, IoError> {
        let listen: SocketAddr = config.listen.parse().map_err(|_| IoError::Listen {
            addr: config.listen.clone(),
            reason: "not an IP address and port".into(),
        })?;
        let inputs: Vec<Shown> = map.inputs.iter().map(shown_input).collect();
        let outputs: Vec<Shown> = map.outputs.iter().map(shown_output).collect();
        for s in inputs.iter().chain(&outputs) {
            below_server_area(s)?;
        }
        let mut bank = Bank {
            input_registers: vec![0; SERVER_AREA as usize + STATUS_LEN],
            ..Bank::default()
        };
        for s in inputs.iter().chain(&outputs) {
            lay_out(&mut bank, s);
        }
        let mut writable = Writable {
            coils: vec![false; bank.coils.len()],
            holding_registers: vec![false; bank.holding_registers.len()],
        };
        for s in &inputs {
            let Some(p) = s.written else { continue };
            let n = s.channel.address.width() as usize;
            let mask = match p.table {
                Table::Coils => &mut writable.coils,
                _ => &mut writable.holding_registers,
            };
            mask[p.at..p.at + n].fill(true);
        }
        bank.writable = Some(writable);
        // Written inputs start at their safe values, as the program's inputs do.
        for s in &inputs {
            let v = map.safe_inputs[s.channel.signal];
            show(&mut bank, s, s.shown, v);
            if let Some(p) = s.written {
                show(&mut bank, s, p, v);
            }
        }
        let bank = Arc::new(Mutex::new(bank));
        let server = BankServer::start(
            listen,
            bank.clone(),
            ServeOptions {
                unit: 1,
                max_connections: config.max_connections,
                idle_timeout: std::time::Duration::from_micros(config.idle_timeout_us),
                write_from: WriteFrom::Only(config.write_from.clone()),
            },
        )?;
        Ok(ImageServer {
            bank,
            server,
            held: map.safe_inputs.clone(),
            inputs,
            outputs,
            contended: 0,
        })
    }

    /// Where it listens.
    pub fn addr(&self) -> SocketAddr {
        self.server.addr
    }

    /// What it did (off the scan thread: it locks the bank).
    pub fn counters(&self) -> BankCounters {
        lock(&self.bank).counters
    }

    /// Cycles in which a client held the bank and the scan kept its values.
    pub fn contended(&self) -> u64 {
        self.contended
    }

    /// The status registers' writer, for the node to call after each cycle.
    pub fn status_board(&self) -> StatusBoard {
        StatusBoard {
            bank: self.bank.clone(),
        }
    }

    /// Shows the channels that a live update appended to `map` (the field map, grown at the
    /// install): the tables grow to hold them, new inputs show their safe values until the scan
    /// shows what the program got, new outputs 0 until the dispatch of the same cycle shows them. A new
    /// signal is read-only to clients (only a device-served signal can be added, and a
    /// device-served input is never `hmi_writable`). On the scan thread, at that install's cycle
    /// boundary only: it locks the bank once, for the copy.
    pub fn grow(&mut self, map: &FieldMap) {
        let known =
            |shown: &[Shown], c: &Channel| shown.iter().any(|s| s.channel.signal == c.signal);
        let new_inputs: Vec<Shown> = map
            .inputs
            .iter()
            .filter(|c| !known(&self.inputs, c))
            .map(shown_input)
            .filter(|s| s.written.is_none() && below_server_area(s).is_ok())
            .collect();
        let new_outputs: Vec<Shown> = map
            .outputs
            .iter()
            .filter(|c| !known(&self.outputs, c))
            .map(shown_output)
            .filter(|s| below_server_area(s).is_ok())
            .collect();
        grow(&mut self.held, map.safe_inputs.len(), Value::Bool(false));
        let mut b = lock(&self.bank);
        for s in &new_inputs {
            lay_out(&mut b, s);
            let v = map.safe_inputs[s.channel.signal];
            self.held[s.channel.signal] = v;
            show(&mut b, s, s.shown, v);
        }
        for s in &new_outputs {
            lay_out(&mut b, s);
            show(&mut b, s, s.shown, s.channel.ty.zero());
        }
        drop(b);
        self.inputs.extend(new_inputs);
        self.outputs.extend(new_outputs);
    }
}

impl Provider for ImageServer {
    fn read_inputs(&mut self, _now_us: u64, inputs: &mut [Value]) {
        let Some(mut b) = try_bank(&self.bank) else {
            self.contended += 1;
            for s in &self.inputs {
                if s.written.is_some() {
                    if let Some(slot) = inputs.get_mut(s.channel.signal) {
                        *slot = self.held[s.channel.signal];
                    }
                }
            }
            return;
        };
        for s in &self.inputs {
            let Some(slot) = inputs.get_mut(s.channel.signal) else {
                continue;
            };
            if let Some(p) = s.written {
                if let Some(v) = take(&mut b, s, p) {
                    self.held[s.channel.signal] = v;
                    *slot = v;
                }
            }
            if s.written != Some(s.shown) {
                show(&mut b, s, s.shown, *slot);
            }
        }
    }
}

impl Dispatcher for ImageServer {
    fn write_outputs(&mut self, _now_us: u64, outputs: &[Value]) {
        let Some(mut b) = try_bank(&self.bank) else {
            self.contended += 1;
            return;
        };
        for s in &self.outputs {
            if let Some(&v) = outputs.get(s.channel.signal) {
                show(&mut b, s, s.shown, v);
            }
        }
    }
}

impl StatusBoard {
    /// Shows the PLC's PRIMARY, STATUS, cycle counter and drift; skipped in a cycle in which a
    /// client holds the bank (the next cycle shows them).
    pub fn show(&mut self, plc: &Plc) {
        let Some(mut b) = try_bank(&self.bank) else {
            return;
        };
        let status = match plc.status() {
            Status::Idle => 0,
            Status::Setup => 1,
            Status::Quarantine => 2,
            Status::Probation => 3,
            Status::Fault => 4,
        };
        let cycles = plc.cycles();
        let drift = plc.drift();
        let d = u32::try_from(drift.unwrap_or(0)).unwrap_or(u32::MAX);
        let regs = [
            plc.primary().index() as u16,
            status,
            (cycles >> 48) as u16,
            (cycles >> 32) as u16,
            (cycles >> 16) as u16,
            cycles as u16,
            (d >> 16) as u16,
            d as u16,
            u16::from(drift.is_some()),
        ];
        let at = usize::from(REG_PRIMARY);
        if let Some(r) = b.input_registers.get_mut(at..at + STATUS_LEN) {
            r.copy_from_slice(&regs);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::IoConfig;
    use crate::map::tests::signal;
    use cetratus_program::Type;

    #[test]
    fn a_signal_among_the_servers_own_entries_is_refused_before_listening() {
        let config = IoConfig::parse(
            "io.toml",
            "[server]\nmodbus = \"127.0.0.1:0\"\nwrite_from = [\"127.0.0.1\"]\n",
        )
        .unwrap();
        let map =
            FieldMap::bind(&config, &[signal("SP", Type::Int, "%MW7200")], &[], false).unwrap();
        let Err(e) = ImageServer::start(config.server.as_ref().unwrap(), &map) else {
            panic!("a setpoint at holding register 8224 was served");
        };
        assert!(e.to_string().contains("from 8192 on"), "{e}");
    }
}
