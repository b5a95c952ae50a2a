//! `cetratus run`: a program against a digital twin, in virtual or real time.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use anyhow::{bail, Context};
use cetratus_io::TwinDriver;
use cetratus_program::Program;
use cetratus_runtime::{trace::Trace, Container, CycleFigures, ScanCycle};
use cetratus_twin::{Plant, Twin, TwinKind};
use serde::Serialize;

use crate::duration::parse_duration_us;

/// Arguments of `cetratus run`.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// The program: a TOML program file, or a PNML file that carries its program.
    program: PathBuf,
    /// The plant to drive: a digital twin.
    #[arg(long, value_parser = ["vernadat", "festo"])]
    twin: String,
    /// Run in virtual time: as fast as the machine goes, deterministic.
    #[arg(long = "virtual")]
    virtual_time: bool,
    /// How much program time to run (e.g. `1h`, `90s`, `500ms`); real-time runs default to forever.
    #[arg(long = "for")]
    for_: Option<String>,
    /// In real time, how many times faster than the wall clock the program clock runs.
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
    /// Seed of the twin's randomness.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Press a twin button at a time, e.g. `START@0.1s` (repeatable). The Festo station gets
    /// `START@100ms` when none is given.
    #[arg(long = "press")]
    press: Vec<String>,
    /// Write the I/O trace: `.csv` or `.json`.
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Write an SVG timing diagram of inputs and outputs.
    #[arg(long)]
    svg: Option<PathBuf>,
    /// Ask for SCHED_FIFO and mlockall (real time only); warns and goes on where refused.
    #[arg(long)]
    rt: bool,
    /// Print the closing summary as one JSON object.
    #[arg(long)]
    json: bool,
}

/// The closing summary of a run.
#[derive(Debug, Serialize)]
pub struct Summary {
    /// Program name.
    pub program: String,
    /// Twin name.
    pub twin: String,
    /// Program time run, in seconds.
    pub seconds: f64,
    /// Scans run.
    pub scans: u64,
    /// Transitions fired.
    pub firings: u64,
    /// Parts that left the plant finished.
    pub parts_finished: u64,
    /// Physical faults the twin saw, declared invariants broken, and scan errors.
    pub faults: Vec<String>,
    /// The twin's counters.
    pub counters: serde_json::Value,
    /// Scan timing figures.
    pub scan: CycleFigures,
}

/// Runs `cetratus run`.
pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    let program = Arc::new(
        Program::load(&args.program)
            .with_context(|| format!("cannot load {}", args.program.display()))?,
    );
    let kind: TwinKind = args.twin.parse().map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut twin = kind.build(args.seed);
    let mut presses = args.press.clone();
    if presses.is_empty() && kind == TwinKind::Festo {
        presses.push("START@100ms".to_string());
    }
    for p in &presses {
        let (button, at) = p.split_once('@').unwrap_or((p.as_str(), "0s"));
        let at_us = parse_duration_us(at)?;
        twin.press(button, at_us)
            .map_err(|e| anyhow::anyhow!("--press {p}: {e}"))?;
    }
    let until_us = match (&args.for_, args.virtual_time) {
        (Some(d), _) => parse_duration_us(d)?,
        (None, true) => bail!("a virtual run needs a length: add --for, e.g. --for 1h"),
        (None, false) => u64::MAX,
    };
    let mut io = TwinDriver::new(twin, program.inputs(), program.outputs())?;
    let mut cycle = ScanCycle::new(Container::new(program.clone(), 0));
    let mut trace = Trace::new(
        program.inputs().iter().map(|s| s.name.clone()).collect(),
        program.outputs().iter().map(|s| s.name.clone()).collect(),
    );
    let record = args.trace.is_some() || args.svg.is_some();
    let mut violations: Vec<String> = Vec::new();
    let observe = |c: &ScanCycle, now: u64, _: &mut TwinDriver<Twin>| {
        let k = c.container();
        if record {
            trace.observe(k.scans() - 1, now, k.inputs(), k.outputs());
        }
        if violations.len() < 100 {
            if let Err(v) = k.program().check_invariants(k.marking()) {
                violations.push(format!("{:.3}s: {v}", now as f64 / 1e6));
            }
        }
    };
    let result = if args.virtual_time {
        cycle.run_virtual(0, until_us, &mut io, observe)
    } else {
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        ctrlc::set_handler(move || s.store(true, std::sync::atomic::Ordering::Relaxed))
            .context("cannot install the Ctrl-C handler")?;
        if args.rt {
            let status = cetratus_runtime::rt::request(80);
            for w in &status.warnings {
                eprintln!("warning: {w}");
            }
            eprintln!("real time: {status}");
        }
        if !args.json {
            eprintln!(
                "running {} on the {} twin in real time (speed {}); Ctrl-C stops",
                program.name(),
                kind,
                args.speed
            );
        }
        cycle.run_realtime(until_us, args.speed, &stop, &mut io, observe)
    };
    let mut faults: Vec<String> = io.plant().faults().iter().map(|f| f.to_string()).collect();
    faults.extend(violations);
    let reached_us = match result {
        Ok(t) => t,
        Err(e) => {
            faults.push(format!("scan error: {e}"));
            cycle.container().scans() * cycle.period_us()
        }
    };
    let counters = io.plant().counters();
    let parts_finished = counters
        .get("parts_finished")
        .or_else(|| counters.get("parts_ejected"))
        .unwrap_or(0);
    let summary = Summary {
        program: program.name().to_string(),
        twin: kind.to_string(),
        seconds: reached_us as f64 / 1e6,
        scans: cycle.container().scans(),
        firings: cycle.container().firings().iter().sum(),
        parts_finished,
        faults,
        counters: serde_json::to_value(&counters)?,
        scan: cycle.figures(),
    };
    trace.end_us = reached_us;
    if let Some(path) = &args.trace {
        let text = if path.extension().is_some_and(|e| e == "json") {
            serde_json::to_string_pretty(&trace)?
        } else {
            trace.to_csv()
        };
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(path) = &args.svg {
        let title = format!("{} on the {} twin", program.name(), kind);
        std::fs::write(path, trace.diagram(&title).to_svg())
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_summary(&summary);
    }
    Ok(())
}

fn print_summary(s: &Summary) {
    println!(
        "{} on the {} twin: {:.1} s of program time",
        s.program, s.twin, s.seconds
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
    if s.faults.is_empty() {
        println!("  faults          none");
    } else {
        println!("  faults          {}", s.faults.len());
        for fault in s.faults.iter().take(20) {
            println!("    {fault}");
        }
    }
}
