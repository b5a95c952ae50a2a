//! Workloads of the state-space benches: reachability speed and memory on Kanban and FMS, the
//! Farkas invariants' time, and the plain-Python BFS baseline on the same nets.

use std::process::Command;
use std::time::Instant;

use cetratus_analysis::families::{fms, kanban};
use cetratus_analysis::invariants::{p_semiflows, t_semiflows, DEFAULT_MAX_ROWS};
use cetratus_analysis::reach::{explore, structural_packing, ReachOptions, ReachResult};
use cetratus_analysis::{check_property, CheckOptions, Property};
use cetratus_net::Net;
use serde::Serialize;

/// The figures of one net.
#[derive(Clone, Debug, Serialize)]
pub struct NetFigures {
    /// `Kanban` or `FMS`.
    pub family: &'static str,
    /// The family's parameter.
    pub n: u32,
    /// Reachable states.
    pub states: u64,
    /// Edges.
    pub edges: u64,
    /// Wall-clock seconds of the exploration on one thread.
    pub seconds: f64,
    /// `reachability_states_per_s` on one thread: states discovered per second (the one-core
    /// target).
    pub reachability_states_per_s: f64,
    /// Bits per packed state.
    pub bits_per_state: usize,
    /// Peak bytes of the one-thread state store (states, BFS parents, hash table) per state.
    pub bytes_per_state: f64,
    /// Threads of the multi-thread run: the available parallelism (1: no such run).
    pub threads_multi: usize,
    /// Wall-clock seconds of the exploration on `threads_multi` threads (same states and edges).
    pub seconds_multi: f64,
    /// States discovered per second on `threads_multi` threads.
    pub reachability_states_per_s_multi: f64,
    /// Peak bytes per state of the multi-thread store (it adds the batch's outboxes).
    pub bytes_per_state_multi: f64,
    /// Time of the minimal P- and T-semiflows, in milliseconds.
    pub invariants_ms: f64,
    /// Number of P-semiflows and T-semiflows.
    pub invariants: (usize, usize),
}

impl NetFigures {
    /// The faster of the two runs: `(seconds, threads)`.
    pub fn fastest(&self) -> (f64, usize) {
        if self.threads_multi > 1 && self.seconds_multi < self.seconds {
            (self.seconds_multi, self.threads_multi)
        } else {
            (self.seconds, 1)
        }
    }
}

/// The Python baseline and this crate on the same net, in the same run (our time is the faster
/// of [`NetFigures::seconds`] and [`NetFigures::seconds_multi`]).
#[derive(Clone, Debug, Serialize)]
pub struct Baseline {
    /// `Kanban` or `FMS`.
    pub family: &'static str,
    /// The family's parameter.
    pub n: u32,
    /// States found by Python (must equal ours).
    pub states: u64,
    /// Python's seconds.
    pub python_seconds: f64,
    /// Our seconds on the same net, from the faster run.
    pub rust_seconds: f64,
    /// Threads of that run (1: the single-threaded explorer).
    pub rust_threads: usize,
    /// `python_seconds / rust_seconds`.
    pub speedup: f64,
    /// `python_seconds / seconds` of the one-thread run.
    pub speedup_one_thread: f64,
}

/// Everything `cetratus bench` reports about the analysis.
#[derive(Clone, Debug, Serialize)]
pub struct ReachabilityFigures {
    /// Per net.
    pub nets: Vec<NetFigures>,
    /// Per baseline comparison; empty when `python3` is not available.
    pub baselines: Vec<Baseline>,
    /// Why a baseline is missing, if it is.
    pub baseline_note: Option<String>,
    /// Stubborn-set reduced state counts beside the full ones.
    pub reductions: Vec<Reduction>,
}

/// The state space that `cetratus check --property deadlock` explores with stubborn sets, beside
/// the full one, on one net.
#[derive(Clone, Debug, Serialize)]
pub struct Reduction {
    /// `Kanban` or `FMS`.
    pub family: &'static str,
    /// The family's parameter.
    pub n: u32,
    /// States of the full reachability graph, explored in the same run.
    pub full_states: u64,
    /// Wall-clock seconds of the full exploration (one thread, no liveness pass).
    pub full_seconds: f64,
    /// States of the reduced graph (`--property deadlock`, no deadlock: explored to the end).
    pub reduced_states: u64,
    /// Wall-clock seconds of the reduced search.
    pub reduced_seconds: f64,
    /// Whether the reduced search found a deadlock (it must agree with the full count).
    pub deadlock: bool,
}

/// The full and the stubborn-set reduced state space of a family member.
pub fn reduction(family_name: &'static str, n: u32) -> Reduction {
    let net = family(family_name, n);
    let t = Instant::now();
    let full = explore_once(&net);
    let full_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let r = check_property(&net, &Property::Deadlock, &CheckOptions::default());
    let reduced_seconds = t.elapsed().as_secs_f64();
    let deadlock = r.holds == Some(true);
    assert_eq!(
        deadlock,
        full.deadlocks > 0,
        "the reduced search must agree with the full one on deadlocks"
    );
    Reduction {
        family: family_name,
        n,
        full_states: full.states,
        full_seconds,
        reduced_states: r.states,
        reduced_seconds,
        deadlock,
    }
}

/// Builds a family member.
pub fn family(name: &str, n: u32) -> Net {
    let net = if name == "FMS" { fms(n) } else { kanban(n) };
    net.expect("the family generators build well-formed nets")
}

/// Explores `net` once (no liveness pass, one thread), as the bench measures it.
pub fn explore_once(net: &Net) -> ReachResult {
    explore_with(net, 1)
}

/// Explores `net` once (no liveness pass) with `threads` threads.
pub fn explore_with(net: &Net, threads: usize) -> ReachResult {
    let packing = structural_packing(net, DEFAULT_MAX_ROWS)
        .expect("structural bounds of the families")
        .expect("the families are structurally bounded");
    let opts = ReachOptions {
        threads,
        ..ReachOptions::default()
    };
    explore(net, &packing, &opts).expect("the families fit the packed explorer")
}

/// Threads of the multi-thread run: what the machine offers.
fn available_threads() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}

fn measure(family_name: &'static str, n: u32) -> NetFigures {
    let net = family(family_name, n);
    let t = Instant::now();
    let r = explore_once(&net);
    let seconds = t.elapsed().as_secs_f64();
    let threads_multi = available_threads();
    let (seconds_multi, bytes_multi) = if threads_multi > 1 {
        let t = Instant::now();
        let m = explore_with(&net, threads_multi);
        let s = t.elapsed().as_secs_f64();
        assert_eq!(
            (m.states, m.edges),
            (r.states, r.edges),
            "the parallel exploration must find what the sequential one finds"
        );
        (s, m.peak_bytes)
    } else {
        (seconds, r.peak_bytes)
    };
    let ti = Instant::now();
    let p = p_semiflows(&net, DEFAULT_MAX_ROWS).map_or(0, |v| v.len());
    let tt = t_semiflows(&net, DEFAULT_MAX_ROWS).map_or(0, |v| v.len());
    let invariants_ms = ti.elapsed().as_secs_f64() * 1e3;
    NetFigures {
        family: family_name,
        n,
        states: r.states,
        edges: r.edges,
        seconds,
        reachability_states_per_s: r.states as f64 / seconds,
        bits_per_state: r.bits_per_state,
        bytes_per_state: r.peak_bytes as f64 / r.states as f64,
        threads_multi,
        seconds_multi,
        reachability_states_per_s_multi: r.states as f64 / seconds_multi,
        bytes_per_state_multi: bytes_multi as f64 / r.states as f64,
        invariants_ms,
        invariants: (p, tt),
    }
}

fn python(family_name: &str, n: u32) -> Result<(u64, f64), String> {
    let script = crate::embedded::bfs_baseline();
    let out = Command::new("python3")
        .arg(&script)
        .args([
            "--family",
            &family_name.to_lowercase(),
            "--n",
            &n.to_string(),
        ])
        .output()
        .map_err(|e| format!("python3 not runnable: {e}"))?;
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned());
    }
    // The script prints `states edges seconds` on its last line.
    let text = String::from_utf8_lossy(&out.stdout);
    let last: Vec<&str> = text
        .lines()
        .last()
        .unwrap_or("")
        .split_whitespace()
        .collect();
    match last.as_slice() {
        [s, _, secs] => Ok((
            s.parse().map_err(|_| "bad state count".to_string())?,
            secs.parse().map_err(|_| "bad seconds".to_string())?,
        )),
        _ => Err(format!("unexpected output from the baseline: {text}")),
    }
}

/// Measures the figures on Kanban and FMS with N = 5 (quick: N = 3): speed on one thread and on
/// all available threads, memory, invariants, and the Python baseline on the same nets (about a
/// minute of Python at N = 5), whose speedup is taken from the faster of our two runs; then the
/// stubborn-set reduced state counts beside the full ones at N = 5 and 6 (quick: N = 3).
pub fn reachability_figures(quick: bool) -> ReachabilityFigures {
    let n = if quick { 3 } else { 5 };
    let nets = vec![measure("Kanban", n), measure("FMS", n)];
    let mut baselines = Vec::new();
    let mut baseline_note = None;
    for ours in &nets {
        match python(ours.family, n) {
            Ok((states, python_seconds)) => {
                if states != ours.states {
                    baseline_note = Some(format!(
                        "Python found {states} states of {}({n}), this crate {}",
                        ours.family, ours.states
                    ));
                    continue;
                }
                let (rust_seconds, rust_threads) = ours.fastest();
                baselines.push(Baseline {
                    family: ours.family,
                    n,
                    states,
                    python_seconds,
                    rust_seconds,
                    rust_threads,
                    speedup: python_seconds / rust_seconds,
                    speedup_one_thread: python_seconds / ours.seconds,
                });
            }
            Err(e) => baseline_note = Some(e),
        }
    }
    // N = 6 (11 and 15 million states, a few seconds each) only in the full run.
    let sizes: &[u32] = if quick { &[3] } else { &[5, 6] };
    let reductions = sizes
        .iter()
        .flat_map(|&n| [reduction("Kanban", n), reduction("FMS", n)])
        .collect();
    ReachabilityFigures {
        nets,
        baselines,
        baseline_note,
        reductions,
    }
}
