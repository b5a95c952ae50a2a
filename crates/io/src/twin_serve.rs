//! A digital twin as a Modbus TCP device (`cetratus twin serve`): the plant in a process of its
//! own, which a PLC drives over the network as it would drive the machine (virtual
//! commissioning).
//!
//! Its sensors are discrete inputs and its actuators coils, at the addresses that the example
//! program declares for them ([`TwinMap::for_example`]), so that the unchanged program runs
//! against it through `examples/<twin>/io-modbus.toml`. The twin steps in real time, every
//! millisecond, under the coils last written.

use std::fmt::Write as _;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use cetratus_twin::{Plant, Twin, TwinKind};
use serde::Deserialize;

use crate::address::{AddressError, IecAddress, Table};
use crate::bank::{lock, Bank, BankCounters, BankServer, ServeOptions, WriteFrom};
use crate::IoError;

const VERNADAT: &str = include_str!("../../../examples/vernadat/vernadat.toml");
const FESTO: &str = include_str!("../../../examples/festo/festo.toml");

/// Where each of a twin's signals is on the Modbus device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TwinMap {
    /// Each plant input (sensor): its name, IEC address and discrete input number.
    pub inputs: Vec<(String, IecAddress, u16)>,
    /// Each plant output (actuator): its name, IEC address and coil number.
    pub outputs: Vec<(String, IecAddress, u16)>,
}

#[derive(Deserialize)]
struct Decls {
    #[serde(default)]
    input: Vec<Decl>,
    #[serde(default)]
    output: Vec<Decl>,
}

#[derive(Deserialize)]
struct Decl {
    name: String,
    address: Option<String>,
}

impl TwinMap {
    /// The map of the example program of `kind`: each twin signal at the address the program
    /// declares for the signal of the same name.
    pub fn for_example(kind: TwinKind, twin: &Twin) -> Result<TwinMap, IoError> {
        let text = match kind {
            TwinKind::Vernadat => VERNADAT,
            TwinKind::Festo => FESTO,
        };
        let decls: Decls = toml::from_str(text).map_err(|e| IoError::Config {
            at: format!("the embedded {kind} example"),
            message: e.message().to_string(),
        })?;
        let find = |list: &[Decl],
                    name: &str,
                    table: Table|
         -> Result<(String, IecAddress, u16), IoError> {
            let d = list
                .iter()
                .find(|d| d.name == name)
                .ok_or_else(|| IoError::Unmapped {
                    signal: name.to_string(),
                    why: format!("the {kind} example program does not declare it"),
                })?;
            let text = d.address.as_deref().ok_or_else(|| IoError::Unmapped {
                signal: name.to_string(),
                why: "the example program gives it no address".into(),
            })?;
            let a: IecAddress = text.parse().map_err(|e: AddressError| IoError::Unmapped {
                signal: name.to_string(),
                why: e.to_string(),
            })?;
            let (t, n) = a.default_location();
            if t != table {
                return Err(IoError::Unmapped {
                    signal: name.to_string(),
                    why: format!("{a} is not a {}", table.name()),
                });
            }
            Ok((name.to_string(), a, n as u16))
        };
        Ok(TwinMap {
            inputs: twin
                .input_names()
                .iter()
                .map(|n| find(&decls.input, n, Table::DiscreteInputs))
                .collect::<Result<_, _>>()?,
            outputs: twin
                .output_names()
                .iter()
                .map(|n| find(&decls.output, n, Table::Coils))
                .collect::<Result<_, _>>()?,
        })
    }

    /// The map as a table for people (`--print-map`).
    pub fn print(&self) -> String {
        let mut s = String::from("signal            address   Modbus\n");
        for (name, a, n) in &self.inputs {
            let _ = writeln!(s, "{name:<17} {:<9} discrete input {n}", a.to_string());
        }
        for (name, a, n) in &self.outputs {
            let _ = writeln!(s, "{name:<17} {:<9} coil {n}", a.to_string());
        }
        s
    }
}

/// What a served twin did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ServeReport {
    /// The twin's name.
    pub twin: String,
    /// Seconds of twin time.
    pub seconds: f64,
    /// Parts finished (good parts for the Festo station).
    pub parts_finished: u64,
    /// Physical faults seen (kept and only counted).
    pub twin_faults: u64,
    /// Their descriptions.
    pub faults: Vec<String>,
    /// The twin's counters.
    pub counters: serde_json::Value,
    /// What the Modbus server did.
    pub modbus: BankCounters,
}

/// Serves `twin` on `listen` until `until_us` of twin time or `stop`; `on_listen` is told the
/// address once the server listens. Twin time starts at the first request a client makes.
pub fn serve(
    mut twin: Twin,
    map: &TwinMap,
    listen: SocketAddr,
    until_us: u64,
    stop: &AtomicBool,
    on_listen: impl FnOnce(SocketAddr),
) -> Result<ServeReport, IoError> {
    let size = |list: &[(String, IecAddress, u16)]| {
        list.iter().map(|x| usize::from(x.2) + 1).max().unwrap_or(0)
    };
    let bank = Arc::new(Mutex::new(Bank {
        discrete_inputs: vec![false; size(&map.inputs)],
        coils: vec![false; size(&map.outputs)],
        ..Bank::default()
    }));
    let server = BankServer::start(
        listen,
        bank.clone(),
        ServeOptions {
            unit: 1,
            max_connections: 16,
            idle_timeout: crate::bank::DEFAULT_IDLE_TIMEOUT,
            write_from: WriteFrom::Anyone,
        },
    )?;
    on_listen(server.addr);
    let mut outputs = vec![false; map.outputs.len()];
    let mut inputs = vec![false; map.inputs.len()];
    // The plant's clock starts with its controller's first request: a twin that ran ahead of a
    // PLC still starting would not be the plant that PLC meets. Until then it shows its
    // initial sensors.
    twin.inputs(&mut inputs);
    {
        let mut b = lock(&bank);
        for (v, (_, _, n)) in inputs.iter().zip(&map.inputs) {
            b.discrete_inputs[usize::from(*n)] = *v;
        }
    }
    while lock(&bank).counters.requests == 0 && !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(1));
    }
    let start = Instant::now();
    let mut now_us = 0;
    while now_us < until_us && !stop.load(Ordering::Relaxed) {
        {
            let b = lock(&bank);
            for (o, (_, _, n)) in outputs.iter_mut().zip(&map.outputs) {
                *o = b.coils[usize::from(*n)];
            }
        }
        twin.step(now_us, &outputs);
        twin.inputs(&mut inputs);
        {
            let mut b = lock(&bank);
            for (v, (_, _, n)) in inputs.iter().zip(&map.inputs) {
                b.discrete_inputs[usize::from(*n)] = *v;
            }
        }
        std::thread::sleep(Duration::from_millis(1));
        now_us = start.elapsed().as_micros() as u64;
    }
    let modbus = lock(&bank).counters;
    server.stop();
    let counters = twin.counters();
    Ok(ServeReport {
        twin: twin.name().to_string(),
        seconds: now_us as f64 / 1e6,
        parts_finished: counters
            .get("parts_finished")
            .or_else(|| counters.get("parts_good"))
            .unwrap_or(0),
        twin_faults: twin.faults().len() as u64 + twin.faults_dropped(),
        faults: twin.faults().iter().map(|f| f.to_string()).collect(),
        counters: serde_json::to_value(counters).unwrap_or_default(),
        modbus,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use cetratus_twin::TwinSettings;

    #[test]
    fn each_twin_signal_gets_the_address_its_example_program_declares() {
        for kind in [TwinKind::Vernadat, TwinKind::Festo] {
            let twin = kind.configure(&TwinSettings::default()).unwrap();
            let map = TwinMap::for_example(kind, &twin).unwrap();
            assert_eq!(map.inputs.len(), twin.input_names().len());
            assert!(map.print().contains("discrete input 0"));
        }
        let twin = TwinKind::Vernadat
            .configure(&TwinSettings::default())
            .unwrap();
        let map = TwinMap::for_example(TwinKind::Vernadat, &twin).unwrap();
        assert_eq!(map.inputs[0], ("PE".into(), "%IX0.0".parse().unwrap(), 0));
        assert_eq!(map.outputs[2], ("DM1".into(), "%QX0.2".parse().unwrap(), 2));
    }
}
