//! `cetratus run`: a program against a digital twin, in virtual or real time.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use anyhow::{bail, Context};
use cetratus_io::TwinDriver;
use cetratus_program::Program;
use cetratus_runtime::persist::{
    self, AuditRecord, PersistConfig, PersistFigures, PersistStats, Persister, StateStore,
};
use cetratus_runtime::trace::Trace;
use cetratus_runtime::{
    run_periodic, Command, CycleFigures, Event, LoopTiming, Plc, SubstituteMode, SubstituteRequest,
};
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
    /// Real-time runs with MQTT but without the dashboard (e.g. a fleet watched by one `cetratus mct`).
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

/// A scripted command.
struct Scripted {
    at_us: u64,
    verb: String,
    arg: Option<String>,
}

fn parse_script(items: &[String]) -> anyhow::Result<Vec<Scripted>> {
    let mut v = Vec::new();
    for item in items {
        let mut parts = item.split_whitespace();
        let (Some(t), Some(verb)) = (parts.next(), parts.next()) else {
            bail!("--at `{item}`: expected a time and a command, e.g. `10s load u1.cpkg`");
        };
        if !matches!(verb, "load" | "substitute" | "remove" | "abort" | "reset") {
            bail!("--at `{item}`: unknown command `{verb}`; expected load, substitute, remove, abort or reset");
        }
        v.push(Scripted {
            at_us: parse_duration_us(t)?,
            verb: verb.to_string(),
            arg: parts.next().map(str::to_string),
        });
    }
    v.sort_by_key(|s| s.at_us);
    Ok(v)
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
}

/// Runs `cetratus run`.
pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    let program = Arc::new(
        Program::load(&args.program)
            .with_context(|| format!("cannot load {}", args.program.display()))?,
    );
    let kind: TwinKind = args.twin.parse().map_err(|e| anyhow::anyhow!("{e}"))?;
    let twin = kind.build(args.seed);
    let until_us = match (&args.for_, args.virtual_time) {
        (Some(d), _) => parse_duration_us(d)?,
        (None, true) => bail!("a virtual run needs a length: add --for, e.g. --for 1h"),
        (None, false) => u64::MAX,
    };
    let mut io = TwinDriver::new(twin, program.inputs(), program.outputs())?;
    let script = parse_script(&args.at)?;
    let local = args.config.load()?;
    let trust = match &args.trust {
        Some(dir) => cetratus_program::TrustStore::load_dir(dir)?,
        None => local.trust.clone(),
    };
    let allow_unsigned = args.allow_unsigned || local.allow_unsigned;
    if !args.json && !args.virtual_time {
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
    let period_us = match &args.period {
        Some(p) => parse_duration_us(p)?.max(1),
        None => program.scan_period().as_micros() as u64,
    };
    let state_dir = state_dir(args, program.name());
    let mut events: Vec<Event> = Vec::new();
    let (mut plc, mut persister) = match &state_dir {
        Some(dir) => {
            let (plc, p) = open_state(dir, &program, args, period_us, &mut events)?;
            (plc, Some(p))
        }
        None => {
            if args.cold && !args.json {
                eprintln!("cold start: no state directory, nothing saved is used");
            }
            (Plc::new(program.clone(), 0), None)
        }
    };
    if args.virtual_time {
        plc.use_virtual_time(period_us);
    } else if args.period.is_some() {
        plc.set_limits(cetratus_runtime::Limits::for_period_us(period_us));
    }
    // Program time resumes after the last committed cycle; `--for`, `--at` and `--press` count
    // from the start of this run.
    let base_us = if plc.cycles() > 0 {
        plc.now_us() + period_us
    } else {
        0
    };
    for e in plc.drain_events() {
        print_event(&e, args.json);
        events.push(e);
    }
    let mut presses = args.press.clone();
    if presses.is_empty() && kind == TwinKind::Festo {
        presses.push("START@100ms".to_string());
    }
    for p in &presses {
        let (button, at) = p.split_once('@').unwrap_or((p.as_str(), "0s"));
        let at_us = parse_duration_us(at)?;
        io.plant_mut()
            .press(button, at_us.saturating_add(base_us))
            .map_err(|e| anyhow::anyhow!("--press {p}: {e}"))?;
    }
    // Real-time runs are watched and commanded over MQTT, with the dashboard beside them.
    let mut mct = None;
    if !args.virtual_time && !args.no_mct {
        let mut config = args.mqtt.config(&local)?;
        config.publish_period = std::time::Duration::from_millis(200);
        let plc_id = config.plc_id.clone();
        let (link, handle) = cetratus_mct::start(config)?;
        let broker_url = args.mqtt.client_url()?;
        let http: std::net::SocketAddr = args.http.parse().with_context(|| {
            format!(
                "--http `{}`: expected an address such as 127.0.0.1:8080",
                args.http
            )
        })?;
        let dashboard = if args.no_dashboard {
            None
        } else {
            Some(cetratus_dashboard::serve(
                cetratus_dashboard::DashboardConfig {
                    http,
                    broker_url: broker_url.clone(),
                    user: args.mqtt.user.clone(),
                    password: args.mqtt.password.clone(),
                    signer: None,
                },
            )?)
        };
        if !args.json {
            match &dashboard {
                Some(d) => eprintln!(
                    "MQTT {broker_url} (topics cetratus/{plc_id}/…), dashboard http://{}/",
                    d.local_addr()
                ),
                None => eprintln!("MQTT {broker_url} (topics cetratus/{plc_id}/…)"),
            }
        }
        let speed = if args.speed.is_finite() && args.speed > 0.0 {
            args.speed
        } else {
            1.0
        };
        let publish_every = ((200_000.0 * speed) / period_us.max(1) as f64)
            .round()
            .max(1.0) as u64;
        let node = crate::node::Node::start(
            &plc,
            link,
            trust.clone(),
            args.allow_unsigned,
            publish_every,
        );
        mct = Some((node, handle, dashboard));
    }
    let mut trace = Trace::new(plc.io_inputs().to_vec(), plc.io_outputs().to_vec());
    let record = args.trace.is_some() || args.svg.is_some();
    let mut violations: Vec<String> = Vec::new();
    let mut next_cmd = 0usize;
    let mut script_error: Option<anyhow::Error> = None;
    let json = args.json;
    let progress = args.progress.filter(|&n| n > 0);
    let mut persist_warned = false;
    let mut body =
        |plc: &mut Plc, now: u64, io: &mut TwinDriver<Twin>, timing: &LoopTiming| -> bool {
            let now = now + base_us;
            if let Some((node, _, _)) = mct.as_mut() {
                let who = node.take_commands(plc);
                let cmd_events = plc.drain_events();
                for e in &cmd_events {
                    print_event(e, json);
                    if let Some(p) = persister.as_mut() {
                        p.audit(e, who.as_deref().unwrap_or("mqtt"));
                    }
                }
                node.queue_events(&cmd_events);
                events.extend(cmd_events);
            }
            // One command per cycle: each takes effect at the next cycle boundary, so the next one
            // (a substitute after a load) sees that effect, even when a late cycle makes both due.
            if next_cmd < script.len() && script[next_cmd].at_us + base_us <= now {
                let s = &script[next_cmd];
                next_cmd += 1;
                let cmd = match scripted_command(plc, s, &trust, allow_unsigned) {
                    Ok(c) => c,
                    Err(e) => {
                        script_error = Some(e);
                        return false;
                    }
                };
                let _ = plc.command(cmd);
                for e in plc.drain_events() {
                    print_event(&e, json);
                    if let Some(p) = persister.as_mut() {
                        p.audit(&e, "cli");
                    }
                    events.push(e);
                }
            }
            plc.cycle(now, io);
            let k = plc.primary_container();
            if record {
                trace.observe(plc.cycles() - 1, now, plc.inputs(), plc.dispatched());
            }
            if violations.len() < 100 {
                if let Err(v) = k.program().check_invariants(k.marking()) {
                    violations.push(format!("{:.3}s: {v}", now as f64 / 1e6));
                }
            }
            let cycle_events = plc.drain_events();
            for e in &cycle_events {
                print_event(e, json);
                if let Some(p) = persister.as_mut() {
                    p.audit(e, "plc");
                }
            }
            if let Some((node, _, _)) = mct.as_mut() {
                node.after_cycle(plc, &cycle_events, timing, now);
            }
            events.extend(cycle_events);
            if let Some(p) = persister.as_mut() {
                p.offer(plc);
                // Said once: a full disk fails every commit, and the summary gives the count.
                if !persist_warned {
                    if let Some(err) = p.take_error() {
                        eprintln!("warning: the state directory could not be written: {err}");
                        persist_warned = true;
                    }
                }
                if let Some(n) = progress {
                    if plc.cycles() % n == 0 {
                        eprintln!(
                            "progress cycle={} committed={}",
                            plc.cycles(),
                            p.committed_cycle().map_or(-1, |c| c as i64)
                        );
                    }
                }
            }
            drop(plc.take_retired());
            true
        };
    let mut timing = LoopTiming::default();
    let reached_us = if args.virtual_time {
        let mut now = 0;
        let idle = LoopTiming::default();
        while now < until_us && body(&mut plc, now, &mut io, &idle) {
            now += period_us;
        }
        now
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
        run_periodic(
            period_us,
            until_us,
            args.speed,
            &stop,
            &mut timing,
            |now, timing| body(&mut plc, now, &mut io, timing),
        )
    };
    let persist = persister.map(|p| p.stop(&plc));
    if let Some((node, handle, dashboard)) = mct {
        node.stop();
        handle.shutdown();
        if let Some(d) = dashboard {
            d.stop();
        }
    }
    if let Some(e) = script_error {
        return Err(e);
    }
    if let (Some(stats), Some(dir)) = (&persist, &state_dir) {
        if let Some(err) = &stats.last_error {
            eprintln!(
                "warning: the state directory {} could not be written: {err}",
                dir.display()
            );
        }
    }
    let mut faults: Vec<String> = io.plant().faults().iter().map(|f| f.to_string()).collect();
    faults.extend(violations);
    faults.extend(
        events
            .iter()
            .filter(|e| matches!(e.kind, "primary_fault" | "deadlock_alarm"))
            .map(|e| format!("{:.3}s: {}", e.time_us as f64 / 1e6, e.message)),
    );
    let scan = plc.monitor.stats[plc.primary().index()].scan.summary();
    let figures = CycleFigures {
        cycles: plc.cycles(),
        period_us,
        scan,
        cycle: timing.cycle.summary(),
        latency: timing.latency.summary(),
        overruns: timing.overruns,
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
        scans: plc.cycles(),
        firings: plc.primary_container().firings().iter().sum(),
        parts_finished,
        faults,
        counters: serde_json::to_value(counters)?,
        scan: figures,
        primary: plc.primary().name(),
        status: plc.status().name(),
        state_dir: state_dir.as_ref().map(|d| d.display().to_string()),
        persist,
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

fn print_event(e: &Event, json: bool) {
    if !json {
        eprintln!(
            "{:>10.3} s  {:<20} {}",
            e.time_us as f64 / 1e6,
            e.kind,
            e.message
        );
    }
}

/// The state directory of this run: `--state-dir`, or for a real-time run
/// `$XDG_STATE_HOME/cetratus/<program name>` (`~/.local/state/cetratus/<program name>`). A virtual
/// run is a simulation and keeps no state unless asked to.
fn state_dir(args: &RunArgs, program_name: &str) -> Option<PathBuf> {
    if let Some(d) = &args.state_dir {
        return Some(d.clone());
    }
    if args.virtual_time {
        return None;
    }
    let base = std::env::var_os("XDG_STATE_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/state")))?;
    // A program name is free text; only a safe subset of it may become a directory name.
    let name: String = program_name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    let name = if name.trim_matches('.').is_empty() {
        "program".to_string()
    } else {
        name
    };
    Some(base.join("cetratus").join(name))
}

/// Opens the state directory and starts the PLC from it (warm, or cold with `--cold` or when
/// nothing is saved). Before the first scan, the start is made durable: the programs, a first
/// snapshot and the start-up records of the audit log are written synchronously, so a crash at
/// any later instant warm starts from this run, never from what `--cold` discarded.
fn open_state(
    dir: &Path,
    program: &Arc<Program>,
    args: &RunArgs,
    period_us: u64,
    events: &mut Vec<Event>,
) -> anyhow::Result<(Plc, Persister)> {
    let mut store = StateStore::open(dir)
        .with_context(|| format!("cannot open the state directory {}", dir.display()))?;
    let saved = if args.cold {
        store.load_state().ok().flatten()
    } else {
        None
    };
    let mut plc = persist::start(&store, program.clone(), args.cold)?;
    let now = std::time::SystemTime::now();
    if args.cold {
        let message = match &saved {
            Some(s) => format!(
                "cold start: the saved state in {} is ignored (cycle {}, PRIMARY {}, {})",
                dir.display(),
                s.snapshot.cycle,
                s.snapshot.primary.map_or("?", |p| p.name()),
                s.snapshot.status.map_or("?", |st| st.name())
            ),
            None => format!(
                "cold start: the saved state in {} is ignored (there was none)",
                dir.display()
            ),
        };
        eprintln!("{message}");
        store.append_audit(&AuditRecord {
            utc: persist::rfc3339_utc(now),
            cycle: 0,
            time_us: 0,
            who: "cli".into(),
            what: "cold_start_requested".into(),
            message,
            detail: serde_json::Value::Null,
        })?;
    }
    for e in plc.drain_events() {
        print_event(&e, args.json);
        store.append_audit(&AuditRecord::of_event(&e, "local", now))?;
        events.push(e);
    }
    for slot in [cetratus_runtime::Slot::A, cetratus_runtime::Slot::B] {
        if let Some(c) = plc.container(slot) {
            store.save_program(c.program())?;
        }
    }
    let config = PersistConfig::for_period_us(period_us);
    let mut snap = Default::default();
    plc.snapshot_into(&mut snap);
    store.commit(
        &snap,
        &PersistFigures {
            every_cycles: config.every_cycles,
            ..Default::default()
        },
    )?;
    if !args.json {
        eprintln!(
            "state: {} (a snapshot every {} cycles; see docs/persistence.md)",
            dir.display(),
            config.every_cycles
        );
    }
    let persister = Persister::start(store, config)?;
    Ok((plc, persister))
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
    if s.faults.is_empty() {
        println!("  faults          none");
    } else {
        println!("  faults          {}", s.faults.len());
        for fault in s.faults.iter().take(20) {
            println!("    {fault}");
        }
    }
}

fn scripted_command(
    plc: &Plc,
    s: &Scripted,
    trust: &cetratus_program::TrustStore,
    allow_unsigned: bool,
) -> anyhow::Result<Command> {
    Ok(match s.verb.as_str() {
        "load" => {
            let Some(path) = &s.arg else {
                bail!("`load` needs a package file");
            };
            let bytes = std::fs::read(path).with_context(|| format!("cannot read {path}"))?;
            // Verified and built here, between cycles; the install happens at the next boundary.
            match plc
                .update_context()
                .prepare_package(&bytes, trust, allow_unsigned, false)
            {
                Ok(p) => Command::Load(Box::new(p)),
                Err(e) => bail!("{path}: {e}"),
            }
        }
        "substitute" => Command::Substitute(SubstituteRequest {
            mode: match s.arg.as_deref() {
                Some(m) => m
                    .parse::<SubstituteMode>()
                    .map_err(|e| anyhow::anyhow!(e))?,
                None => SubstituteMode::Retransform,
            },
            when: None,
            within_us: None,
            force: false,
        }),
        "remove" => Command::Remove,
        "abort" => Command::Abort,
        _ => Command::Reset,
    })
}
