//! Inputs written by OPC UA clients have a quality and a stale policy, as a field device's:
//! asyncua (FreeOpcUa's Python stack) writes an input with a keep-alive, then goes away, and
//! the real `cetratus run` shows the quality in `exec_info` and its summary and applies the
//! policy to what the program gets (docs/io.md, *Quality*).

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::opcua;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{run_vernadat, stop_with_sigterm as stop, ChildGuard};
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn peer(args: &[&str]) -> Command {
    let mut c = opcua::command();
    c.args(args);
    c
}

/// The quality of the OPC UA inputs in the PLC's `exec_info`, once it is `want` (or the last
/// seen after a minute).
fn quality_until(mqtt: u16, want: &str) -> Value {
    let end = Instant::now() + Duration::from_secs(60);
    loop {
        let out = Command::new(BIN)
            .args(["exec-info", "--broker", &format!("mqtt://127.0.0.1:{mqtt}")])
            .args(["--plc", "cell", "--json"])
            .output()
            .expect("run cetratus exec-info");
        let reply: Value = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
        let q = reply["result"][0]["input_quality"].clone();
        let found = q
            .as_array()
            .and_then(|a| a.iter().find(|d| d["device"] == "opcua"))
            .cloned()
            .unwrap_or(Value::Null);
        if found["quality"] == want || Instant::now() > end {
            return found;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn start(dir: &Path, io_body: &str, port: u16, mqtt: u16) -> ChildGuard {
    let io = dir.join("io.toml");
    std::fs::write(&io, io_body).unwrap();
    let plc = ChildGuard::spawn(
        run_vernadat(BIN, &io, dir)
            .arg("--no-dashboard")
            .args(["--mqtt", &format!("127.0.0.1:{mqtt}")])
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    wait_for_port(port, "the PLC's OPC UA server", Duration::from_secs(60));
    wait_for_port(mqtt, "the embedded broker", Duration::from_secs(60));
    plc
}

fn opcua_fault(summary: &Value) -> bool {
    summary["faults"]
        .as_array()
        .unwrap()
        .iter()
        .any(|f| f.as_str().unwrap_or("").contains("OPC UA inputs"))
}

#[test]
fn inputs_whose_client_went_away_go_stale_and_take_their_safe_values_under_safe() {
    let dir = tempfile::tempdir().unwrap();
    let (port, mqtt) = (free_port(), free_port());
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let plc = start(
        dir.path(),
        &format!("start_timeout = \"1s\"\n\n[opcua]\nlisten = \"{url}\"\ninputs = true\nstale = \"safe\"\nstale_after = 30\n"),
        port,
        mqtt,
    );
    // Before any write: initial.
    let q = quality_until(mqtt, "initial");
    assert_eq!(q["quality"], "initial", "{q}");
    // A client that writes PE = true every 50 ms (its keep-alive) for a while, then leaves.
    let mut writer = ChildGuard::spawn(
        peer(&["run", &url, "keep:cell.Inputs.PE:bool:1:8"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    let q = quality_until(mqtt, "good");
    assert_eq!(q["quality"], "good", "{q}");
    assert_eq!(q["link"], "up", "{q}");
    // While it writes, the program gets what it writes.
    assert_eq!(
        opcua::run(&["wait", &url, "cell.Inputs.PE", "1", "10"]),
        ["ok"]
    );
    let status = writer.0.wait().unwrap();
    assert!(status.success());
    // Gone: stale after 30 cycles, and under `safe` the program gets PE's safe value (false).
    let q = quality_until(mqtt, "stale");
    assert_eq!(q["quality"], "stale", "{q}");
    assert_eq!(q["link"], "down", "{q}");
    assert!(q["missed_cycles"].as_u64().unwrap() >= 30, "{q}");
    assert_eq!(
        opcua::run(&["wait", &url, "cell.Inputs.PE", "0", "10"]),
        ["ok"]
    );
    // A client that comes back makes it good again, and its value reaches the program.
    assert_eq!(
        opcua::run(&[
            "run",
            &url,
            "w:cell.Inputs.PE:bool:1",
            "wait:cell.Inputs.PE:1"
        ]),
        ["ok", "ok"]
    );
    let s = stop(plc);
    let io = s["io"].as_array().expect("io in the summary");
    let o = io.iter().find(|d| d["name"] == "opcua").expect("opcua");
    assert!(o["reads"].as_u64().unwrap() >= 10, "{s}");
    // (The cell itself may stall on its watchdogs with one sensor written: not an I/O fault.)
    assert!(!opcua_fault(&s), "{s}");
}

/// Starts a PLC whose inputs come from OPC UA, with `policy` (lines of `[opcua]`) and
/// `stale_after = 20`; a client writes PE = true once and leaves, and the inputs go stale.
/// Returns the PLC and its server's URL.
fn written_once_then_stale(dir: &Path, policy: &str) -> (ChildGuard, String) {
    let (port, mqtt) = (free_port(), free_port());
    let url = format!("opc.tcp://127.0.0.1:{port}");
    let plc = start(
        dir,
        &format!("start_timeout = \"1s\"\n\n[opcua]\nlisten = \"{url}\"\ninputs = true\n{policy}stale_after = 20\n"),
        port,
        mqtt,
    );
    assert_eq!(
        opcua::run(&[
            "run",
            &url,
            "w:cell.Inputs.PE:bool:1",
            "wait:cell.Inputs.PE:1"
        ]),
        ["ok", "ok"]
    );
    let q = quality_until(mqtt, "stale");
    assert_eq!(q["quality"], "stale", "{q}");
    (plc, url)
}

#[test]
fn under_hold_a_silent_client_leaves_the_last_value_and_under_fault_the_run_faults() {
    let dir = tempfile::tempdir().unwrap();
    let (plc, url) = written_once_then_stale(dir.path(), "");
    // `hold` (the default): the program keeps the last value written.
    assert_eq!(
        opcua::run(&["read", &url, "cell.Inputs.PE"]),
        ["cell.Inputs.PE=1"]
    );
    let s = stop(plc);
    // (The cell itself may stall on its watchdogs with one sensor written: not an I/O fault.)
    assert!(!opcua_fault(&s), "{s}");

    let dir = tempfile::tempdir().unwrap();
    let (plc, url) = written_once_then_stale(dir.path(), "stale = \"fault\"\n");
    // `fault`: safe inputs, latched; a new write does not bring the inputs back.
    assert_eq!(
        opcua::run(&[
            "run",
            &url,
            "w:cell.Inputs.PE:bool:1",
            "wait:cell.Inputs.PE:0"
        ]),
        ["ok", "ok"]
    );
    let s = stop(plc);
    assert!(opcua_fault(&s), "{s}");
}
