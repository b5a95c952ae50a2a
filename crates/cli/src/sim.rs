//! `cetratus sim`: the token game on the bare net.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use cetratus_net::{Engine, Net, Policy};
use serde::Serialize;

/// Arguments of `cetratus sim`.
#[derive(clap::Args, Debug)]
pub struct SimArgs {
    /// A PNML file (ISO or PIPE dialect) or a program file.
    file: PathBuf,
    /// How many scans to play; the game also stops at a deadlock.
    #[arg(long, default_value_t = 20)]
    steps: u64,
    /// Firing policy: step, single-last, single-first or single-priority. Default: the
    /// program's own policy when the file is (or carries) a program, else step.
    #[arg(long)]
    policy: Option<Policy>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Step<'a> {
    step: u64,
    fired: Vec<&'a str>,
    marking: BTreeMap<&'a str, u32>,
}

#[derive(Serialize)]
struct Report<'a> {
    net: &'a str,
    policy: String,
    initial: BTreeMap<&'a str, u32>,
    steps: Vec<Step<'a>>,
    deadlock: bool,
}

/// Loads the net of a PNML file or of a program file.
pub fn load_net(path: &std::path::Path) -> anyhow::Result<Net> {
    Ok(load_net_and_policy(path)?.0)
}

/// The net of a PNML file or of a program file, with the program's firing policy when the file
/// is a program or a PNML file that carries one.
fn load_net_and_policy(path: &std::path::Path) -> anyhow::Result<(Net, Option<Policy>)> {
    let is_program = path.extension().is_some_and(|e| e == "toml");
    if is_program {
        let program = cetratus_program::Program::load(path)?;
        return Ok(((**program.net()).clone(), Some(program.policy())));
    }
    let net = cetratus_net::pnml::read_file(path)?;
    if net
        .toolspecific()
        .iter()
        .any(|t| t.tool == cetratus_program::TOOL)
    {
        let program = cetratus_program::Program::load(path)?;
        return Ok((net, Some(program.policy())));
    }
    Ok((net, None))
}

fn marking_map<'a>(net: &'a Net, m: &[u32]) -> BTreeMap<&'a str, u32> {
    net.places()
        .iter()
        .map(|p| p.id.as_str())
        .zip(m.iter().copied())
        .collect()
}

/// Runs `cetratus sim`.
pub fn run(args: &SimArgs) -> anyhow::Result<()> {
    let (net, own) = load_net_and_policy(&args.file)
        .with_context(|| format!("cannot load {}", args.file.display()))?;
    let policy = args.policy.or(own).unwrap_or_default();
    let net = Arc::new(net);
    let mut engine = Engine::new(net.clone());
    let mut steps = Vec::new();
    let mut deadlock = false;
    if !args.json {
        println!(
            "{}: {} places, {} transitions, policy {}",
            net.name().unwrap_or(net.id()),
            net.num_places(),
            net.num_transitions(),
            policy
        );
        println!("M0  {}", render(&net, engine.marking()));
    }
    for step in 1..=args.steps {
        let fired: Vec<&str> = engine
            .scan(policy, |_| Ok::<bool, std::convert::Infallible>(true))
            .map_err(|e| anyhow::anyhow!("scan {step}: {e}"))?
            .iter()
            .map(|&t| net.transition(t).id.as_str())
            .collect();
        if fired.is_empty() {
            deadlock = true;
            if !args.json {
                println!(
                    "deadlock after {} scans: no transition is enabled",
                    step - 1
                );
            }
            break;
        }
        if !args.json {
            println!("{step:<3} fired {}", fired.join(", "));
            println!("    {}", render(&net, engine.marking()));
        }
        steps.push(Step {
            step,
            fired,
            marking: marking_map(&net, engine.marking()),
        });
    }
    if args.json {
        let report = Report {
            net: net.id(),
            policy: policy.to_string(),
            initial: marking_map(&net, net.initial_marking().as_slice()),
            steps,
            deadlock,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
    }
    Ok(())
}

fn render(net: &Net, m: &[u32]) -> String {
    net.places()
        .iter()
        .zip(m)
        .filter(|(_, &k)| k > 0)
        .map(|(p, k)| format!("{}={k}", p.id))
        .collect::<Vec<_>>()
        .join(" ")
}
