//! `cetratus bench io`: what field I/O costs.
//!
//! * The Modbus round trip of one cycle, as a Cetratus I/O thread makes it with tokio-modbus: 64
//!   coils written (function 15), 16 holding registers written (16), 64 discrete inputs read (2)
//!   and 16 input registers read (4), one cycle every period, against a pymodbus device and
//!   against Cetratus's own Modbus server (`bank`, the server of `twin serve`).
//! * The scan latency of the Vernadat program on its twin with no field I/O, and with its
//!   outputs also written to the pymodbus device through the process image, in the same run: the
//!   two phases alternate in slices of [`SLICE_US`] (off, on, on, off, ...), each with its own
//!   histogram, so that both see the same host conditions. With `rt`, the scan thread has
//!   SCHED_FIFO, locked memory and a CPU of its own, as `cetratus run --rt` gives it, and the I/O
//!   thread keeps the normal policy on the other CPUs, as in a run.

use std::net::{SocketAddr, TcpStream};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use cetratus_io::bank::{Bank, BankServer, ServeOptions, WriteFrom};
use cetratus_io::config::IoConfig;
use cetratus_io::field::{DeviceStatus, FieldIo};
use cetratus_io::map::FieldMap;
use cetratus_io::plant::{Field, PlantDriver, PlantIo};
use cetratus_io::TwinDriver;
use cetratus_node::clock::MonotonicStopwatch;
use cetratus_node::periodic::run_periodic;
use cetratus_runtime::{Container, CycleFigures, LoopTiming, ScanCycle};
use cetratus_twin::TwinKind;
use serde::Serialize;
use tokio_modbus::client::sync::{Reader, Writer};

use crate::harness::BenchError;
use crate::program::vernadat_program;

/// The pymodbus peer of the tests, embedded so that the bench runs from any directory.
const MODBUS_PEER: &str = include_str!("../../scripts/modbus_peer.py");

/// Coils and registers exchanged per cycle.
pub const COILS: usize = 64;
/// Registers written and read per cycle.
pub const REGISTERS: usize = 16;
/// The length of one slice of a latency phase: off and on alternate in slices this long.
pub const SLICE_US: u64 = 2_000_000;

/// Round trips of one peer.
#[derive(Clone, Debug, Serialize)]
pub struct RoundTrip {
    /// Who answered.
    pub peer: String,
    /// Cycles measured.
    pub cycles: u64,
    /// Cycles in which a request failed (not measured).
    pub failed: u64,
    /// Median of the four requests of a cycle, in µs.
    pub p50_us: f64,
    /// 99th percentile, in µs.
    pub p99_us: f64,
    /// Largest, in µs.
    pub max_us: f64,
}

/// Scan latency of one phase.
#[derive(Clone, Debug, Serialize)]
pub struct Latency {
    /// Cycles run.
    pub cycles: u64,
    /// Median latency (cycle start after its deadline), in µs.
    pub p50_us: f64,
    /// 99th percentile, in µs.
    pub p99_us: f64,
    /// Largest, in µs.
    pub max_us: f64,
    /// Cycles that overran their period.
    pub overruns: u64,
}

impl From<&CycleFigures> for Latency {
    fn from(f: &CycleFigures) -> Self {
        Latency {
            cycles: f.cycles,
            p50_us: f.latency.p50_ns as f64 / 1e3,
            p99_us: f.latency.p99_ns as f64 / 1e3,
            max_us: f.latency.max_ns as f64 / 1e3,
            overruns: f.overruns,
        }
    }
}

/// Everything `bench io` measures.
#[derive(Clone, Debug, Serialize)]
pub struct IoFigures {
    /// The cycle period, in µs.
    pub period_us: u64,
    /// Against pymodbus, then against Cetratus's own server.
    pub round_trips: Vec<RoundTrip>,
    /// The scan without field I/O.
    pub latency_io_off: Latency,
    /// The scan with its outputs also on the pymodbus device.
    pub latency_io_on: Latency,
    /// The budget of the I/O: p99 on at most 1.1 × p99 off + 20 µs.
    pub budget_p99_us: f64,
    /// Whether p99 with I/O kept within it.
    pub within_budget: bool,
    /// The slices in which off and on alternate, in µs.
    pub slice_us: u64,
    /// What `--rt` obtained, or `not requested`.
    pub rt: String,
    /// What the device's I/O thread did in the phase with I/O (reads, writes, errors).
    pub device: Option<DeviceStatus>,
}

/// A file removed on drop.
struct TempScript(PathBuf);

impl Drop for TempScript {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// A pymodbus device on a free loopback port, stopped on drop.
struct Pymodbus {
    child: Child,
    addr: SocketAddr,
    _script: TempScript,
}

impl Drop for Pymodbus {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn free_addr() -> Result<SocketAddr, BenchError> {
    let l =
        std::net::TcpListener::bind("127.0.0.1:0").map_err(|e| BenchError::from(e.to_string()))?;
    l.local_addr().map_err(|e| BenchError::from(e.to_string()))
}

fn pymodbus() -> Result<Pymodbus, BenchError> {
    let script = TempScript(std::env::temp_dir().join(format!(
        "cetratus-bench-modbus-peer-{}.py",
        std::process::id()
    )));
    std::fs::write(&script.0, MODBUS_PEER).map_err(|e| BenchError::from(e.to_string()))?;
    let addr = free_addr()?;
    let child = Command::new("python3")
        .arg(&script.0)
        .args(["device", &addr.port().to_string(), "--size", "128"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| {
            BenchError::from(format!("cannot start python3 for the pymodbus device: {e}"))
        })?;
    let p = Pymodbus {
        child,
        addr,
        _script: script,
    };
    let end = Instant::now() + Duration::from_secs(30);
    while TcpStream::connect(addr).is_err() {
        if Instant::now() > end {
            return Err(BenchError::from(
                "the pymodbus device did not listen within 30 s; install it with `python3 -m pip install pymodbus`",
            ));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    Ok(p)
}

fn percentile(sorted: &[u64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i] as f64 / 1e3
}

/// One cycle's exchange every `period` for `for_`, against `addr`.
fn round_trips(
    peer: &str,
    addr: SocketAddr,
    period: Duration,
    for_: Duration,
) -> Result<RoundTrip, BenchError> {
    let mut ctx = tokio_modbus::client::sync::tcp::connect_slave(addr, tokio_modbus::Slave(1))
        .map_err(|e| BenchError::from(format!("cannot connect to {peer} at {addr}: {e}")))?;
    ctx.set_timeout(Duration::from_secs(1));
    let mut took = Vec::with_capacity((for_.as_micros() / period.as_micros().max(1)) as usize);
    let mut failed = 0;
    let (mut coils, mut regs) = ([false; COILS], [0u16; REGISTERS]);
    let origin = Instant::now();
    let mut k: u32 = 0;
    while origin.elapsed() < for_ {
        let planned = origin + period * k;
        if let Some(wait) = planned.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        k += 1;
        // New values every cycle, as outputs that change.
        coils[k as usize % COILS] ^= true;
        regs[k as usize % REGISTERS] = k as u16;
        let t0 = Instant::now();
        let ok = matches!(ctx.write_multiple_coils(0, &coils), Ok(Ok(())))
            && matches!(ctx.write_multiple_registers(0, &regs), Ok(Ok(())))
            && matches!(ctx.read_discrete_inputs(0, COILS as u16), Ok(Ok(v)) if v.len() >= COILS)
            && matches!(ctx.read_input_registers(0, REGISTERS as u16), Ok(Ok(v)) if v.len() == REGISTERS);
        if ok {
            took.push(t0.elapsed().as_nanos() as u64);
        } else {
            failed += 1;
        }
    }
    took.sort_unstable();
    Ok(RoundTrip {
        peer: peer.into(),
        cycles: took.len() as u64,
        failed,
        p50_us: percentile(&took, 0.5),
        p99_us: percentile(&took, 0.99),
        max_us: took.last().map_or(0.0, |&n| n as f64 / 1e3),
    })
}

/// One latency phase: the Vernadat program on its own twin, with or without field I/O.
struct Phase {
    cycle: ScanCycle,
    io: PlantIo,
    timing: LoopTiming,
    // Program time run so far: each slice goes on from there.
    reached_us: u64,
}

impl Phase {
    fn new(period_us: u64, field: Option<FieldIo>) -> Result<Phase, BenchError> {
        let program = vernadat_program();
        let twin = TwinKind::Vernadat.build(1);
        let driver = TwinDriver::new(twin, program.inputs(), program.outputs())
            .map_err(|e| BenchError::from(e.to_string()))?;
        let mut drivers: Vec<Box<dyn PlantDriver>> = vec![Box::new(driver)];
        if let Some(f) = Field::new(field, None) {
            drivers.push(Box::new(f));
        }
        let io = PlantIo::new(drivers).ok_or_else(|| BenchError::from("no I/O"))?;
        let mut cycle = ScanCycle::new(Container::new(program, 0), MonotonicStopwatch::boxed());
        cycle.set_period_us(period_us);
        Ok(Phase {
            cycle,
            io,
            timing: LoopTiming::default(),
            reached_us: 0,
        })
    }

    /// Runs `slice_us` more of the phase in real time.
    fn slice(&mut self, period_us: u64, slice_us: u64, stop: &AtomicBool) {
        let base = self.reached_us;
        let (cycle, io) = (&mut self.cycle, &mut self.io);
        let reached = run_periodic(
            period_us,
            slice_us,
            1.0,
            stop,
            &mut self.timing,
            |now, _| cycle.cycle(base + now, io).is_ok(),
        );
        self.reached_us += reached.max(period_us);
    }

    fn figures(mut self) -> CycleFigures {
        self.cycle.set_timing(std::mem::take(&mut self.timing));
        self.io.stop();
        self.cycle.figures()
    }
}

/// The field I/O of the phase with I/O: the Vernadat outputs on the device's coils.
fn field_io(program_period_us: u64, device: SocketAddr) -> Result<FieldIo, BenchError> {
    let program = vernadat_program();
    let config = IoConfig::parse(
        "bench-io.toml",
        &format!("[[device]]\nname = \"bench\"\ntransport = \"modbus-tcp\"\naddress = \"{device}\"\nserves = [{{ from = \"%QX0.0\", to = \"%QX0.7\" }}]\n"),
    )
    .map_err(|e| BenchError::from(e.to_string()))?;
    let map = FieldMap::bind(&config, program.inputs(), program.outputs(), true)
        .map_err(|e| BenchError::from(e.to_string()))?;
    // The thread polls on its own only when no cycle wakes it: not while the other phase runs.
    let poll_us = program_period_us.max(4 * SLICE_US);
    FieldIo::start(&config, map, poll_us).map_err(|e| BenchError::from(e.to_string()))
}

/// Scan latency without field I/O and with it, `for_us` of each, in alternating slices.
fn scan_latency(
    period_us: u64,
    for_us: u64,
    device: SocketAddr,
    rt: bool,
) -> Result<(CycleFigures, CycleFigures, String, Option<DeviceStatus>), BenchError> {
    let mut off = Phase::new(period_us, None)?;
    let mut on = Phase::new(period_us, Some(field_io(period_us, device)?))?;
    // After the I/O thread started, as in `cetratus run --rt`: it stays off the scan's CPU.
    let rt = if rt {
        cetratus_node::rt::request(80).to_string()
    } else {
        "not requested".to_string()
    };
    let stop = AtomicBool::new(false);
    let mut round = 0u64;
    while off.reached_us < for_us || on.reached_us < for_us {
        let (first, second) = if round.is_multiple_of(2) {
            (&mut off, &mut on)
        } else {
            (&mut on, &mut off)
        };
        for p in [first, second] {
            let left = for_us.saturating_sub(p.reached_us);
            if left > 0 {
                p.slice(period_us, left.min(SLICE_US), &stop);
            }
        }
        round += 1;
    }
    let device = on.io.report().io.and_then(|all| all.into_iter().next());
    Ok((off.figures(), on.figures(), rt, device))
}

/// Runs every measurement of `bench io`: each round-trip series and each latency phase lasts
/// `for_us` of wall time (the two phases in alternating slices); `rt` as `cetratus run --rt`.
pub fn figures(period_us: u64, for_us: u64, rt: bool) -> Result<IoFigures, BenchError> {
    let period = Duration::from_micros(period_us.max(1));
    let for_ = Duration::from_micros(for_us);
    let device = pymodbus()?;
    let mut round = vec![round_trips("pymodbus", device.addr, period, for_)?];
    let bank = Bank {
        discrete_inputs: vec![false; 128],
        coils: vec![false; 128],
        input_registers: vec![0; 128],
        holding_registers: vec![0; 128],
        ..Bank::default()
    };
    let server = BankServer::start(
        SocketAddr::from(([127, 0, 0, 1], 0)),
        Arc::new(Mutex::new(bank)),
        ServeOptions {
            unit: 1,
            max_connections: 8,
            idle_timeout: cetratus_io::bank::DEFAULT_IDLE_TIMEOUT,
            write_from: WriteFrom::Anyone,
        },
    )
    .map_err(|e| BenchError::from(e.to_string()))?;
    round.push(round_trips("cetratus", server.addr, period, for_)?);
    server.stop();
    let (off, on, rt, status) = scan_latency(period_us, for_us, device.addr, rt)?;
    let (off, on) = (Latency::from(&off), Latency::from(&on));
    let budget = off.p99_us * 1.1 + 20.0;
    Ok(IoFigures {
        period_us,
        round_trips: round,
        within_budget: on.p99_us <= budget,
        budget_p99_us: budget,
        latency_io_off: off,
        latency_io_on: on,
        slice_us: SLICE_US,
        rt,
        device: status,
    })
}
