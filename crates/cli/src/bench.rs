//! `cetratus bench`: the figures of docs/performance.md, measured on this machine.

use std::collections::BTreeMap;

/// Arguments of `cetratus bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Shorter batches: the whole run stays under a minute.
    #[arg(long)]
    quick: bool,
    /// Print one JSON object with every figure.
    #[arg(long)]
    json: bool,
}

/// Runs `cetratus bench`.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let engine = cetratus_bench::measure::engine_figures(args.quick);
    let mut out: BTreeMap<&str, serde_json::Value> = BTreeMap::new();
    out.insert("vernadat_scan_ns", engine.vernadat_scan_ns.into());
    out.insert("scale_ratio_1m_vs_1k", engine.scale_ratio_1m_vs_1k.into());
    out.insert("dense_speedup_10k", engine.dense_speedup_10k.into());
    out.insert("dense_speedup_1k", engine.dense_speedup_1k.into());
    out.insert("ring_scan_ns", serde_json::to_value(&engine.ring_scan_ns)?);
    out.insert(
        "dense_scan_ns",
        serde_json::to_value(&engine.dense_scan_ns)?,
    );
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        for (k, v) in &out {
            println!("{k:<24} {v}");
        }
    }
    Ok(())
}
