//! The closing summary of `cetratus run`, as text or JSON.

use cetratus_persist::PersistStats;
use cetratus_runtime::CycleFigures;
use serde::Serialize;

/// The closing summary of a run.
#[derive(Debug, Serialize)]
pub struct Summary {
    /// Program name.
    pub program: String,
    /// Twin name (empty without a twin).
    pub twin: String,
    /// What the program ran against, in words: `vernadat twin`, `field I/O`, `replayed trace`.
    pub plant: String,
    /// Program time run, in seconds.
    pub seconds: f64,
    /// Scans run.
    pub scans: u64,
    /// Transitions fired.
    pub firings: u64,
    /// Parts that left the plant finished.
    pub parts_finished: u64,
    /// Physical faults the twin saw (those it kept and those it only counted).
    pub twin_faults: u64,
    /// Physical faults the twin saw, declared invariants broken, and scan errors.
    pub faults: Vec<String>,
    /// The twin's counters.
    pub counters: serde_json::Value,
    /// Every field device's figures, with field I/O.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub io: Option<Vec<cetratus_io::field::DeviceStatus>>,
    /// What the PLC's Modbus server did, when it had one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub modbus_server: Option<cetratus_io::bank::BankCounters>,
    /// What the PLC's OPC UA server did, when it had one.
    #[cfg(feature = "opcua")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub opcua_server: Option<cetratus_io::opcua::OpcUaCounters>,
    /// Scan timing figures.
    pub scan: CycleFigures,
    /// PRIMARY at the end.
    pub primary: &'static str,
    /// STATUS at the end.
    pub status: &'static str,
    /// The state directory, when the run kept its state.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub state_dir: Option<String>,
    /// What the persistence thread did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub persist: Option<PersistStats>,
    /// The run's events, in order, as on the `events` topic (the first [`MAX_EVENTS`]).
    pub events: Vec<cetratus_proto::EventMsg>,
    /// Events left out of `events`: past [`MAX_EVENTS`], or dropped while the printer was behind.
    pub events_left_out: u64,
}

/// How many events a summary keeps.
pub const MAX_EVENTS: usize = 10_000;

pub fn print_summary(s: &Summary) {
    let plant = &s.plant;
    println!(
        "{} on the {plant}: {:.1} s of program time",
        s.program, s.seconds
    );
    println!("  scans           {}", s.scans);
    println!("  firings         {}", s.firings);
    println!("  parts finished  {}", s.parts_finished);
    if let Some(obj) = s.counters.as_object() {
        for (k, v) in obj {
            println!("  {k:<15} {v}");
        }
    }
    let f = &s.scan;
    println!(
        "  scan time       last {} ns, min {} ns, mean {} ns, p99 {} ns, max {} ns",
        f.scan.last_ns, f.scan.min_ns, f.scan.mean_ns, f.scan.p99_ns, f.scan.max_ns
    );
    if f.cycle.count > 0 {
        println!(
            "  cycle time      mean {} ns, p99 {} ns, max {} ns (period {} µs)",
            f.cycle.mean_ns, f.cycle.p99_ns, f.cycle.max_ns, f.period_us
        );
        println!(
            "  latency         mean {} ns, p99 {} ns, max {} ns; overruns {}",
            f.latency.mean_ns, f.latency.p99_ns, f.latency.max_ns, f.overruns
        );
    }
    if let (Some(dir), Some(p)) = (&s.state_dir, &s.persist) {
        println!(
            "  state           {dir}: {} snapshots committed, {} superseded, max commit {} µs{}",
            p.commits,
            p.coalesced,
            p.max_commit_us,
            if p.errors > 0 {
                format!(", {} write errors", p.errors)
            } else {
                String::new()
            }
        );
    }
    for d in s.io.iter().flatten() {
        println!(
            "  device {:<8} {:?}, {} reads, {} writes, {} errors, {} exceptions, {} reconnects{}",
            d.name,
            d.quality,
            d.reads,
            d.writes,
            d.errors,
            d.exceptions,
            d.reconnects,
            d.last_error
                .as_ref()
                .map_or(String::new(), |e| format!("; last error: {e}"))
        );
    }
    if let Some(m) = &s.modbus_server {
        println!(
            "  modbus server   {} requests, {} exceptions, {} connections refused",
            m.requests, m.exceptions, m.refused
        );
    }
    #[cfg(feature = "opcua")]
    print_opcua(s);
    if s.faults.is_empty() {
        println!("  faults          none");
    } else {
        println!("  faults          {}", s.faults.len());
        for fault in s.faults.iter().take(20) {
            println!("    {fault}");
        }
    }
}

/// Prints an event as one line of stderr (not in `--json` runs).
pub fn print_event(e: &cetratus_runtime::Event, json: bool) {
    if !json {
        eprintln!(
            "{:>10.3} s  {:<20} {}",
            e.time_us as f64 / 1e6,
            e.kind,
            e.message
        );
    }
}

/// The OPC UA server's line of the summary, when the run had one.
#[cfg(feature = "opcua")]
fn print_opcua(s: &Summary) {
    if let Some(o) = &s.opcua_server {
        println!(
            "  opc ua server   {} cycles published, {} input writes, {} refused, {} connections refused, {} model changes; logins {} ok, {} wrong, {} refused unchecked",
            o.published, o.writes, o.refused_writes, o.refused_connections, o.model_changes, o.logins, o.failed_logins, o.refused_logins
        );
    }
}
