//! The plant of `cetratus run`: the twin, the field I/O (`--io`, or the local configuration's
//! `[io]`), or both, and the PLC's Modbus server when the I/O configuration has a `[server]`.

use std::path::Path;

use anyhow::{bail, Context};
use cetratus_io::bank::BankCounters;
use cetratus_io::config::IoConfig;
use cetratus_io::field::{DeviceStatus, FieldIo};
use cetratus_io::map::FieldMap;
use cetratus_io::plant::PlantIo;
use cetratus_io::server::ImageServer;
use cetratus_io::TwinDriver;
use cetratus_program::Program;
use cetratus_twin::{Plant, TwinKind, TwinSettings};

/// What the run is connected to.
pub struct Opened {
    /// The I/O.
    pub io: PlantIo,
    /// The twin, when there is one.
    pub kind: Option<TwinKind>,
}

/// Opens the run's I/O. `io_file` is `--io`; `local_io` the local configuration's `[io]`;
/// `plc_id` names the OPC UA server's nodes.
// The run's options as the command line gives them, each used once.
#[allow(clippy::too_many_arguments)]
pub fn open(
    program: &Program,
    twin: Option<&str>,
    settings: &TwinSettings,
    io_file: Option<&Path>,
    local_io: Option<&IoConfig>,
    virtual_time: bool,
    period_us: u64,
    plc_id: &str,
) -> anyhow::Result<Opened> {
    let kind: Option<TwinKind> = match twin {
        Some(t) => Some(t.parse().map_err(|e| anyhow::anyhow!("{e}"))?),
        None => None,
    };
    let config = match io_file {
        Some(p) => Some(IoConfig::load(p)?),
        // A simulation never reaches for the node's field devices.
        None if virtual_time => None,
        None => local_io.cloned(),
    };
    if virtual_time {
        if kind.is_none() {
            bail!("a virtual run needs a twin to simulate the plant: add --twin vernadat or --twin festo");
        }
        if let Some(c) = &config {
            bail!(
                "{}: a virtual run cannot use network I/O (its time runs faster than any device's); run in real time, or leave --io out",
                c.file
            );
        }
    }
    let opcua_inputs = config
        .as_ref()
        .and_then(|c| c.opcua.as_ref())
        .is_some_and(|o| o.inputs);
    if let (true, Some(k), Some(c)) = (opcua_inputs, kind, &config) {
        bail!("{}: [opcua] inputs = true and --twin {k} would both provide the inputs; an input has one source: leave out --twin, or inputs = true", c.file);
    }
    let twin = match kind {
        Some(k) => {
            let t = k
                .configure(settings)
                .map_err(|e| anyhow::anyhow!("--twin {k}: {e}"))?;
            Some(TwinDriver::new(t, program.inputs(), program.outputs())?)
        }
        None => None,
    };
    let (field, server) = match &config {
        Some(c) => {
            let map = FieldMap::bind(
                c,
                program.inputs(),
                program.outputs(),
                kind.is_some() || opcua_inputs,
            )
            .with_context(|| {
                format!("the program does not fit the I/O configuration {}", c.file)
            })?;
            let server = match &c.server {
                Some(s) => {
                    let server = ImageServer::start(s, &map)
                        .with_context(|| format!("the Modbus server of {}", c.file))?;
                    eprintln!(
                        "Modbus server of the process image on {} (writes from {})",
                        server.addr(),
                        if s.write_from.is_empty() {
                            "nobody".to_string()
                        } else {
                            s.write_from
                                .iter()
                                .map(|a| a.to_string())
                                .collect::<Vec<_>>()
                                .join(", ")
                        }
                    );
                    Some(server)
                }
                None => None,
            };
            (start_field(c, map, period_us)?, server)
        }
        None => (None, None),
    };
    let opcua = crate::run_opcua::start(config.as_ref(), program, plc_id)?;
    let io = PlantIo::with_servers(twin, field, server, opcua).ok_or_else(|| {
        anyhow::anyhow!("nothing to run against: give --twin vernadat|festo, --io IO.toml, or both (or an [io] section in the local configuration)")
    })?;
    Ok(Opened { io, kind })
}

/// Starts the field devices' I/O threads and waits for the first input image; `None` when the
/// configuration has no device (a server only).
fn start_field(c: &IoConfig, map: FieldMap, period_us: u64) -> anyhow::Result<Option<FieldIo>> {
    if c.devices.is_empty() {
        return Ok(None);
    }
    let field = FieldIo::start(c, map, period_us)?;
    let missing = field.wait_first_image(c.start_timeout_us);
    if !missing.is_empty() {
        eprintln!(
            "warning: no complete input image from {} within {} µs; the first scans run on the safe values of their inputs",
            missing.join(", "),
            c.start_timeout_us
        );
    }
    Ok(Some(field))
}

/// Schedules the `--press BUTTON@TIME` presses of the twin (program time from `base_us`); the
/// twin's own start presses when none are given (the Festo station's RESET and START).
pub fn press(io: &mut PlantIo, presses: &[String], base_us: u64) -> anyhow::Result<()> {
    let Some(t) = io.twin_mut() else {
        if presses.is_empty() {
            return Ok(());
        }
        bail!("--press needs a twin; with field I/O, press the machine's own buttons");
    };
    Ok(cetratus_node::script::press_buttons(
        t.plant_mut(),
        presses,
        base_us,
    )?)
}

/// Lets live updates use signals the running program does not, on channels the field devices
/// serve (docs/io.md).
pub fn admit(io: &PlantIo, plc: &mut cetratus_runtime::Plc) {
    if let Some(f) = io.field() {
        plc.set_io_admission(f.admission());
    }
}

/// What the plant says at the end of a run.
pub struct PlantReport {
    /// Parts finished (good parts for the Festo station); 0 without a twin.
    pub parts_finished: u64,
    /// Physical faults the twin saw.
    pub twin_faults: u64,
    /// Their descriptions.
    pub faults: Vec<String>,
    /// The twin's counters.
    pub counters: serde_json::Value,
    /// Every field device's figures.
    pub io: Option<Vec<DeviceStatus>>,
    /// What the PLC's Modbus server did.
    pub server: Option<BankCounters>,
    /// What the PLC's OPC UA server did.
    pub opcua: Option<cetratus_io::opcua::OpcUaCounters>,
}

/// The plant's end-of-run figures.
pub fn report(io: &PlantIo) -> anyhow::Result<PlantReport> {
    let mut r = PlantReport {
        parts_finished: 0,
        twin_faults: 0,
        faults: Vec::new(),
        counters: serde_json::Value::Object(Default::default()),
        io: crate::run_opcua::input_status(io),
        server: io.server().map(|s| s.counters()),
        opcua: io.opcua().map(|s| s.counters()),
    };
    if let Some(t) = io.twin() {
        let plant = t.plant();
        r.faults = plant.faults().iter().map(|f| f.to_string()).collect();
        let counters = plant.counters();
        r.parts_finished = counters
            .get("parts_finished")
            .or_else(|| counters.get("parts_good"))
            .unwrap_or(0);
        r.twin_faults = plant.faults().len() as u64 + plant.faults_dropped();
        r.counters = serde_json::to_value(counters)?;
    }
    if io.opcua().is_some_and(|o| o.faulted()) {
        r.faults
            .push("OPC UA inputs: no client wrote an input for `stale_after` cycles under the `fault` policy; the PLC's I/O went to its safe state: safe inputs, and safe outputs on the field devices and the Outputs nodes".into());
    }
    if io.field().is_some_and(|f| f.faulted()) {
        r.faults
            .push("field I/O: a device with the `fault` stale policy went silent; the PLC's I/O went to its safe state: safe inputs, and safe outputs on the field devices and the OPC UA Outputs nodes".into());
    }
    Ok(r)
}
