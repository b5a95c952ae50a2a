//! `cetratus run`: a program against a digital twin, field I/O or both, in virtual or real time.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use anyhow::{bail, Context};
use cetratus_node::clock::MonotonicStopwatch;
use cetratus_node::script::Script;
use cetratus_node::{state, wire, Echo, Node, NodeOptions};
use cetratus_program::Program;
use cetratus_runtime::{CycleFigures, Plc};

use crate::summary::{print_event, print_summary, Summary, MAX_EVENTS};

use crate::parse_duration_us;

/// Arguments of `cetratus run`.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// The program: a TOML program file, or a PNML file that carries its program.
    program: PathBuf,
    /// The plant to drive: a digital twin (a run has --twin, --io, or both).
    #[arg(long, value_parser = ["vernadat", "festo"])]
    twin: Option<String>,
    /// The field I/O configuration (docs/io.md); instead of the local configuration's `[io]`.
    #[arg(long = "io", value_name = "IO.toml")]
    io: Option<PathBuf>,
    /// Run in virtual time: as fast as the machine goes, deterministic.
    #[arg(long = "virtual")]
    virtual_time: bool,
    /// How much program time to run (e.g. `1h`, `90s`, `500ms`); real-time runs default to forever.
    #[arg(long = "for")]
    for_: Option<String>,
    /// In real time, how many times faster than the wall clock the program clock runs.
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
    #[command(flatten)]
    plant: crate::twin_cmd::PlantArgs,
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
    /// Scripted operator commands at program times (repeatable): `10s load PKG`,
    /// `60s substitute [keep|retransform]`, `70s remove`, `70s abort`, `80s reset`. Times count
    /// from the start of this run; commands due in the same cycle run one per cycle, in order.
    #[arg(long = "at")]
    at: Vec<String>,
    /// MQTT (real-time runs): the embedded broker by default, or a plant broker.
    #[command(flatten)]
    mqtt: crate::mqtt_args::MqttArgs,
    /// Where the dashboard listens (real-time runs).
    #[arg(long, default_value = "127.0.0.1:8080")]
    http: String,
    /// Real-time runs without MQTT and dashboard.
    #[arg(long)]
    no_mct: bool,
    /// Real-time runs with MQTT but without the dashboard (e.g. a fleet watched by one `cetratus dashboard`).
    #[arg(long)]
    no_dashboard: bool,
    /// Override the program's scan period, e.g. `100ms`.
    #[arg(long)]
    period: Option<String>,
    /// The local configuration (trusted keys, operator keys, broker accounts).
    #[command(flatten)]
    config: crate::config::ConfigArgs,
    /// Directory of trusted public keys for `load` (instead of the configuration's `trusted/`).
    #[arg(long)]
    trust: Option<PathBuf>,
    /// Accept unsigned packages (local configuration only).
    #[arg(long)]
    allow_unsigned: bool,
    /// Keep the PLC's state here (programs, PRIMARY/STATUS, markings, timers, retained variables,
    /// audit log) and warm start from it. Real-time runs default to
    /// `$XDG_STATE_HOME/cetratus/<program name>`; virtual runs keep no state unless given a directory.
    #[arg(long = "state-dir")]
    state_dir: Option<PathBuf>,
    /// Start afresh: the saved state is ignored and replaced (programs and audit log are kept).
    #[arg(long)]
    cold: bool,
    /// Print `progress cycle=N committed=M` to stderr every this many cycles (for crash tests).
    #[arg(long, hide = true)]
    progress: Option<u64>,
}

/// Runs `cetratus run`.
pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    let program = Arc::new(
        Program::load(&args.program)
            .with_context(|| format!("cannot load {}", args.program.display()))?,
    );
    let until_us = match (&args.for_, args.virtual_time) {
        (Some(d), _) => parse_duration_us(d)?,
        (None, true) => bail!("a virtual run needs a length: add --for, e.g. --for 1h"),
        (None, false) => u64::MAX,
    };
    let settings = args.plant.settings();
    let script = Script::parse(&args.at)?;
    let local = args.config.load()?;
    let trust = match &args.trust {
        Some(dir) => cetratus_program::TrustStore::load_dir(dir)?,
        None => local.trust.clone(),
    };
    let allow_unsigned = args.allow_unsigned || local.allow_unsigned;
    let quiet = args.json || args.virtual_time;
    if !quiet {
        eprintln!(
            "configuration {}: {} trusted package keys, {}, unsigned packages {}",
            local.dir.display(),
            trust.len(),
            if local.operators.is_some() {
                "signed commands required"
            } else {
                "no operator keys (commands need no signature)"
            },
            if allow_unsigned {
                "ACCEPTED"
            } else {
                "refused"
            }
        );
    }
    let period_us = (args.period.as_deref().map(parse_duration_us).transpose()?)
        .map_or(program.scan_period().as_micros() as u64, |p| p.max(1));
    let crate::run_io::Opened { mut io, kind } = crate::run_io::open(
        &program,
        args.twin.as_deref(),
        &settings,
        args.io.as_deref(),
        local.io.as_ref(),
        args.virtual_time,
        period_us,
        &args.mqtt.plc_id(),
    )?;
    local.check_validation(io.twin().is_some())?;
    let plant = kind.map_or("field I/O".to_string(), |k| format!("{k} twin"));
    // Real-time runs are watched and commanded over MQTT, with the dashboard beside them; their
    // ports are taken before anything is written, so a start that cannot bind leaves no trace.
    let mqtt = if !args.virtual_time && !args.no_mct {
        let wanted = crate::mqtt_args::Wanted {
            dashboard: (!args.no_dashboard).then_some(args.http.as_str()),
            announce: !args.json,
        };
        Some(crate::mqtt_args::start_services(
            &args.mqtt, &local, wanted,
        )?)
    } else {
        None
    };
    // A virtual run is a simulation and keeps no state unless asked to.
    let state_dir = match (&args.state_dir, args.virtual_time) {
        (Some(d), _) => Some(d.clone()),
        (None, true) => None,
        (None, false) => state::default_dir(program.name()),
    };
    let (mut plc, persister, start_events) = match &state_dir {
        Some(dir) => {
            let s = state::open(
                dir,
                &program,
                args.cold,
                period_us,
                MonotonicStopwatch::boxed(),
            )
            .with_context(|| format!("the state directory {}", dir.display()))?;
            for n in &s.notes {
                eprintln!("{n}");
            }
            if !args.json {
                eprintln!(
                    "state: {} (a snapshot every {} cycles; see docs/persistence.md)",
                    dir.display(),
                    s.persister.config().every_cycles
                );
            }
            (s.plc, Some(s.persister), s.events)
        }
        None => {
            if args.cold && !args.json {
                eprintln!("cold start: no state directory, nothing saved is used");
            }
            let mut plc = Plc::new(program.clone(), 0, MonotonicStopwatch::boxed());
            let ev = plc.drain_events();
            (plc, None, ev)
        }
    };
    for e in &start_events {
        print_event(e, args.json);
    }
    if args.virtual_time {
        plc.use_virtual_time(period_us);
    } else if args.period.is_some() {
        plc.set_limits(cetratus_runtime::Limits::for_period_us(period_us));
    }
    plc.set_limits(local.limits(plc.limits()));
    // Program time resumes after the last committed cycle; `--for`, `--at` and `--press` count
    // from the start of this run.
    let base_us = if plc.cycles() > 0 {
        plc.now_us().saturating_add(period_us)
    } else {
        0
    };
    crate::run_io::press(&mut io, &args.plant.press, base_us)?;
    crate::run_io::admit(&io, &mut plc);
    let load = cetratus_node::load::LoadPolicy {
        trust: trust.clone(),
        unsigned: cetratus_program::Unsigned::allowed_if(allow_unsigned),
        gate: local.gate,
    };
    let opts = NodeOptions {
        base_us,
        load: load.clone(),
        record_trace: args.trace.is_some() || args.svg.is_some(),
        progress_every: args.progress,
    };
    let observer = crate::run_opcua::observer(&io);
    let mut node = Node::new(plc, io, opts)
        .with_script(script)
        .with_validation(local.validation, period_us, |io| {
            io.twin().map(|t| t.plant().clone())
        })
        .with_auto_substitute(local.auto_substitute.clone());
    if let Some(observe) = observer {
        node = node.with_observer(observe);
    }
    if let Some(p) = persister {
        node = node.with_persister(p);
    }
    let json = args.json;
    // Kept for the JSON summary; on the echo thread, never on the scan thread.
    let events = Arc::new(Mutex::new((
        start_events.iter().map(wire::event).collect(),
        0,
    )));
    let kept = events.clone();
    node = node.with_echo(move |e| match e {
        Echo::Event(e) => {
            print_event(&e, json);
            if let Ok(mut k) = kept.lock() {
                let (list, left_out): &mut (Vec<_>, u64) = &mut k;
                if list.len() < MAX_EVENTS {
                    list.push(wire::event(&e));
                } else {
                    *left_out += 1;
                }
            }
        }
        Echo::Warning(w) => eprintln!("warning: {w}"),
        Echo::Progress { cycle, committed } => eprintln!(
            "progress cycle={cycle} committed={}",
            committed.map_or(-1, |c| c as i64)
        ),
    });
    let mut services = None;
    if let Some((link, s)) = mqtt {
        let mut link =
            crate::mqtt_args::control_link(link, node.plc(), load, args.speed, period_us);
        if let Some(q) = crate::run_opcua::input_quality(node.io()) {
            link.set_input_quality(q);
        }
        node = node.with_link(link);
        services = Some(s);
    }
    let reached_us = if args.virtual_time {
        node.run_virtual(period_us, until_us)
    } else {
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        ctrlc::set_handler(move || s.store(true, std::sync::atomic::Ordering::Relaxed))
            .context("cannot install the Ctrl-C handler")?;
        if args.rt {
            let status = cetratus_node::rt::request(80);
            for w in &status.warnings {
                eprintln!("warning: {w}");
            }
            eprintln!("real time: {status}");
        }
        if !args.json {
            eprintln!(
                "running {} on the {plant} in real time (speed {}); Ctrl-C stops",
                program.name(),
                args.speed
            );
        }
        let reached = node.run_realtime(period_us, until_us, args.speed, &stop);
        // On a stop, the field gets its safe values before anything else is shut down.
        if let Some(f) = node.io_mut().field_mut() {
            f.stop();
        }
        reached
    };
    let finished = node.finish();
    if let Some(s) = services {
        s.stop();
    }
    let (plc, io, report) = finished?;
    if let Some(c) = report.link.filter(|c| c.dropped > 0) {
        eprintln!(
            "warning: {} events and replies were not published: the MQTT client was behind",
            c.dropped
        );
    }
    if let (Some(stats), Some(dir)) = (&report.persist, &state_dir) {
        if let Some(err) = &stats.last_error {
            eprintln!(
                "warning: the state directory {} could not be written: {err}",
                dir.display()
            );
        }
    }
    let plant_report = crate::run_io::report(&io)?;
    let mut faults = plant_report.faults;
    faults.extend(report.faults);
    let scan = plc.monitor().stats[plc.primary().index()].scan.summary();
    let figures = CycleFigures {
        cycles: plc.cycles(),
        period_us,
        scan,
        cycle: report.timing.cycle.summary(),
        latency: report.timing.latency.summary(),
        overruns: report.timing.overruns,
    };
    let (events, left_out) = std::mem::take(
        &mut *events
            .lock()
            .map_err(|_| anyhow::anyhow!("the event list was poisoned"))?,
    );
    let summary = Summary {
        events,
        events_left_out: left_out + report.echo_dropped,
        program: program.name().to_string(),
        twin: kind.map_or_else(String::new, |k| k.to_string()),
        seconds: reached_us as f64 / 1e6,
        scans: plc.cycles(),
        firings: plc.primary_container().firings().iter().sum(),
        parts_finished: plant_report.parts_finished,
        twin_faults: plant_report.twin_faults,
        faults,
        counters: plant_report.counters,
        io: plant_report.io,
        modbus_server: plant_report.server,
        opcua_server: plant_report.opcua,
        scan: figures,
        primary: plc.primary().as_str(),
        status: plc.status().as_str(),
        state_dir: state_dir.as_ref().map(|d| d.display().to_string()),
        persist: report.persist,
    };
    if let Some(mut trace) = report.trace {
        trace.end_us = reached_us;
        if let Some(path) = &args.trace {
            let text = if path.extension().is_some_and(|e| e == "json") {
                serde_json::to_string_pretty(&trace)?
            } else {
                trace.to_csv()
            };
            std::fs::write(path, text)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
        if let Some(path) = &args.svg {
            let title = format!("{} on the {plant}", program.name());
            let mut diagram = trace.diagram(&title);
            // In virtual time every scan is one period: the axis can number the scan steps.
            diagram.scan_period_us = args.virtual_time.then_some(period_us);
            std::fs::write(path, diagram.to_svg())
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_summary(&summary);
    }
    Ok(())
}
