//! The machine's own timer latency, from `cyclictest` (Debian `rt-tests`), for `bench jitter`:
//! the physical limit that the scan's latency is read against.
//!
//! Like with like: without `--rt` cyclictest runs one thread at normal priority and leaves the
//! CPUs' idle states alone (`--laptop`), as the scan thread does; with `--rt` it runs at
//! SCHED_FIFO 80 with its memory locked (`-m -p 80`) and holds `/dev/cpu_dma_latency` at 0, as
//! `--rt` does for the scan thread. Both sleep to absolute deadlines at the same period.

use std::process::Command;

use serde::Serialize;

/// Histogram buckets (1 µs each); a latency beyond lands in the overflow count.
const HISTOGRAM_US: u64 = 100_000;

/// What cyclictest measured, or why it did not.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum Machine {
    /// Its figures.
    Measured {
        /// The command line it ran with.
        command: String,
        /// Wake-ups measured.
        cycles: u64,
        /// Median latency, in µs.
        p50_us: u64,
        /// 99th percentile, in µs (the histogram's end when it overflowed there).
        p99_us: u64,
        /// Largest, in µs.
        max_us: u64,
    },
    /// Not measured: cyclictest is missing, refused its priority, or failed.
    NotMeasured {
        /// Why, for people.
        cyclictest: String,
    },
}

/// Runs cyclictest for `for_us` at `period_us`, with `--rt`'s settings when `rt`.
pub fn measure(period_us: u64, for_us: u64, rt: bool) -> Machine {
    let secs = for_us.div_ceil(1_000_000).max(1);
    let mut args: Vec<String> = vec![
        "-q".into(),
        "-t".into(),
        "1".into(),
        format!("-i{}", period_us.max(100)),
        format!("-D{secs}"),
        format!("-h{HISTOGRAM_US}"),
    ];
    if rt {
        args.extend(["-m".into(), "-p80".into()]);
    } else {
        args.push("--laptop".into());
    }
    let command = format!("cyclictest {}", args.join(" "));
    let out = match Command::new("cyclictest").args(&args).output() {
        Ok(o) => o,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Machine::NotMeasured {
                cyclictest: "missing: install the Debian package rt-tests".into(),
            }
        }
        Err(e) => {
            return Machine::NotMeasured {
                cyclictest: format!("could not start: {e}"),
            }
        }
    };
    let stderr = String::from_utf8_lossy(&out.stderr);
    let refused = stderr.lines().find(|l| {
        let l = l.to_ascii_lowercase();
        l.contains("operation not permitted")
            || l.contains("unable to change scheduling policy")
            || l.contains("mlockall")
    });
    if let Some(line) = refused {
        return Machine::NotMeasured {
            cyclictest: format!("refused its priority ({command}): {}", line.trim()),
        };
    }
    if !out.status.success() {
        return Machine::NotMeasured {
            cyclictest: format!(
                "failed ({command}): {}",
                stderr.lines().next().unwrap_or("no message")
            ),
        };
    }
    match parse(&String::from_utf8_lossy(&out.stdout)) {
        Some((cycles, p50_us, p99_us, max_us)) => Machine::Measured {
            command,
            cycles,
            p50_us,
            p99_us,
            max_us,
        },
        None => Machine::NotMeasured {
            cyclictest: format!("printed no histogram ({command})"),
        },
    }
}

/// Wake-ups, p50, p99 and max (µs) of cyclictest's histogram output.
fn parse(text: &str) -> Option<(u64, u64, u64, u64)> {
    let mut buckets: Vec<(u64, u64)> = Vec::new();
    let (mut overflows, mut max) = (0u64, None);
    for line in text.lines() {
        if let Some(rest) = line.strip_prefix("# Histogram Overflows:") {
            overflows = rest.split_whitespace().next()?.parse().ok()?;
        } else if let Some(rest) = line.strip_prefix("# Max Latencies:") {
            max = rest.split_whitespace().next()?.parse::<u64>().ok();
        } else if !line.starts_with('#') {
            let mut f = line.split_whitespace();
            if let (Some(us), Some(n)) = (f.next(), f.next()) {
                buckets.push((us.parse().ok()?, n.parse().ok()?));
            }
        }
    }
    let total: u64 = buckets.iter().map(|b| b.1).sum::<u64>() + overflows;
    if total == 0 {
        return None;
    }
    let at = |q: f64| {
        let want = ((total as f64) * q).ceil().max(1.0) as u64;
        let mut seen = 0;
        for &(us, n) in &buckets {
            seen += n;
            if seen >= want {
                return us;
            }
        }
        HISTOGRAM_US
    };
    Some((total, at(0.5), at(0.99), max?))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_histogram_gives_the_percentiles_and_overflows_count() {
        let text = "# /dev/cpu_dma_latency set to 0us\n000001 000050\n000002 000048\n000003 000001\n# Total: 000000100\n# Min Latencies: 00001\n# Max Latencies: 00250\n# Histogram Overflows: 00001\n";
        assert_eq!(super::parse(text), Some((100, 1, 3, 250)));
        assert_eq!(super::parse("# Histogram\n"), None);
    }
}
