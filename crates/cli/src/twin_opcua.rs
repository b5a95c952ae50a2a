//! `cetratus twin serve … --opcua URL`: the twin as the OPC UA client of a PLC's server.

use std::sync::atomic::AtomicBool;

use cetratus_io::opcua::twin_client::serve;
use cetratus_twin::{Plant, Twin};

/// Drives `twin` from the PLC at `url` and prints the closing summary.
pub fn run(
    twin: Twin,
    url: &str,
    plc: Option<&str>,
    until_us: u64,
    stop: &AtomicBool,
    json: bool,
) -> anyhow::Result<()> {
    let name = twin.name().to_string();
    if !json {
        eprintln!("the {name} twin connects to {url} (retrying until the PLC is up); Ctrl-C stops");
    }
    let report = serve(twin, url, plc, until_us, stop, |plc| {
        if !json {
            eprintln!("connected: the {name} twin is the plant of {plc}");
        }
    })?;
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{} twin: {:.1} s, {} parts finished, {} faults; OPC UA: {} reads, {} writes, {} errors",
            report.twin,
            report.seconds,
            report.parts_finished,
            report.twin_faults,
            report.opcua.reads,
            report.opcua.writes,
            report.opcua.errors
        );
        for f in report.faults.iter().take(20) {
            println!("  {f}");
        }
    }
    Ok(())
}
