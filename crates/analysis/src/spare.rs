//! Whether the machine has a core to spare: what a default `check` asks before it takes a second
//! thread (two threads only pay on a core of their own). Read from Linux's `/proc/loadavg` and
//! `/proc/stat`; where they cannot be read, no core is spare.

use std::sync::Arc;

use crate::SpareCoreFn;

/// A probe that says, each time it is asked, whether a second core stayed idle since now.
pub fn from_now() -> SpareCoreFn {
    let start = cpu_ticks();
    Arc::new(move || spare_core_since(start))
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

/// Asked when a default run has found [`crate::PARALLEL_FROM`] states: whether a
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
