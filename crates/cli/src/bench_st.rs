//! `cetratus bench st`: Structured Text scans on Cetratus against the same programs compiled by
//! MATIEC and `cc -O2`, and the import of a 5 000-line file; `cetratus bench export`: the
//! exported programs compiled the same way against their interpreted scans (docs/performance.md).

use std::path::PathBuf;

use cetratus_bench::st;

/// Arguments of `cetratus bench st` and `cetratus bench export`.
#[derive(clap::Args, Debug)]
pub struct StArgs {
    /// A MATIEC install dir (`bin/iec2c`, `lib/`), for the compiled-C baseline; without it
    /// only Cetratus's side is measured, and the output says so.
    #[arg(long)]
    matiec: Option<PathBuf>,
    /// Fewer scans: a smoke run, not a figure.
    #[arg(long)]
    quick: bool,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// Runs `cetratus bench st`.
pub fn run(args: &StArgs) -> anyhow::Result<()> {
    let f = st::figures(args.matiec.as_deref(), args.quick).map_err(|e| anyhow::anyhow!("{e}"))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&f)?);
        return Ok(());
    }
    if let Some(why) = &f.matiec_skipped {
        println!("MATIEC's side skipped: {why}");
    }
    println!(
        "{:<8} {:>8} {:>12} {:>12} {:>14} {:>12} {:>7}",
        "program", "scans", "cetratus ns", "st pass ns", "interpreted ns", "matiec ns", "ratio"
    );
    for p in &f.programs {
        let or_dash =
            |x: Option<f64>, digits: usize| x.map_or("-".to_string(), |v| format!("{v:.digits$}"));
        println!(
            "{:<8} {:>8} {:>12.0} {:>12.0} {:>14.0} {:>12} {:>7}",
            p.name,
            p.scans,
            p.cetratus_ns,
            p.pass_ns,
            p.interpreted_ns,
            or_dash(p.matiec_ns, 0),
            or_dash(p.ratio, 2)
        );
    }
    println!(
        "import and compile of {} lines of ST: {:.1} ms",
        f.import_lines, f.import_ms
    );
    match f.translate_ms {
        Some(ms) => println!(
            "translation of its {} instructions into machine code: {ms:.0} ms",
            f.translate_ops
        ),
        None => {
            println!("no machine code in this build or on this machine: the interpreter runs ST")
        }
    }
    Ok(())
}

/// Runs `cetratus bench export`.
pub fn export(args: &StArgs) -> anyhow::Result<()> {
    let f = cetratus_bench::export::figures(args.matiec.as_deref(), args.quick)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&f)?);
        return Ok(());
    }
    if let Some(why) = &f.matiec_skipped {
        println!("the compiled side skipped: {why}");
    }
    println!(
        "{:<18} {:>6} {:>9} {:>8} {:>8} {:>12} {:>12}",
        "program", "P×T", "export ms", "sparse B", "dense B", "cetratus ns", "compiled ns"
    );
    for p in &f.programs {
        println!(
            "{:<18} {:>6} {:>9.3} {:>8} {:>8} {:>12.0} {:>12}",
            p.name,
            format!("{}×{}", p.places, p.transitions),
            p.export_ms,
            p.sparse_bytes,
            p.dense_bytes,
            p.cetratus_ns,
            p.compiled_ns.map_or("-".to_string(), |v| format!("{v:.0}"))
        );
    }
    let c = &f.chart;
    println!(
        "SFC chart {} ({} steps, {} transitions) written back as a chart: {:.3} ms, its import check included (the import alone: {:.3} ms)",
        c.name, c.steps, c.transitions, c.export_ms, c.import_ms
    );
    Ok(())
}
