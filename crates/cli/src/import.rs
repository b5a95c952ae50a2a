//! `cetratus import plcopen` and `cetratus import st`: a POU of a PLCopen XML file (an SFC chart,
//! or an ST, LD or FBD body), or of a Structured Text file, written as a Cetratus program.

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
    /// A POU of PLCopen TC6 XML (CODESYS, TwinCAT, Beremiz, OpenPLC Editor): an SFC chart
    /// (docs/sfc.md), or an ST, LD or FBD body (docs/st.md).
    Plcopen(PlcopenArgs),
    /// A PROGRAM or FUNCTION_BLOCK of an IEC 61131-3 Structured Text file; docs/st.md says
    /// what is accepted and how it runs.
    St(StArgs),
}

/// Arguments of `cetratus import st`.
#[derive(clap::Args, Debug)]
struct StArgs {
    /// The Structured Text file.
    file: PathBuf,
    /// The PROGRAM or FUNCTION_BLOCK to import; needed when the file has several PROGRAMs.
    #[arg(long)]
    pou: Option<String>,
    /// The directory to write the program to (`POU.toml` and `POU.pnml`); created if needed.
    #[arg(short, long)]
    output: PathBuf,
}

/// Arguments of `cetratus import plcopen`.
#[derive(clap::Args, Debug)]
struct PlcopenArgs {
    /// The PLCopen XML file.
    file: PathBuf,
    /// The POU to import; needed unless the file has one SFC POU, or none and one PROGRAM.
    #[arg(long)]
    pou: Option<String>,
    /// The directory to write the program to (`POU.toml` and `POU.pnml`); created if needed.
    #[arg(short, long)]
    output: PathBuf,
}

/// Runs `cetratus import`.
pub fn run(args: &ImportArgs) -> anyhow::Result<()> {
    let a = match &args.from {
        From::Plcopen(a) => a,
        From::St(a) => return structured_text(a),
    };
    let (label, text) = read(&a.file)?;
    let imported = match cetratus_sfc::import_pou(&text, &label, a.pou.as_deref())? {
        cetratus_sfc::ImportedPou::Chart(chart) => *chart,
        cetratus_sfc::ImportedPou::Text(pou) => return print_pou(&a.output, &pou),
    };
    let toml_path = write(
        &a.output,
        &imported.program,
        &imported.net,
        &imported.toml,
        &imported.notes,
    )?;
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

/// `cetratus import st`.
fn structured_text(a: &StArgs) -> anyhow::Result<()> {
    let (label, text) = read(&a.file)?;
    let imported = cetratus_sfc::structured::import_st(&text, &label, a.pou.as_deref())?;
    print_pou(&a.output, &imported)
}

/// Writes a POU imported as Structured Text and says what it became.
fn print_pou(
    output: &std::path::Path,
    imported: &cetratus_sfc::structured::ImportedSt,
) -> anyhow::Result<()> {
    let toml_path = write(
        output,
        &imported.program,
        &imported.net,
        &imported.toml,
        &imported.notes,
    )?;
    let p = &imported.program;
    println!(
        "{}: POU {}, {} inputs, {} outputs, scan period {:?}; program hash {}",
        toml_path.display(),
        p.name(),
        p.inputs().len(),
        p.outputs().len(),
        p.scan_period(),
        p.hash_hex()
    );
    Ok(())
}

/// The file to import, as UTF-8 text, with its name for messages.
fn read(file: &std::path::Path) -> anyhow::Result<(String, String)> {
    let label = file.display().to_string();
    let text = std::fs::read_to_string(file)
        .with_context(|| format!("cannot read {label} as UTF-8 text"))?;
    Ok((label, text))
}

/// Writes an imported program to `output` (`NAME.toml` beside `NAME.pnml`, as its `net =`
/// names it) and prints what the importer noted; the TOML file's path.
fn write(
    output: &std::path::Path,
    program: &cetratus_program::Program,
    net: &cetratus_net::Net,
    toml: &str,
    notes: &[String],
) -> anyhow::Result<PathBuf> {
    let stem = program.name();
    std::fs::create_dir_all(output)
        .with_context(|| format!("cannot create {}", output.display()))?;
    let toml_path = output.join(format!("{stem}.toml"));
    cetratus_net::pnml::write_file(net, &output.join(format!("{stem}.pnml")))?;
    std::fs::write(&toml_path, toml)
        .with_context(|| format!("cannot write {}", toml_path.display()))?;
    for note in notes {
        eprintln!("note: {note}");
    }
    Ok(toml_path)
}
