//! `cetratus demo`: the paper's U.1/U.2 experiment on the Vernadat cell (`cetratus_node::demo`).
//!
//! `--scripted` plays the experiment in virtual time and prints a table like the paper's Fig. 7,
//! an SVG timing diagram and, with `--json`, one JSON object. Without it, the cell runs in real
//! time with the embedded broker and the dashboard.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use cetratus_node::demo::{default_dir, diagram, prepare, scripted, table, DemoFiles};
use cetratus_node::plant::PlantSpec;
use cetratus_node::services::Services;
use cetratus_node::{Echo, NodeSpec, Notice, StateDir, TimeMode};
use cetratus_program::Program;
use cetratus_twin::TwinKind;

/// Arguments of `cetratus demo`.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Play the experiment in virtual time and print the table, the diagram and the events.
    #[arg(long)]
    pub scripted: bool,
    /// Print one JSON object with `steps` and `events`.
    #[arg(long)]
    pub json: bool,
    /// Write the SVG timing diagram here.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// Where the demo keeps its programs, key and packages.
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// In real time, how many times faster than the wall clock the cell runs.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Where the dashboard listens.
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub http: String,
    /// Run for this long (program time), then stop; forever when absent.
    #[arg(long = "for")]
    pub for_: Option<String>,
    /// MQTT: the embedded broker, or a plant broker.
    #[command(flatten)]
    pub mqtt: crate::mqtt_args::MqttArgs,
    /// The local configuration (operator keys, broker accounts, more trusted keys).
    #[command(flatten)]
    pub config: crate::config::ConfigArgs,
}

/// Runs `cetratus demo`.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    let dir = args.dir.clone().unwrap_or_else(default_dir);
    let json = args.json;
    let files = prepare(&dir, |line| {
        if !json {
            eprintln!("{line}");
        }
    })?;
    if !args.scripted {
        return live(args, &files);
    }
    // The analysis gate as the configuration sets it, as in a real run.
    let local = args.config.load()?;
    let rec = scripted(&files, local.gate)?;
    let end_ms = rec.steps.last().map_or(0.0, |s| s.time_ms);
    if let Some(path) = &args.svg {
        std::fs::write(path, diagram(&rec, end_ms).to_svg())
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    if args.json {
        println!("{}", serde_json::to_string(&rec)?);
        return Ok(());
    }
    print!("{}", table(&rec));
    println!("\nevents:");
    for e in &rec.events {
        println!(
            "  {:>9.2} s  {:<20} {}",
            e.time_us as f64 / 1e6,
            e.kind,
            e.message
        );
    }
    for info in &rec.exec_info {
        for c in info.0.iter().flatten() {
            if c.role == cetratus_proto::Role::Candidate {
                println!(
                    "\nquarantine of {} {}: divergence {}, cause: {}, max drift {}",
                    c.program.name,
                    c.program.version,
                    serde_json::json!(c.divergence),
                    c.first_cause.as_deref().unwrap_or("none"),
                    c.max_drift
                );
            }
        }
    }
    println!(
        "\n{} parts finished, {} faults; PRIMARY = {} at the end",
        rec.parts_finished,
        rec.faults.len(),
        rec.steps.last().map_or("A", |s| s.primary.as_str())
    );
    Ok(())
}

/// The live demo: the cell in real time, the embedded broker and the dashboard.
fn live(args: &DemoArgs, files: &DemoFiles) -> anyhow::Result<()> {
    use std::sync::atomic::{AtomicBool, Ordering};

    let program = Arc::new(Program::load(&files.program)?);
    let local = args.config.load()?;
    let until_us = match &args.for_ {
        Some(d) => crate::parse_duration_us(d)?,
        None => u64::MAX,
    };
    let plc_id = args.mqtt.plc_id();
    let plant = PlantSpec {
        twin: Some(TwinKind::Vernadat),
        settings: cetratus_twin::TwinSettings {
            seed: 1,
            ..Default::default()
        },
        ..PlantSpec::default()
    };
    let mut spec = NodeSpec::new(program, &plc_id, local, plant);
    // The demo key, and whatever the local configuration trusts.
    let mut trust = files.trust.clone();
    trust.merge(&spec.local.trust);
    spec.trust = Some(trust);
    spec.time = TimeMode::Real {
        speed: args.speed,
        rt: false,
    };
    spec.state = StateDir::Nowhere;
    spec.mqtt = Some(args.mqtt.spec(&spec.local, Some(&args.http), false)?);
    spec.echo = Some(Box::new(|e| {
        if let Echo::Event(e) = e {
            crate::summary::print_event(&e, false);
        }
    }));
    let speed = spec.time.speed();
    let mut say = |n: Notice| match n {
        Notice::Warning(line) => eprintln!("warning: {line}"),
        Notice::Note(line) | Notice::Info(line) => eprintln!("{line}"),
    };
    let mut node = spec.start(&mut say)?;
    if let Some(services) = node.services() {
        banner(files, services, speed, &plc_id);
    }
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    ctrlc::set_handler(move || s.store(true, Ordering::Relaxed))
        .context("cannot install the Ctrl-C handler")?;
    node.run(until_us, &stop, &mut say);
    let finished = node.finish()?;
    println!(
        "stopped: {} parts finished, {} faults",
        finished.plant.parts_finished, finished.plant.twin_faults
    );
    Ok(())
}

/// What the live demo prints first: where the dashboard and the broker are, the packages, and
/// what to try.
fn banner(files: &DemoFiles, services: &Services, speed: f64, plc_id: &str) {
    let broker_url = services.broker_url();
    println!(
        "Cetratus demo: the Vernadat cell runs in real time (speed {speed}) with its digital twin."
    );
    if let Some(url) = services.companion_link() {
        println!("  dashboard   {url}");
        println!("              (a one-time link: it logs one browser in)");
    }
    println!("  MQTT        {broker_url}, topics cetratus/{plc_id}/…");
    println!(
        "  U.1         {}  (two more buffer slots; load it first)",
        files.u1_path.display()
    );
    println!(
        "  U.2         {}  (lubrication stage; built against U.1)",
        files.u2_path.display()
    );
    println!(
        "Try: open the dashboard, Load U.1 and watch B run in quarantine beside A; when the buffer"
    );
    println!("fills, A blocks at T13 and B does not. Substitute, then load U.2 the same way.");
    println!(
        "From a shell: cetratus load {} --plc {plc_id} --broker {broker_url}",
        files.u1_path.display()
    );
    println!("Ctrl-C stops.");
}
