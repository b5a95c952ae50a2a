//! `cetratus run`: a program against a digital twin, field I/O or both, in virtual or real time.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use anyhow::{bail, Context};
use cetratus_node::plant::PlantSpec;
use cetratus_node::script::Script;
use cetratus_node::{wire, Echo, Finished, NodeSpec, Notice, StateDir, TimeMode};
use cetratus_program::Program;
use cetratus_runtime::CycleFigures;
use cetratus_twin::TwinKind;

use crate::summary::{print_event, print_summary, Summary, MAX_EVENTS};

use crate::parse_duration_us;

/// Arguments of `cetratus run`.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// The program: a TOML program file, or a PNML file that carries its program.
    program: PathBuf,
    /// The plant to drive: a digital twin (a run has --twin, --io, or both).
    #[arg(long)]
    twin: Option<TwinKind>,
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
    /// Play back recorded inputs, one row per scan, from a CSV in the format `--trace` writes
    /// (instead of a twin; docs/operations.md, *Replaying a trace*).
    #[arg(long, value_name = "TRACE.csv")]
    replay: Option<PathBuf>,
    /// Write the I/O trace: `.csv` or `.json`.
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Record a variable of the program's Structured Text in the trace too, as a column after
    /// the outputs: `NAME` or `INSTANCE.MEMBER`, of an elementary type (repeatable).
    #[arg(long, value_name = "NAME")]
    watch: Vec<String>,
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
    /// `60s substitute [keep|retransform]`, `70s remove`, `70s abort`, `80s reset`, and in
    /// probation `90s revert` or `90s accept`. Times count from the start of this run; commands
    /// due in the same cycle run one per cycle, in order.
    #[arg(long = "at")]
    at: Vec<String>,
    /// MQTT (real-time runs): the embedded broker by default, or a plant broker.
    #[command(flatten)]
    mqtt: crate::mqtt_args::MqttArgs,
    /// Where the dashboard listens (real-time runs).
    #[arg(long, default_value = "127.0.0.1:8080")]
    http: String,
    /// Real-time runs without MQTT and dashboard (`--no-mct`, its old name, still works).
    #[arg(long, alias = "no-mct")]
    no_mqtt: bool,
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

/// The events a run keeps for its JSON summary, and how many it left out.
type Kept = Arc<Mutex<(Vec<cetratus_proto::EventMsg>, u64)>>;

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
    let kept: Kept = Arc::default();
    let spec = spec(args, program.clone(), kept.clone())?;
    let quiet = args.json || args.virtual_time;
    let mut say = |n: Notice| match n {
        Notice::Note(line) => eprintln!("{line}"),
        Notice::Info(line) if !quiet => eprintln!("{line}"),
        Notice::Info(_) => {}
        Notice::Warning(line) => eprintln!("warning: {line}"),
    };
    let mut node = spec.start(&mut say)?;
    if let Ok(mut k) = kept.lock() {
        k.0.extend(node.start_events().iter().map(wire::event));
    }
    for e in node.start_events() {
        print_event(e, args.json);
    }
    let plant = plant_label(args);
    let stop = Arc::new(AtomicBool::new(false));
    if !args.virtual_time {
        let s = stop.clone();
        ctrlc::set_handler(move || s.store(true, std::sync::atomic::Ordering::Relaxed))
            .context("cannot install the Ctrl-C handler")?;
        if !args.json {
            eprintln!(
                "running {} on the {plant} in real time (speed {}); Ctrl-C stops",
                program.name(),
                args.speed
            );
        }
    }
    let reached_us = node.run(until_us, &stop, &mut say);
    let state_dir = node.state_dir().map(|d| d.display().to_string());
    let period_us = node.period_us();
    let finished = node.finish()?;
    warn_dropped(&finished, state_dir.as_deref());
    let summary = summary(
        args, &program, &finished, &kept, reached_us, period_us, state_dir,
    )?;
    write_trace(
        args,
        &plant,
        &program,
        finished.report.trace,
        reached_us,
        period_us,
    )?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_summary(&summary);
    }
    Ok(())
}

/// What the run drives, in words.
fn plant_label(args: &RunArgs) -> String {
    match (args.twin, &args.replay) {
        (Some(k), _) => format!("{k} twin"),
        (None, Some(_)) => "replayed trace".to_string(),
        (None, None) => "field I/O".to_string(),
    }
}

/// The node `args` ask for: the command line mapped onto a [`NodeSpec`], nothing decided here.
fn spec(args: &RunArgs, program: Arc<Program>, kept: Kept) -> anyhow::Result<NodeSpec> {
    let local = args.config.load()?;
    let io = args
        .io
        .as_deref()
        .map(cetratus_io::config::IoConfig::load)
        .transpose()?;
    let plant = PlantSpec {
        twin: args.twin,
        settings: args.plant.settings(),
        io,
        presses: args.plant.press.clone(),
        replay: args.replay.clone(),
    };
    let mut spec = NodeSpec::new(program, &args.mqtt.plc_id(), local, plant);
    spec.time = if args.virtual_time {
        TimeMode::Virtual
    } else {
        TimeMode::Real {
            speed: args.speed,
            rt: args.rt,
        }
    };
    spec.period_us = args.period.as_deref().map(parse_duration_us).transpose()?;
    if !args.no_mqtt {
        let dashboard = (!args.no_dashboard).then_some(args.http.as_str());
        spec.mqtt = Some(args.mqtt.spec(&spec.local, dashboard, !args.json)?);
    }
    spec.state = args
        .state_dir
        .clone()
        .map_or(StateDir::Default, StateDir::At);
    spec.cold = args.cold;
    spec.trust = args
        .trust
        .as_deref()
        .map(cetratus_program::TrustStore::load_dir)
        .transpose()?;
    spec.allow_unsigned = args.allow_unsigned;
    spec.script = Script::parse(&args.at)?;
    spec.record_trace = args.trace.is_some() || args.svg.is_some();
    spec.watch = watched(args, &spec.program)?;
    spec.progress_every = args.progress;
    spec.echo = Some(Box::new(echo(args.json, kept)));
    Ok(spec)
}

/// The `--watch` names, each a variable of the program (`[[variable]]`) or one of an elementary
/// type of its Structured Text.
fn watched(args: &RunArgs, program: &Program) -> anyhow::Result<Vec<String>> {
    if args.watch.is_empty() {
        return Ok(Vec::new());
    }
    if args.trace.is_none() && args.svg.is_none() {
        bail!("--watch adds columns to the trace: add --trace FILE.csv (or --svg)");
    }
    for name in &args.watch {
        if program.variable_index(name).is_some() {
            continue;
        }
        let st = program.st();
        if st.is_some_and(|st| st.locate(name).is_some()) {
            continue;
        }
        let mut vars: Vec<&str> = program
            .variables()
            .iter()
            .map(|v| v.name.as_str())
            .collect();
        if let Some(st) = st {
            vars.extend(st.unit().vars.iter().map(|v| v.name.as_str()));
        }
        let listed = match vars.is_empty() {
            true => "it has none; watch its signals in the trace as they are".to_string(),
            false => format!(
                "its variables: {}; a member of an ST instance is INSTANCE.MEMBER",
                vars.join(", ")
            ),
        };
        bail!(
            "--watch {name}: `{}` has no variable `{name}` ({listed})",
            program.name()
        );
    }
    Ok(args.watch.clone())
}

/// Prints what the node echoes, and keeps its events for the JSON summary (on the echo thread,
/// never on the scan thread).
fn echo(json: bool, kept: Kept) -> impl FnMut(Echo) + Send + 'static {
    move |e| match e {
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
        Echo::Progress { cycle, committed } => eprintln!(
            "progress cycle={cycle} committed={}",
            committed.map_or(-1, |c| c as i64)
        ),
    }
}

/// Warns of what the node could not publish or save.
fn warn_dropped(finished: &Finished, state_dir: Option<&str>) {
    if let Some(c) = finished.report.link.filter(|c| c.dropped > 0) {
        eprintln!(
            "warning: {} events and replies were not published: the MQTT client was behind",
            c.dropped
        );
    }
    if let (Some(stats), Some(dir)) = (&finished.report.persist, state_dir) {
        if let Some(err) = &stats.last_error {
            eprintln!("warning: the state directory {dir} could not be written: {err}");
        }
    }
}

/// The closing summary of the run.
fn summary(
    args: &RunArgs,
    program: &Program,
    f: &Finished,
    kept: &Kept,
    reached_us: u64,
    period_us: u64,
    state_dir: Option<String>,
) -> anyhow::Result<Summary> {
    let (plc, report, plant) = (&f.plc, &f.report, &f.plant);
    let mut faults = plant.faults.clone();
    faults.extend(report.faults.iter().cloned());
    let figures = CycleFigures {
        cycles: plc.cycles(),
        period_us,
        scan: plc.monitor().stats[plc.primary().index()].scan.summary(),
        cycle: report.timing.cycle.summary(),
        latency: report.timing.latency.summary(),
        overruns: report.timing.overruns,
    };
    let (events, left_out) = std::mem::take(
        &mut *kept
            .lock()
            .map_err(|_| anyhow::anyhow!("the event list was poisoned"))?,
    );
    Ok(Summary {
        events,
        events_left_out: left_out + report.echo_dropped,
        program: program.name().to_string(),
        twin: args.twin.map_or_else(String::new, |k| k.to_string()),
        plant: plant_label(args),
        seconds: reached_us as f64 / 1e6,
        scans: plc.cycles(),
        firings: plc.primary_container().firings().iter().sum(),
        parts_finished: plant.parts_finished,
        twin_faults: plant.twin_faults,
        faults,
        counters: serde_json::to_value(&plant.counters)?,
        io: plant.io.clone(),
        modbus_server: plant.server,
        #[cfg(feature = "opcua")]
        opcua_server: plant.opcua,
        scan: figures,
        primary: plc.primary().as_str(),
        status: plc.status().as_str(),
        state_dir,
        persist: report.persist.clone(),
    })
}

/// Writes the I/O trace (`--trace`) and its timing diagram (`--svg`), when asked for.
fn write_trace(
    args: &RunArgs,
    plant: &str,
    program: &Program,
    trace: Option<cetratus_runtime::trace::Trace>,
    reached_us: u64,
    period_us: u64,
) -> anyhow::Result<()> {
    let Some(mut trace) = trace else {
        return Ok(());
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
        let title = format!("{} on the {plant}", program.name());
        let mut diagram = trace.diagram(&title);
        // In virtual time every scan is one period: the axis can number the scan steps.
        diagram.scan_period_us = args.virtual_time.then_some(period_us);
        std::fs::write(path, diagram.to_svg())
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}
