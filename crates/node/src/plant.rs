//! The plant a node runs against, opened from its [`PlantSpec`]: the digital twin, the field
//! devices and the PLC's Modbus server, and the PLC's OPC UA server, as one list of drivers
//! ([`PlantIo`]).

use cetratus_io::config::IoConfig;
use cetratus_io::field::FieldIo;
use cetratus_io::map::FieldMap;
use cetratus_io::plant::{Field, PlantDriver, PlantIo};
use cetratus_io::server::ImageServer;
use cetratus_io::TwinDriver;
use cetratus_program::Program;
use cetratus_twin::{TwinKind, TwinSettings};

use crate::spec::{Notice, Say, SpecError};

/// The plant of a node.
#[derive(Clone, Debug, Default)]
pub struct PlantSpec {
    /// The digital twin to drive, if any.
    pub twin: Option<TwinKind>,
    /// The twin's seed and defect rate.
    pub settings: TwinSettings,
    /// The field I/O configuration; `None` takes the local configuration's `[io]` in real time
    /// (a simulation never reaches for the node's field devices).
    pub io: Option<IoConfig>,
    /// Twin button presses, `BUTTON@TIME`; the twin's own start presses when empty.
    pub presses: Vec<String>,
    /// Recorded inputs to play back, one row per scan (`--replay`), instead of a twin.
    pub replay: Option<std::path::PathBuf>,
}

/// What [`open`] needs besides the spec.
pub(crate) struct Opening<'a> {
    pub program: &'a Program,
    pub local_io: Option<&'a IoConfig>,
    pub virtual_time: bool,
    pub period_us: u64,
    // Names the OPC UA server's nodes, in a build that has it.
    #[cfg_attr(not(feature = "opcua"), allow(dead_code))]
    pub plc_id: &'a str,
}

/// Opens the plant: the twin first, then the field (devices and Modbus server), then the OPC UA
/// server, which is the order inputs are read in.
pub(crate) fn open(spec: &PlantSpec, at: &Opening<'_>, say: Say<'_>) -> Result<PlantIo, SpecError> {
    let config = match &spec.io {
        Some(c) => Some(c.clone()),
        None if at.virtual_time => None,
        None => at.local_io.cloned(),
    };
    check_sources(spec, config.as_ref(), at.virtual_time)?;
    let mut drivers: Vec<Box<dyn PlantDriver>> = Vec::new();
    if let Some(path) = &spec.replay {
        let replay = cetratus_io::replay::Replay::open(path, at.program.inputs())?;
        drivers.push(Box::new(replay));
    }
    if let Some(k) = spec.twin {
        let t = k
            .configure(&spec.settings)
            .map_err(|error| SpecError::Twin { kind: k, error })?;
        let driver: TwinDriver<cetratus_twin::Twin> =
            TwinDriver::new(t, at.program.inputs(), at.program.outputs())?;
        drivers.push(Box::new(driver));
    }
    if let Some(c) = &config {
        let others_provide = spec.twin.is_some() || opcua_inputs(c);
        if let Some(field) = open_field(c, at, others_provide, say)? {
            drivers.push(Box::new(field));
        }
        if let Some(server) = open_opcua(c, at, say)? {
            drivers.push(server);
        }
    }
    PlantIo::new(drivers).ok_or(SpecError::NoPlant)
}

/// Whether the OPC UA server's clients provide the inputs.
fn opcua_inputs(c: &IoConfig) -> bool {
    c.opcua.as_ref().is_some_and(|o| o.inputs)
}

/// Refuses a plant whose inputs would have no source, or two.
fn check_sources(
    spec: &PlantSpec,
    config: Option<&IoConfig>,
    virtual_time: bool,
) -> Result<(), SpecError> {
    let twin = spec.twin;
    if spec.replay.is_some() && (twin.is_some() || config.is_some()) {
        return Err(SpecError::ReplayAndPlant);
    }
    if virtual_time {
        if twin.is_none() && spec.replay.is_none() {
            return Err(SpecError::VirtualNeedsTwin);
        }
        if let Some(c) = config {
            return Err(SpecError::VirtualNetworkIo {
                file: c.file.clone(),
            });
        }
    }
    if let (Some(twin), Some(c)) = (twin, config) {
        if opcua_inputs(c) {
            return Err(SpecError::TwoInputSources {
                file: c.file.clone(),
                twin,
            });
        }
    }
    Ok(())
}

/// The field devices and the Modbus server of `c`, bound to the program.
fn open_field(
    c: &IoConfig,
    at: &Opening<'_>,
    others_provide: bool,
    say: Say<'_>,
) -> Result<Option<Field>, SpecError> {
    let map = FieldMap::bind(c, at.program.inputs(), at.program.outputs(), others_provide)
        .map_err(|error| SpecError::DoesNotFit {
            file: c.file.clone(),
            error,
        })?;
    let server = match &c.server {
        Some(s) => {
            let server = ImageServer::start(s, &map).map_err(|error| SpecError::Server {
                what: "Modbus",
                file: c.file.clone(),
                error,
            })?;
            let writers = if s.write_from.is_empty() {
                "nobody".to_string()
            } else {
                let all: Vec<String> = s.write_from.iter().map(|a| a.to_string()).collect();
                all.join(", ")
            };
            say(Notice::Note(format!(
                "Modbus server of the process image on {} (writes from {writers})",
                server.addr()
            )));
            Some(server)
        }
        None => None,
    };
    Ok(Field::new(
        start_devices(c, map, at.period_us, say)?,
        server,
    ))
}

/// Starts the field devices' I/O threads and waits for the first input image; `None` when the
/// configuration has no device (a server only).
fn start_devices(
    c: &IoConfig,
    map: FieldMap,
    period_us: u64,
    say: Say<'_>,
) -> Result<Option<FieldIo>, SpecError> {
    if c.devices.is_empty() {
        return Ok(None);
    }
    let field = FieldIo::start(c, map, period_us)?;
    let missing = field.wait_first_image(c.start_timeout_us);
    if !missing.is_empty() {
        say(Notice::Warning(format!(
            "no complete input image from {} within {} µs; the first scans run on the safe values of their inputs",
            missing.join(", "),
            c.start_timeout_us
        )));
    }
    Ok(Some(field))
}

/// Starts the OPC UA server of `c`, if it has one, named by the PLC's id; when its clients
/// provide the inputs, waits (before the first scan) for them to write every input once, up to
/// the configuration's `start_timeout`.
#[cfg(feature = "opcua")]
fn open_opcua(
    c: &IoConfig,
    at: &Opening<'_>,
    say: Say<'_>,
) -> Result<Option<Box<dyn PlantDriver>>, SpecError> {
    use cetratus_io::opcua::{OpcUaServer, Start};

    let Some(o) = c.opcua.as_ref() else {
        return Ok(None);
    };
    let program = std::sync::Arc::new(at.program.clone());
    let server = OpcUaServer::start(
        o,
        Start {
            plc: at.plc_id,
            program: &program,
            inputs: program.inputs(),
            outputs: program.outputs(),
            passwords: password_check(o)?,
        },
    )
    .map_err(|error| SpecError::Server {
        what: "OPC UA",
        file: c.file.clone(),
        error,
    })?;
    let inputs = if o.inputs {
        "written by OPC UA clients"
    } else {
        "read only"
    };
    say(Notice::Note(format!(
        "OPC UA server on {} (namespace urn:cetratus, nodes {}.*; inputs {inputs})",
        server.url(),
        at.plc_id
    )));
    if o.inputs && !server.wait_first_image(c.start_timeout_us) {
        say(Notice::Warning(format!(
            "no OPC UA client wrote every input within {} µs; the first scans run on the safe values of the inputs not written yet",
            c.start_timeout_us
        )));
    }
    Ok(Some(Box::new(server)))
}

/// A build without OPC UA refuses a configuration that asks for its server.
#[cfg(not(feature = "opcua"))]
fn open_opcua(
    c: &IoConfig,
    _at: &Opening<'_>,
    _say: Say<'_>,
) -> Result<Option<Box<dyn PlantDriver>>, SpecError> {
    match c.opcua {
        Some(_) => Err(SpecError::NoOpcUa {
            file: c.file.clone(),
        }),
        None => Ok(None),
    }
}

/// The check of the OPC UA users' passwords: the server hands over the hash it found for the
/// user, and the check is the one of the dashboard and the broker (argon2, slow on purpose, run
/// on a blocking thread). `None` when the configuration has no user.
#[cfg(feature = "opcua")]
fn password_check(
    o: &cetratus_io::opcua::config::OpcUaConfig,
) -> Result<Option<cetratus_io::opcua::PasswordCheck>, SpecError> {
    use cetratus_mct::password::HashedPassword;

    let mut hashes = Vec::new();
    for u in &o.users {
        let h =
            HashedPassword::parse(&u.password_hash).map_err(|error| SpecError::PasswordHash {
                at: u.at.clone(),
                user: u.name.clone(),
                error,
            })?;
        hashes.push((u.password_hash.clone(), h));
    }
    if hashes.is_empty() {
        return Ok(None);
    }
    Ok(Some(std::sync::Arc::new(
        move |phc: &str, password: &[u8]| {
            hashes
                .iter()
                .find(|(p, _)| p == phc)
                .is_some_and(|(_, h)| h.verify(password))
        },
    )))
}
