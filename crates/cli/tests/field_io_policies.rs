//! The stale-input policies against a real pymodbus device that goes away and comes back, seen
//! through the PLC's own Modbus server (its discrete inputs are the inputs as the program got
//! them) and through the device's coils: `hold` keeps the last values, `safe` takes the safe
//! values and reads again when the device is back, `fault` puts the field I/O in its safe state
//! until the run is restarted, device back or not. And a device that answers every request three
//! cycles late, without a timeout: its inputs go stale, the policy applies, the scan goes on.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::modbus::{self, read};
use cetratus_testkit::paths::example;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::ChildGuard;
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// Reads until `table` at `address` reads `want`, for 30 s at most; returns what it read last.
fn wait_read(port: u16, table: &str, address: u16, want: &str) -> String {
    let end = Instant::now() + Duration::from_secs(30);
    let mut seen = String::new();
    while Instant::now() < end {
        seen = read(port, table, address, 1);
        if seen == want {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    seen
}

/// One device on `port` serving the Vernadat program's addresses with `policy`, and the PLC's
/// server on `server`.
fn io_file(dir: &Path, port: u16, server: u16, device_extra: &str) -> PathBuf {
    let path = dir.join("io.toml");
    std::fs::write(
        &path,
        format!(
            "start_timeout = \"2s\"\n[[device]]\nname = \"cell\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:{port}\"\nreconnect_min = \"50ms\"\nreconnect_max = \"200ms\"\nserves = [{{ from = \"%IX0.0\", to = \"%IX0.7\" }}, {{ from = \"%QX0.0\", to = \"%QX0.7\" }}]\n{device_extra}\n[server]\nmodbus = \"127.0.0.1:{server}\"\n"
        ),
    )
    .expect("write io.toml");
    path
}

fn start(io: &Path, dir: &Path, length: &str) -> ChildGuard {
    ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(example("vernadat/vernadat.toml"))
            .arg("--io")
            .arg(io)
            .args(["--for", length, "--json", "--no-mqtt", "--cold"])
            .arg("--state-dir")
            .arg(dir.join("state"))
            .arg("--config")
            .arg(dir.join("config"))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    )
}

fn finish(mut plc: ChildGuard) -> Value {
    let child = std::mem::replace(&mut plc.0, Command::new("true").spawn().expect("true"));
    let out: Output = child.wait_with_output().expect("the run ends");
    assert!(
        out.status.success(),
        "cetratus run failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("run --json prints one JSON object")
}

/// Runs the drop-and-return scenario under `policy`; returns what the PLC's server showed for
/// PE while the device was away, after it came back, the device's coil 0 (CM1) after it came
/// back, and the run's summary.
fn drop_and_return(policy: &str) -> (String, String, String, Value) {
    let dir = tempfile::tempdir().expect("temp dir");
    let (port, server) = (free_port(), free_port());
    let dev = modbus::device(port, &["--di", "1"]);
    let io = io_file(
        dir.path(),
        port,
        server,
        &format!("stale = \"{policy}\"\nstale_after = 20\n"),
    );
    let plc = start(&io, dir.path(), "12s");
    wait_for_port(server, "the PLC's Modbus server", Duration::from_secs(30));
    // PE is on: the program got it, and CM1 went on at the device.
    assert_eq!(
        wait_read(server, "di", 0, "1"),
        "1",
        "PE reached the program"
    );
    assert_eq!(
        wait_read(port, "coils", 0, "1"),
        "1",
        "CM1 reached the device"
    );
    drop(dev);
    // A second is a hundred cycles, far past stale_after (20 cycles: a loaded machine can keep
    // the I/O thread of a device that is there from a few cycles).
    std::thread::sleep(Duration::from_secs(1));
    let away = wait_read(server, "di", 0, if policy == "hold" { "1" } else { "0" });
    // The reconnect writes every output again: CM1 on, or its safe value (off) after a fault.
    // The device comes back with CM1 at the other value, so that the write shows.
    let fault = policy == "fault";
    let _back = modbus::device(port, &["--di", "1", "--co", if fault { "1" } else { "0" }]);
    let coil = wait_read(port, "coils", 0, if fault { "0" } else { "1" });
    let back = wait_read(server, "di", 0, if fault { "0" } else { "1" });
    let summary = finish(plc);
    (away, back, coil, summary)
}

#[test]
fn hold_keeps_the_last_inputs_while_the_device_is_away_and_reads_again_when_it_is_back() {
    let (away, back, coil, s) = drop_and_return("hold");
    assert_eq!((away.as_str(), back.as_str()), ("1", "1"), "{s}");
    assert_eq!(coil, "1", "CM1 written again after the reconnect: {s}");
    let d = &s["io"][0];
    assert!(d["reconnects"].as_u64().unwrap() >= 1, "{d}");
    assert_eq!(d["quality"], "good", "{d}");
    assert!(!s["faults"].to_string().contains("field I/O"), "{s}");
}

#[test]
fn safe_takes_the_safe_inputs_while_the_device_is_away_and_reads_again_when_it_is_back() {
    let (away, back, coil, s) = drop_and_return("safe");
    assert_eq!((away.as_str(), back.as_str()), ("0", "1"), "{s}");
    assert_eq!(coil, "1", "CM1 written again after the reconnect: {s}");
    assert_eq!(s["io"][0]["quality"], "good", "{s}");
    assert!(!s["faults"].to_string().contains("field I/O"), "{s}");
}

#[test]
fn fault_holds_inputs_and_outputs_safe_until_a_restart_even_when_the_device_is_back() {
    let (away, back, coil, s) = drop_and_return("fault");
    assert_eq!((away.as_str(), back.as_str()), ("0", "0"), "{s}");
    assert_eq!(
        coil, "0",
        "CM1 stays at its safe value after the reconnect: {s}"
    );
    let d = &s["io"][0];
    // The device is read again and says so; the field I/O stays in its safe state.
    assert_eq!(d["link"], "up", "{d}");
    assert!(d["reconnects"].as_u64().unwrap() >= 1, "{d}");
    let faults = s["faults"].to_string();
    assert!(
        faults.contains("field I/O") && faults.contains("safe"),
        "{s}"
    );
}

#[test]
fn a_device_that_answers_three_cycles_late_goes_stale_without_stalling_the_scan() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (port, server) = (free_port(), free_port());
    // 100 ms per answer at a 10 ms cycle, well within the timeout: every read completes about
    // ten cycles after the one it was for, past `stale_after = 2` even when a loaded machine
    // stretches the cycles threefold.
    let _dev = modbus::device(port, &["--di", "1", "--delay-ms", "100"]);
    // The device answers a real read before the PLC starts: an open port alone has been seen
    // refusing the PLC's first connections on a loaded machine.
    let answered = (0..50).any(|_| {
        read(port, "di", 0, 1) == "1" || {
            std::thread::sleep(Duration::from_millis(100));
            false
        }
    });
    assert!(answered, "the pymodbus device never answered");
    let io = io_file(
        dir.path(),
        port,
        server,
        "timeout = \"500ms\"\nstale = \"safe\"\nstale_after = 2\n",
    );
    let plc = start(&io, dir.path(), "8s");
    wait_for_port(server, "the PLC's Modbus server", Duration::from_secs(30));
    // A late read is not taken as fresh: PE, on at the device, is held at its safe value while
    // the device is stale, which is most of the time. Read the program's PE until it is seen
    // safe, a few times at most.
    let mut seen = Vec::new();
    for _ in 0..20 {
        seen.push(read(server, "di", 0, 1));
        if seen.last().is_some_and(|v| v == "0") {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let s = finish(plc);
    let d = &s["io"][0];
    assert!(d["reads"].as_u64().unwrap() > 3, "the answers came: {d}");
    assert_eq!(d["errors"], 0, "none timed out: {d}");
    assert!(
        seen.iter().any(|v| v == "0"),
        "PE safe while stale: {seen:?}"
    );
    assert!(
        s["scan"]["cycles"].as_u64().unwrap() >= 200,
        "the scan went on at its period: {s}"
    );
}
