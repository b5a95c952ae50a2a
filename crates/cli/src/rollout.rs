//! `cetratus rollout start|status|pause|resume|abort`: one package across many PLCs, stage by
//! stage (docs/fleet.md). The rollout runs in the process of `start` (or `resume`) until it
//! ends, with a live view of its steps on stderr; its record stays in the state directory, so
//! that `status`, `pause` and `abort` reach it from another terminal and `resume` carries it on
//! after a crash.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::bail;
use cetratus_fleet::record::Record;
use cetratus_fleet::run::{self, Options};
use cetratus_fleet::{journal, LinkConfig, Outcome};

use crate::mqtt_args::BrokerArgs;

/// `cetratus rollout`.
#[derive(clap::Args, Debug)]
pub struct RolloutArgs {
    #[command(subcommand)]
    command: RolloutCommand,
}

#[derive(clap::Subcommand, Debug)]
enum RolloutCommand {
    /// Start the rollout a plan (`rollout.toml`) describes, and follow it to its end.
    Start(StartArgs),
    /// Show where the rollout of the state directory stands.
    Status(StatusArgs),
    /// Take no PLC further until `resume`.
    Pause(StatusArgs),
    /// Carry on a paused rollout, or one whose process ended (a crash): no PLC is loaded twice.
    Resume(Box<DriveArgs>),
    /// Remove or revert the PLCs mid-update and end the rollout; PLCs already done stay.
    Abort(Box<DriveArgs>),
}

/// Where the rollout keeps its record.
#[derive(clap::Args, Debug)]
struct StateDirArg {
    /// The rollout's state directory (its record, its log and its lock).
    #[arg(long, default_value = "cetratus-rollout")]
    state_dir: PathBuf,
}

#[derive(clap::Args, Debug)]
struct StatusArgs {
    #[command(flatten)]
    dir: StateDirArg,
    /// Print the report as one JSON object.
    #[arg(long)]
    json: bool,
}

/// What `start`, `resume` and `abort` need to drive a rollout.
#[derive(clap::Args, Debug)]
struct DriveArgs {
    #[command(flatten)]
    dir: StateDirArg,
    /// The plant broker the PLCs are on.
    #[command(flatten)]
    broker: BrokerArgs,
    /// Sign commands with this operator key, as `cetratus load --key` does.
    #[arg(long)]
    key: Option<PathBuf>,
    /// How long to listen to the broker for the fleet's retained states before the plan is
    /// checked against them.
    #[arg(long, default_value = "2s")]
    discover: String,
    /// Wait for the end without the live view, printing only the report.
    #[arg(long)]
    wait: bool,
    /// Print the report as one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args, Debug)]
struct StartArgs {
    /// The plan.
    plan: PathBuf,
    #[command(flatten)]
    drive: DriveArgs,
}

/// Runs `cetratus rollout`.
pub fn run(a: &RolloutArgs) -> anyhow::Result<()> {
    match &a.command {
        RolloutCommand::Start(s) => {
            let record = run::start(&s.plan, options(&s.drive)?)?;
            finish(&record, &s.drive)
        }
        RolloutCommand::Resume(d) => {
            let record = run::resume(options(d)?)?;
            finish(&record, d)
        }
        RolloutCommand::Abort(d) => match run::abort(options(d)?)? {
            Some(record) => finish(&record, d),
            None => {
                eprintln!(
                    "asked the rollout process of {} to abort; follow it with `cetratus rollout status`",
                    d.dir.state_dir.display()
                );
                Ok(())
            }
        },
        RolloutCommand::Status(s) => status(s),
        RolloutCommand::Pause(s) => {
            let asked = run::pause(&s.dir.state_dir)?;
            eprintln!(
                "{}",
                if asked {
                    "asked the rollout process to pause"
                } else {
                    "paused: no process runs the rollout; `cetratus rollout resume` carries it on"
                }
            );
            Ok(())
        }
    }
}

fn options(d: &DriveArgs) -> anyhow::Result<Options> {
    let live = !d.wait;
    Ok(Options {
        link: LinkConfig {
            url: d.broker.client_url()?,
            credentials: d.broker.credentials(),
            key: crate::client::operator_key(d.key.as_deref())?,
            timeout: Duration::from_secs(10),
            account: None,
        },
        state_dir: d.dir.state_dir.clone(),
        discover: Duration::from_micros(crate::parse_duration_us(&d.discover)?),
        progress: Box::new(move |record: &Record, lines: &[String]| {
            if live {
                for l in lines {
                    eprintln!("{l}");
                }
                eprintln!("  {}", summary(record));
            }
        }),
    })
}

/// One line: the stage, and how many PLCs stand at each step.
fn summary(r: &Record) -> String {
    let mut counts: std::collections::BTreeMap<&str, usize> = Default::default();
    for p in r.plcs.values() {
        *counts.entry(p.step.as_str()).or_default() += 1;
    }
    let steps: Vec<String> = counts.iter().map(|(s, n)| format!("{n} {s}")).collect();
    let stage = r.stage.min(r.stages.len());
    let paused = if r.paused { " (paused)" } else { "" };
    format!(
        "{}{paused} · stage {stage}/{} · {}",
        r.outcome.as_str(),
        r.stages.len(),
        steps.join(", ")
    )
}

/// Prints the report, and fails unless the rollout is done.
fn finish(record: &Record, d: &DriveArgs) -> anyhow::Result<()> {
    print_report(record, d.json)?;
    match record.outcome {
        Outcome::Done => Ok(()),
        Outcome::Aborted => bail!("rollout {} aborted", record.id),
        _ => bail!(
            "rollout {} {}: {}",
            record.id,
            record.outcome.as_str(),
            record.reason.as_deref().unwrap_or("no reason recorded")
        ),
    }
}

fn print_report(record: &Record, json: bool) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string(&record.report())?);
        return Ok(());
    }
    println!(
        "rollout {} of {}: {}",
        record.id,
        record.target.update,
        summary(record)
    );
    if let Some(r) = &record.reason {
        println!("  {r}");
    }
    if record.alarm {
        println!("  ALARM: PLCs were left mid-update (on_failure = \"hold\")");
    }
    for (k, ids) in record.stages.iter().enumerate() {
        for id in ids {
            let Some(p) = record.plcs.get(id) else {
                continue;
            };
            let note = p
                .note
                .as_deref()
                .map(|n| format!("  {n}"))
                .unwrap_or_default();
            println!("  stage {}  {id:<24} {}{note}", k + 1, p.step.as_str());
        }
    }
    Ok(())
}

fn status(s: &StatusArgs) -> anyhow::Result<()> {
    let record = journal::read(&s.dir.state_dir)?;
    print_report(&record, s.json)?;
    if !s.json {
        let running = journal::held(&s.dir.state_dir);
        println!(
            "  {}",
            if running {
                "a process runs it"
            } else if record.outcome.ended() {
                "ended"
            } else {
                "no process runs it: `cetratus rollout resume` carries it on"
            }
        );
    }
    Ok(())
}
