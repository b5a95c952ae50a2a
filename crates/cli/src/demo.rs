//! `cetratus demo`: the paper's U.1/U.2 experiment on the Vernadat cell.
//!
//! On first run it writes the Vernadat example into its directory, makes a demo signing key, and
//! builds and signs U.1 and U.2. `--scripted` plays the experiment in virtual time and prints a
//! table like the paper's Fig. 7, an SVG timing diagram and, with `--json`, one JSON object.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{bail, Context};
use cetratus_io::TwinDriver;
use cetratus_program::{build_package, KeyPair, Program, TrustStore, Value};
use cetratus_runtime::monitor::Slot;
use cetratus_runtime::trace::{Lane, TimingDiagram};
use cetratus_runtime::{Command, Event, Plc, SubstituteMode, SubstituteRequest};
use cetratus_twin::{Twin, TwinKind};
use serde::Serialize;

/// The Vernadat example, embedded so the demo runs from any directory.
const FILES: [(&str, &str); 8] = [
    (
        "vernadat.toml",
        include_str!("../../../examples/vernadat/vernadat.toml"),
    ),
    (
        "vernadat.pnml",
        include_str!("../../../examples/vernadat/vernadat.pnml"),
    ),
    (
        "u1.toml",
        include_str!("../../../examples/vernadat/u1.toml"),
    ),
    (
        "u1.pnml",
        include_str!("../../../examples/vernadat/u1.pnml"),
    ),
    (
        "u2.toml",
        include_str!("../../../examples/vernadat/u2.toml"),
    ),
    (
        "u2.pnml",
        include_str!("../../../examples/vernadat/u2.pnml"),
    ),
    (
        "u1.package.toml",
        include_str!("../../../examples/vernadat/u1.package.toml"),
    ),
    (
        "u2.package.toml",
        include_str!("../../../examples/vernadat/u2.package.toml"),
    ),
];

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

/// The files the demo works with.
pub struct DemoFiles {
    /// The initial program.
    pub program: PathBuf,
    /// U.1, signed.
    pub u1: Vec<u8>,
    /// U.2, signed.
    pub u2: Vec<u8>,
    /// Where U.1 was written.
    pub u1_path: PathBuf,
    /// Where U.2 was written.
    pub u2_path: PathBuf,
    /// Trusts the demo key.
    pub trust: TrustStore,
}

/// The demo's directory: `$XDG_DATA_HOME/cetratus/demo`, `~/.local/share/cetratus/demo`, or
/// `.cetratus-demo` here.
pub fn default_dir() -> PathBuf {
    if let Some(x) = std::env::var_os("XDG_DATA_HOME") {
        return PathBuf::from(x).join("cetratus/demo");
    }
    if let Some(h) = std::env::var_os("HOME") {
        return PathBuf::from(h).join(".local/share/cetratus/demo");
    }
    PathBuf::from(".cetratus-demo")
}

/// Writes the example, makes the key and builds the packages where missing.
pub fn prepare(dir: &Path, quiet: bool) -> anyhow::Result<DemoFiles> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    for (name, text) in FILES {
        let path = dir.join(name);
        if std::fs::read_to_string(&path).ok().as_deref() != Some(text) {
            std::fs::write(&path, text)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
    }
    let key_path = dir.join("demo.key");
    let key = if key_path.exists() {
        KeyPair::load(&key_path)?
    } else {
        let k = KeyPair::generate();
        k.save(&key_path)?;
        if !quiet {
            eprintln!(
                "made a demo signing key {} (id {})",
                key_path.display(),
                k.key_id()
            );
        }
        k
    };
    let trusted = dir.join("trusted");
    std::fs::create_dir_all(&trusted)?;
    let pub_src = KeyPair::public_path(&key_path);
    std::fs::copy(&pub_src, trusted.join("demo.pub"))
        .with_context(|| format!("cannot copy {}", pub_src.display()))?;
    let trust = TrustStore::load_dir(&trusted)?;
    let build = |manifest: &str, out: &str| -> anyhow::Result<Vec<u8>> {
        let (bytes, _report) = build_package(&dir.join(manifest), Some(&key))?;
        std::fs::write(dir.join(out), &bytes)?;
        Ok(bytes)
    };
    let u1 = build("u1.package.toml", "u1.cpkg")?;
    let u2 = build("u2.package.toml", "u2.cpkg")?;
    if !quiet {
        eprintln!(
            "built and signed {} and {}",
            dir.join("u1.cpkg").display(),
            dir.join("u2.cpkg").display()
        );
    }
    Ok(DemoFiles {
        u1_path: dir.join("u1.cpkg"),
        u2_path: dir.join("u2.cpkg"),
        program: dir.join("vernadat.toml"),
        u1,
        u2,
        trust,
    })
}

/// One scan in which anything changed.
#[derive(Debug, Serialize)]
pub struct Step {
    /// Scan index.
    pub step: u64,
    /// Virtual time at the scan's start, ms.
    pub time_ms: f64,
    /// PRIMARY.
    pub primary: Slot,
    /// STATUS.
    pub status: &'static str,
    /// Inputs by name.
    pub inputs: BTreeMap<String, bool>,
    /// Outputs of A by name, or null.
    pub outputs_a: Option<BTreeMap<String, bool>>,
    /// Outputs of B by name, or null.
    pub outputs_b: Option<BTreeMap<String, bool>>,
    /// Dispatched outputs by name.
    pub dispatched: BTreeMap<String, bool>,
    /// Marking of A by place id, or null.
    pub marking_a: Option<BTreeMap<String, u32>>,
    /// Marking of B by place id, or null.
    pub marking_b: Option<BTreeMap<String, u32>>,
}

/// The record of a scripted run.
#[derive(Debug, Serialize)]
pub struct DemoRecord {
    /// The steps.
    pub steps: Vec<Step>,
    /// The events.
    pub events: Vec<Event>,
    /// Parts finished by the twin.
    pub parts_finished: u64,
    /// Faults the twin saw.
    pub faults: Vec<String>,
    /// program_exec_info at the end of each quarantine, in order.
    pub exec_info: Vec<serde_json::Value>,
}

fn named(names: &[String], values: &[Value]) -> BTreeMap<String, bool> {
    names
        .iter()
        .zip(values)
        .map(|(n, v)| (n.clone(), matches!(v, Value::Bool(true))))
        .collect()
}

/// What makes a step differ from the previous one.
type StepKey = (
    Slot,
    &'static str,
    Vec<Value>,
    Vec<Option<Vec<Value>>>,
    Vec<Option<Vec<u32>>>,
);

struct Recorder {
    steps: Vec<Step>,
    last_key: Option<StepKey>,
}

impl Recorder {
    fn observe(&mut self, plc: &Plc, now_us: u64) {
        let outs: Vec<Option<Vec<Value>>> = [Slot::A, Slot::B]
            .iter()
            .map(|&s| plc.outputs_of(s).map(|o| o.to_vec()))
            .collect();
        let marks: Vec<Option<Vec<u32>>> = [Slot::A, Slot::B]
            .iter()
            .map(|&s| plc.container(s).map(|c| c.marking().to_vec()))
            .collect();
        let key = (
            plc.primary(),
            plc.status().name(),
            plc.inputs().to_vec(),
            outs,
            marks,
        );
        if self.last_key.as_ref() == Some(&key) {
            return;
        }
        let io_out = plc.io_outputs();
        let marking = |s: Slot| {
            plc.container(s).map(|c| {
                c.program()
                    .net()
                    .places()
                    .iter()
                    .zip(c.marking())
                    .map(|(p, &m)| (p.id.clone(), m))
                    .collect()
            })
        };
        self.steps.push(Step {
            step: plc.cycles() - 1,
            time_ms: now_us as f64 / 1e3,
            primary: plc.primary(),
            status: plc.status().name(),
            inputs: named(plc.io_inputs(), plc.inputs()),
            outputs_a: plc.outputs_of(Slot::A).map(|o| named(io_out, o)),
            outputs_b: plc.outputs_of(Slot::B).map(|o| named(io_out, o)),
            dispatched: named(io_out, plc.dispatched()),
            marking_a: marking(Slot::A),
            marking_b: marking(Slot::B),
        });
        self.last_key = Some(key);
    }
}

const PERIOD_US: u64 = 10_000;

struct Run {
    plc: Plc,
    io: TwinDriver<Twin>,
    now: u64,
    rec: Recorder,
    events: Vec<Event>,
}

impl Run {
    fn step(&mut self) {
        self.plc.cycle(self.now, &mut self.io);
        self.rec.observe(&self.plc, self.now);
        self.events.extend(self.plc.drain_events());
        drop(self.plc.take_retired());
        self.now += PERIOD_US;
    }
    fn run_until(&mut self, t_us: u64) {
        while self.now < t_us {
            self.step();
        }
    }
    fn run_while(&mut self, max_us: u64, mut cond: impl FnMut(&Plc) -> bool) {
        let end = self.now + max_us;
        while self.now < end && cond(&self.plc) {
            self.step();
        }
    }
    fn command(&mut self, cmd: Command) -> anyhow::Result<()> {
        let r = self.plc.command(cmd);
        self.events.extend(self.plc.drain_events());
        r.map_err(|e| anyhow::anyhow!(e))
    }
    fn load(&mut self, bytes: &[u8], trust: &TrustStore) -> anyhow::Result<()> {
        let prepared = self
            .plc
            .update_context()
            .prepare_package(bytes, trust, false, false)
            .map_err(|e| anyhow::anyhow!(e))?;
        self.command(Command::Load(Box::new(prepared)))
    }
    fn substitute(&mut self) -> anyhow::Result<()> {
        self.command(Command::Substitute(SubstituteRequest {
            mode: SubstituteMode::Retransform,
            when: None,
            within_us: None,
            force: false,
        }))?;
        self.step();
        Ok(())
    }
    fn exec_info(&self) -> serde_json::Value {
        serde_json::to_value(self.plc.exec_info()).unwrap_or(serde_json::Value::Null)
    }
}

/// Plays the paper's experiment in virtual time.
pub fn scripted(files: &DemoFiles) -> anyhow::Result<DemoRecord> {
    let program = Arc::new(Program::load(&files.program)?);
    let twin = TwinKind::Vernadat.build(1);
    let io = TwinDriver::new(twin, program.inputs(), program.outputs())?;
    let mut plc = Plc::new(program, 0);
    plc.use_virtual_time(PERIOD_US);
    let mut r = Run {
        plc,
        io,
        now: 0,
        rec: Recorder {
            steps: Vec::new(),
            last_key: None,
        },
        events: Vec::new(),
    };
    let mut exec_info = Vec::new();
    r.step();
    r.run_until(10_000_000);

    // U.1 into B; quarantine until the buffer is full in A's eyes and B keeps going.
    r.load(&files.u1, &files.trust)?;
    r.step();
    let b = Slot::B.index();
    r.run_while(300_000_000, |plc| {
        plc.monitor.stats[b]
            .divergent_cycles
            .iter()
            .all(|&n| n == 0)
    });
    r.run_until(r.now + 10_000_000);
    exec_info.push(r.exec_info());
    r.substitute()?;
    if r.plc.primary() != Slot::B {
        bail!("U.1 was not substituted: {:?}", r.events.last());
    }
    r.run_until(r.now + 10_000_000);

    // U.2 into A with the generated transformation; quarantine over a full processing cycle, so
    // that LM1 and LM2 show in the candidate's outputs and the drift shows.
    r.load(&files.u2, &files.trust)?;
    r.step();
    let a = Slot::A.index();
    let lm: Vec<usize> = ["LM1", "LM2"]
        .iter()
        .filter_map(|n| r.plc.io_outputs().iter().position(|o| o == n))
        .collect();
    let mut seen = vec![false; lm.len()];
    let mut drift_seen = false;
    r.run_while(120_000_000, |plc| {
        if let Some(o) = plc.outputs_of(Slot::A) {
            for (s, &k) in seen.iter_mut().zip(&lm) {
                *s |= matches!(o[k], Value::Bool(true));
            }
        }
        drift_seen |= plc.monitor.stats[a].drift > 0;
        !(seen.iter().all(|&s| s) && drift_seen)
    });
    r.run_until(r.now + 5_000_000);
    exec_info.push(r.exec_info());
    r.substitute()?;
    if r.plc.primary() != Slot::A {
        bail!("U.2 was not substituted: {:?}", r.events.last());
    }
    r.run_until(r.now + 20_000_000);

    use cetratus_twin::Plant;
    Ok(DemoRecord {
        parts_finished: r.io.plant().counters().get("parts_finished").unwrap_or(0),
        faults: r
            .io
            .plant()
            .faults()
            .iter()
            .map(|f| f.to_string())
            .collect(),
        steps: r.rec.steps,
        events: r.events,
        exec_info,
    })
}

/// The SVG timing diagram of a scripted run (the paper's Fig. 7).
pub fn diagram(rec: &DemoRecord, end_ms: f64) -> TimingDiagram {
    let mut d = TimingDiagram::new(
        "Vernadat cell: U.1 then U.2, live (inputs, outputs of A and B, dispatched)",
        (end_ms * 1e3) as u64,
    );
    let Some(first) = rec.steps.first() else {
        return d;
    };
    let lane = |group: &str, name: &str, pick: &dyn Fn(&Step) -> Option<bool>| Lane {
        label: name.to_string(),
        group: group.to_string(),
        changes: rec
            .steps
            .iter()
            .map(|s| ((s.time_ms * 1e3) as u64, pick(s).unwrap_or(false)))
            .collect(),
    };
    for n in first.inputs.keys() {
        d.lanes
            .push(lane("inputs", n, &|s| s.inputs.get(n).copied()));
    }
    for n in first.dispatched.keys() {
        d.lanes.push(lane("outputs of A", n, &|s| {
            s.outputs_a.as_ref().and_then(|o| o.get(n).copied())
        }));
    }
    for n in first.dispatched.keys() {
        d.lanes.push(lane("outputs of B", n, &|s| {
            s.outputs_b.as_ref().and_then(|o| o.get(n).copied())
        }));
    }
    for n in first.dispatched.keys() {
        d.lanes
            .push(lane("dispatched", n, &|s| s.dispatched.get(n).copied()));
    }
    for e in &rec.events {
        if matches!(
            e.kind,
            "load_accepted" | "substituted" | "quarantine_started"
        ) {
            d.markers.push((e.time_us, e.kind.replace('_', " ")));
        }
    }
    d
}

fn on(m: &BTreeMap<String, bool>) -> String {
    let v: Vec<&str> = m
        .iter()
        .filter(|(_, &b)| b)
        .map(|(k, _)| k.as_str())
        .collect();
    if v.is_empty() {
        "-".into()
    } else {
        v.join(" ")
    }
}

/// The Fig. 7-like table: one row per step.
pub fn table(rec: &DemoRecord) -> String {
    let mut s = format!(
        "{:>9}  {:<3} {:<10}  {:<28} | {:<22} | {:<22} | {}\n",
        "time s", "PRI", "STATUS", "inputs", "outputs A", "outputs B", "dispatched"
    );
    for st in &rec.steps {
        let opt = |o: &Option<BTreeMap<String, bool>>| o.as_ref().map_or("(empty)".to_string(), on);
        s.push_str(&format!(
            "{:>9.2}  {:<3} {:<10}  {:<28} | {:<22} | {:<22} | {}\n",
            st.time_ms / 1e3,
            st.primary.name(),
            st.status,
            on(&st.inputs),
            opt(&st.outputs_a),
            opt(&st.outputs_b),
            on(&st.dispatched)
        ));
    }
    s
}

/// Runs `cetratus demo`.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    let dir = args.dir.clone().unwrap_or_else(default_dir);
    let files = prepare(&dir, args.json)?;
    if !args.scripted {
        return live(args, &files);
    }
    let rec = scripted(&files)?;
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
        for c in info
            .as_array()
            .into_iter()
            .flatten()
            .filter(|c| !c.is_null())
        {
            if c["role"] == "candidate" {
                println!(
                    "\nquarantine of {} {}: divergence {}, cause: {}, max drift {}",
                    c["program"]["name"],
                    c["program"]["version"],
                    c["divergence"],
                    c["first_cause"],
                    c["max_drift"]
                );
            }
        }
    }
    println!(
        "\n{} parts finished, {} faults; PRIMARY = {} at the end",
        rec.parts_finished,
        rec.faults.len(),
        rec.steps.last().map_or("A", |s| s.primary.name())
    );
    Ok(())
}

/// The live demo: the cell in real time, the embedded broker and the dashboard.
fn live(args: &DemoArgs, files: &DemoFiles) -> anyhow::Result<()> {
    use std::sync::atomic::{AtomicBool, Ordering};

    let program = Arc::new(Program::load(&files.program)?);
    let io = TwinDriver::new(
        TwinKind::Vernadat.build(1),
        program.inputs(),
        program.outputs(),
    )?;
    let plc = Plc::new(program, 0);
    let local = args.config.load()?;
    let mut config = args.mqtt.config(&local)?;
    let speed = if args.speed.is_finite() && args.speed > 0.0 {
        args.speed
    } else {
        1.0
    };
    config.publish_period = std::time::Duration::from_millis(200);
    let plc_id = config.plc_id.clone();
    let (link, mqtt) = cetratus_mct::start(config)?;
    let broker_url = args.mqtt.client_url()?;
    let http: std::net::SocketAddr = args.http.parse().with_context(|| {
        format!(
            "--http `{}`: expected an address such as 127.0.0.1:8080",
            args.http
        )
    })?;
    let dashboard = cetratus_dashboard::serve(cetratus_dashboard::DashboardConfig {
        http,
        broker_url: broker_url.clone(),
        user: args.mqtt.user.clone(),
        password: args.mqtt.password.clone(),
        signer: None,
    })?;
    let until_us = match &args.for_ {
        Some(d) => crate::duration::parse_duration_us(d)?,
        None => u64::MAX,
    };
    println!(
        "Cetratus demo: the Vernadat cell runs in real time (speed {speed}) with its digital twin."
    );
    println!("  dashboard   http://{}/", dashboard.local_addr());
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
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    ctrlc::set_handler(move || s.store(true, Ordering::Relaxed))
        .context("cannot install the Ctrl-C handler")?;
    // Snapshots go out about five times a second of wall time, whatever the speed.
    let period_us = 10_000f64;
    let publish_every = ((200_000.0 * speed) / period_us).round().max(1.0) as u64;
    let opts = crate::node::NodeOptions {
        speed,
        until_us,
        trust: {
            // The demo key, and whatever the local configuration trusts.
            let mut t = files.trust.clone();
            t.merge(&local.trust);
            t
        },
        allow_unsigned: local.allow_unsigned,
        publish_every,
        echo_events: true,
    };
    let (_plc, io) = crate::node::run_node(plc, io, link, opts, &stop);
    mqtt.shutdown();
    dashboard.stop();
    use cetratus_twin::Plant;
    println!(
        "stopped: {} parts finished, {} faults",
        io.plant().counters().get("parts_finished").unwrap_or(0),
        io.plant().faults().len()
    );
    Ok(())
}
