//! `cetratus convert`: PNML, DOT and SVG out of any net the project reads.

use std::path::PathBuf;

use anyhow::Context;
use cetratus_net::{export, pnml};

/// Output formats of `cetratus convert`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Format {
    /// ISO/IEC 15909-2 PNML.
    Pnml,
    /// Graphviz DOT.
    Dot,
    /// An SVG drawing with the initial marking.
    Svg,
}

/// Arguments of `cetratus convert`.
#[derive(clap::Args, Debug)]
pub struct ConvertArgs {
    /// A PNML file (ISO or PIPE dialect) or a program file.
    file: PathBuf,
    /// The output format.
    #[arg(long)]
    to: Format,
    /// Where to write; standard output when absent.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

/// Runs `cetratus convert`.
pub fn run(args: &ConvertArgs) -> anyhow::Result<()> {
    let net = crate::sim::load_net(&args.file)
        .with_context(|| format!("cannot load {}", args.file.display()))?;
    let m0 = net.initial_marking();
    let text = match args.to {
        Format::Pnml => pnml::write_string(&net),
        Format::Dot => export::to_dot(&net, Some(m0.as_slice())),
        Format::Svg => export::to_svg(&net, Some(m0.as_slice())),
    };
    match &args.output {
        Some(path) => std::fs::write(path, text)
            .with_context(|| format!("cannot write {}", path.display()))?,
        None => print!("{text}"),
    }
    Ok(())
}
