//! Field I/O against a real Modbus peer (pymodbus, installed by scripts/test): the Vernadat
//! program reads a remote I/O device and drives its coils, in real time, through devices that
//! answer, are missing, answer with exceptions, answer late, or go away and come back.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::modbus::{self, read};
use cetratus_testkit::paths::example;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::ChildGuard;
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// An I/O configuration of one device on `port` serving the Vernadat program's addresses.
fn io_file(dir: &Path, port: u16, extra: &str) -> PathBuf {
    let path = dir.join("io.toml");
    std::fs::write(
        &path,
        format!(
            "start_timeout = \"1s\"\n[[device]]\nname = \"cell\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:{port}\"\ntimeout = \"500ms\"\nreconnect_min = \"50ms\"\nreconnect_max = \"200ms\"\nserves = [{{ from = \"%IX0.0\", to = \"%IX0.7\" }}, {{ from = \"%QX0.0\", to = \"%QX0.7\" }}]\n{extra}"
        ),
    )
    .expect("write io.toml");
    path
}

fn run(io: &Path, dir: &Path, length: &str) -> Command {
    let mut c = Command::new(BIN);
    c.arg("run")
        .arg(example("vernadat/vernadat.toml"))
        .arg("--io")
        .arg(io)
        .args(["--for", length, "--json", "--no-mqtt", "--cold"])
        .arg("--state-dir")
        .arg(dir.join("state"))
        .arg("--config")
        .arg(dir.join("config"));
    c
}

fn summary(out: &Output) -> Value {
    assert!(
        out.status.success(),
        "cetratus run failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("run --json prints one JSON object")
}

#[test]
fn the_program_reads_a_pymodbus_device_drives_its_coils_and_leaves_them_safe_on_stop() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let _dev = modbus::device(port, &["--di", "1"]);
    let io = io_file(dir.path(), port, "");
    let mut plc = ChildGuard::spawn(
        run(&io, dir.path(), "4s")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    // PE is on, so T10 fires and CM1 (coil 0) goes on while the robot waits for FCM1.
    let end = Instant::now() + Duration::from_secs(30);
    let mut seen = String::new();
    while Instant::now() < end {
        seen = read(port, "coils", 0, 8);
        if seen.starts_with('1') {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(seen, "1,0,0,0,0,0,0,0", "CM1 reached the device's coil 0");
    let out = std::mem::replace(&mut plc.0, Command::new("true").spawn().unwrap())
        .wait_with_output()
        .unwrap();
    let s = summary(&out);
    let d = &s["io"][0];
    assert_eq!(d["name"], "cell");
    assert_eq!(d["quality"], "good", "{d}");
    assert!(d["reads"].as_u64().unwrap() > 10, "{d}");
    assert!(d["writes"].as_u64().unwrap() >= 1, "{d}");
    assert_eq!(
        read(port, "coils", 0, 8),
        "0,0,0,0,0,0,0,0",
        "the stop left the safe values"
    );
}

#[test]
fn an_unreachable_device_at_start_leaves_the_inputs_safe_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let io = io_file(dir.path(), free_port(), "");
    let out = run(&io, dir.path(), "1s").output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    let s = summary(&out);
    assert!(
        stderr.contains("no complete input image from cell"),
        "{stderr}"
    );
    let d = &s["io"][0];
    assert_eq!(
        (
            d["quality"].as_str(),
            d["link"].as_str(),
            d["reads"].as_u64()
        ),
        (Some("initial"), Some("down"), Some(0)),
        "{d}"
    );
    assert!(
        d["last_error"].as_str().unwrap().contains("cannot connect"),
        "{d}"
    );
    assert!(
        s["scan"]["cycles"].as_u64().unwrap() > 50,
        "the scan went on: {s}"
    );
}

#[test]
fn exception_responses_and_a_wrong_unit_id_are_counted_and_never_read_as_values() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    // The inputs are served past the device's 64 entries: every read is an illegal address.
    let _dev = modbus::device(port, &["--di", "1"]);
    let io = io_file(dir.path(), port, "");
    let text = std::fs::read_to_string(&io).unwrap();
    std::fs::write(
        &io,
        text.replace("to = \"%IX0.7\" }", "to = \"%IX0.7\", offset = 1000 }"),
    )
    .unwrap();
    let s = summary(&run(&io, dir.path(), "1s").output().unwrap());
    let d = &s["io"][0];
    assert_eq!(d["reads"], 0, "{d}");
    assert!(d["exceptions"].as_u64().unwrap() > 5, "{d}");
    assert_eq!(d["link"], "up", "an exception keeps the connection: {d}");

    let port = free_port();
    let _dev = modbus::device(port, &["--di", "1"]);
    let io = io_file(dir.path(), port, "unit = 7\n");
    let s = summary(&run(&io, dir.path(), "1s").output().unwrap());
    let d = &s["io"][0];
    assert_eq!(d["reads"], 0, "{d}");
    assert!(
        d["exceptions"].as_u64().unwrap() + d["errors"].as_u64().unwrap() > 5,
        "{d}"
    );
}

#[test]
fn a_device_that_answers_late_goes_stale_and_its_inputs_take_their_safe_values() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    // Three cycles late, past a 20 ms timeout.
    let _dev = modbus::device(port, &["--di", "1", "--delay-ms", "30"]);
    let io = io_file(dir.path(), port, "stale = \"safe\"\nstale_after = 3\n");
    let text = std::fs::read_to_string(&io).unwrap();
    std::fs::write(
        &io,
        text.replace("timeout = \"500ms\"", "timeout = \"20ms\""),
    )
    .unwrap();
    let s = summary(&run(&io, dir.path(), "1s").output().unwrap());
    let d = &s["io"][0];
    assert!(d["errors"].as_u64().unwrap() > 0, "{d}");
    assert_ne!(d["quality"], "good", "{d}");
}

#[test]
fn a_device_that_drops_mid_run_is_reconnected_and_read_again() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let dev = modbus::device(port, &["--di", "1"]);
    let io = io_file(dir.path(), port, "");
    let plc = run(&io, dir.path(), "5s")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_secs(2));
    drop(dev);
    std::thread::sleep(Duration::from_millis(500));
    let _back = modbus::device(port, &["--di", "1"]);
    let s = summary(&plc.wait_with_output().unwrap());
    let d = &s["io"][0];
    assert!(d["reconnects"].as_u64().unwrap() >= 1, "{d}");
    assert_eq!(d["quality"], "good", "{d}");
    assert_eq!(
        read(port, "coils", 0, 8),
        "0,0,0,0,0,0,0,0",
        "the stop left the safe values"
    );
}

#[test]
fn overlapping_maps_and_addresses_no_device_serves_are_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let io = io_file(dir.path(), 1502, "[[device]]\nname = \"b\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:1503\"\nserves = [{ from = \"%QX0.4\" }]\n");
    let out = run(&io, dir.path(), "1s").output().unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        e.contains("io.toml:14:") && e.contains("overlapping maps"),
        "{e}"
    );

    let io = dir.path().join("short.toml");
    std::fs::write(&io, "[[device]]\nname = \"cell\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:1502\"\nserves = [{ from = \"%IX0.0\", to = \"%IX0.5\" }]\n").unwrap();
    let out = run(&io, dir.path(), "1s").output().unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("signal `FPM2`: no device serves %IX0.6"), "{e}");
}

#[test]
fn a_virtual_run_needs_a_twin_and_refuses_network_io() {
    let dir = tempfile::tempdir().unwrap();
    let io = io_file(dir.path(), 1502, "");
    let program = example("vernadat/vernadat.toml");
    let out = Command::new(BIN)
        .arg("run")
        .arg(&program)
        .args(["--virtual", "--for", "1s"])
        .arg("--io")
        .arg(&io)
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("a virtual run needs a plant"));
    let out = Command::new(BIN)
        .arg("run")
        .arg(&program)
        .args(["--virtual", "--for", "1s", "--twin", "vernadat"])
        .arg("--io")
        .arg(&io)
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot use network I/O"));
    let out = Command::new(BIN)
        .arg("run")
        .arg(&program)
        .args(["--for", "1s", "--no-mqtt"])
        .arg("--config")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("nothing to run against"));
}

#[test]
fn exec_info_reports_the_quality_of_each_devices_inputs() {
    let (port, silent, mqtt) = (free_port(), free_port(), free_port());
    let dir = tempfile::tempdir().unwrap();
    let _device = modbus::device(port, &["--di", "1"]);
    // A second device, for outputs only, that nobody answers for.
    let extra = format!("[[device]]\nname = \"valves\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:{silent}\"\nserves = [{{ from = \"%QX1.0\", to = \"%QX1.7\" }}]\n");
    let io = io_file(dir.path(), port, &extra);
    let mut c = Command::new(BIN);
    c.arg("run")
        .arg(example("vernadat/vernadat.toml"))
        .arg("--io")
        .arg(&io)
        .args(["--for", "60s", "--cold", "--plc", "cell1", "--no-dashboard"])
        .arg("--state-dir")
        .arg(dir.path().join("state"))
        .arg("--config")
        .arg(dir.path().join("config"))
        .args(["--mqtt", &format!("127.0.0.1:{mqtt}")])
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    let _plc = ChildGuard::spawn(&mut c);
    wait_for_port(mqtt, "the embedded broker", Duration::from_secs(60));
    let end = Instant::now() + Duration::from_secs(60);
    let quality = loop {
        let out = Command::new(BIN)
            .args(["exec-info", "--broker", &format!("mqtt://127.0.0.1:{mqtt}")])
            .args(["--plc", "cell1", "--json"])
            .output()
            .expect("run cetratus exec-info");
        let reply: Value = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
        let q = reply["result"][0]["input_quality"].clone();
        if q[0]["quality"] == "good" || Instant::now() > end {
            break q;
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    assert_eq!(quality[0]["device"], "cell", "{quality}");
    assert_eq!(quality[0]["quality"], "good", "{quality}");
    assert_eq!(quality[0]["link"], "up", "{quality}");
    assert_eq!(quality[1]["device"], "valves", "{quality}");
    assert_eq!(quality[1]["quality"], "initial", "{quality}");
    assert_ne!(quality[1]["link"], "up", "{quality}");
}
