//! `cetratus import plcopen`: an SFC chart of a PLCopen XML file written as a Cetratus program.

use std::path::PathBuf;

use anyhow::Context;

/// Arguments of `cetratus import`.
#[derive(clap::Args, Debug)]
pub struct ImportArgs {
    #[command(subcommand)]
    from: From,
}

#[derive(clap::Subcommand, Debug)]
enum From {
    /// An IEC 61131-3 SFC from PLCopen TC6 XML (CODESYS, TwinCAT, Beremiz, OpenPLC Editor);
    /// docs/sfc.md has the mapping.
    Plcopen(PlcopenArgs),
}

/// Arguments of `cetratus import plcopen`.
#[derive(clap::Args, Debug)]
struct PlcopenArgs {
    /// The PLCopen XML file.
    file: PathBuf,
    /// The SFC POU to import; needed when the file has several.
    #[arg(long)]
    pou: Option<String>,
    /// The directory to write the program to (`POU.toml` and `POU.pnml`); created if needed.
    #[arg(short, long)]
    output: PathBuf,
}

/// Runs `cetratus import`.
pub fn run(args: &ImportArgs) -> anyhow::Result<()> {
    let From::Plcopen(a) = &args.from;
    let label = a.file.display().to_string();
    let text = std::fs::read_to_string(&a.file)
        .with_context(|| format!("cannot read {label} as UTF-8 text"))?;
    let imported = cetratus_sfc::import_program(&text, &label, a.pou.as_deref())?;
    let stem = imported.program.name().to_string();
    let net_file = format!("{stem}.pnml");
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("cannot create {}", a.output.display()))?;
    let toml_path = a.output.join(format!("{stem}.toml"));
    let net_path = a.output.join(&net_file);
    cetratus_net::pnml::write_file(&imported.net, &net_path)?;
    std::fs::write(&toml_path, &imported.toml)
        .with_context(|| format!("cannot write {}", toml_path.display()))?;
    for note in &imported.notes {
        eprintln!("note: {note}");
    }
    // Counted as drawn: the chart and its nested charts (not their held places and hold and
    // resume transitions).
    let charts = || std::iter::once(&imported.chart).chain(&imported.nested);
    let nested: Vec<&str> = imported
        .nested
        .iter()
        .map(|c| c.location.trim_start_matches("action "))
        .collect();
    println!(
        "{}: {} steps, {} transitions, {} actions{}; program hash {}",
        toml_path.display(),
        charts().map(|c| c.steps.len()).sum::<usize>(),
        charts().map(|c| c.transitions.len()).sum::<usize>(),
        charts().map(|c| c.associations.len()).sum::<usize>(),
        if nested.is_empty() {
            String::new()
        } else {
            format!(" (with the nested charts of {})", nested.join(", "))
        },
        imported.program.hash_hex()
    );
    Ok(())
}
