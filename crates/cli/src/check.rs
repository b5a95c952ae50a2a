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
    /// XML file, whose SFC POU is checked as `cetratus import plcopen` imports it.
    pub file: PathBuf,
    /// The SFC POU of a PLCopen file (needed when the file has several).
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
            // The program `import plcopen` would write, with the chart checks.
            let imported = cetratus_sfc::import_program(&text, &path.display().to_string(), pou)?;
            for note in &imported.notes {
                eprintln!("note: {note}");
            }
            return Ok((imported.net, true));
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

/// Whether a second core is idle right now: the machine has at least two cores, nothing else is
/// runnable (`/proc/loadavg` counts this process alone) and the load average of the last minute
/// stays below the number of cores. False when the load cannot be read.
fn idle_now() -> bool {
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let text = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let mut fields = text.split_whitespace();
    let minute = fields.next().and_then(|f| f.parse::<f64>().ok());
    let runnable = fields
        .nth(2)
        .and_then(|f| f.split('/').next()?.parse::<usize>().ok());
    matches!((minute, runnable), (Some(m), Some(r)) if cores >= 2 && r < cores && m < cores as f64)
}

/// The machine's CPU time so far, from the first line of `/proc/stat`: idle ticks (idle and
/// I/O wait), all ticks, and the number of CPUs.
fn cpu_ticks() -> Option<(u64, u64, u64)> {
    let text = std::fs::read_to_string("/proc/stat").ok()?;
    let fields: Vec<u64> = text
        .lines()
        .next()?
        .strip_prefix("cpu ")?
        .split_whitespace()
        .take(8)
        .map(|f| f.parse().ok())
        .collect::<Option<_>>()?;
    let cpus = text
        .lines()
        .filter(|l| {
            l.strip_prefix("cpu")
                .is_some_and(|r| r.starts_with(|c: char| c.is_ascii_digit()))
        })
        .count() as u64;
    (fields.len() == 8 && cpus > 0).then(|| (fields[3] + fields[4], fields.iter().sum(), cpus))
}

/// Asked when a default run has found [`cetratus_analysis::PARALLEL_FROM`] states: whether a
/// second core stayed idle since `start` (the [`cpu_ticks`] at the run's start), i.e. whether
/// the machine's idle time over the interval adds up to at least three quarters of one CPU's.
/// The kernel counts in ticks of 10 ms: over fewer than two ticks per CPU the count says too
/// little, and the load test of [`idle_now`] decides.
fn spare_core_since(start: Option<(u64, u64, u64)>) -> bool {
    start
        .zip(cpu_ticks())
        .and_then(|(start, now)| idle_core(start, now))
        .unwrap_or_else(idle_now)
}

/// Whether the idle time between two [`cpu_ticks`] adds up to three quarters of one CPU's at
/// least; `None` over fewer than two ticks per CPU.
fn idle_core(
    (idle0, all0, cpus): (u64, u64, u64),
    (idle1, all1, _): (u64, u64, u64),
) -> Option<bool> {
    let all = all1.checked_sub(all0)?;
    let idle = idle1.saturating_sub(idle0);
    // idle CPUs = idle ticks / ticks per CPU = idle · cpus / all; compared as 4·idle·cpus ≥ 3·all.
    (all >= 2 * cpus).then_some(4 * idle * cpus >= 3 * all)
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
        spare_core: args.threads.is_none().then(|| {
            let start = cpu_ticks();
            Arc::new(move || spare_core_since(start)) as cetratus_analysis::SpareCoreFn
        }),
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

#[cfg(test)]
mod tests {
    use super::idle_core;

    #[test]
    fn a_core_counts_as_spare_when_three_quarters_of_one_cpu_were_idle() {
        // Two CPUs, 40 ticks in all (20 each): this process kept one busy.
        let start = (1_000, 10_000, 2);
        assert_eq!(idle_core(start, (1_020, 10_040, 2)), Some(true));
        assert_eq!(idle_core(start, (1_015, 10_040, 2)), Some(true));
        assert_eq!(idle_core(start, (1_014, 10_040, 2)), Some(false));
        assert_eq!(idle_core(start, (1_000, 10_040, 2)), Some(false));
        // Too short to say, or a counter that went back.
        assert_eq!(idle_core(start, (1_002, 10_003, 2)), None);
        assert_eq!(idle_core(start, (1_000, 9_000, 2)), None);
    }
}
