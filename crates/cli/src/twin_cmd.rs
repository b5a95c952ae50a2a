//! `cetratus twin serve`: a digital twin as a Modbus TCP device, for a PLC in another process.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Context;
use cetratus_io::twin_serve::{serve, TwinMap};
use cetratus_twin::{parse_defect_rate, ParamValue, TwinKind, TwinParam, TwinSettings};

use crate::parse_duration_us;

/// Arguments of `cetratus twin`.
#[derive(clap::Args, Debug)]
pub struct TwinArgs {
    #[command(subcommand)]
    command: TwinCommand,
}

#[derive(clap::Subcommand, Debug)]
enum TwinCommand {
    /// Run a twin as a Modbus TCP device (at the addresses its example program declares), or as
    /// the OPC UA client of a PLC's server.
    Serve(ServeArgs),
}

/// Arguments of `cetratus twin serve`.
#[derive(clap::Args, Debug)]
pub struct ServeArgs {
    /// The twin.
    #[arg(value_parser = ["vernadat", "festo"])]
    twin: String,
    /// Where the Modbus device listens, e.g. `127.0.0.1:15020`.
    #[arg(long, conflicts_with = "opcua")]
    modbus: Option<String>,
    /// The PLC's OPC UA server to be the plant of, e.g. `opc.tcp://127.0.0.1:14840`; retried
    /// until it is up.
    #[arg(long)]
    opcua: Option<String>,
    /// The PLC's name in the server's nodes (`<plc>.Inputs.…`); the one PLC it shows by default.
    #[arg(long, requires = "opcua")]
    plc: Option<String>,
    #[cfg(feature = "opcua")]
    #[command(flatten)]
    security: crate::twin_opcua::SecurityArgs,
    /// Print the address map and stop.
    #[arg(long)]
    print_map: bool,
    /// How long to run (e.g. `1min`), counted from the first request; forever by default,
    /// Ctrl-C stops.
    #[arg(long = "for")]
    for_: Option<String>,
    /// Print the closing summary as one JSON object.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    plant: PlantArgs,
}

/// What a twin is given from the command line, by `run` and by `twin serve`.
#[derive(clap::Args, Debug)]
pub struct PlantArgs {
    /// Seed of the twin's randomness (jitter, which parts are defective).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Share of defective parts the Festo station is supplied: `5%`, `0.05` or `50000ppm`.
    #[arg(long = "defect-rate", value_name = "RATE", default_value = "0", value_parser = parse_defect_rate)]
    pub defect_ppm: u32,
    /// Press a twin button at a time, e.g. `START@0.5s` (repeatable); the Festo station gets
    /// `RESET@100ms` and `START@500ms` when none is given.
    #[arg(long = "press")]
    pub press: Vec<String>,
    /// Change one of the twin's parameters, e.g. `m2_machining=24s` or `buffer_capacity=7`
    /// (repeatable): a plant that is not quite the model (docs/operations.md, *The digital twins*).
    #[arg(long = "twin-param", value_name = "NAME=VALUE", value_parser = parse_twin_param)]
    pub params: Vec<TwinParam>,
}

impl PlantArgs {
    /// The twin's settings.
    pub fn settings(&self) -> TwinSettings {
        TwinSettings {
            seed: self.seed,
            defect_ppm: self.defect_ppm,
            params: self.params.clone(),
        }
    }
}

/// `NAME=VALUE`: a whole number is a count, anything else a duration (`24s`, `500ms`).
fn parse_twin_param(text: &str) -> Result<TwinParam, String> {
    let Some((name, value)) = text.split_once('=') else {
        return Err(format!(
            "`{text}` is not NAME=VALUE; write e.g. m2_machining=24s or buffer_capacity=7"
        ));
    };
    let value = match value.trim().parse::<u64>() {
        Ok(n) => ParamValue::Count(n),
        Err(_) => ParamValue::Micros(
            crate::parse_duration_us(value.trim())
                .map_err(|e| format!("`{value}` is neither a count nor a duration: {e}"))?,
        ),
    };
    Ok(TwinParam {
        name: name.trim().to_string(),
        value,
    })
}

/// Runs `cetratus twin`.
pub fn run(args: &TwinArgs) -> anyhow::Result<()> {
    let TwinCommand::Serve(a) = &args.command;
    let kind: TwinKind = a.twin.parse().map_err(|e| anyhow::anyhow!("{e}"))?;
    let settings = a.plant.settings();
    let mut twin = kind
        .configure(&settings)
        .map_err(|e| anyhow::anyhow!("{kind}: {e}"))?;
    let map = TwinMap::for_example(kind, &twin)?;
    if a.print_map {
        print!("{}", map.print());
        return Ok(());
    }
    if a.modbus.is_none() && a.opcua.is_none() {
        anyhow::bail!(
            "give the address to serve on, e.g. --modbus 127.0.0.1:15020, or the PLC's OPC UA server, e.g. --opcua opc.tcp://127.0.0.1:14840 (or --print-map)"
        );
    }
    let security = opcua_security(a)?;
    cetratus_node::script::press_buttons(&mut twin, &a.plant.press, 0)?;
    let until_us = match &a.for_ {
        Some(d) => parse_duration_us(d)?,
        None => u64::MAX,
    };
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    ctrlc::set_handler(move || s.store(true, Ordering::Relaxed))
        .context("cannot install the Ctrl-C handler")?;
    let json = a.json;
    if let Some(url) = &a.opcua {
        let plc = a.plc.as_deref();
        return opcua_client(twin, url, plc, until_us, &stop, &security, json);
    }
    let Some(listen) = &a.modbus else {
        anyhow::bail!("give --modbus ADDR or --opcua URL");
    };
    let listen = listen.parse().with_context(|| {
        format!("--modbus {listen}: write an IP address and a port, e.g. 127.0.0.1:15020")
    })?;
    let report = serve(twin, &map, listen, until_us, &stop, |addr| {
        if !json {
            eprintln!("the {kind} twin serves Modbus TCP on {addr}; Ctrl-C stops");
        }
    })?;
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{} twin: {:.1} s, {} parts finished, {} faults; Modbus: {} requests, {} exceptions, {} connections refused",
            report.twin,
            report.seconds,
            report.parts_finished,
            report.twin_faults,
            report.modbus.requests,
            report.modbus.exceptions,
            report.modbus.refused
        );
        for f in report.faults.iter().take(20) {
            println!("  {f}");
        }
    }
    Ok(())
}

/// How `--opcua` reaches the PLC's server: the URL checked, the security options resolved.
#[cfg(feature = "opcua")]
fn opcua_security(
    a: &ServeArgs,
) -> anyhow::Result<cetratus_io::opcua::twin_client::ClientSecurity> {
    if let Some(url) = &a.opcua {
        cetratus_io::opcua::config::parse_url(url).map_err(|e| anyhow::anyhow!("--opcua: {e}"))?;
    }
    a.security.resolve(a.opcua.is_some())
}

/// A build without OPC UA refuses `--opcua` before anything starts.
#[cfg(not(feature = "opcua"))]
fn opcua_security(a: &ServeArgs) -> anyhow::Result<NoOpcUa> {
    match a.opcua {
        Some(_) => anyhow::bail!("--opcua: this build of cetratus has no OPC UA (it was built without the `opcua` feature); serve the twin with --modbus, or use a full build"),
        None => Ok(NoOpcUa),
    }
}

/// What a build without OPC UA has of its client's security: nothing.
#[cfg(not(feature = "opcua"))]
struct NoOpcUa;

#[cfg(feature = "opcua")]
use crate::twin_opcua::run as opcua_client;

/// Never called: [`opcua_security`] refused `--opcua` already.
#[cfg(not(feature = "opcua"))]
fn opcua_client(
    _twin: cetratus_twin::Twin,
    url: &str,
    _plc: Option<&str>,
    _until_us: u64,
    _stop: &AtomicBool,
    _security: &NoOpcUa,
    _json: bool,
) -> anyhow::Result<()> {
    anyhow::bail!("--opcua {url}: this build of cetratus has no OPC UA")
}
