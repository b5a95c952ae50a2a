//! A Modbus TCP server over a bank of bits and registers (tokio-modbus's `Service`), on a thread
//! of its own: what `cetratus twin serve` is to a PLC.
//!
//! Every request is checked before it touches the bank: the function, the unit id, the quantity
//! (at most what one frame carries: 2000 bits or 125 registers read, 1968 bits or 123 registers
//! written), that the whole range lies in the table, and, for a write, that the client may write
//! and that every entry written is writable. Anything else is answered with a Modbus exception;
//! nothing a client sends panics or grows memory (a frame is at most 260 bytes, and connections
//! beyond the limit are closed at once).
//!
//! The PLC's own server ([`crate::server`]) is this server with a write policy: only some coils
//! and registers are writable, and only from an allow-list of addresses.

use std::future::{ready, Ready};
use std::net::{IpAddr, SocketAddr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use tokio_modbus::server::tcp::Server;
use tokio_modbus::server::Service;
use tokio_modbus::{ExceptionCode, Request, Response, SlaveRequest};

use crate::IoError;
use cetratus_slots::{Idle, IdleTimeout, Slot, Slots};

/// The four tables of a Modbus device, and which of them clients may write.
#[derive(Debug, Default, Clone)]
pub struct Bank {
    /// Discrete inputs (read-only to clients).
    pub discrete_inputs: Vec<bool>,
    /// Coils.
    pub coils: Vec<bool>,
    /// Input registers (read-only to clients).
    pub input_registers: Vec<u16>,
    /// Holding registers.
    pub holding_registers: Vec<u16>,
    /// Which coils and holding registers clients may write; all of them when `None`.
    pub writable: Option<Writable>,
    /// Requests answered, exceptions sent, connections refused.
    pub counters: BankCounters,
}

/// The coils and holding registers a client may write, one flag per entry of each table.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Writable {
    /// Per coil.
    pub coils: Vec<bool>,
    /// Per holding register.
    pub holding_registers: Vec<bool>,
}

/// Which clients may write.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum WriteFrom {
    /// Every client (a simulated device, such as a twin).
    Anyone,
    /// Only clients at these addresses; the others read only.
    Only(Vec<IpAddr>),
}

impl WriteFrom {
    /// Whether a client at `ip` may write.
    pub fn allows(&self, ip: IpAddr) -> bool {
        match self {
            WriteFrom::Anyone => true,
            // An IPv4 client of a dual-stack listener arrives as ::ffff:a.b.c.d.
            WriteFrom::Only(list) => list.contains(&ip.to_canonical()),
        }
    }
}

/// How a server is reached and who may do what.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServeOptions {
    /// The unit id it answers to (0 and 255 always reach it too).
    pub unit: u8,
    /// Clients served at once; further connections are closed at once (one address holds at
    /// most half of them, and the last quarter is kept for addresses served before:
    /// [`cetratus_slots`]).
    pub max_connections: usize,
    /// A connection that sends nothing for this long is closed.
    pub idle_timeout: Duration,
    /// Who may write.
    pub write_from: WriteFrom,
}

/// The idle timeout of a Modbus server when the configuration names none.
pub const DEFAULT_IDLE_TIMEOUT: Duration = Duration::from_secs(60);

/// What the server did.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct BankCounters {
    /// Requests answered with data.
    pub requests: u64,
    /// Requests answered with an exception.
    pub exceptions: u64,
    /// Connections closed at once because no slot was left for them.
    pub refused: u64,
}

/// Locks a bank; a panic elsewhere does not stop the server.
pub fn lock(bank: &Mutex<Bank>) -> MutexGuard<'_, Bank> {
    bank.lock().unwrap_or_else(|p| p.into_inner())
}

/// Bits one read may ask for (Modbus Application Protocol 1.1b3, 6.1 and 6.2).
const MAX_READ_BITS: usize = 2000;
/// Registers one read may ask for (6.3, 6.4).
const MAX_READ_REGISTERS: usize = 125;
/// Coils one write may carry (6.11).
const MAX_WRITE_BITS: usize = 1968;
/// Registers one write may carry (6.12).
const MAX_WRITE_REGISTERS: usize = 123;

/// The entries `at .. at + n` of a table of `len`, for a request that may carry at most `max`:
/// a quantity out of bounds is an illegal value, a range outside the table an illegal address.
fn range(
    len: usize,
    at: u16,
    n: usize,
    max: usize,
) -> Result<std::ops::Range<usize>, ExceptionCode> {
    if n == 0 || n > max {
        return Err(ExceptionCode::IllegalDataValue);
    }
    let start = usize::from(at);
    match start.checked_add(n) {
        Some(end) if end <= len => Ok(start..end),
        _ => Err(ExceptionCode::IllegalDataAddress),
    }
}

/// Whether every entry of `r` is writable (`None`: the whole table is).
fn writable(mask: Option<&[bool]>, r: &std::ops::Range<usize>) -> Result<(), ExceptionCode> {
    match mask {
        Some(m) if !m.get(r.clone()).is_some_and(|m| m.iter().all(|&w| w)) => {
            Err(ExceptionCode::IllegalDataAddress)
        }
        _ => Ok(()),
    }
}

impl Bank {
    /// Answers one request from a client that may write (`may_write`) or only read.
    pub fn answer(
        &mut self,
        req: &Request<'_>,
        may_write: bool,
    ) -> Result<Response, ExceptionCode> {
        let r = self.answer_unchecked(req, may_write);
        match &r {
            Ok(_) => self.counters.requests += 1,
            Err(_) => self.counters.exceptions += 1,
        }
        r
    }

    fn answer_unchecked(
        &mut self,
        req: &Request<'_>,
        may_write: bool,
    ) -> Result<Response, ExceptionCode> {
        let is_write = matches!(
            req,
            Request::WriteSingleCoil(..)
                | Request::WriteMultipleCoils(..)
                | Request::WriteSingleRegister(..)
                | Request::WriteMultipleRegisters(..)
        );
        if is_write && !may_write {
            // This client reads only: the function is not one it may use.
            return Err(ExceptionCode::IllegalFunction);
        }
        let coils_mask = self.writable.as_ref().map(|w| w.coils.as_slice());
        let regs_mask = self
            .writable
            .as_ref()
            .map(|w| w.holding_registers.as_slice());
        match req {
            Request::ReadDiscreteInputs(at, n) => {
                let r = range(
                    self.discrete_inputs.len(),
                    *at,
                    usize::from(*n),
                    MAX_READ_BITS,
                )?;
                Ok(Response::ReadDiscreteInputs(
                    self.discrete_inputs[r].to_vec(),
                ))
            }
            Request::ReadCoils(at, n) => {
                let r = range(self.coils.len(), *at, usize::from(*n), MAX_READ_BITS)?;
                Ok(Response::ReadCoils(self.coils[r].to_vec()))
            }
            Request::ReadInputRegisters(at, n) => {
                let len = self.input_registers.len();
                let r = range(len, *at, usize::from(*n), MAX_READ_REGISTERS)?;
                Ok(Response::ReadInputRegisters(
                    self.input_registers[r].to_vec(),
                ))
            }
            Request::ReadHoldingRegisters(at, n) => {
                let len = self.holding_registers.len();
                let r = range(len, *at, usize::from(*n), MAX_READ_REGISTERS)?;
                Ok(Response::ReadHoldingRegisters(
                    self.holding_registers[r].to_vec(),
                ))
            }
            Request::WriteSingleCoil(at, v) => {
                let r = range(self.coils.len(), *at, 1, 1)?;
                writable(coils_mask, &r)?;
                self.coils[r.start] = *v;
                Ok(Response::WriteSingleCoil(*at, *v))
            }
            Request::WriteMultipleCoils(at, vs) => {
                let r = range(self.coils.len(), *at, vs.len(), MAX_WRITE_BITS)?;
                writable(coils_mask, &r)?;
                self.coils[r].copy_from_slice(vs);
                Ok(Response::WriteMultipleCoils(*at, vs.len() as u16))
            }
            Request::WriteSingleRegister(at, v) => {
                let r = range(self.holding_registers.len(), *at, 1, 1)?;
                writable(regs_mask, &r)?;
                self.holding_registers[r.start] = *v;
                Ok(Response::WriteSingleRegister(*at, *v))
            }
            Request::WriteMultipleRegisters(at, vs) => {
                let len = self.holding_registers.len();
                let r = range(len, *at, vs.len(), MAX_WRITE_REGISTERS)?;
                writable(regs_mask, &r)?;
                self.holding_registers[r].copy_from_slice(vs);
                Ok(Response::WriteMultipleRegisters(*at, vs.len() as u16))
            }
            _ => Err(ExceptionCode::IllegalFunction),
        }
    }
}

/// One connection's service, holding its slot.
struct BankService {
    bank: Arc<Mutex<Bank>>,
    unit: u8,
    may_write: bool,
    slot: Slot,
    served: AtomicBool,
}

impl Service for BankService {
    type Request = SlaveRequest<'static>;
    type Response = Response;
    type Exception = ExceptionCode;
    type Future = Ready<Result<Response, ExceptionCode>>;

    fn call(&self, req: Self::Request) -> Self::Future {
        if !self.served.swap(true, Ordering::Relaxed) {
            self.slot.served();
        }
        let mut bank = lock(&self.bank);
        // 0 and 255 address "the device behind this connection" in Modbus TCP.
        if req.slave != self.unit && req.slave != 0 && req.slave != 255 {
            bank.counters.exceptions += 1;
            return ready(Err(ExceptionCode::GatewayTargetDevice));
        }
        ready(bank.answer(&req.request, self.may_write))
    }
}

/// A running server; dropping it leaves the thread running until the process ends, so stop it.
pub struct BankServer {
    /// Where it listens.
    pub addr: SocketAddr,
    shutdown: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl BankServer {
    /// Listens on `addr`, serving `bank` as `options` say.
    pub fn start(
        addr: SocketAddr,
        bank: Arc<Mutex<Bank>>,
        options: ServeOptions,
    ) -> Result<BankServer, IoError> {
        let ServeOptions {
            unit,
            max_connections,
            idle_timeout,
            write_from,
        } = options;
        let listener = std::net::TcpListener::bind(addr).map_err(|e| IoError::Listen {
            addr: addr.to_string(),
            reason: e.to_string(),
        })?;
        let addr = listener.local_addr().map_err(|e| IoError::Listen {
            addr: addr.to_string(),
            reason: e.to_string(),
        })?;
        listener
            .set_nonblocking(true)
            .map_err(|e| IoError::Listen {
                addr: addr.to_string(),
                reason: e.to_string(),
            })?;
        let (tx, rx) = tokio::sync::oneshot::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("cetratus-modbus-server".into())
            .spawn(move || {
                let Ok(rt) = tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .build()
                else {
                    return;
                };
                rt.block_on(async move {
                    let Ok(listener) = tokio::net::TcpListener::from_std(listener) else {
                        return;
                    };
                    let server = Server::new(listener);
                    let slots = Slots::shared(max_connections);
                    let on_connected = |stream, peer: SocketAddr| {
                        let (bank, slots) = (bank.clone(), slots.clone());
                        let may_write = write_from.allows(peer.ip());
                        async move {
                            let Ok(slot) = Slots::take(&slots, peer.ip()) else {
                                lock(&bank).counters.refused += 1;
                                return Ok(None);
                            };
                            let svc = BankService {
                                bank,
                                unit,
                                may_write,
                                slot,
                                served: AtomicBool::new(false),
                            };
                            Ok(Some((
                                svc,
                                Idle::new(stream, IdleTimeout::after(idle_timeout)),
                            )))
                        }
                    };
                    tokio::select! {
                        _ = server.serve(&on_connected, |_err| {}) => {}
                        _ = rx => {}
                    }
                });
            })
            .map_err(|e| IoError::Thread(e.to_string()))?;
        Ok(BankServer {
            addr,
            shutdown: Some(tx),
            thread: Some(thread),
        })
    }

    /// Stops listening and closes every connection.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        if let Some(tx) = self.shutdown.take() {
            let _ = tx.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for BankServer {
    fn drop(&mut self) {
        self.halt();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_outside_the_tables_or_of_unknown_functions_get_exceptions() {
        let mut b = Bank {
            discrete_inputs: vec![true; 8],
            coils: vec![false; 8],
            ..Bank::default()
        };
        let mut ask = |r: Request<'_>| b.answer(&r, true);
        assert_eq!(
            ask(Request::ReadDiscreteInputs(0, 8)),
            Ok(Response::ReadDiscreteInputs(vec![true; 8]))
        );
        assert_eq!(
            ask(Request::ReadDiscreteInputs(1, 8)),
            Err(ExceptionCode::IllegalDataAddress)
        );
        assert_eq!(
            ask(Request::ReadDiscreteInputs(u16::MAX, 2)),
            Err(ExceptionCode::IllegalDataAddress)
        );
        assert_eq!(
            ask(Request::ReadCoils(0, 0)),
            Err(ExceptionCode::IllegalDataValue)
        );
        assert_eq!(
            ask(Request::WriteSingleRegister(0, 1)),
            Err(ExceptionCode::IllegalDataAddress)
        );
        assert_eq!(
            ask(Request::ReportServerId),
            Err(ExceptionCode::IllegalFunction)
        );
        assert_eq!(
            ask(Request::WriteMultipleCoils(6, vec![true, true].into())),
            Ok(Response::WriteMultipleCoils(6, 2))
        );
        assert_eq!(&b.coils[5..], &[false, true, true]);
        assert_eq!(
            b.counters,
            BankCounters {
                requests: 2,
                exceptions: 5,
                refused: 0
            }
        );
    }

    #[test]
    fn a_read_longer_than_one_frame_carries_is_an_illegal_value_not_a_malformed_answer() {
        let mut b = Bank {
            holding_registers: vec![0; 1000],
            coils: vec![false; 4000],
            ..Bank::default()
        };
        assert_eq!(
            b.answer(&Request::ReadHoldingRegisters(0, 126), false),
            Err(ExceptionCode::IllegalDataValue)
        );
        assert_eq!(
            b.answer(&Request::ReadCoils(0, 2001), false),
            Err(ExceptionCode::IllegalDataValue)
        );
        assert!(b
            .answer(&Request::ReadHoldingRegisters(0, 125), false)
            .is_ok());
        assert!(b.answer(&Request::ReadCoils(0, 2000), false).is_ok());
    }

    #[test]
    fn writes_reach_only_writable_entries_and_only_from_clients_that_may_write() {
        let mut b = Bank {
            holding_registers: vec![0; 4],
            writable: Some(Writable {
                coils: Vec::new(),
                holding_registers: vec![false, true, true, false],
            }),
            ..Bank::default()
        };
        assert_eq!(
            b.answer(&Request::WriteSingleRegister(1, 7), false),
            Err(ExceptionCode::IllegalFunction)
        );
        assert_eq!(
            b.answer(&Request::WriteSingleRegister(0, 7), true),
            Err(ExceptionCode::IllegalDataAddress)
        );
        assert_eq!(
            b.answer(
                &Request::WriteMultipleRegisters(1, vec![8, 9, 10].into()),
                true
            ),
            Err(ExceptionCode::IllegalDataAddress)
        );
        assert_eq!(
            b.answer(&Request::WriteMultipleRegisters(1, vec![8, 9].into()), true),
            Ok(Response::WriteMultipleRegisters(1, 2))
        );
        assert_eq!(b.holding_registers, [0, 8, 9, 0]);
        let only = WriteFrom::Only(vec!["127.0.0.1".parse().unwrap()]);
        assert!(only.allows("::ffff:127.0.0.1".parse().unwrap()));
        assert!(!only.allows("127.0.0.2".parse().unwrap()));
    }
}
