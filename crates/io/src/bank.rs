//! A Modbus TCP server over a bank of bits and registers (tokio-modbus's `Service`), on a thread
//! of its own: what `cetratus twin serve` is to a PLC.
//!
//! Every request is checked before it touches the bank: the function, the unit id, and that the
//! whole range lies in the table. Anything else is answered with a Modbus exception; nothing a
//! client sends panics or grows memory (a frame is at most 260 bytes, and connections beyond the
//! limit are closed at once).

use std::future::{ready, Ready};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use tokio_modbus::server::tcp::{accept_tcp_connection, Server};
use tokio_modbus::server::Service;
use tokio_modbus::{ExceptionCode, Request, Response, SlaveRequest};

use crate::IoError;

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
    /// Requests answered, exceptions sent, connections refused.
    pub counters: BankCounters,
}

/// What the server did.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct BankCounters {
    /// Requests answered with data.
    pub requests: u64,
    /// Requests answered with an exception.
    pub exceptions: u64,
    /// Connections closed at once because the limit was reached.
    pub refused: u64,
}

/// Locks a bank; a panic elsewhere does not stop the server.
pub fn lock(bank: &Mutex<Bank>) -> MutexGuard<'_, Bank> {
    bank.lock().unwrap_or_else(|p| p.into_inner())
}

fn range(len: usize, at: u16, n: usize) -> Result<std::ops::Range<usize>, ExceptionCode> {
    let start = usize::from(at);
    match start.checked_add(n) {
        Some(end) if n > 0 && end <= len => Ok(start..end),
        _ => Err(ExceptionCode::IllegalDataAddress),
    }
}

impl Bank {
    /// Answers one request.
    pub fn answer(&mut self, req: &Request<'_>) -> Result<Response, ExceptionCode> {
        let r = match req {
            Request::ReadDiscreteInputs(at, n) => {
                range(self.discrete_inputs.len(), *at, usize::from(*n))
                    .map(|r| Response::ReadDiscreteInputs(self.discrete_inputs[r].to_vec()))
            }
            Request::ReadCoils(at, n) => range(self.coils.len(), *at, usize::from(*n))
                .map(|r| Response::ReadCoils(self.coils[r].to_vec())),
            Request::ReadInputRegisters(at, n) => {
                range(self.input_registers.len(), *at, usize::from(*n))
                    .map(|r| Response::ReadInputRegisters(self.input_registers[r].to_vec()))
            }
            Request::ReadHoldingRegisters(at, n) => {
                range(self.holding_registers.len(), *at, usize::from(*n))
                    .map(|r| Response::ReadHoldingRegisters(self.holding_registers[r].to_vec()))
            }
            Request::WriteSingleCoil(at, v) => range(self.coils.len(), *at, 1).map(|r| {
                self.coils[r.start] = *v;
                Response::WriteSingleCoil(*at, *v)
            }),
            Request::WriteMultipleCoils(at, vs) => {
                range(self.coils.len(), *at, vs.len()).map(|r| {
                    self.coils[r].copy_from_slice(vs);
                    Response::WriteMultipleCoils(*at, vs.len() as u16)
                })
            }
            Request::WriteSingleRegister(at, v) => {
                range(self.holding_registers.len(), *at, 1).map(|r| {
                    self.holding_registers[r.start] = *v;
                    Response::WriteSingleRegister(*at, *v)
                })
            }
            Request::WriteMultipleRegisters(at, vs) => {
                range(self.holding_registers.len(), *at, vs.len()).map(|r| {
                    self.holding_registers[r].copy_from_slice(vs);
                    Response::WriteMultipleRegisters(*at, vs.len() as u16)
                })
            }
            _ => Err(ExceptionCode::IllegalFunction),
        };
        match &r {
            Ok(_) => self.counters.requests += 1,
            Err(_) => self.counters.exceptions += 1,
        }
        r
    }
}

/// One connection's service.
struct BankService {
    bank: Arc<Mutex<Bank>>,
    unit: u8,
    open: Arc<AtomicUsize>,
}

impl Drop for BankService {
    fn drop(&mut self) {
        self.open.fetch_sub(1, Ordering::SeqCst);
    }
}

impl Service for BankService {
    type Request = SlaveRequest<'static>;
    type Response = Response;
    type Exception = ExceptionCode;
    type Future = Ready<Result<Response, ExceptionCode>>;

    fn call(&self, req: Self::Request) -> Self::Future {
        let mut bank = lock(&self.bank);
        // 0 and 255 address "the device behind this connection" in Modbus TCP.
        if req.slave != self.unit && req.slave != 0 && req.slave != 255 {
            bank.counters.exceptions += 1;
            return ready(Err(ExceptionCode::GatewayTargetDevice));
        }
        ready(bank.answer(&req.request))
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
    /// Listens on `addr` for at most `max_connections` clients at once, serving `bank` as unit
    /// `unit`.
    pub fn start(
        addr: SocketAddr,
        bank: Arc<Mutex<Bank>>,
        unit: u8,
        max_connections: usize,
    ) -> Result<BankServer, IoError> {
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
                    let open = Arc::new(AtomicUsize::new(0));
                    let on_connected = |stream, peer| {
                        let (bank, open) = (bank.clone(), open.clone());
                        async move {
                            if open.load(Ordering::SeqCst) >= max_connections {
                                lock(&bank).counters.refused += 1;
                                return Ok(None);
                            }
                            open.fetch_add(1, Ordering::SeqCst);
                            let svc = std::cell::Cell::new(Some(BankService { bank, unit, open }));
                            accept_tcp_connection(stream, peer, |_| Ok(svc.take()))
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
        assert_eq!(
            b.answer(&Request::ReadDiscreteInputs(0, 8)),
            Ok(Response::ReadDiscreteInputs(vec![true; 8]))
        );
        assert_eq!(
            b.answer(&Request::ReadDiscreteInputs(1, 8)),
            Err(ExceptionCode::IllegalDataAddress)
        );
        assert_eq!(
            b.answer(&Request::ReadDiscreteInputs(u16::MAX, u16::MAX)),
            Err(ExceptionCode::IllegalDataAddress)
        );
        assert_eq!(
            b.answer(&Request::ReadCoils(0, 0)),
            Err(ExceptionCode::IllegalDataAddress)
        );
        assert_eq!(
            b.answer(&Request::WriteSingleRegister(0, 1)),
            Err(ExceptionCode::IllegalDataAddress)
        );
        assert_eq!(
            b.answer(&Request::ReportServerId),
            Err(ExceptionCode::IllegalFunction)
        );
        assert_eq!(
            b.answer(&Request::WriteMultipleCoils(6, vec![true, true].into())),
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
}
