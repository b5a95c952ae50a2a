//! The measuring harnesses behind `cetratus bench`: the full run of every figure, the real-time
//! jitter, the command flood against a running node, the floods of what others can send
//! ([`crate::flood`]), and a fleet of PLC processes
//! watched by one dashboard. Each returns its figures as one JSON object by name.

use std::collections::BTreeMap;

use crate::{measure, program};

pub use crate::flood::{flood, Beside, BesideParts, FloodKind};

/// What a harness can fail with (a process that does not start, a port that is taken).
pub type BenchError = Box<dyn std::error::Error + Send + Sync>;

/// Figures by name.
pub type Figures = BTreeMap<String, serde_json::Value>;

fn s(key: &str) -> String {
    key.to_string()
}

/// Every figure of docs/performance.md that needs no network: engine, programs, updates,
/// analysis (with the Python baseline). `quick` keeps the run under a minute.
pub fn all_figures(quick: bool) -> Result<Figures, BenchError> {
    let mut out: BTreeMap<String, serde_json::Value> = BTreeMap::new();
    let engine = measure::engine_figures(quick);
    out.insert(s("vernadat_scan_ns"), engine.vernadat_scan_ns.into());
    out.insert(
        s("scale_ratio_1m_vs_1k"),
        engine.scale_ratio_1m_vs_1k.into(),
    );
    out.insert(s("dense_speedup_10k"), engine.dense_speedup_10k.into());
    out.insert(s("dense_speedup_1k"), engine.dense_speedup_1k.into());
    out.insert(
        s("ring_scan_ns"),
        serde_json::to_value(&engine.ring_scan_ns)?,
    );
    out.insert(
        s("dense_scan_ns"),
        serde_json::to_value(&engine.dense_scan_ns)?,
    );

    out.insert(s("program_scan_ns"), program::program_scan_ns(quick).into());
    out.insert(
        s("program_scan_full_ns"),
        program::program_scan_full_ns(quick).into(),
    );
    out.insert(s("program_load_us"), program::program_load_us(quick).into());
    let (guard_ns, body_ns) = program::ns_per_instruction(quick);
    out.insert(s("guard_ns_per_instruction"), guard_ns.into());
    out.insert(s("body_ns_per_instruction"), body_ns.into());
    // A chart four times longer costs four times more when the import is linear.
    let import_ms = |text: String| program::plcopen_import_ms(&text, 3);
    let (short, long) = (
        import_ms(program::plcopen_chain(5_000)),
        import_ms(program::plcopen_chain(20_000)),
    );
    out.insert(s("plcopen_import_20k_steps_ms"), long.into());
    out.insert(s("plcopen_import_ratio_20k_vs_5k"), (long / short).into());
    let (short, long) = (
        import_ms(program::plcopen_networks(2_000)),
        import_ms(program::plcopen_networks(8_000)),
    );
    out.insert(s("plcopen_networks_import_8k_ms"), long.into());
    out.insert(
        s("plcopen_networks_import_ratio_8k_vs_2k"),
        (long / short).into(),
    );
    let hour = program::twin_hour();
    out.insert(s("twin_hour_wall_ms"), hour.wall_ms.into());
    out.insert(s("twin_hour_parts_finished"), hour.parts_finished.into());

    let update = crate::update::update_figures(quick);
    if let serde_json::Value::Object(map) = serde_json::to_value(&update)? {
        out.extend(map);
    }

    let analysis = crate::analysis::reachability_figures(quick);
    // The headline figures of the analysis issue: the slowest of Kanban and FMS.
    let min = |f: &dyn Fn(&crate::analysis::NetFigures) -> f64| {
        analysis.nets.iter().map(f).fold(f64::INFINITY, f64::min)
    };
    let max = |f: &dyn Fn(&crate::analysis::NetFigures) -> f64| {
        analysis.nets.iter().map(f).fold(0.0, f64::max)
    };
    out.insert(
        s("reachability_states_per_s"),
        min(&|n| n.reachability_states_per_s).into(),
    );
    out.insert(
        s("reachability_states_per_s_all_cores"),
        min(&|n| n.reachability_states_per_s_multi).into(),
    );
    out.insert(
        s("reachability_bytes_per_state"),
        max(&|n| n.bytes_per_state).into(),
    );
    if !analysis.baselines.is_empty() {
        let sp = |f: &dyn Fn(&crate::analysis::Baseline) -> f64| {
            analysis
                .baselines
                .iter()
                .map(f)
                .fold(f64::INFINITY, f64::min)
        };
        out.insert(s("python_speedup"), sp(&|b| b.speedup).into());
        out.insert(
            s("python_speedup_one_thread"),
            sp(&|b| b.speedup_one_thread).into(),
        );
    }
    if let serde_json::Value::Object(map) = serde_json::to_value(&analysis)? {
        for (k, v) in map {
            out.insert(k, v);
        }
    }
    Ok(out)
}

/// The real-time jitter of the Vernadat program on its twin at `period_us` for `for_us`.
pub fn jitter_figures(period_us: u64, for_us: u64, rt: bool) -> Figures {
    let (figures, status) = program::jitter(period_us, for_us, rt);
    let mut out = Figures::new();
    out.insert(s("period_us"), period_us.into());
    out.insert(s("cycles"), figures.cycles.into());
    out.insert(s("latency_p50_ns"), figures.latency.p50_ns.into());
    out.insert(s("latency_p99_ns"), figures.latency.p99_ns.into());
    out.insert(s("latency_max_ns"), figures.latency.max_ns.into());
    out.insert(s("scan_p99_ns"), figures.scan.p99_ns.into());
    out.insert(s("cycle_p99_ns"), figures.cycle.p99_ns.into());
    out.insert(s("overruns"), figures.overruns.into());
    out.insert(
        s("rt"),
        status.unwrap_or_else(|| "not requested".into()).into(),
    );
    // The machine's own limit, in the same run, with the same period and settings.
    let machine = crate::cyclictest::measure(period_us, for_us, rt);
    out.insert(
        s("machine"),
        serde_json::to_value(machine).unwrap_or_default(),
    );
    out
}

/// The Vernadat PLC on its twin as `cetratus run --period` has it, assembled by the same
/// [`NodeSpec`](cetratus_node::NodeSpec): an embedded broker on `addr`, the node's MQTT link,
/// snapshots published five times a second, no local configuration and no state directory. The
/// MQTT client is connected when it returns.
pub fn vernadat_node(
    plc_id: &str,
    addr: std::net::SocketAddr,
    period_us: u64,
) -> Result<cetratus_node::RunningNode, BenchError> {
    use cetratus_node::plant::PlantSpec;
    use cetratus_node::services::MqttSpec;
    use cetratus_node::{NodeSpec, StateDir};

    let plant = PlantSpec {
        twin: Some(cetratus_twin::TwinKind::Vernadat),
        settings: cetratus_twin::TwinSettings {
            seed: 1,
            ..Default::default()
        },
        ..PlantSpec::default()
    };
    let local = cetratus_node::config::LocalConfig::default();
    let mut spec = NodeSpec::new(program::vernadat_program(), plc_id, local, plant);
    spec.period_us = Some(period_us);
    spec.state = StateDir::Nowhere;
    spec.mqtt = Some(MqttSpec {
        embedded: Some(addr.to_string()),
        ..MqttSpec::default()
    });
    let node = spec.start(&mut |_| {})?;
    if let Some(s) = node.services() {
        s.mqtt().wait_connected(std::time::Duration::from_secs(10));
    }
    Ok(node)
}

/// Runs the Vernadat node on an embedded broker at `period_us`, first alone for `phase_us`, then
/// while a client sends `rate` commands per second, and reports the scan latency of both phases.
pub fn command_load(rate: u32, phase_us: u64, period_us: u64) -> Result<Figures, BenchError> {
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::Arc;
    use std::time::{Duration, Instant};

    use cetratus_node::periodic::run_periodic;
    use cetratus_runtime::LoopTiming;
    use rumqttc::v5::mqttbytes::QoS;

    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    let mut node = vernadat_node(
        "bench",
        std::net::SocketAddr::from(([127, 0, 0, 1], port)),
        period_us,
    )?;
    let mut now_base = 0u64;
    let mut phase = |node: &mut cetratus_node::RunningNode| {
        let stop = AtomicBool::new(false);
        let mut timing = LoopTiming::default();
        let base = now_base;
        let reached = run_periodic(period_us, phase_us, 1.0, &stop, &mut timing, |now, t| {
            node.node_mut().step(base + now, t);
            true
        });
        now_base += reached;
        timing
    };
    let quiet = phase(&mut node);

    // The flood: a client on its own thread, mixed valid and invalid commands.
    let sent = Arc::new(AtomicU64::new(0));
    let stop_flood = Arc::new(AtomicBool::new(false));
    let flood = {
        let (sent, stop_flood) = (sent.clone(), stop_flood.clone());
        let url = format!("mqtt://127.0.0.1:{port}");
        std::thread::spawn(move || -> Result<(), BenchError> {
            let opts = cetratus_mct::client_options(&url, "bench-flood")?;
            let (client, mut conn) = rumqttc::v5::Client::new(opts, 4096);
            std::thread::spawn(move || for _ in conn.iter() {});
            let payloads: [(&str, &[u8]); 4] = [
                (
                    "exec_info",
                    b"{\"reply_to\": \"cetratus/bench/reply/flood\"}",
                ),
                ("load", b"\x00\x01 not json"),
                (
                    "frobnicate",
                    b"{\"reply_to\": \"cetratus/bench/reply/flood\"}",
                ),
                (
                    "substitute",
                    b"{\"mode\": \"sideways\", \"reply_to\": \"cetratus/bench/reply/flood\"}",
                ),
            ];
            let start = Instant::now();
            let mut k = 0u64;
            while !stop_flood.load(Ordering::Relaxed) {
                let due = start + Duration::from_secs_f64(k as f64 / f64::from(rate.max(1)));
                if let Some(wait) = due.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
                let (verb, body) = payloads[(k % 4) as usize];
                let _ = client.try_publish(
                    format!("cetratus/bench/cmd/{verb}"),
                    QoS::AtMostOnce,
                    false,
                    body.to_vec(),
                );
                k += 1;
                sent.store(k, Ordering::Relaxed);
            }
            Ok(())
        })
    };
    let loaded = phase(&mut node);
    stop_flood.store(true, Ordering::Relaxed);
    let _ = flood.join();
    let plc = node.finish()?.plc;

    let (q, l) = (quiet.latency.summary(), loaded.latency.summary());
    let limit = 1.2 * q.p99_ns as f64 + 20_000.0;
    let mut out: BTreeMap<String, serde_json::Value> = BTreeMap::new();
    out.insert(s("period_us"), period_us.into());
    out.insert(s("phase_s"), (phase_us as f64 / 1e6).into());
    out.insert(s("commands_sent"), sent.load(Ordering::Relaxed).into());
    out.insert(
        s("commands_per_s"),
        (sent.load(Ordering::Relaxed) as f64 / (phase_us as f64 / 1e6)).into(),
    );
    out.insert(s("latency_p99_ns_unloaded"), q.p99_ns.into());
    out.insert(s("latency_p99_ns_loaded"), l.p99_ns.into());
    out.insert(s("latency_p50_ns_unloaded"), q.p50_ns.into());
    out.insert(s("latency_p50_ns_loaded"), l.p50_ns.into());
    out.insert(s("latency_max_ns_unloaded"), q.max_ns.into());
    out.insert(s("latency_max_ns_loaded"), l.max_ns.into());
    out.insert(s("overruns_unloaded"), quiet.overruns.into());
    out.insert(s("overruns_loaded"), loaded.overruns.into());
    out.insert(s("limit_ns"), limit.into());
    out.insert(s("within_limit"), ((l.p99_ns as f64) <= limit).into());
    out.insert(s("primary_status"), plc.status().as_str().into());
    Ok(out)
}

/// Reads the one-time login link `cetratus dashboard` prints on its first line of output, opens it
/// on the dashboard at port `http`, and returns the session's `Cookie` header line.
fn dashboard_login(process: &mut std::process::Child, http: u16) -> Result<String, BenchError> {
    use std::io::{BufRead, BufReader, Read, Write};
    let out = process
        .stdout
        .take()
        .ok_or_else(|| BenchError::from("`cetratus dashboard` has no piped output"))?;
    let mut line = String::new();
    BufReader::new(out).read_line(&mut line)?;
    let path = line
        .split_whitespace()
        .find_map(|w| w.find("/login?token=").map(|i| w[i..].to_string()))
        .ok_or_else(|| {
            BenchError::from(format!(
                "`cetratus dashboard` printed no login link: {line}"
            ))
        })?;
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", http))?;
    write!(stream, "GET {path} HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")?;
    let mut head = String::new();
    stream.read_to_string(&mut head)?;
    head.lines()
        .find_map(|l| {
            l.strip_prefix("set-cookie: ")
                .or_else(|| l.strip_prefix("Set-Cookie: "))
        })
        .and_then(|c| c.split(';').next())
        .map(|c| format!("Cookie: {c}"))
        .ok_or_else(|| BenchError::from(format!("the login link did not log in: {head}")))
}

/// Kills a child process when dropped.
pub(crate) struct Child(pub(crate) std::process::Child);

impl Drop for Child {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// CPU seconds (user + system) a process has used, from /proc.
pub(crate) fn cpu_seconds(pid: u32) -> Result<f64, BenchError> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat"))?;
    // Fields after the command name, which is in parentheses and may hold spaces.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    // utime and stime are fields 14 and 15 of the whole line: 11 and 12 after the name.
    Ok((ticks(11) + ticks(12)) / 100.0)
}

/// A free TCP port on the loopback interface.
pub(crate) fn free_port() -> Result<u16, BenchError> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// Waits until a process listens on `port`, for 20 s at most: what it serves is then asked for,
/// and fails clearly if it is still missing.
pub(crate) fn wait_for_port(port: u16) {
    use std::time::{Duration, Instant};
    let end = Instant::now() + Duration::from_secs(20);
    while Instant::now() < end && std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Starts a Mosquitto on a free port, and returns it with the port.
pub(crate) fn start_mosquitto() -> Result<(Child, u16), BenchError> {
    use std::process::{Command, Stdio};
    let mosquitto = ["/usr/sbin/mosquitto", "/usr/bin/mosquitto"]
        .into_iter()
        .find(|p| std::path::Path::new(p).exists())
        .ok_or("mosquitto is missing: apt-get install mosquitto")?;
    let port = free_port()?;
    let broker = Child(
        Command::new(mosquitto)
            .args(["-p", &port.to_string()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()?,
    );
    wait_for_port(port);
    Ok((broker, port))
}

/// Starts `n` runtime processes of the Vernadat program on its twin (`cell0`, `cell1`, …) with
/// the `cetratus` binary `exe`, publishing to the broker at `url`, each with its state in `dir`
/// and the arguments `extra` (its period, speed, configuration).
pub(crate) fn start_plcs(
    exe: &std::path::Path,
    n: usize,
    url: &str,
    dir: &std::path::Path,
    extra: &[&std::ffi::OsStr],
) -> Result<Vec<Child>, BenchError> {
    use std::process::{Command, Stdio};
    let program = program::examples_dir().join("vernadat/vernadat.toml");
    let mut plcs = Vec::with_capacity(n);
    for k in 0..n {
        plcs.push(Child(
            Command::new(exe)
                .arg("run")
                .arg(&program)
                .args(["--twin", "vernadat", "--no-dashboard"])
                .args(["--plc", &format!("cell{k}"), "--broker", url])
                .args(extra)
                .arg("--state-dir")
                .arg(dir.join(format!("cell{k}")))
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()?,
        ));
    }
    Ok(plcs)
}

/// The value at share `p` (0 to 1) of `sorted`, the nearest rank; NaN when it is empty.
pub(crate) fn quantile(sorted: &[f64], p: f64) -> f64 {
    sorted
        .get(((sorted.len() as f64 - 1.0) * p).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

/// Starts `cetratus dashboard` on the broker at `url` with its dashboard on a free port, and logs in;
/// the process, the dashboard's port and the session's `Cookie` header line.
pub(crate) fn start_dashboard(
    exe: &std::path::Path,
    url: &str,
) -> Result<(Child, u16, String), BenchError> {
    use std::process::{Command, Stdio};
    let http = free_port()?;
    let mut dashboard = Child(
        Command::new(exe)
            .args([
                "dashboard",
                "--http",
                &format!("127.0.0.1:{http}"),
                "--broker",
                url,
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()?,
    );
    wait_for_port(http);
    let cookie = dashboard_login(&mut dashboard.0, http)?;
    Ok((dashboard, http, cookie))
}

/// How many PLCs the dashboard at port `http` lists.
pub(crate) fn plcs_listed(http: u16, cookie: &str) -> Result<usize, BenchError> {
    use std::io::Write;
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", http))?;
    write!(
        stream,
        "GET /api/plcs HTTP/1.0\r\nHost: 127.0.0.1\r\n{cookie}\r\n\r\n"
    )?;
    let mut body = String::new();
    std::io::Read::read_to_string(&mut stream, &mut body)?;
    let json = body.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    Ok(serde_json::from_str::<serde_json::Value>(json)
        .ok()
        .and_then(|v| v.as_array().map(Vec::len))
        .unwrap_or(0))
}

/// The update latency, in ms, of every io message of `cell0` that the dashboard at port `http`
/// delivers to a stream client, as a browser is one, until `for_us` after `t0`.
pub(crate) fn update_latencies(
    http: u16,
    cookie: &str,
    t0: std::time::Instant,
    for_us: u64,
) -> Result<Vec<f64>, BenchError> {
    use std::io::{BufRead, BufReader, Write};
    use std::time::Duration;
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", http))?;
    stream.set_read_timeout(Some(Duration::from_millis(500)))?;
    write!(stream, "GET /api/stream?plc=cell0 HTTP/1.0\r\nHost: 127.0.0.1\r\n{cookie}\r\nAccept: text/event-stream\r\n\r\n")?;
    let mut reader = BufReader::new(stream);
    let mut lat_ms: Vec<f64> = Vec::new();
    let mut line = String::new();
    while t0.elapsed() < Duration::from_micros(for_us) {
        line.clear();
        match reader.read_line(&mut line) {
            Ok(0) => break,
            Ok(_) => {}
            Err(_) => continue,
        }
        let Some(data) = line.strip_prefix("data:") else {
            continue;
        };
        let Ok(v) = serde_json::from_str::<serde_json::Value>(data.trim()) else {
            continue;
        };
        if let Some(sent) = v["data"]["unix_ms"].as_f64() {
            let now = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64() * 1e3);
            lat_ms.push(now - sent);
        }
    }
    Ok(lat_ms)
}

/// Starts a Mosquitto, `n` runtime processes publishing to it, and one `cetratus dashboard`; then
/// measures, for `for_us` of wall time, the dashboard update latency (PLC publish → event
/// delivered by the dashboard's stream) and the CPU the dashboard uses.
/// `exe` is the `cetratus` binary to start.
pub fn fleet(
    exe: &std::path::Path,
    n: usize,
    period: &str,
    for_us: u64,
) -> Result<Figures, BenchError> {
    use std::time::{Duration, Instant};

    let (_broker, port) = start_mosquitto()?;
    let dir = std::env::temp_dir().join(format!("cetratus-fleet-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let url = format!("mqtt://127.0.0.1:{port}");
    let plcs = start_plcs(
        exe,
        n,
        &url,
        &dir,
        &[
            "--period".as_ref(),
            period.as_ref(),
            "--for".as_ref(),
            "10h".as_ref(),
        ],
    )?;
    let (dashboard, http, cookie) = start_dashboard(exe, &url)?;
    // Let every PLC connect before measuring.
    std::thread::sleep(Duration::from_secs(5));
    let plcs_seen = plcs_listed(http, &cookie)?;
    let cpu0 = cpu_seconds(dashboard.0.id())?;
    let t0 = Instant::now();
    let mut lat_ms = update_latencies(http, &cookie, t0, for_us)?;
    let wall = t0.elapsed().as_secs_f64();
    let cpu = cpu_seconds(dashboard.0.id())? - cpu0;
    drop(plcs);
    drop(dashboard);
    let _ = std::fs::remove_dir_all(&dir);
    lat_ms.sort_by(|a, b| a.total_cmp(b));
    let q = |p: f64| quantile(&lat_ms, p);
    let mut out: BTreeMap<String, serde_json::Value> = BTreeMap::new();
    out.insert(s("plcs"), n.into());
    out.insert(s("plcs_seen_by_dashboard"), plcs_seen.into());
    out.insert(s("period"), period.into());
    out.insert(s("seconds"), wall.into());
    out.insert(s("io_messages_measured"), lat_ms.len().into());
    out.insert(s("update_latency_ms_p50"), q(0.5).into());
    out.insert(s("update_latency_ms_p99"), q(0.99).into());
    out.insert(s("update_latency_ms_max"), q(1.0).into());
    out.insert(
        s("dashboard_cpu_percent_of_one_core"),
        (100.0 * cpu / wall).into(),
    );
    Ok(out)
}
