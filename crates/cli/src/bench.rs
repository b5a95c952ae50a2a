//! `cetratus bench`: the figures of docs/performance.md, measured on this machine.

use std::collections::BTreeMap;

use cetratus_bench::{measure, program};

use crate::duration::parse_duration_us;

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

/// Runs `cetratus bench`.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    if let Some(What::CommandLoad {
        rate,
        for_,
        period,
        json,
    }) = &args.what
    {
        let out = command_load(*rate, parse_duration_us(for_)?, parse_duration_us(period)?)?;
        return print(&out, *json || args.json);
    }
    if let Some(What::Jitter {
        period,
        for_,
        rt,
        json,
    }) = &args.what
    {
        return jitter(period, for_, *rt, *json || args.json);
    }
    let mut out: BTreeMap<String, serde_json::Value> = BTreeMap::new();
    let engine = measure::engine_figures(args.quick);
    out.insert(s("vernadat_scan_ns"), engine.vernadat_scan_ns.into());
    out.insert(
        s("scale_ratio_1m_vs_1k"),
        engine.scale_ratio_1m_vs_1k.into(),
    );
    out.insert(s("dense_speedup_10k"), engine.dense_speedup_10k.into());
    out.insert(s("dense_speedup_1k"), engine.dense_speedup_1k.into());
    out.insert(
        s("ring_scan_ns"),
        serde_json::to_value(&engine.ring_scan_ns)?,
    );
    out.insert(
        s("dense_scan_ns"),
        serde_json::to_value(&engine.dense_scan_ns)?,
    );

    out.insert(
        s("program_scan_ns"),
        program::program_scan_ns(args.quick).into(),
    );
    out.insert(
        s("program_load_us"),
        program::program_load_us(args.quick).into(),
    );
    let hour = program::twin_hour();
    out.insert(s("twin_hour_wall_ms"), hour.wall_ms.into());
    out.insert(s("twin_hour_parts_finished"), hour.parts_finished.into());

    let update = cetratus_bench::update::update_figures(args.quick);
    if let serde_json::Value::Object(map) = serde_json::to_value(&update)? {
        out.extend(map);
    }

    let analysis = cetratus_bench::analysis::reachability_figures(args.quick);
    if let serde_json::Value::Object(map) = serde_json::to_value(&analysis)? {
        for (k, v) in map {
            out.insert(k, v);
        }
    }
    print(&out, args.json)
}

fn jitter(period: &str, for_: &str, rt: bool, json: bool) -> anyhow::Result<()> {
    let period_us = parse_duration_us(period)?;
    let for_us = parse_duration_us(for_)?;
    let (figures, status) = program::jitter(period_us, for_us, rt);
    let mut out: BTreeMap<String, serde_json::Value> = BTreeMap::new();
    out.insert(s("period_us"), period_us.into());
    out.insert(s("cycles"), figures.cycles.into());
    out.insert(s("latency_p50_ns"), figures.latency.p50_ns.into());
    out.insert(s("latency_p99_ns"), figures.latency.p99_ns.into());
    out.insert(s("latency_max_ns"), figures.latency.max_ns.into());
    out.insert(s("scan_p99_ns"), figures.scan.p99_ns.into());
    out.insert(s("cycle_p99_ns"), figures.cycle.p99_ns.into());
    out.insert(s("overruns"), figures.overruns.into());
    out.insert(
        s("rt"),
        status.unwrap_or_else(|| "not requested".into()).into(),
    );
    print(&out, json)
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

fn s(key: &str) -> String {
    key.to_string()
}

/// Runs the Vernadat node on an embedded broker at `period_us`, first alone for `phase_us`, then
/// while a client sends `rate` commands per second, and reports the scan latency of both phases.
fn command_load(
    rate: u32,
    phase_us: u64,
    period_us: u64,
) -> anyhow::Result<BTreeMap<String, serde_json::Value>> {
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::Arc;
    use std::time::{Duration, Instant};

    use cetratus_runtime::{run_periodic, LoopTiming, Plc};
    use rumqttc::v5::mqttbytes::QoS;

    let program = program::vernadat_program();
    let mut io = cetratus_io::TwinDriver::new(
        cetratus_twin::TwinKind::Vernadat.build(1),
        program.inputs(),
        program.outputs(),
    )?;
    let mut plc = Plc::new(program, 0);
    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    let mut config = cetratus_mct::MqttConfig::new("bench");
    config.broker = cetratus_mct::BrokerChoice::Embedded {
        addr: std::net::SocketAddr::from(([127, 0, 0, 1], port)),
        users: Vec::new(),
    };
    config.publish_period = Duration::from_millis(200);
    let (link, handle) = cetratus_mct::start(config)?;
    handle.wait_connected(Duration::from_secs(10));
    let mut node = crate::node::Node::start(
        &plc,
        link,
        cetratus_program::TrustStore::empty(),
        false,
        (200_000 / period_us.max(1)).max(1),
    );
    let mut now_base = 0u64;
    let mut phase = |plc: &mut Plc,
                     io: &mut cetratus_io::TwinDriver<cetratus_twin::Twin>,
                     node: &mut crate::node::Node| {
        let stop = AtomicBool::new(false);
        let mut timing = LoopTiming::default();
        let base = now_base;
        let reached = run_periodic(period_us, phase_us, 1.0, &stop, &mut timing, |now, t| {
            let now = base + now;
            node.take_commands(plc);
            let pre = plc.drain_events();
            node.queue_events(&pre);
            plc.cycle(now, io);
            let events = plc.drain_events();
            node.after_cycle(plc, &events, t, now);
            drop(plc.take_retired());
            true
        });
        now_base += reached;
        timing
    };
    let quiet = phase(&mut plc, &mut io, &mut node);

    // The flood: a client on its own thread, mixed valid and invalid commands.
    let sent = Arc::new(AtomicU64::new(0));
    let stop_flood = Arc::new(AtomicBool::new(false));
    let flood = {
        let (sent, stop_flood) = (sent.clone(), stop_flood.clone());
        let url = format!("mqtt://127.0.0.1:{port}");
        std::thread::spawn(move || -> anyhow::Result<()> {
            let opts = cetratus_mct::client_options(&url, "bench-flood")?;
            let (client, mut conn) = rumqttc::v5::Client::new(opts, 4096);
            std::thread::spawn(move || for _ in conn.iter() {});
            let payloads: [(&str, &[u8]); 4] = [
                ("exec_info", b"{\"reply_to\": \"bench/replies\"}"),
                ("load", b"\x00\x01 not json"),
                ("frobnicate", b"{\"reply_to\": \"bench/replies\"}"),
                (
                    "substitute",
                    b"{\"mode\": \"sideways\", \"reply_to\": \"bench/replies\"}",
                ),
            ];
            let start = Instant::now();
            let mut k = 0u64;
            while !stop_flood.load(Ordering::Relaxed) {
                let due = start + Duration::from_secs_f64(k as f64 / f64::from(rate.max(1)));
                if let Some(wait) = due.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
                let (verb, body) = payloads[(k % 4) as usize];
                let _ = client.try_publish(
                    format!("cetratus/bench/cmd/{verb}"),
                    QoS::AtMostOnce,
                    false,
                    body.to_vec(),
                );
                k += 1;
                sent.store(k, Ordering::Relaxed);
            }
            Ok(())
        })
    };
    let loaded = phase(&mut plc, &mut io, &mut node);
    stop_flood.store(true, Ordering::Relaxed);
    let _ = flood.join();
    node.stop();
    handle.shutdown();

    let (q, l) = (quiet.latency.summary(), loaded.latency.summary());
    let limit = 1.2 * q.p99_ns as f64 + 20_000.0;
    let mut out: BTreeMap<String, serde_json::Value> = BTreeMap::new();
    out.insert(s("period_us"), period_us.into());
    out.insert(s("phase_s"), (phase_us as f64 / 1e6).into());
    out.insert(s("commands_sent"), sent.load(Ordering::Relaxed).into());
    out.insert(
        s("commands_per_s"),
        (sent.load(Ordering::Relaxed) as f64 / (phase_us as f64 / 1e6)).into(),
    );
    out.insert(s("latency_p99_ns_unloaded"), q.p99_ns.into());
    out.insert(s("latency_p99_ns_loaded"), l.p99_ns.into());
    out.insert(s("latency_p50_ns_unloaded"), q.p50_ns.into());
    out.insert(s("latency_p50_ns_loaded"), l.p50_ns.into());
    out.insert(s("latency_max_ns_unloaded"), q.max_ns.into());
    out.insert(s("latency_max_ns_loaded"), l.max_ns.into());
    out.insert(s("overruns_unloaded"), quiet.overruns.into());
    out.insert(s("overruns_loaded"), loaded.overruns.into());
    out.insert(s("limit_ns"), limit.into());
    out.insert(s("within_limit"), ((l.p99_ns as f64) <= limit).into());
    out.insert(s("primary_status"), plc.status().name().into());
    Ok(out)
}
