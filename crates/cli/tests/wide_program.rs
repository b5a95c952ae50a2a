//! A program of 200 signals (100 inputs on a pymodbus remote I/O device, 100 outputs on its
//! coils) runs end to end: every output reaches the device, the dashboard's timing diagram draws
//! signals past the 64th at their levels, and the Monitor counts a candidate's divergence on an
//! output past the 64th in exec_info.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::browser::{require_chromium, Browser};
use cetratus_testkit::modbus::read;
use cetratus_testkit::paths::workspace_root;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{login_link, stderr_lines, ChildGuard};
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");
/// Inputs and outputs each.
const N: usize = 100;
/// The inputs the device has on.
const ON: [usize; 3] = [0, 70, 99];

/// Writes `name.toml` and `name.pnml`: output `y_i` follows input `x_i` one cycle later
/// (places `p_i` off, `q_i` on), except that `y_inverted` is on while its input is off.
fn program(dir: &Path, name: &str, version: &str, inverted: Option<usize>) -> PathBuf {
    let mut pnml = String::from(
        "<?xml version=\"1.0\"?>\n<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\">\n<net id=\"wide\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\"><page id=\"g\">\n",
    );
    let mut toml = format!(
        "[program]\nname = \"wide\"\nversion = \"{version}\"\nnet = \"{name}.pnml\"\npolicy = \"step\"\nscan_period = \"10ms\"\n"
    );
    for i in 0..N {
        pnml.push_str(&format!(
            "<place id=\"p{i}\"><initialMarking><text>1</text></initialMarking></place><place id=\"q{i}\"/>\n<transition id=\"on{i}\"/><transition id=\"off{i}\"/>\n<arc id=\"a{i}\" source=\"p{i}\" target=\"on{i}\"/><arc id=\"b{i}\" source=\"on{i}\" target=\"q{i}\"/><arc id=\"c{i}\" source=\"q{i}\" target=\"off{i}\"/><arc id=\"d{i}\" source=\"off{i}\" target=\"p{i}\"/>\n"
        ));
        toml.push_str(&format!(
            "[[input]]\nname = \"x{i}\"\ntype = \"bool\"\naddress = \"%IX{}.{}\"\n",
            i / 8,
            i % 8
        ));
    }
    for i in 0..N {
        toml.push_str(&format!(
            "[[output]]\nname = \"y{i}\"\ntype = \"bool\"\naddress = \"%QX{}.{}\"\n",
            i / 8,
            i % 8
        ));
    }
    toml.push_str("[guards]\n");
    for i in 0..N {
        toml.push_str(&format!("on{i} = \"x{i}\"\noff{i} = \"!x{i}\"\n"));
    }
    for i in 0..N {
        let place = if Some(i) == inverted { "p" } else { "q" };
        toml.push_str(&format!(
            "[[action]]\nplace = \"{place}{i}\"\nqualifier = \"N\"\ntarget = \"y{i}\"\n"
        ));
    }
    pnml.push_str("</page></net></pnml>\n");
    std::fs::write(dir.join(format!("{name}.pnml")), pnml).expect("write the net");
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, toml).expect("write the program");
    path
}

fn cetratus(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("cetratus runs")
}

fn ok(out: Output) -> Output {
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn s(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_program_of_200_signals_runs_is_drawn_and_monitored_past_the_64th() {
    require_chromium();
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let base = program(d, "wide", "1.0.0", None);
    // The candidate differs from it on y90 only.
    program(d, "wide2", "1.1.0", Some(90));
    std::fs::write(
        d.join("wide2.package.toml"),
        "[package]\nname = \"y90 inverted\"\nversion = \"1.1.0\"\nauthor = \"tests\"\nprogram = \"wide2.toml\"\nbase = \"wide.toml\"\n",
    )
    .expect("write the manifest");
    let key = d.join("k.key");
    ok(cetratus(&["package", "keygen", "--out", s(&key)]));
    std::fs::create_dir_all(d.join("trusted")).expect("mkdir");
    std::fs::copy(d.join("k.key.pub"), d.join("trusted/k.pub")).expect("copy the key");
    let pkg = d.join("wide2.cpkg");
    ok(cetratus(&[
        "package",
        "build",
        s(&d.join("wide2.package.toml")),
        "--key",
        s(&key),
        "-o",
        s(&pkg),
    ]));

    let (device, mqtt, http) = (free_port(), free_port(), free_port());
    let di: Vec<&str> = (0..N)
        .map(|i| if ON.contains(&i) { "1" } else { "0" })
        .collect();
    let _device = ChildGuard::spawn(
        Command::new("python3")
            .arg(workspace_root().join("scripts/modbus_peer.py"))
            .args(["device", &device.to_string(), "--size", "128"])
            .args(["--di", &di.join(",")])
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    wait_for_port(device, "the pymodbus device", Duration::from_secs(30));
    let io = d.join("io.toml");
    std::fs::write(
        &io,
        format!("[[device]]\nname = \"rack\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:{device}\"\ntimeout = \"500ms\"\nserves = [{{ from = \"%IX0.0\", to = \"%IX12.3\" }}, {{ from = \"%QX0.0\", to = \"%QX12.3\" }}]\n"),
    )
    .expect("write io.toml");
    let mut plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(&base)
            .arg("--io")
            .arg(&io)
            .args(["--for", "10min", "--cold", "--plc", "wide1"])
            .args(["--mqtt", &format!("127.0.0.1:{mqtt}")])
            .args(["--http", &format!("127.0.0.1:{http}")])
            .arg("--trust")
            .arg(d.join("trusted"))
            .arg("--state-dir")
            .arg(d.join("state"))
            .arg("--config")
            .arg(d.join("config"))
            .stdout(Stdio::null())
            .stderr(Stdio::piped()),
    );
    wait_for_port(http, "the dashboard", Duration::from_secs(60));
    let link = login_link(&stderr_lines(&mut plc.0), Duration::from_secs(30));

    // Every output reached the device's coils, the 100th too.
    let want: Vec<&str> = di.clone();
    let end = Instant::now() + Duration::from_secs(30);
    let mut coils = String::new();
    while Instant::now() < end {
        coils = read(device, "coils", 0, N as u16);
        if coils == want.join(",") {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(coils, want.join(","), "the coils follow the inputs");

    // The timing diagram draws lanes past the 64th signal at their levels.
    let c = Browser::start().await;
    c.goto(&link).await.expect("the page loads");
    let within = Duration::from_secs(30);
    c.wait_lane_level("inputs", "x70", true, within).await;
    c.wait_lane_level("inputs", "x99", true, within).await;
    c.wait_lane_level("inputs", "x98", false, within).await;
    c.wait_lane_level("dispatched", "y99", true, within).await;
    c.wait_lane_level("dispatched", "y64", false, within).await;
    c.wait_lane_level("A", "y70", true, within).await;

    // A candidate that differs on y90 only: the Monitor counts its divergence there, and the
    // diagram draws B's y90 on while A's is off.
    let broker = format!("127.0.0.1:{mqtt}");
    ok(cetratus(&[
        "load",
        s(&pkg),
        "--plc",
        "wide1",
        "--mqtt",
        &broker,
    ]));
    c.wait_lane_level("B", "y90", true, within).await;
    c.wait_lane_level("A", "y90", false, within).await;
    let end = Instant::now() + Duration::from_secs(30);
    let divergence = loop {
        let out = cetratus(&[
            "exec-info",
            "--broker",
            &format!("mqtt://{broker}"),
            "--plc",
            "wide1",
            "--json",
        ]);
        let reply: Value = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
        let candidate = reply["result"]
            .as_array()
            .and_then(|r| r.iter().find(|e| e["container"] == "B"))
            .cloned()
            .unwrap_or(Value::Null);
        let d = candidate["divergence"].clone();
        if d["y90"].as_u64().unwrap_or(0) > 0 || Instant::now() > end {
            break d;
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    assert!(divergence["y90"].as_u64().unwrap_or(0) > 0, "{divergence}");
    let others: Vec<_> = divergence
        .as_object()
        .expect("a map")
        .iter()
        .filter(|(k, v)| *k != "y90" && v.as_u64() != Some(0))
        .collect();
    assert!(others.is_empty(), "only y90 diverges: {divergence}");
    c.close().await;
}
