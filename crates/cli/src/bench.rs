//! `cetratus bench`: the figures of docs/performance.md, measured on this machine by the harnesses
//! of `cetratus-bench`.

use std::collections::BTreeMap;

use cetratus_bench::harness;

use crate::parse_duration_us;

/// Arguments of `cetratus bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    #[command(subcommand)]
    what: Option<What>,
    /// Shorter batches: the whole run stays under a minute.
    #[arg(long)]
    quick: bool,
    /// Print one JSON object with every figure.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Subcommand, Debug)]
enum What {
    /// Structured Text scans against MATIEC's compiled C, and a 5 000-line import.
    St(crate::bench_st::StArgs),
    /// The export compiled by MATIEC and `cc -O2` against the interpreted scan, its data's bytes
    /// and its time.
    Export(crate::bench_st::StArgs),
    /// OPC UA write → scan → read latency of the real binary (p50, p99).
    Opcua(crate::bench_opcua::OpcuaArgs),
    /// Write a member of a benchmark family as ISO PNML, for `cetratus check` and other tools.
    Net {
        /// `kanban` or `fms`.
        family: String,
        /// The family's parameter (cards per cell, parts per type).
        n: u32,
        /// Where to write the PNML file.
        #[arg(long)]
        out: std::path::PathBuf,
    },
    /// A fleet: N runtime processes on one Mosquitto, watched by one `cetratus dashboard`.
    Fleet {
        /// How many PLC processes.
        #[arg(long, default_value_t = 50)]
        n: usize,
        /// Their scan period.
        #[arg(long, default_value = "100ms")]
        period: String,
        /// How long to measure, wall time.
        #[arg(long = "for", default_value = "30s")]
        for_: String,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// A rollout of U.1 across N PLC processes on one Mosquitto: the control plane's own time
    /// per PLC and per stage, the dashboard's latency meanwhile, one PLC's memory.
    Rollout {
        /// How many PLC processes.
        #[arg(long, default_value_t = 50)]
        n: usize,
        /// Their scan period.
        #[arg(long, default_value = "100ms")]
        period: String,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Scan latency with and without a flood of MQTT commands (mixed valid and invalid).
    CommandLoad {
        /// Commands per second during the loaded phase.
        #[arg(long, default_value_t = 1000)]
        rate: u32,
        /// Length of each phase (unloaded, then loaded), wall time.
        #[arg(long = "for", default_value = "60s")]
        for_: String,
        /// The scan period.
        #[arg(long, default_value = "1ms")]
        period: String,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Fuzz every reader of outside input (PNML, guards, programs, packages, state.json, MQTT
    /// commands); inputs that make one panic are kept in the corpus directory.
    Fuzz {
        /// How long per reader, wall time.
        #[arg(long = "for", default_value = "60s")]
        for_: String,
        /// Seed of the mutations (a round is reproducible from it).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Where to keep the inputs that crash a reader.
        #[arg(long)]
        corpus: Option<std::path::PathBuf>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Scan latency and peak memory while others flood the PLC: garbage, refused loads,
    /// exec_info, 1 MiB payloads and event spam, one kind per phase, against an unloaded phase.
    Flood {
        /// How long each kind floods in all, wall time (in slices, between unloaded slices).
        #[arg(long = "for", default_value = "60s")]
        for_: String,
        /// Length of one slice: an unloaded slice and a flood slice alternate, round-robin over
        /// the kinds, until each kind has had `--for`.
        #[arg(long, default_value = "2s")]
        slice: String,
        /// The scan period.
        #[arg(long, default_value = "1ms")]
        period: String,
        /// Ask for SCHED_FIFO and mlockall for the scan thread, as `run --rt` does.
        #[arg(long)]
        rt: bool,
        /// The kinds to flood, comma separated, among garbage, refused_loads,
        /// exec_info, large_payloads, event_spam, dashboard_logins, deep_topics, wills and
        /// id_takeover. All of them by default; a single kind with `--for 20s` takes about a
        /// minute.
        #[arg(long, value_delimiter = ',')]
        kinds: Vec<String>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Field I/O: the Modbus round trip of a cycle (64 coils, 16 registers) against pymodbus
    /// and against Cetratus's own server, and scan latency with field I/O off and on.
    Io {
        /// The cycle period.
        #[arg(long, default_value = "10ms")]
        period: String,
        /// Length of each series and phase, wall time (the two latency phases alternate in 2 s
        /// slices).
        #[arg(long = "for", default_value = "30s")]
        for_: String,
        /// Ask for SCHED_FIFO and mlockall for the scan thread, as `run --rt` does.
        #[arg(long)]
        rt: bool,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Real-time jitter of the scan cycle: the Vernadat program on its twin at a fixed period.
    Jitter {
        /// The scan period.
        #[arg(long, default_value = "1ms")]
        period: String,
        /// How long to run, in wall time.
        #[arg(long = "for", default_value = "60s")]
        for_: String,
        /// Ask for SCHED_FIFO and mlockall first.
        #[arg(long)]
        rt: bool,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
}

/// The dashboard beside the flooded PLC, as `cetratus run` starts it, with one account for the
/// login flood to get wrong.
fn flood_dashboard(broker: &str) -> Result<harness::BesideParts, harness::BenchError> {
    let hash = cetratus_dashboard::hash_password("bench-secret")?;
    let d = cetratus_dashboard::serve(cetratus_dashboard::DashboardConfig {
        http: std::net::SocketAddr::from(([127, 0, 0, 1], 0)),
        broker_url: broker.to_string(),
        user: None,
        password: None,
        signer: None,
        access: cetratus_dashboard::AccessConfig {
            accounts: vec![cetratus_dashboard::Account {
                name: "ops".into(),
                password_hash: hash,
            }],
            ..cetratus_dashboard::AccessConfig::default()
        },
        tls: None,
        rollouts: None,
    })?;
    let addr = d.local_addr();
    Ok((Box::new(d), Some((addr, "ops".to_string()))))
}

/// Runs `cetratus bench`.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    if let Some(What::Opcua(a)) = &args.what {
        return crate::bench_opcua::run(a);
    }
    if let Some(What::St(a)) = &args.what {
        return crate::bench_st::run(a);
    }
    if let Some(What::Export(a)) = &args.what {
        return crate::bench_st::export(a);
    }
    if let Some(What::Net { family, n, out }) = &args.what {
        let net = match family.to_ascii_lowercase().as_str() {
            "kanban" => cetratus_analysis::families::kanban(*n)?,
            "fms" => cetratus_analysis::families::fms(*n)?,
            other => anyhow::bail!("unknown family `{other}`; choose kanban or fms"),
        };
        cetratus_net::pnml::write_file(&net, out)?;
        return Ok(());
    }
    if let Some(what) = &args.what {
        if let Some((out, json)) = over_mqtt(what)? {
            return print(&out, json || args.json);
        }
    }
    if let Some(What::Fuzz {
        for_,
        seed,
        corpus,
        json,
    }) = &args.what
    {
        let budget = std::time::Duration::from_micros(parse_duration_us(for_)?);
        let rounds = cetratus_bench::fuzz::all(budget, *seed, corpus.as_deref());
        let out: BTreeMap<String, serde_json::Value> = rounds
            .iter()
            .map(|(t, r)| {
                (
                    t.name().to_string(),
                    serde_json::to_value(r).unwrap_or_default(),
                )
            })
            .collect();
        print(&out, *json || args.json)?;
        let panics: u64 = rounds.values().map(|r| r.panics).sum();
        if panics > 0 {
            anyhow::bail!("{panics} inputs made a reader panic; they are in the corpus directory");
        }
        return Ok(());
    }
    if let Some(What::Flood {
        for_,
        slice,
        period,
        rt,
        kinds,
        json,
    }) = &args.what
    {
        let kinds = harness::FloodKind::list(kinds).map_err(|e| anyhow::anyhow!("{e}"))?;
        let out = harness::flood(
            parse_duration_us(for_)?,
            parse_duration_us(period)?,
            parse_duration_us(slice)?,
            *rt,
            &kinds,
            &flood_dashboard,
        )
        .map_err(|e| anyhow::anyhow!("{e}"))?;
        return print(&out, *json || args.json);
    }
    if let Some(What::Io {
        period,
        for_,
        rt,
        json,
    }) = &args.what
    {
        let f =
            cetratus_bench::io::figures(parse_duration_us(period)?, parse_duration_us(for_)?, *rt)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        let out = match serde_json::to_value(&f)? {
            serde_json::Value::Object(m) => m.into_iter().collect(),
            _ => BTreeMap::new(),
        };
        return print(&out, *json || args.json);
    }
    if let Some(What::Jitter {
        period,
        for_,
        rt,
        json,
    }) = &args.what
    {
        let out =
            harness::jitter_figures(parse_duration_us(period)?, parse_duration_us(for_)?, *rt);
        return print(&out, *json || args.json);
    }
    let out = harness::all_figures(args.quick).map_err(|e| anyhow::anyhow!("{e}"))?;
    print(&out, args.json)
}

/// The harnesses of many processes over MQTT (`fleet`, `rollout`, `command-load`): their
/// figures and whether to print them as JSON, or `None` when `what` is another.
fn over_mqtt(what: &What) -> anyhow::Result<Option<(harness::Figures, bool)>> {
    let bench = |e: harness::BenchError| anyhow::anyhow!("{e}");
    Ok(Some(match what {
        What::Fleet {
            n,
            period,
            for_,
            json,
        } => {
            let exe = std::env::current_exe()?;
            let for_us = parse_duration_us(for_)?;
            (
                harness::fleet(&exe, *n, period, for_us).map_err(bench)?,
                *json,
            )
        }
        What::Rollout { n, period, json } => {
            let exe = std::env::current_exe()?;
            let out = cetratus_bench::rollout::rollout(&exe, *n, period).map_err(bench)?;
            (out, *json)
        }
        What::CommandLoad {
            rate,
            for_,
            period,
            json,
        } => {
            let (for_us, period_us) = (parse_duration_us(for_)?, parse_duration_us(period)?);
            let out = harness::command_load(*rate, for_us, period_us).map_err(bench)?;
            (out, *json)
        }
        _ => return Ok(None),
    }))
}

fn print(out: &BTreeMap<String, serde_json::Value>, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(out)?);
    } else {
        for (k, v) in out {
            println!("{k:<28} {v}");
        }
    }
    Ok(())
}
