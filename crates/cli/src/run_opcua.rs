//! The PLC's OPC UA server in `cetratus run`: started from the I/O configuration's `[opcua]`,
//! published after every cycle beside the Modbus server's status registers.

use std::sync::Arc;

use anyhow::Context;
use cetratus_io::config::IoConfig;
use cetratus_io::field::DeviceStatus;
use cetratus_io::opcua::{OpcUaServer, PasswordCheck, Start};
use cetratus_io::plant::PlantIo;
use cetratus_mct::password::HashedPassword;
use cetratus_program::Program;
use cetratus_runtime::Plc;

/// Starts the OPC UA server of `config`, if it has one, named `plc`; when its clients provide
/// the inputs, waits (before the first scan) for them to write every input once, up to the
/// configuration's `start_timeout`.
pub fn start(
    config: Option<&IoConfig>,
    program: &Program,
    plc: &str,
) -> anyhow::Result<Option<OpcUaServer>> {
    let Some((c, o)) = config.and_then(|c| c.opcua.as_ref().map(|o| (c, o))) else {
        return Ok(None);
    };
    let mut hashes = Vec::new();
    for u in &o.users {
        let h = HashedPassword::parse(&u.password_hash).map_err(|e| {
            anyhow::anyhow!("{}: the password hash of `{}` is not an argon2 hash ({e}); make one with `cetratus hash-password`", u.at, u.name)
        })?;
        hashes.push((u.password_hash.clone(), h));
    }
    // The server hands over the hash it found for the user; the check is the one of the
    // dashboard and the broker (argon2, slow on purpose, run on a blocking thread).
    let passwords: Option<PasswordCheck> = (!hashes.is_empty()).then(|| {
        let check: PasswordCheck = Arc::new(move |phc: &str, password: &[u8]| {
            hashes
                .iter()
                .find(|(p, _)| p == phc)
                .is_some_and(|(_, h)| h.verify(password))
        });
        check
    });
    let program = Arc::new(program.clone());
    let server = OpcUaServer::start(
        o,
        Start {
            plc,
            program: &program,
            inputs: program.inputs(),
            outputs: program.outputs(),
            passwords,
        },
    )
    .with_context(|| format!("the OPC UA server of {}", c.file))?;
    eprintln!(
        "OPC UA server on {} (namespace urn:cetratus, nodes {plc}.*; inputs {})",
        server.url(),
        if o.inputs {
            "written by OPC UA clients"
        } else {
            "read only"
        }
    );
    if o.inputs && !server.wait_first_image(c.start_timeout_us) {
        eprintln!(
            "warning: no OPC UA client wrote every input within {} µs; the first scans run on the safe values of the inputs not written yet",
            c.start_timeout_us
        );
    }
    Ok(Some(server))
}

/// The observer of each cycle: the Modbus server's status registers and the OPC UA nodes.
pub fn observer(io: &PlantIo) -> Option<impl FnMut(&Plc) + Send + 'static> {
    let mut board = io.server().map(|s| s.status_board());
    let mut publisher = io.opcua().map(|s| s.publisher());
    let any = board.is_some() || publisher.is_some();
    any.then_some(move |plc: &Plc| {
        if let Some(b) = board.as_mut() {
            b.show(plc);
        }
        if let Some(p) = publisher.as_mut() {
            p.show(plc);
        }
    })
}

/// Every source of inputs with a quality, for the run summary: the field devices, then the
/// OPC UA clients when they provide the inputs; `None` when there is neither.
pub fn input_status(io: &PlantIo) -> Option<Vec<DeviceStatus>> {
    let mut all = io.field().map(|f| f.status());
    if let Some(s) = io.opcua().and_then(|o| o.status()) {
        all.get_or_insert_with(Vec::new).push(s);
    }
    all
}

/// The reader of the same for `exec_info`, on the publisher's thread.
pub fn input_quality(io: &PlantIo) -> Option<cetratus_node::link::InputQualityReader> {
    let field = io.field().map(|f| f.status_reader());
    let opcua = io.opcua().and_then(|o| o.status_reader());
    if field.is_none() && opcua.is_none() {
        return None;
    }
    Some(Arc::new(move || {
        let mut all = field.as_ref().map(|f| f.read()).unwrap_or_default();
        all.extend(opcua.as_ref().map(|o| o()));
        all
    }))
}
