//! `cetratus bench opcua`: the OPC UA write → scan → read latency of a running PLC, measured on
//! this machine against the real binary: a mirror program (`Y` follows `X`) runs as `cetratus run`
//! with its inputs from OPC UA, and a client writes `X` and reads `Y` until it follows.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::Context;

use crate::parse_duration_us;

/// Arguments of `cetratus bench opcua`.
#[derive(clap::Args, Debug)]
pub struct OpcuaArgs {
    /// The mirror program's scan period.
    #[arg(long, default_value = "10ms")]
    period: String,
    /// Writes measured.
    #[arg(long, default_value_t = 2000)]
    samples: usize,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

const NET: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<pnml xmlns="http://www.pnml.org/version-2009/grammar/pnml">
  <net id="mirror" type="http://www.pnml.org/version-2009/grammar/ptnet">
    <page id="page0">
      <place id="Off"><initialMarking><text>1</text></initialMarking></place>
      <place id="On"/>
      <transition id="T1"/><transition id="T0"/>
      <arc id="a1" source="Off" target="T1"/><arc id="a2" source="T1" target="On"/>
      <arc id="a3" source="On" target="T0"/><arc id="a4" source="T0" target="Off"/>
    </page>
  </net>
</pnml>
"#;

fn program(period: &str) -> String {
    format!(
        r#"[program]
name = "mirror"
version = "1.0.0"
net = "mirror.pnml"
policy = "step"
scan_period = "{period}"

[[input]]
name = "X"
type = "bool"

[[output]]
name = "Y"
type = "bool"

[guards]
T1 = "X"
T0 = "!X"

[[action]]
place = "On"
qualifier = "N"
target = "Y"
"#
    )
}

fn quantile(sorted: &[u64], q: f64) -> u64 {
    let i = ((sorted.len() as f64) * q).ceil().max(1.0) as usize - 1;
    sorted[i.min(sorted.len() - 1)]
}

/// Runs `cetratus bench opcua`.
pub fn run(a: &OpcuaArgs) -> anyhow::Result<()> {
    anyhow::ensure!(a.samples > 0, "--samples must be at least 1");
    let period_us = parse_duration_us(&a.period)?;
    let dir = std::env::temp_dir().join(format!("cetratus-bench-opcua-{}", std::process::id()));
    std::fs::create_dir_all(&dir).context("a temporary directory")?;
    let d = dir.as_path();
    std::fs::write(d.join("mirror.pnml"), NET)?;
    std::fs::write(d.join("mirror.toml"), program(&a.period))?;
    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    let url = format!("opc.tcp://127.0.0.1:{port}");
    std::fs::write(
        d.join("io.toml"),
        format!("start_timeout = \"1s\"\n\n[opcua]\nlisten = \"{url}\"\ninputs = true\n"),
    )?;
    std::fs::create_dir_all(d.join("config"))?;
    let mut plc = Command::new(std::env::current_exe()?)
        .arg("run")
        .arg(d.join("mirror.toml"))
        .arg("--io")
        .arg(d.join("io.toml"))
        .args(["--no-mqtt", "--cold", "--plc", "bench"])
        .arg("--state-dir")
        .arg(d.join("state"))
        .arg("--config")
        .arg(d.join("config"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .context("start the PLC")?;
    let end = Instant::now() + Duration::from_secs(30);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        if Instant::now() > end {
            let _ = plc.kill();
            anyhow::bail!("the PLC's OPC UA server did not come up on {url}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let measured = cetratus_io::opcua::probe::write_scan_read(&url, "X", "Y", a.samples);
    let _ = plc.kill();
    let _ = plc.wait();
    let _ = std::fs::remove_dir_all(d);
    let mut ns = measured?;
    ns.sort_unstable();
    let us = |q: f64| quantile(&ns, q) as f64 / 1e3;
    let out = serde_json::json!({
        "period_us": period_us,
        "samples": ns.len(),
        "write_scan_read_p50_us": us(0.5),
        "write_scan_read_p99_us": us(0.99),
        "write_scan_read_max_us": us(1.0),
    });
    if a.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "OPC UA write → scan → read, {} samples at a {} µs cycle: p50 {:.0} µs, p99 {:.0} µs, max {:.0} µs",
            ns.len(),
            period_us,
            us(0.5),
            us(0.99),
            us(1.0)
        );
    }
    Ok(())
}
