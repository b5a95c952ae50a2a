//! `cetratus export`: a program as IEC 61131-3 Structured Text for a vendor PLC
//! (docs/export.md).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use cetratus_export::{Dialect, StExport};

/// What `cetratus export` writes.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Target {
    /// IEC 61131-3 Structured Text: `DIR/<program>.st` (`.scl` for TIA) and its I/O map
    /// `DIR/<program>.io.csv`.
    St,
    /// A PLCopen TC6 XML project (Beremiz, OpenPLC Editor, CODESYS): `DIR/<program>.xml`, its
    /// POUs with ST bodies (a program imported from an SFC chart: that chart), and the I/O map.
    Plcopen,
}

/// Arguments of `cetratus export`.
#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    /// The program: a `.toml` beside its net, or a `.pnml` that carries it.
    program: PathBuf,
    /// What to write.
    #[arg(long)]
    to: Target,
    /// The ST dialect: iec (MATIEC, OpenPLC, Beremiz), codesys (also TwinCAT), tia (Siemens SCL,
    /// written as `.scl`) or omron (Sysmac Studio).
    #[arg(long, default_value = "iec")]
    dialect: String,
    /// The directory to write into; one that holds files is refused unless --force.
    #[arg(short, long)]
    output: PathBuf,
    /// Write into a directory that already holds files (replacing the export's own).
    #[arg(long)]
    force: bool,
}

/// Runs `cetratus export`: everything is made in memory first, so that a refusal writes
/// nothing, and each file is written whole beside its final name, then renamed.
pub fn run(args: &ExportArgs) -> anyhow::Result<()> {
    let dialect: Dialect = args.dialect.parse()?;
    let program = crate::package::load_program(&args.program)?;
    let export = match args.to {
        Target::St => cetratus_export::to_st(&program, dialect),
        Target::Plcopen if dialect != Dialect::Iec => {
            bail!("--dialect applies to --to st; PLCopen XML is one format for every editor")
        }
        Target::Plcopen => cetratus_export::to_plcopen(&program),
    }
    .with_context(|| format!("cannot export {}", args.program.display()))?;
    ready(&args.output, args.force)?;
    let stem = Path::new(&export.file_name)
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let files = [
        (export.file_name.clone(), export.text.as_str()),
        (format!("{stem}.io.csv"), export.io_csv.as_str()),
    ];
    for (name, text) in files {
        write_whole(&args.output.join(name), text)?;
    }
    summary(&args.output, &export, dialect);
    Ok(())
}

/// Refuses a directory that holds files, unless `force`; makes it when absent.
fn ready(dir: &Path, force: bool) -> anyhow::Result<()> {
    match std::fs::read_dir(dir) {
        Ok(mut entries) => {
            if entries.next().is_some() && !force {
                bail!(
                    "{} already holds files; export into an empty directory, or add --force to write over the export's own files there",
                    dir.display()
                );
            }
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))
        }
        Err(e) => Err(e).with_context(|| format!("cannot read the directory {}", dir.display())),
    }
}

/// Writes `text` to `path` through a temporary file beside it, so that no reader ever sees
/// half of it.
fn write_whole(path: &Path, text: &str) -> anyhow::Result<()> {
    let tmp: PathBuf = path.with_extension("part");
    std::fs::write(&tmp, text).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}

fn summary(dir: &Path, export: &StExport, dialect: Dialect) {
    for note in &export.notes {
        eprintln!("note: {note}");
    }
    if export.chart {
        println!(
            "{}: the SFC chart {}, {} lines",
            dir.join(&export.file_name).display(),
            export.program,
            export.text.lines().count()
        );
        return;
    }
    println!(
        "{}: PROGRAM {} ({dialect}), {} lines; the net's data {} bytes sparse ({} dense)",
        dir.join(&export.file_name).display(),
        export.program,
        export.text.lines().count(),
        export.data.sparse_bytes,
        export.data.dense_bytes
    );
    for r in export.io.iter().filter(|r| r.assigned) {
        println!("  {} assigned {}", r.signal, r.address);
    }
    for r in &export.renames {
        println!("  {} `{}` renamed {}", r.kind, r.from, r.to);
    }
}
