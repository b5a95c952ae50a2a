//! `cetratus twin serve`: the twin as a Modbus TCP device in a process of its own, driven by
//! `cetratus run --io` in another (virtual commissioning), and what a hostile client gets from it.

use std::process::{Command, Stdio};
use std::time::Duration;

use cetratus_testkit::modbus::client as peer;
use cetratus_testkit::paths::example;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{json_of, ChildGuard};
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

#[test]
fn twin_serve_prints_the_addresses_the_example_program_declares() {
    let out = Command::new(BIN)
        .args(["twin", "serve", "festo", "--print-map"])
        .output()
        .unwrap();
    let map = String::from_utf8_lossy(&out.stdout);
    assert!(
        map.contains("START             %IX0.0    discrete input 0"),
        "{map}"
    );
    assert!(map.contains("TABLE_MOTOR       %QX0.0    coil 0"), "{map}");
}

#[test]
fn a_flood_of_connections_is_refused_past_the_limit_and_bad_requests_get_exceptions() {
    let port = free_port();
    let twin = ChildGuard::spawn(
        Command::new(BIN)
            .args(["twin", "serve", "vernadat", "--for", "4s", "--json"])
            .args(["--modbus", &format!("127.0.0.1:{port}")])
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    wait_for_port(port, "the twin's Modbus server", Duration::from_secs(30));
    peer(&["flood", &port.to_string(), "100"]);
    // Past the table, a write to a coil that is not there, and a wrong unit id.
    assert!(peer(&["read", &port.to_string(), "di", "0", "64"]).starts_with("exception"));
    assert!(peer(&["write", &port.to_string(), "coils", "500", "1"]).starts_with("exception"));
    assert!(
        peer(&["read", &port.to_string(), "di", "0", "8", "--unit", "9"]).starts_with("exception")
    );
    // The server still answers.
    let di = peer(&["read", &port.to_string(), "di", "0", "8"]);
    assert_eq!(di.split(',').count(), 8, "{di}");
    let s = json_of(twin);
    assert!(s["modbus"]["refused"].as_u64().unwrap() >= 80, "{s}");
    assert!(s["modbus"]["exceptions"].as_u64().unwrap() >= 3, "{s}");
}

/// The audit log's `what` of every record, in order.
fn audit(state: &std::path::Path) -> Vec<String> {
    std::fs::read_to_string(state.join("audit.jsonl"))
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .map(|r| r["what"].as_str().unwrap_or("").to_string())
        .collect()
}

/// The one real-time run of this suite: a minute of the cell with the PLC and the twin in two
/// processes, with the paper's U.1 loaded at 10 s and substituted at 20 s over the Modbus link,
/// compared with the in-process twin under the same script.
#[test]
fn a_minute_with_the_twin_in_its_own_process_takes_u1_and_finishes_as_many_parts_as_in_process() {
    let port = free_port();
    let dir = tempfile::tempdir().unwrap();
    // The demo's program and its signed U.1, with the key that signed it.
    let demo = dir.path().join("demo");
    let out = Command::new(BIN)
        .args(["demo", "--scripted", "--json", "--dir"])
        .arg(&demo)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let script = [
        "--at".to_string(),
        format!("10s load {}", demo.join("u1.cpkg").display()),
        "--at".to_string(),
        "20s substitute".to_string(),
        "--at".to_string(),
        "22s accept".to_string(),
    ];
    let io = dir.path().join("io-modbus.toml");
    let text = std::fs::read_to_string(example("vernadat/io-modbus.toml")).unwrap();
    std::fs::write(&io, text.replace("15020", &port.to_string())).unwrap();
    let twin = ChildGuard::spawn(
        Command::new(BIN)
            .args(["twin", "serve", "vernadat", "--for", "60s", "--json"])
            .args(["--modbus", &format!("127.0.0.1:{port}")])
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    wait_for_port(port, "the twin's Modbus server", Duration::from_secs(30));
    // The PLC outlives the twin, so that the twin never sees its outputs go safe mid-move.
    let state = dir.path().join("state");
    let _plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(demo.join("vernadat.toml"))
            .arg("--io")
            .arg(&io)
            .args(["--no-mqtt", "--cold", "--json"])
            .arg("--trust")
            .arg(demo.join("trusted"))
            .args(&script)
            .arg("--state-dir")
            .arg(&state)
            .arg("--config")
            .arg(dir.path().join("config"))
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    let served = json_of(twin);
    let in_process = Command::new(BIN)
        .arg("run")
        .arg(demo.join("vernadat.toml"))
        .args(["--twin", "vernadat", "--virtual", "--for", "60s", "--json"])
        .arg("--trust")
        .arg(demo.join("trusted"))
        .args(&script)
        .arg("--state-dir")
        .arg(dir.path().join("state-in-process"))
        .arg("--config")
        .arg(dir.path().join("config"))
        .output()
        .unwrap();
    let in_process: Value = serde_json::from_slice(&in_process.stdout).unwrap();
    let (two, one) = (
        served["parts_finished"].as_i64().unwrap(),
        in_process["parts_finished"].as_i64().unwrap(),
    );
    assert!(
        one > 0 && (two - one).abs() <= 1,
        "two processes {two}, in process {one}"
    );
    assert_eq!(served["twin_faults"], 0, "{served}");
    // U.1 was loaded, quarantined and substituted over the Modbus link, then accepted.
    let events = audit(&state);
    let at = |what: &str| events.iter().position(|e| e == what);
    let order = [at("quarantine_started"), at("substituted"), at("accepted")];
    assert!(
        order.iter().all(Option::is_some) && order.windows(2).all(|w| w[0] < w[1]),
        "{events:?}"
    );
    assert!(
        !events
            .iter()
            .any(|e| e.contains("fault") || e == "reverted"),
        "{events:?}"
    );
}
