//! The I/O of a node: a list of drivers behind one trait ([`PlantDriver`]): a digital twin in
//! process, the field devices with the PLC's Modbus server of their process image, and the PLC's
//! OPC UA server. A new driver implements the trait and is pushed on the list; nothing else
//! names it.

use std::sync::Arc;

use cetratus_program::{Signal, Value};
use cetratus_runtime::{Dispatcher, Plc, Provider, SharedAdmission};
use cetratus_twin::{Plant, Twin};

use crate::bank::BankCounters;
use crate::field::{DeviceStatus, FieldIo};
use crate::server::ImageServer;
use crate::TwinDriver;

/// Reads the quality of a node's input sources from another thread than the scan's (the MQTT
/// publisher's, for `exec_info`).
pub type QualityReader = Arc<dyn Fn() -> Vec<DeviceStatus> + Send + Sync>;

/// What runs on the scan thread after each cycle to show the PLC's state to a driver's clients
/// (the Modbus status registers, the OPC UA nodes); it must neither block nor allocate.
pub type CycleObserver = Box<dyn FnMut(&Plc) + Send>;

/// One driver of a node's I/O. Its [`Provider`] and [`Dispatcher`] faces run on the scan thread
/// each cycle, in the order the drivers are listed; the rest are hooks with defaults, called
/// when the node is assembled, reported on or stopped.
pub trait PlantDriver: Provider + Dispatcher + Send {
    /// Whether the driver put the PLC's I/O in its safe state on its own (its inputs went stale
    /// under the `fault` policy): the node's other drivers then follow it there.
    fn faulted(&self) -> bool {
        false
    }

    /// Whether the driver shows its safe state (the default, for a driver without one: yes).
    fn in_safe_state(&self) -> bool {
        true
    }

    /// Takes the driver to the PLC's safe state, for another driver's fault.
    fn enter_safe_state(&mut self) {}

    /// Stops the driver at the end of a run: the field gets its safe values.
    fn stop(&mut self) {}

    /// The simulated plant, when the driver is a twin: the node forks it to validate updates.
    fn plant(&self) -> Option<&Twin> {
        None
    }

    /// The simulated plant, to press its buttons.
    fn plant_mut(&mut self) -> Option<&mut Twin> {
        None
    }

    /// What shows the PLC's state to the driver's clients after each cycle, if anything.
    fn observer(&self) -> Option<CycleObserver> {
        None
    }

    /// The quality of the inputs the driver provides, readable off the scan thread.
    fn quality_reader(&self) -> Option<QualityReader> {
        None
    }

    /// What lets a live update use new signals on channels this driver serves.
    fn admission(&self) -> Option<SharedAdmission> {
        None
    }

    /// Adds the driver's end-of-run figures to `report`.
    fn report(&self, _report: &mut PlantReport) {}
}

/// What the plant says at the end of a run.
#[derive(Debug, Default)]
pub struct PlantReport {
    /// Parts finished (good parts for the Festo station); 0 without a twin.
    pub parts_finished: u64,
    /// Physical faults the twin saw.
    pub twin_faults: u64,
    /// Their descriptions, and the safe states the I/O went to.
    pub faults: Vec<String>,
    /// The twin's counters, by name.
    pub counters: std::collections::BTreeMap<String, u64>,
    /// Every source of inputs with a quality: the field devices, then the OPC UA clients.
    pub io: Option<Vec<DeviceStatus>>,
    /// What the PLC's Modbus server did.
    pub server: Option<BankCounters>,
    /// What the PLC's OPC UA server did.
    #[cfg(feature = "opcua")]
    pub opcua: Option<crate::opcua::OpcUaCounters>,
}

impl PlantReport {
    /// Adds the figures of one input source.
    pub fn add_source(&mut self, status: impl IntoIterator<Item = DeviceStatus>) {
        self.io.get_or_insert_with(Vec::new).extend(status);
    }
}

/// A node's drivers as one [`Provider`] and [`Dispatcher`]: inputs from each driver in turn (a
/// later one overwrites what an earlier one read), outputs to all of them.
pub struct PlantIo {
    drivers: Vec<Box<dyn PlantDriver>>,
}

impl PlantIo {
    /// The I/O of a node; `None` when it has no driver at all.
    pub fn new(drivers: Vec<Box<dyn PlantDriver>>) -> Option<PlantIo> {
        (!drivers.is_empty()).then_some(PlantIo { drivers })
    }

    /// The drivers, in order.
    pub fn drivers(&self) -> &[Box<dyn PlantDriver>] {
        &self.drivers
    }

    /// The simulated plant, when a driver is a twin.
    pub fn plant(&self) -> Option<&Twin> {
        self.drivers.iter().find_map(|d| d.plant())
    }

    /// The simulated plant, to press its buttons.
    pub fn plant_mut(&mut self) -> Option<&mut Twin> {
        self.drivers.iter_mut().find_map(|d| d.plant_mut())
    }

    /// Every driver's observer, as one, or `None` when no driver has one.
    pub fn observer(&self) -> Option<CycleObserver> {
        let mut all: Vec<CycleObserver> =
            self.drivers.iter().filter_map(|d| d.observer()).collect();
        (!all.is_empty()).then(|| -> CycleObserver {
            Box::new(move |plc: &Plc| all.iter_mut().for_each(|o| o(plc)))
        })
    }

    /// Every driver's quality reader, as one, or `None` when no driver provides inputs with a
    /// quality.
    pub fn quality_reader(&self) -> Option<QualityReader> {
        let all: Vec<QualityReader> = self
            .drivers
            .iter()
            .filter_map(|d| d.quality_reader())
            .collect();
        (!all.is_empty())
            .then(|| -> QualityReader { Arc::new(move || all.iter().flat_map(|r| r()).collect()) })
    }

    /// The admission of the driver that serves new signals (the field's), if any.
    pub fn admission(&self) -> Option<SharedAdmission> {
        self.drivers.iter().find_map(|d| d.admission())
    }

    /// Stops every driver, in order.
    pub fn stop(&mut self) {
        self.drivers.iter_mut().for_each(|d| d.stop());
    }

    /// Every driver's end-of-run figures.
    pub fn report(&self) -> PlantReport {
        let mut r = PlantReport::default();
        self.drivers.iter().for_each(|d| d.report(&mut r));
        r
    }
}

impl Provider for PlantIo {
    fn io_map_grew(&mut self, inputs: &[Signal], outputs: &[Signal]) {
        self.drivers
            .iter_mut()
            .for_each(|d| d.io_map_grew(inputs, outputs));
    }

    fn read_inputs(&mut self, now_us: u64, inputs: &mut [Value]) {
        self.drivers
            .iter_mut()
            .for_each(|d| d.read_inputs(now_us, inputs));
    }
}

impl Dispatcher for PlantIo {
    fn safe_outputs(&mut self, safe: &[Value]) {
        self.drivers.iter_mut().for_each(|d| d.safe_outputs(safe));
    }

    fn write_outputs(&mut self, now_us: u64, outputs: &[Value]) {
        // The PLC's I/O has one safe state: a driver that faults (a field device or the OPC UA
        // server's clients, stale under `fault`) takes the others into it.
        if self.drivers.iter().any(|d| d.faulted()) {
            for d in self.drivers.iter_mut().filter(|d| !d.in_safe_state()) {
                d.enter_safe_state();
            }
        }
        self.drivers
            .iter_mut()
            .for_each(|d| d.write_outputs(now_us, outputs));
    }
}

impl PlantDriver for TwinDriver<Twin> {
    fn plant(&self) -> Option<&Twin> {
        Some(TwinDriver::plant(self))
    }

    fn plant_mut(&mut self) -> Option<&mut Twin> {
        Some(TwinDriver::plant_mut(self))
    }

    fn report(&self, r: &mut PlantReport) {
        let plant = TwinDriver::plant(self);
        r.faults
            .extend(plant.faults().iter().map(|f| f.to_string()));
        let counters = plant.counters();
        r.parts_finished = counters
            .get("parts_finished")
            .or_else(|| counters.get("parts_good"))
            .unwrap_or(0);
        r.twin_faults = plant.faults().len() as u64 + plant.faults_dropped();
        r.counters = counters
            .iter()
            .map(|c| (c.name.to_string(), c.value))
            .collect();
    }
}

/// The field devices and the PLC's Modbus server of their process image: one driver, because
/// the server shows the field's map and grows with it when a live update adds signals. Either
/// may be absent (a server with no device, devices with no server).
pub struct Field {
    devices: Option<FieldIo>,
    server: Option<ImageServer>,
}

impl Field {
    /// The field driver; `None` when it has neither devices nor a server.
    pub fn new(devices: Option<FieldIo>, server: Option<ImageServer>) -> Option<Field> {
        (devices.is_some() || server.is_some()).then_some(Field { devices, server })
    }
}

impl Provider for Field {
    fn io_map_grew(&mut self, inputs: &[Signal], outputs: &[Signal]) {
        // Only the devices serve new signals (their admission refuses the others); the server
        // shows them from then on.
        if let Some(f) = self.devices.as_mut() {
            f.io_map_grew(inputs, outputs);
            if let Some(s) = self.server.as_mut() {
                s.grow(f.map());
            }
        }
    }

    fn read_inputs(&mut self, now_us: u64, inputs: &mut [Value]) {
        if let Some(f) = self.devices.as_mut() {
            f.read_inputs(now_us, inputs);
        }
        if let Some(s) = self.server.as_mut() {
            s.read_inputs(now_us, inputs);
        }
    }
}

impl Dispatcher for Field {
    fn safe_outputs(&mut self, safe: &[Value]) {
        if let Some(f) = self.devices.as_mut() {
            f.safe_outputs(safe);
        }
    }

    fn write_outputs(&mut self, now_us: u64, outputs: &[Value]) {
        if let Some(f) = self.devices.as_mut() {
            f.write_outputs(now_us, outputs);
        }
        if let Some(s) = self.server.as_mut() {
            s.write_outputs(now_us, outputs);
        }
    }
}

impl PlantDriver for Field {
    fn faulted(&self) -> bool {
        self.devices.as_ref().is_some_and(|f| f.faulted())
    }

    fn in_safe_state(&self) -> bool {
        self.devices.as_ref().is_none_or(|f| f.in_safe_state())
    }

    fn enter_safe_state(&mut self) {
        if let Some(f) = self.devices.as_mut() {
            f.enter_safe_state();
        }
    }

    fn stop(&mut self) {
        if let Some(f) = self.devices.as_mut() {
            f.stop();
        }
    }

    fn observer(&self) -> Option<CycleObserver> {
        let mut board = self.server.as_ref()?.status_board();
        Some(Box::new(move |plc: &Plc| board.show(plc)))
    }

    fn quality_reader(&self) -> Option<QualityReader> {
        let reader = self.devices.as_ref()?.status_reader();
        Some(Arc::new(move || reader.read()))
    }

    fn admission(&self) -> Option<SharedAdmission> {
        let a: SharedAdmission = self.devices.as_ref()?.admission();
        Some(a)
    }

    fn report(&self, r: &mut PlantReport) {
        if let Some(f) = &self.devices {
            r.add_source(f.status());
            if f.faulted() {
                r.faults.push("field I/O: a device with the `fault` stale policy went silent; the PLC's I/O went to its safe state: safe inputs, and safe outputs on the field devices and the OPC UA Outputs nodes".into());
            }
        }
        r.server = self.server.as_ref().map(|s| s.counters());
    }
}

#[cfg(feature = "opcua")]
impl PlantDriver for crate::opcua::OpcUaServer {
    fn faulted(&self) -> bool {
        crate::opcua::OpcUaServer::faulted(self)
    }

    fn in_safe_state(&self) -> bool {
        crate::opcua::OpcUaServer::in_safe_state(self)
    }

    fn enter_safe_state(&mut self) {
        crate::opcua::OpcUaServer::enter_safe_state(self);
    }

    fn observer(&self) -> Option<CycleObserver> {
        let mut publisher = self.publisher();
        Some(Box::new(move |plc: &Plc| publisher.show(plc)))
    }

    fn quality_reader(&self) -> Option<QualityReader> {
        let reader = self.status_reader()?;
        Some(Arc::new(move || vec![reader()]))
    }

    fn report(&self, r: &mut PlantReport) {
        r.add_source(self.status());
        r.opcua = Some(self.counters());
        if crate::opcua::OpcUaServer::faulted(self) {
            r.faults.push("OPC UA inputs: no client wrote an input for `stale_after` cycles under the `fault` policy; the PLC's I/O went to its safe state: safe inputs, and safe outputs on the field devices and the Outputs nodes".into());
        }
    }
}
