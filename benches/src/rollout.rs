//! `cetratus bench rollout`: one rollout of U.1 across `n` real PLC processes (the Vernadat
//! cell on its twin, ten times real time) on one Mosquitto, run by the real `cetratus rollout`,
//! watched by one `cetratus dashboard`. It measures:
//!
//! * the control plane's own time: each PLC's time from its load to its acceptance, less the
//!   plan's least quarantine and probation (what the waits take in wall time at the PLCs'
//!   speed), and the same per stage; and the rollout process's CPU time per PLC;
//! * the dashboard's update latency (a PLC's publication to its delivery on the dashboard's
//!   stream) while the rollout runs;
//! * the resident memory of one PLC process (`run` with a twin, on the plant broker, no
//!   dashboard), split into what is its own (anonymous) and what it shares (the binary).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::harness::{
    self, quantile, start_dashboard, start_mosquitto, update_latencies, BenchError, Child, Figures,
};
use crate::program;

/// The PLCs' speed: program time runs ten times the wall clock.
const SPEED: f64 = 10.0;
/// The plan's least quarantine and probation, in program time.
const QUARANTINE_S: f64 = 15.0;
const PROBATION_S: f64 = 10.0;

/// Runs the whole measurement with the `cetratus` binary `exe`.
pub fn rollout(exe: &Path, n: usize, period: &str) -> Result<Figures, BenchError> {
    let dir = std::env::temp_dir().join(format!("cetratus-rollout-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("trusted"))?;
    let package = package(exe, &dir)?;
    let (_broker, port) = start_mosquitto()?;
    let url = format!("mqtt://127.0.0.1:{port}");
    let plcs = start_plcs(exe, n, period, &url, &dir)?;
    let (_dashboard, http, cookie) = start_dashboard(exe, &url)?;
    std::thread::sleep(Duration::from_secs(5 + n as u64 / 10));
    let plan = dir.join("rollout.toml");
    std::fs::write(
        &plan,
        format!(
            "package = \"{}\"\nselect = \"*\"\nstages = [\"1\", \"10%\", \"50%\", \"100%\"]\n\
             quarantine = \"{QUARANTINE_S}s\"\nprobation = \"{PROBATION_S}s\"\nmax_parallel = {n}\n\
             on_failure = \"stop\"\nsilent = \"60s\"\n",
            package.display()
        ),
    )?;
    // The baseline: the same dashboard's latency for 10 s before the rollout.
    let idle = update_latencies(http, &cookie, Instant::now(), 10_000_000)?;
    let (report, cpu_s, lat_ms) = run_rollout(exe, &plan, &url, &dir, (http, &cookie))?;
    let mut out = Figures::new();
    out.insert("plcs".into(), n.into());
    out.insert("period".into(), period.into());
    out.insert("outcome".into(), report["outcome"].clone());
    out.insert(
        "rollout_cpu_ms_per_plc".into(),
        (1000.0 * cpu_s / n as f64).into(),
    );
    control_plane(&dir.join("state/rollout.log"), &report, &mut out)?;
    latency("dashboard_idle", idle, &mut out);
    latency("dashboard", lat_ms, &mut out);
    memory(&plcs, &mut out)?;
    drop(plcs);
    let _ = std::fs::remove_dir_all(&dir);
    Ok(out)
}

/// U.1 with its timing changes declared, signed by a key every PLC trusts.
fn package(exe: &Path, dir: &Path) -> Result<PathBuf, BenchError> {
    let src = program::examples_dir().join("vernadat");
    for f in ["vernadat.toml", "vernadat.pnml", "u1.toml", "u1.pnml"] {
        std::fs::copy(src.join(f), dir.join(f))?;
    }
    let manifest = std::fs::read_to_string(src.join("u1.package.toml"))?
        + "\n[changes]\noutputs = [\"CM1\", \"PM1\", \"DM1\", \"CM2\", \"PM2\", \"DM2\"]\n";
    std::fs::write(dir.join("u1.package.toml"), manifest)?;
    let run = |args: &[&std::ffi::OsStr]| -> Result<(), BenchError> {
        let out = Command::new(exe).args(args).output()?;
        if !out.status.success() {
            return Err(String::from_utf8_lossy(&out.stderr).into_owned().into());
        }
        Ok(())
    };
    let key = dir.join("bench.key");
    run(&[
        "package".as_ref(),
        "keygen".as_ref(),
        "--out".as_ref(),
        key.as_os_str(),
    ])?;
    std::fs::copy(dir.join("bench.key.pub"), dir.join("trusted/bench.pub"))?;
    let package = dir.join("u1.cpkg");
    let manifest = dir.join("u1.package.toml");
    run(&[
        "package".as_ref(),
        "build".as_ref(),
        manifest.as_os_str(),
        "--key".as_ref(),
        key.as_os_str(),
        "-o".as_ref(),
        package.as_os_str(),
    ])?;
    Ok(package)
}

/// `n` PLCs `cell0` … on the broker at `url`, at [`SPEED`], trusting the bench's key, each with
/// a probation window of 20 s.
fn start_plcs(
    exe: &Path,
    n: usize,
    period: &str,
    url: &str,
    dir: &Path,
) -> Result<Vec<Child>, BenchError> {
    let config = dir.join("config");
    std::fs::create_dir_all(&config)?;
    std::fs::write(
        config.join("config.toml"),
        "[labels]\nline = \"1\"\n\n[updates]\nprobation = \"20s\"\n",
    )?;
    let speed = SPEED.to_string();
    let trusted = dir.join("trusted");
    harness::start_plcs(
        exe,
        n,
        url,
        dir,
        &[
            "--speed".as_ref(),
            speed.as_ref(),
            "--period".as_ref(),
            period.as_ref(),
            "--trust".as_ref(),
            trusted.as_os_str(),
            "--config".as_ref(),
            config.as_os_str(),
        ],
    )
}

/// Runs the rollout to its end under bash, whose `times` gives the CPU time of its child, while
/// the dashboard's update latencies are measured; the report, the CPU seconds, the latencies.
fn run_rollout(
    exe: &Path,
    plan: &Path,
    url: &str,
    dir: &Path,
    (http, cookie): (u16, &str),
) -> Result<(serde_json::Value, f64, Vec<f64>), BenchError> {
    let script =
        r#""$0" rollout start "$1" --broker "$2" --state-dir "$3" --wait --json; times >&2"#;
    let mut child = Command::new("bash")
        .args(["-c", script])
        .arg(exe)
        .arg(plan)
        .arg(url)
        .arg(dir.join("state"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()?;
    let mut lat = Vec::new();
    let t0 = Instant::now();
    while child.try_wait()?.is_none() && t0.elapsed() < Duration::from_secs(600) {
        let since = Instant::now();
        lat.extend(update_latencies(http, cookie, since, 2_000_000)?);
    }
    let out = child.wait_with_output()?;
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).map_err(|e| {
        format!(
            "the rollout printed no report ({e}): {}",
            String::from_utf8_lossy(&out.stderr)
        )
    })?;
    // `times` prints the shell's own user and system time, then its children's.
    let stderr = String::from_utf8_lossy(&out.stderr);
    let children = stderr.lines().last().unwrap_or("");
    let cpu_s = children.split_whitespace().map(minutes_seconds).sum();
    Ok((report, cpu_s, lat))
}

/// `1m2.500s` in seconds.
fn minutes_seconds(t: &str) -> f64 {
    let t = t.trim_end_matches('s');
    let (m, s) = t.split_once('m').unwrap_or(("0", t));
    m.parse::<f64>().unwrap_or(0.0) * 60.0 + s.parse::<f64>().unwrap_or(0.0)
}

/// From the rollout's log: each PLC's time from its load to `done` less the waits, and each
/// stage's time from its first load to its last `done` less the waits.
fn control_plane(
    log: &Path,
    report: &serde_json::Value,
    out: &mut Figures,
) -> Result<(), BenchError> {
    let text = std::fs::read_to_string(log)?;
    let mut sent: BTreeMap<&str, f64> = BTreeMap::new();
    let mut done: BTreeMap<&str, f64> = BTreeMap::new();
    for line in text.lines() {
        let Some((t, rest)) = line.split_once(' ') else {
            continue;
        };
        let Ok(t) = t.parse::<f64>() else { continue };
        if let Some(plc) = rest.strip_suffix(": load sent") {
            sent.entry(plc).or_insert(t);
        } else if let Some(plc) = rest.strip_suffix(": done") {
            done.insert(plc, t);
        }
    }
    let waits = (QUARANTINE_S + PROBATION_S) / SPEED;
    let mut per_plc: Vec<f64> = (sent.iter())
        .filter_map(|(p, s)| Some(1000.0 * (done.get(p)? - s - waits)))
        .collect();
    per_plc.sort_by(f64::total_cmp);
    let mut stages: BTreeMap<u64, (f64, f64)> = BTreeMap::new();
    for (plc, p) in report["plcs"].as_object().into_iter().flatten() {
        let (Some(s), Some(d), Some(k)) = (
            sent.get(plc.as_str()),
            done.get(plc.as_str()),
            p["stage"].as_u64(),
        ) else {
            continue;
        };
        let e = stages.entry(k).or_insert((f64::MAX, 0.0));
        e.0 = e.0.min(*s);
        e.1 = e.1.max(*d);
    }
    out.insert("wait_s_per_plc".into(), waits.into());
    out.insert(
        "control_plane_ms_per_plc_p50".into(),
        quantile(&per_plc, 0.5).into(),
    );
    out.insert(
        "control_plane_ms_per_plc_max".into(),
        quantile(&per_plc, 1.0).into(),
    );
    let stage_ms: Vec<serde_json::Value> = (stages.values())
        .map(|(a, b)| (1000.0 * (b - a - waits)).into())
        .collect();
    out.insert("control_plane_ms_per_stage".into(), stage_ms.into());
    Ok(())
}

/// The quantiles of `lat_ms`, as `<name>_latency_ms_p50` and so on.
fn latency(name: &str, mut lat_ms: Vec<f64>, out: &mut Figures) {
    lat_ms.sort_by(f64::total_cmp);
    let q = |p: f64| quantile(&lat_ms, p);
    out.insert(format!("{name}_messages_measured"), lat_ms.len().into());
    out.insert(format!("{name}_latency_ms_p50"), q(0.5).into());
    out.insert(format!("{name}_latency_ms_p99"), q(0.99).into());
    out.insert(format!("{name}_latency_ms_max"), q(1.0).into());
}

/// Each PLC's resident memory (`/proc/<pid>/smaps_rollup`): the largest `Rss`, its `Pss` (the
/// binary's shared pages divided among the processes that map them), and what is anonymous
/// (its own heap and stacks) against file-backed (the binary and libraries).
fn memory(plcs: &[Child], out: &mut Figures) -> Result<(), BenchError> {
    let mut worst: BTreeMap<&str, f64> = BTreeMap::new();
    for p in plcs {
        let text = std::fs::read_to_string(format!("/proc/{}/smaps_rollup", p.0.id()))?;
        for key in ["Rss", "Pss", "Anonymous", "Pss_File"] {
            let kb = text
                .lines()
                .find_map(|l| l.strip_prefix(key)?.strip_prefix(':'))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
                .unwrap_or(0.0);
            let e = worst.entry(key).or_insert(0.0);
            *e = e.max(kb / 1024.0);
        }
    }
    for (key, mib) in worst {
        out.insert(format!("plc_{}_mib_max", key.to_lowercase()), mib.into());
    }
    Ok(())
}
