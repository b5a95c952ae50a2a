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
