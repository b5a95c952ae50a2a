//! The I/O of a run: a digital twin in process, the field, or both (the twin as the plant, with
//! the process image served to SCADA beside it).

use cetratus_program::Value;
use cetratus_runtime::{Dispatcher, Provider};
use cetratus_twin::Twin;

use crate::field::FieldIo;
use crate::TwinDriver;

/// A twin, field I/O, or both, as one [`Provider`] and [`Dispatcher`].
pub struct PlantIo {
    twin: Option<TwinDriver<Twin>>,
    field: Option<FieldIo>,
}

impl PlantIo {
    /// The I/O of a run; `None` when it has neither a twin nor field I/O.
    pub fn new(twin: Option<TwinDriver<Twin>>, field: Option<FieldIo>) -> Option<PlantIo> {
        (twin.is_some() || field.is_some()).then_some(PlantIo { twin, field })
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
    fn read_inputs(&mut self, now_us: u64, inputs: &mut [Value]) {
        if let Some(t) = self.twin.as_mut() {
            t.read_inputs(now_us, inputs);
        }
        if let Some(f) = self.field.as_mut() {
            f.read_inputs(now_us, inputs);
        }
    }
}

impl Dispatcher for PlantIo {
    fn write_outputs(&mut self, now_us: u64, outputs: &[Value]) {
        if let Some(t) = self.twin.as_mut() {
            t.write_outputs(now_us, outputs);
        }
        if let Some(f) = self.field.as_mut() {
            f.write_outputs(now_us, outputs);
        }
    }
}
