//! I/O drivers behind the runtime's [`Provider`] and [`Dispatcher`] traits.
//!
//! * [`TwinDriver`] connects a program's signals, by name, to a digital twin's signals.
//! * [`config`] is the node's I/O configuration (docs/io.md); [`address`] the IEC addresses and
//!   their default Modbus map; [`map`] binds a program's signals to devices.
//! * [`server`] is the PLC's own Modbus server, over [`bank`].

pub mod address;
pub mod bank;
pub mod config;
pub mod field;
pub mod map;
mod modbus;
#[cfg(feature = "opcua")]
pub mod opcua;
/// A build without the `opcua` feature still reads an I/O configuration's `[opcua]` section, so
/// that the node can refuse it by name rather than call it an unknown key.
#[cfg(not(feature = "opcua"))]
pub mod opcua {
    pub mod config;
    pub use config::OpcUaConfig;
}
pub mod plant;
pub mod replay;
pub mod server;
pub mod twin_serve;

use cetratus_program::{Signal, Type, Value};
use cetratus_runtime::{Dispatcher, Provider};
use cetratus_twin::Plant;

/// What can go wrong when connecting a program to a driver.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The program reads an input the plant does not have.
    #[error("the program reads input `{signal}` but the {plant} twin has no such signal; its inputs are {available}")]
    UnknownInput {
        /// The signal.
        signal: String,
        /// The plant's name.
        plant: String,
        /// The plant's inputs, comma-separated.
        available: String,
    },
    /// The program drives an output the plant does not have.
    #[error("the program drives output `{signal}` but the {plant} twin has no such signal; its outputs are {available}")]
    UnknownOutput {
        /// The signal.
        signal: String,
        /// The plant's name.
        plant: String,
        /// The plant's outputs, comma-separated.
        available: String,
    },
    /// The I/O configuration is wrong at a place in its file.
    #[error("{at}: {message}")]
    Config {
        /// `file:line:column`.
        at: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// The I/O configuration could not be read.
    #[error("cannot read the I/O configuration {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A program signal does not fit the I/O configuration.
    #[error("signal `{signal}`: {why}")]
    Unmapped {
        /// The signal.
        signal: String,
        /// Why, and what to do.
        why: String,
    },
    /// A server could not listen.
    #[error("cannot listen on {addr}: {reason}; choose another address or port")]
    Listen {
        /// The address.
        addr: String,
        /// The OS error.
        reason: String,
    },
    /// A certificate of an OPC UA trust list, or the list's directory, cannot be used.
    #[error("{path}: {reason}")]
    Pki {
        /// The file or directory.
        path: String,
        /// What is wrong, and what to do.
        reason: String,
    },
    /// An OPC UA endpoint URL cannot be used.
    #[error("`{url}` {reason}; write e.g. \"opc.tcp://127.0.0.1:14840\"")]
    OpcUaUrl {
        /// The URL as given.
        url: String,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The OPC UA server could not be built as configured.
    #[error("the OPC UA server cannot start: {0}")]
    OpcUa(String),
    /// An I/O thread could not be started.
    #[error("cannot start an I/O thread: {0}")]
    Thread(String),
    /// A simulated signal is not boolean.
    #[error(
        "signal `{signal}` is declared {ty} but the twin's signals are bool; declare it as bool"
    )]
    NotBool {
        /// The signal.
        signal: String,
        /// Its declared type.
        ty: &'static str,
    },
}

/// A digital twin seen as the plant's I/O: it provides the inputs and takes the outputs.
///
/// `write_outputs(now)` applies the outputs at `now`; `read_inputs(now)` advances the plant to `now`
/// under the outputs last written, then reads it.
#[derive(Debug)]
pub struct TwinDriver<P: Plant> {
    plant: P,
    // For each program input, the plant input it reads.
    inputs_from: Vec<usize>,
    // For each plant output, the program output that drives it.
    outputs_from: Vec<Option<usize>>,
    plant_inputs: Vec<bool>,
    plant_outputs: Vec<bool>,
}

impl<P: Plant> TwinDriver<P> {
    /// Connects `plant` to a program's inputs and outputs by name.
    pub fn new(plant: P, inputs: &[Signal], outputs: &[Signal]) -> Result<Self, IoError> {
        let pin = plant.input_names().to_vec();
        let pout = plant.output_names().to_vec();
        for s in inputs.iter().chain(outputs) {
            if s.ty != Type::Bool {
                return Err(IoError::NotBool {
                    signal: s.name.clone(),
                    ty: s.ty.name(),
                });
            }
        }
        let inputs_from = inputs
            .iter()
            .map(|s| {
                pin.iter()
                    .position(|n| *n == s.name)
                    .ok_or_else(|| IoError::UnknownInput {
                        signal: s.name.clone(),
                        plant: plant.name().to_string(),
                        available: pin.join(", "),
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        for s in outputs {
            if !pout.contains(&s.name.as_str()) {
                return Err(IoError::UnknownOutput {
                    signal: s.name.clone(),
                    plant: plant.name().to_string(),
                    available: pout.join(", "),
                });
            }
        }
        let outputs_from = pout
            .iter()
            .map(|n| outputs.iter().position(|s| s.name == *n))
            .collect();
        Ok(TwinDriver {
            plant_inputs: vec![false; pin.len()],
            plant_outputs: vec![false; pout.len()],
            plant,
            inputs_from,
            outputs_from,
        })
    }

    /// The plant.
    pub fn plant(&self) -> &P {
        &self.plant
    }

    /// The plant, for pressing buttons or forking.
    pub fn plant_mut(&mut self) -> &mut P {
        &mut self.plant
    }
}

impl<P: Plant> Provider for TwinDriver<P> {
    fn read_inputs(&mut self, now_us: u64, inputs: &mut [Value]) {
        self.plant.step(now_us, &self.plant_outputs);
        self.plant.inputs(&mut self.plant_inputs);
        for (v, &i) in inputs.iter_mut().zip(&self.inputs_from) {
            *v = Value::Bool(self.plant_inputs[i]);
        }
    }
}

impl<P: Plant> Dispatcher for TwinDriver<P> {
    fn write_outputs(&mut self, now_us: u64, outputs: &[Value]) {
        for (o, from) in self.plant_outputs.iter_mut().zip(&self.outputs_from) {
            *o = from.is_some_and(|j| matches!(outputs.get(j), Some(Value::Bool(true))));
        }
        self.plant.step(now_us, &self.plant_outputs);
    }
}
