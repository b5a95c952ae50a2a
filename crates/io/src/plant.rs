//! The I/O of a run: a digital twin in process, the field, or both, and the PLC's own Modbus
//! and OPC UA servers beside them (the process image for HMIs and SCADA).

use cetratus_program::{Signal, Value};
use cetratus_runtime::{Dispatcher, Provider};
use cetratus_twin::Twin;

use crate::field::FieldIo;
use crate::opcua::OpcUaServer;
use crate::server::ImageServer;
use crate::TwinDriver;

/// A twin, field I/O and the server, each optional, as one [`Provider`] and [`Dispatcher`]:
/// inputs from the twin, then the field devices, then what HMIs wrote.
pub struct PlantIo {
    twin: Option<TwinDriver<Twin>>,
    field: Option<FieldIo>,
    server: Option<ImageServer>,
    opcua: Option<OpcUaServer>,
}

impl PlantIo {
    /// The I/O of a run; `None` when it has no twin, no field I/O and no server.
    pub fn new(
        twin: Option<TwinDriver<Twin>>,
        field: Option<FieldIo>,
        server: Option<ImageServer>,
    ) -> Option<PlantIo> {
        PlantIo::with_servers(twin, field, server, None)
    }

    /// The I/O of a run with the PLC's OPC UA server too (whose clients' inputs come after the
    /// rest); `None` when it has nothing at all.
    pub fn with_servers(
        twin: Option<TwinDriver<Twin>>,
        field: Option<FieldIo>,
        server: Option<ImageServer>,
        opcua: Option<OpcUaServer>,
    ) -> Option<PlantIo> {
        (twin.is_some() || field.is_some() || server.is_some() || opcua.is_some()).then_some(
            PlantIo {
                twin,
                field,
                server,
                opcua,
            },
        )
    }

    /// The PLC's OPC UA server, when the run has one.
    pub fn opcua(&self) -> Option<&OpcUaServer> {
        self.opcua.as_ref()
    }

    /// The PLC's OPC UA server, to stop it.
    pub fn opcua_mut(&mut self) -> Option<&mut OpcUaServer> {
        self.opcua.as_mut()
    }

    /// The PLC's Modbus server, when the run has one.
    pub fn server(&self) -> Option<&ImageServer> {
        self.server.as_ref()
    }

    /// The twin driver, when the run has a twin.
    pub fn twin(&self) -> Option<&TwinDriver<Twin>> {
        self.twin.as_ref()
    }

    /// The twin driver, to press a button.
    pub fn twin_mut(&mut self) -> Option<&mut TwinDriver<Twin>> {
        self.twin.as_mut()
    }

    /// The field I/O, when the run has some.
    pub fn field(&self) -> Option<&FieldIo> {
        self.field.as_ref()
    }

    /// The field I/O, to stop it.
    pub fn field_mut(&mut self) -> Option<&mut FieldIo> {
        self.field.as_mut()
    }
}

impl Provider for PlantIo {
    fn io_map_grew(&mut self, inputs: &[Signal], outputs: &[Signal]) {
        // Only the field serves new signals (its admission refuses the others); the Modbus
        // server and the OPC UA server show them from then on.
        if let Some(f) = self.field.as_mut() {
            f.io_map_grew(inputs, outputs);
            if let Some(s) = self.server.as_mut() {
                s.grow(f.map());
            }
        }
        if let Some(o) = self.opcua.as_mut() {
            o.io_map_grew(inputs, outputs);
        }
    }

    fn read_inputs(&mut self, now_us: u64, inputs: &mut [Value]) {
        if let Some(t) = self.twin.as_mut() {
            t.read_inputs(now_us, inputs);
        }
        if let Some(f) = self.field.as_mut() {
            f.read_inputs(now_us, inputs);
        }
        if let Some(s) = self.server.as_mut() {
            s.read_inputs(now_us, inputs);
        }
        if let Some(o) = self.opcua.as_mut() {
            o.read_inputs(now_us, inputs);
        }
    }
}

impl Dispatcher for PlantIo {
    fn safe_outputs(&mut self, safe: &[Value]) {
        if let Some(f) = self.field.as_mut() {
            f.safe_outputs(safe);
        }
        if let Some(o) = self.opcua.as_mut() {
            o.safe_outputs(safe);
        }
    }

    fn write_outputs(&mut self, now_us: u64, outputs: &[Value]) {
        // The PLC's I/O has one safe state: a source that faults (a field device or the OPC UA
        // server's clients, stale under `fault`) takes the other one into it.
        if let (Some(f), Some(o)) = (self.field.as_mut(), self.opcua.as_mut()) {
            if o.faulted() && !f.in_safe_state() {
                f.enter_safe_state();
            }
            if f.faulted() && !o.in_safe_state() {
                o.enter_safe_state();
            }
        }
        if let Some(t) = self.twin.as_mut() {
            t.write_outputs(now_us, outputs);
        }
        if let Some(f) = self.field.as_mut() {
            f.write_outputs(now_us, outputs);
        }
        if let Some(s) = self.server.as_mut() {
            s.write_outputs(now_us, outputs);
        }
        if let Some(o) = self.opcua.as_mut() {
            o.write_outputs(now_us, outputs);
        }
    }
}
