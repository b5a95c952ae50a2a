//! `cetratus`: the command-line face of the Cetratus soft PLC.
//!
//! A thin layer of argument parsing over the library crates; every subcommand lives in its own
//! module and returns `anyhow::Result`.

mod bench;
mod check;
mod convert;
mod demo;
mod duration;
mod package;
mod run;
mod sim;

use clap::{Parser, Subcommand};

/// Cetratus: a soft PLC whose programs are Petri nets, replaced live under quarantine.
#[derive(Parser, Debug)]
#[command(name = "cetratus", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Play the token game on a net (every guard true) and print firings and markings.
    Sim(sim::SimArgs),
    /// Convert a net to PNML, DOT or SVG.
    Convert(convert::ConvertArgs),
    /// Analyse a net: invariants, reachability, deadlocks, boundedness, liveness.
    Check(check::CheckArgs),
    /// The paper's U.1/U.2 live-update experiment on the Vernadat cell.
    Demo(demo::DemoArgs),
    /// Build, inspect and verify update packages; make signing keys.
    Package(package::PackageArgs),
    /// Run a program against a digital twin, in virtual or real time.
    Run(run::RunArgs),
    /// Measure the figures in docs/performance.md.
    Bench(bench::BenchArgs),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Sim(a) => sim::run(a),
        Command::Convert(a) => convert::run(a),
        Command::Check(a) => check::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Package(a) => package::run(a),
        Command::Run(a) => run::run(a),
        Command::Bench(a) => bench::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
