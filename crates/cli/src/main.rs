//! `cetratus`: the command-line face of the Cetratus soft PLC.
//!
//! A thin layer of argument parsing over the library crates; every subcommand lives in its own
//! module and returns `anyhow::Result`.

#[cfg(feature = "bench")]
mod bench;
#[cfg(feature = "bench")]
mod bench_opcua;
#[cfg(feature = "bench")]
mod bench_st;
mod check;
mod client;
mod config;
mod convert;
mod dashboard_cmd;
mod demo;
mod export;
mod import;
mod mqtt_args;
mod package;
mod package_inspect;
mod progress;
mod rollout;
mod run;
mod sim;
mod state;
mod summary;
mod twin_cmd;
#[cfg(feature = "opcua")]
mod twin_opcua;

use clap::{Parser, Subcommand};

/// A duration on the command line (`500ms`, `1.5s`, `2min`, `1h`; a bare number is seconds), in
/// microseconds.
fn parse_duration_us(text: &str) -> anyhow::Result<u64> {
    use cetratus_program::duration::{parse_us, Bare};
    Ok(parse_us(text, Bare::Seconds)?)
}

// Parsing programs and packages allocates many small strings; mimalloc makes a load and an
// update's setup measurably cheaper than the system allocator (docs/performance.md). The scan
// itself does not allocate.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

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
    /// Write a program for a vendor PLC: `export PROGRAM --to st -o DIR` (IEC 61131-3 ST).
    Export(export::ExportArgs),
    /// Analyse a net: invariants, reachability, deadlocks, boundedness, liveness.
    Check(check::CheckArgs),
    /// Write a program from another tool's file: `import plcopen CHART.xml -o DIR`.
    Import(import::ImportArgs),
    /// The paper's U.1/U.2 live-update experiment on the Vernadat cell.
    Demo(demo::DemoArgs),
    /// Build, inspect and verify update packages; make signing keys.
    Package(package::PackageArgs),
    /// Run a program against a digital twin, field I/O or both, in virtual or real time.
    Run(Box<run::RunArgs>),
    /// Digital twins as processes of their own: `twin serve vernadat --modbus 127.0.0.1:15020`.
    Twin(twin_cmd::TwinArgs),
    /// Show what a state directory holds and what a warm start from it would do.
    State(state::StateArgs),
    /// Measure the figures in docs/performance.md.
    #[cfg(feature = "bench")]
    Bench(bench::BenchArgs),
    /// The dashboard on its own, watching the PLCs on a broker (`mct` is its older name).
    #[command(alias = "mct")]
    Dashboard(dashboard_cmd::DashboardArgs),
    /// Read a password from stdin and print its argon2 hash, for `[dashboard] accounts`.
    HashPassword,
    /// Send an update package to a PLC and follow it into quarantine.
    Load(client::LoadArgs),
    /// Make the candidate in quarantine PRIMARY.
    Substitute(client::SubstituteArgs),
    /// Drop the candidate in quarantine.
    Remove(client::PlainArgs),
    /// Cancel the update under way.
    Abort(client::PlainArgs),
    /// Leave the fault state.
    Reset(client::PlainArgs),
    /// On probation: flip PRIMARY back to the old program.
    Revert(client::PlainArgs),
    /// On probation: end it now; the update is final.
    Accept(client::PlainArgs),
    /// PRIMARY, STATUS and the programs of a PLC.
    Status(client::PlainArgs),
    /// Follow a PLC's state and events.
    Watch(client::PlainArgs),
    /// program_exec_info of both containers.
    ExecInfo(client::PlainArgs),
    /// Take one update package across many PLCs, stage by stage (docs/fleet.md).
    Rollout(rollout::RolloutArgs),
}

/// Sends the libraries' diagnostics (`tracing` events, and `log` records from rmqtt and rumqttc) to
/// stderr, filtered by `RUST_LOG` (default `warn`).
///
/// Stdout and the CLI's own stderr lines are its interface and stay as they are; these lines are
/// for an operator, so a healthy run adds none. A malformed `RUST_LOG` directive is reported and
/// skipped rather than stopping the PLC.
fn init_logging() {
    use std::io::IsTerminal as _;
    use tracing_subscriber::filter::{EnvFilter, LevelFilter};
    let mut filter = EnvFilter::builder()
        .with_default_directive(LevelFilter::WARN.into())
        .from_env_lossy();
    // Policy None needs no certificate, and async-opcua says so on every connection; a client's
    // orderly disconnect is a warning there too.
    for quiet in [
        "opcua_core::comms::secure_channel=off",
        "opcua_crypto::certificate_store=off",
        "opcua_client::session::client=off",
        "opcua_client::config=error",
        "opcua_client::session::event_loop=error",
        // A client that connects again under its own id kicks its old session, and rmqtt warns
        // each time: a client reconnecting in a loop would write a line a connection.
        "rmqtt::shared=error",
    ] {
        if let Ok(d) = quiet.parse() {
            filter = filter.add_directive(d);
        }
    }
    // `try_init` also installs the `log` bridge, capped at the filter's most verbose level.
    let installed = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .try_init();
    if let Err(e) = installed {
        eprintln!("warning: diagnostics from the libraries will not be shown ({e})");
    }
}

/// Keeps backtraces for panics only. Under `RUST_BACKTRACE=1`, anyhow (in rmqtt) captures one
/// for every error, and the broker logs each error a client causes (a reset, a malformed packet)
/// with it: a symbolized backtrace a connection, and the symbols kept in memory, hundreds of MiB.
/// `RUST_LIB_BACKTRACE=0`, unless the operator set it, turns off the capture for errors and
/// leaves it on for panics (docs/operations.md, *Logs*). Runs first, before any thread exists.
fn errors_without_backtraces() {
    if std::env::var_os("RUST_LIB_BACKTRACE").is_none() {
        std::env::set_var("RUST_LIB_BACKTRACE", "0");
    }
}

fn main() -> std::process::ExitCode {
    errors_without_backtraces();
    init_logging();
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Sim(a) => sim::run(a),
        Command::Convert(a) => convert::run(a),
        Command::Export(a) => export::run(a),
        Command::Check(a) => check::run(a),
        Command::Import(a) => import::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Package(a) => package::run(a),
        Command::Run(a) => run::run(a),
        Command::State(a) => state::run(a),
        Command::Twin(a) => twin_cmd::run(a),
        #[cfg(feature = "bench")]
        Command::Bench(a) => bench::run(a),
        Command::Dashboard(a) => dashboard_cmd::run(a),
        Command::HashPassword => dashboard_cmd::hash_password(),
        Command::Load(a) => client::load(a),
        Command::Substitute(a) => client::substitute(a),
        Command::Remove(a) => client::plain(cetratus_proto::Command::Remove, a),
        Command::Abort(a) => client::plain(cetratus_proto::Command::Abort, a),
        Command::Reset(a) => client::plain(cetratus_proto::Command::Reset, a),
        Command::Revert(a) => client::plain(cetratus_proto::Command::Revert, a),
        Command::Accept(a) => client::plain(cetratus_proto::Command::Accept, a),
        Command::Status(a) => client::status(a),
        Command::Watch(a) => client::watch(a),
        Command::ExecInfo(a) => client::exec_info(a),
        Command::Rollout(a) => rollout::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) if e.is::<client::StillPending>() => {
            eprintln!("pending: {e:#}");
            std::process::ExitCode::from(client::StillPending::EXIT_CODE)
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
