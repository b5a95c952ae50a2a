//! `cetratus check FILE`: the structural and behavioural analysis of a net or a program's net.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use cetratus_analysis::budget::{parse_bytes, DEFAULT_MAX_STATES};
use cetratus_analysis::{check, check_property, CheckOptions, Clock, Predicate, Property};
use cetratus_net::Net;

use crate::progress::TerminalProgress;

/// Arguments of `cetratus check`.
#[derive(clap::Args, Debug)]
pub struct CheckArgs {
    /// A PNML file (ISO/IEC 15909-2 or PIPE dialect), a program file (.toml), or a PLCopen TC6
    /// XML file, whose POU is checked as `cetratus import plcopen` imports it (an SFC POU with the
    /// chart checks).
    pub file: PathBuf,
    /// The POU of a PLCopen file (needed unless the file has one SFC POU, or one PROGRAM).
    #[arg(long, value_name = "NAME")]
    pub pou: Option<String>,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Stop exploring after N states; the report is then partial (`max_states`).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_STATES)]
    pub max_states: u64,
    /// Stop before the state space would hold more than this (e.g. 4GiB, 512MiB); the report is
    /// then partial (`max_memory`).
    #[arg(long, value_name = "SIZE", default_value = "4GiB", value_parser = parse_size)]
    pub max_memory: u64,
    /// Stop after this long (e.g. 10min, 30s, 500ms); the report is then partial (`timeout`).
    #[arg(long, value_name = "DURATION", default_value = "10min", value_parser = parse_timeout)]
    pub timeout: Duration,
    /// Threads: with 2 or more the state space is explored in parallel (same states, same ids,
    /// same witness as one thread) and the structural analyses run beside it. By default the
    /// exploration starts on one thread and, once it has found 200,000 states, goes on with two
    /// if the machine has a second core that stayed idle meanwhile: two threads are slower on
    /// smaller state spaces, and on a busy machine (docs/analysis.md, "The default thread
    /// count").
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Check one property only, stopping as soon as it is decided, with a firing sequence that
    /// shows the answer.
    #[arg(long, value_name = "NAME", value_parser = ["deadlock", "bounded", "safe", "live", "reversible"],
          conflicts_with_all = ["reach", "always"])]
    pub property: Option<String>,
    /// Is some marking satisfying this predicate reachable? e.g. 'P10 >= 2 && P20 == 0'
    /// (place ids or names, + - *, < <= == != >= >, && || ! and parentheses).
    #[arg(long, value_name = "PREDICATE", conflicts_with = "always")]
    pub reach: Option<String>,
    /// Does this predicate hold in every reachable marking? (same syntax as --reach)
    #[arg(long, value_name = "PREDICATE")]
    pub always: Option<String>,
    /// Property mode: explore every interleaving (no stubborn sets); witnesses are then shortest.
    #[arg(long)]
    pub no_reduction: bool,
}

fn parse_size(text: &str) -> anyhow::Result<u64> {
    Ok(parse_bytes(text)?)
}

fn parse_timeout(text: &str) -> anyhow::Result<Duration> {
    Ok(Duration::from_micros(crate::parse_duration_us(text)?))
}

/// The machine's monotonic clock, from the start of the check.
struct Monotonic(Instant);

impl Clock for Monotonic {
    fn elapsed(&self) -> Duration {
        self.0.elapsed()
    }
}

/// The net to check, and whether it is an SFC chart (whose chart checks are added).
fn load(path: &Path, pou: Option<&str>) -> anyhow::Result<(Net, bool)> {
    let is_program = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    if is_program {
        let program = cetratus_program::Program::load(path)
            .with_context(|| format!("cannot load the program {}", path.display()))?;
        return Ok((Net::clone(program.net()), program.is_sfc()));
    }
    let is_xml = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("xml"));
    if is_xml {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        if cetratus_sfc::is_plcopen(text.strip_prefix('\u{feff}').unwrap_or(&text)) {
            // The program `import plcopen` would write, with the chart checks for a chart.
            let imported = cetratus_sfc::import_pou(&text, &path.display().to_string(), pou)?;
            for note in imported.notes() {
                eprintln!("note: {note}");
            }
            let is_chart = matches!(imported, cetratus_sfc::ImportedPou::Chart(_));
            return Ok((imported.net().clone(), is_chart));
        }
    }
    if let Some(pou) = pou {
        anyhow::bail!(
            "--pou {pou} names a POU of a PLCopen file, and {} is not one",
            path.display()
        );
    }
    let net = cetratus_net::pnml::read_file(path)
        .with_context(|| format!("cannot read the net {}", path.display()))?;
    Ok((net, false))
}

/// Reads a predicate of `--reach` or `--always`; the error shows the text with a caret under the
/// column at fault.
fn predicate(flag: &str, text: &str, net: &Net) -> anyhow::Result<Predicate> {
    Predicate::parse(text, net).map_err(|e| {
        anyhow::anyhow!(
            "cannot read the predicate of {flag} {e}\n  {text}\n  {caret:>col$}",
            caret = "^",
            col = e.column
        )
    })
}

/// The property asked for on the command line, if any.
fn property(args: &CheckArgs, net: &Net) -> anyhow::Result<Option<Property>> {
    if let Some(name) = &args.property {
        return Property::named(name).map(Some).ok_or_else(|| {
            anyhow::anyhow!(
                "unknown property {name:?}; use one of {}",
                Property::NAMES.join(", ")
            )
        });
    }
    if let Some(text) = &args.reach {
        return Ok(Some(Property::Reach(predicate("--reach", text, net)?)));
    }
    if let Some(text) = &args.always {
        return Ok(Some(Property::Always(predicate("--always", text, net)?)));
    }
    Ok(None)
}

/// Runs `cetratus check`: prints the report, as text or JSON. Ctrl-C stops the exploration and
/// prints what was found so far, marked partial.
pub fn run(args: &CheckArgs) -> anyhow::Result<()> {
    let clock = Arc::new(Monotonic(Instant::now()));
    let (net, is_sfc) = load(&args.file, args.pou.as_deref())?;
    let property = property(args, &net)?;
    let cancel = Arc::new(AtomicBool::new(false));
    let flag = cancel.clone();
    if let Err(e) = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed)) {
        eprintln!("warning: Ctrl-C will end the process without a partial report ({e})");
    }
    // No progress in JSON mode: its reader wants the report alone.
    let progress = (!args.json).then(|| TerminalProgress::new(args.max_states, args.timeout));
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let opts = CheckOptions {
        max_states: Some(args.max_states),
        max_memory: Some(args.max_memory),
        timeout: Some(args.timeout),
        clock: Some(clock),
        // The default starts on one thread and takes a second once the state space is large,
        // if a second core stayed idle meanwhile (two threads only pay on a core of their own).
        threads: args
            .threads
            .unwrap_or(if cores >= 2 { 2 } else { 1 })
            .max(1),
        parallel_from: if args.threads.is_some() {
            0
        } else {
            cetratus_analysis::PARALLEL_FROM
        },
        spare_core: args
            .threads
            .is_none()
            .then(cetratus_analysis::spare::from_now),
        cancel: Some(cancel),
        progress: progress.as_ref().map(TerminalProgress::callback),
        reduction: !args.no_reduction,
        ..CheckOptions::default()
    };
    let mut report = match &property {
        Some(p) => check_property(&net, p, &opts),
        None => check(&net, &opts),
    };
    if is_sfc && property.is_none() {
        let chart = cetratus_analysis::sfc::check_chart(&net, &report);
        report.warnings.extend(chart.warnings());
        report.sfc = Some(chart);
    }
    if let Some(p) = &progress {
        p.finish();
    }
    let text = if args.json {
        format!("{}\n", serde_json::to_string_pretty(&report)?)
    } else {
        report.to_string()
    };
    // A reader that stops early (`| head`) is not an error.
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}
