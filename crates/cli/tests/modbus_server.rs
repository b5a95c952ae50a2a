//! The PLC's own Modbus server, against pymodbus as its client (installed by scripts/test): an
//! HMI reads the process image and the status registers, writes a setpoint word (%MW) and a
//! pushbutton the configuration marks `hmi_writable`, and the program acts on them; everything
//! else a client may try is answered with an exception, and the PLC runs on.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use cetratus_testkit::paths::workspace_root;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{stop_with_sigterm as stop, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// A panel program: `Y` is on while the setpoint `SP` (%MW0) is above 5, `Z` while the button
/// `BTN` (%IX1.0, written by an HMI) is pressed.
const NET: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<pnml xmlns="http://www.pnml.org/version-2009/grammar/pnml">
  <net id="panel" type="http://www.pnml.org/version-2009/grammar/ptnet">
    <page id="page0">
      <place id="YOff"><initialMarking><text>1</text></initialMarking></place>
      <place id="YOn"/>
      <place id="ZOff"><initialMarking><text>1</text></initialMarking></place>
      <place id="ZOn"/>
      <transition id="Y1"/><transition id="Y0"/><transition id="Z1"/><transition id="Z0"/>
      <arc id="a1" source="YOff" target="Y1"/><arc id="a2" source="Y1" target="YOn"/>
      <arc id="a3" source="YOn" target="Y0"/><arc id="a4" source="Y0" target="YOff"/>
      <arc id="a5" source="ZOff" target="Z1"/><arc id="a6" source="Z1" target="ZOn"/>
      <arc id="a7" source="ZOn" target="Z0"/><arc id="a8" source="Z0" target="ZOff"/>
    </page>
  </net>
</pnml>
"#;

const PROGRAM: &str = r#"[program]
name = "panel"
version = "1.0.0"
net = "panel.pnml"
policy = "step"
scan_period = "10ms"

[[input]]
name = "SP"
type = "int"
address = "%MW0"

[[input]]
name = "BTN"
type = "bool"
address = "%IX1.0"

[[output]]
name = "Y"
type = "bool"
address = "%QX0.0"

[[output]]
name = "Z"
type = "bool"
address = "%QX0.1"

[guards]
Y1 = "SP > 5"
Y0 = "SP <= 5"
Z1 = "BTN"
Z0 = "!BTN"

[[action]]
place = "YOn"
qualifier = "N"
target = "Y"

[[action]]
place = "ZOn"
qualifier = "N"
target = "Z"
"#;

/// The panel program and an I/O configuration whose server listens on `port`, taking writes
/// from 127.0.0.1 only.
fn panel(dir: &Path, port: u16) -> (PathBuf, PathBuf) {
    std::fs::write(dir.join("panel.pnml"), NET).expect("write the net");
    let program = dir.join("panel.toml");
    std::fs::write(&program, PROGRAM).expect("write the program");
    let io = dir.join("io.toml");
    std::fs::write(
        &io,
        format!("[[channel]]\naddress = \"%IX1.0\"\nhmi_writable = true\n\n[server]\nmodbus = \"127.0.0.1:{port}\"\nmax_connections = 4\nidle_timeout = \"2s\"\nwrite_from = [\"127.0.0.1\"]\n"),
    )
    .expect("write io.toml");
    (program, io)
}

/// Runs the program in real time, until stopped, with its server on `port`.
fn start(dir: &Path, port: u16) -> ChildGuard {
    let (program, io) = panel(dir, port);
    let plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(program)
            .arg("--io")
            .arg(io)
            .args(["--json", "--no-mqtt", "--cold"])
            .arg("--state-dir")
            .arg(dir.join("state"))
            .arg("--config")
            .arg(dir.join("config"))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    wait_for_port(port, "the PLC's Modbus server", Duration::from_secs(60));
    plc
}

/// One pymodbus client connection running `ops` in turn (scripts/modbus_peer.py `session`);
/// one line of answer per op.
fn session(port: u16, source: Option<&str>, ops: &[&str]) -> Vec<String> {
    let mut c = Command::new("python3");
    c.arg(workspace_root().join("scripts/modbus_peer.py"))
        .args(["session", &port.to_string()])
        .args(ops);
    if let Some(s) = source {
        c.args(["--source", s]);
    }
    let out = c.output().expect("run the pymodbus client");
    let text = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<String> = text.lines().map(str::to_string).collect();
    assert_eq!(
        lines.len(),
        ops.len(),
        "{ops:?} -> {text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    lines
}

fn cycles(status: &str) -> u64 {
    let r: Vec<u64> = status.split(',').map(|x| x.parse().unwrap()).collect();
    (r[2] << 48) | (r[3] << 32) | (r[4] << 16) | r[5]
}

#[test]
fn an_hmi_reads_the_image_and_status_and_its_allowed_writes_reach_the_program() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let plc = start(dir.path(), port);
    let got = session(
        port,
        None,
        &[
            "read:ir:8192:9",
            "read:coils:0:2",
            "write:hr:1024:10",
            "wait:coils:0:1",
            "read:hr:1024:1",
            "write:coils:8200:1",
            "wait:coils:1:1",
            "read:di:8:1",
            "write:hr:1024:3",
            "wait:coils:0:0",
            "read:ir:8192:9",
        ],
    );
    // PRIMARY is A (0), STATUS idle (0), no drift; the cycle counter runs.
    assert!(got[0].starts_with("0,0,"), "{got:?}");
    assert!(got[0].ends_with(",0,0,0"), "{got:?}");
    assert_eq!(got[1], "0,0");
    assert_eq!(got[2], "ok");
    assert_eq!(got[3], "ok", "the setpoint written to %MW0 switched Y on");
    assert_eq!(got[4], "10");
    assert_eq!(got[5], "ok");
    assert_eq!(got[6], "ok", "the HMI's button switched Z on");
    assert_eq!(got[7], "1", "the program's input %IX1.0 shows the press");
    assert_eq!((got[8].as_str(), got[9].as_str()), ("ok", "ok"));
    assert!(cycles(&got[10]) > cycles(&got[0]), "{got:?}");
    let s = stop(plc);
    assert_eq!(s["modbus_server"]["exceptions"], 0, "{s}");
    assert!(
        s["modbus_server"]["requests"].as_u64().unwrap() >= 11,
        "{s}"
    );
}

#[test]
fn writes_to_outputs_status_or_from_other_addresses_and_other_units_get_exceptions() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let plc = start(dir.path(), port);
    let got = session(
        port,
        None,
        &[
            "write:coils:0:1",
            "write:hr:1025:1",
            "write:coils:8:1",
            "read:ir:8201:1",
            "raw:3:0:126",
            "unit:9",
            "read:coils:0:1",
        ],
    );
    // A program output, a memory word no input declares, a coil that is no one's mirror.
    assert_eq!(&got[..3], ["exception 2", "exception 2", "exception 2"]);
    // Past the status registers; more registers than a frame carries.
    assert_eq!(got[3], "exception 2");
    assert_eq!(got[4], "exception 3");
    assert_eq!(got[6], "exception 11", "a wrong unit id");
    // A client not on the allow-list reads, and may not write even a writable word.
    let other = session(
        port,
        Some("127.0.0.2"),
        &["read:hr:1024:1", "write:hr:1024:10", "read:coils:0:1"],
    );
    assert_eq!(other, ["0", "exception 1", "0"]);
    let s = stop(plc);
    assert_eq!(s["modbus_server"]["exceptions"], 7, "{s}");
    assert_eq!(s["status"], "idle", "{s}");
}

#[test]
fn a_flood_of_connections_is_refused_past_the_limit_and_the_server_still_answers() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let plc = start(dir.path(), port);
    let out = Command::new("python3")
        .arg(workspace_root().join("scripts/modbus_peer.py"))
        .args(["flood", &port.to_string(), "100"])
        .output()
        .expect("run the flood");
    assert!(out.status.success());
    let got = session(port, None, &["read:ir:8192:2", "read:coils:0:2"]);
    assert_eq!(got, ["0,0", "0,0"]);
    let s = stop(plc);
    assert!(s["modbus_server"]["refused"].as_u64().unwrap() >= 90, "{s}");
    assert!(s["scans"].as_u64().unwrap() > 0, "{s}");
}

#[test]
fn with_the_twin_as_the_plant_the_server_shows_the_twins_sensors_and_the_programs_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let io = dir.path().join("io-servers.toml");
    let text =
        std::fs::read_to_string(cetratus_testkit::paths::example("vernadat/io-servers.toml"))
            .unwrap();
    let text = text.replace("14841", &free_port().to_string());
    std::fs::write(&io, text.replace("15021", &port.to_string())).unwrap();
    let plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(cetratus_testkit::paths::example("vernadat/vernadat.toml"))
            .args(["--twin", "vernadat", "--io"])
            .arg(&io)
            .args(["--json", "--no-mqtt", "--cold", "--speed", "10"])
            .arg("--state-dir")
            .arg(dir.path().join("state"))
            .arg("--config")
            .arg(dir.path().join("config"))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    wait_for_port(port, "the PLC's Modbus server", Duration::from_secs(60));
    // The robot loads M1 (CM1, coil 0) once a part waits at the infeed (PE, discrete input 0).
    let got = session(port, None, &["wait:coils:0:1", "write:coils:0:0"]);
    assert_eq!(got, ["ok", "exception 2"]);
    let s = stop(plc);
    assert!(s["firings"].as_u64().unwrap() > 0, "{s}");
    assert_eq!(s["twin_faults"], 0, "{s}");
}

#[test]
fn idle_sockets_from_one_host_neither_lock_the_server_nor_keep_their_slots() {
    use std::io::Read;

    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let plc = start(dir.path(), port);
    // Eight connections that never send a byte, from one host: as many as it may keep are
    // kept open, the rest closed at once.
    let idle: Vec<std::net::TcpStream> = (0..8)
        .map(|_| std::net::TcpStream::connect(("127.0.0.1", port)).expect("connect"))
        .collect();
    std::thread::sleep(Duration::from_millis(300));
    // An HMI on another address still gets in.
    let got = session(port, Some("127.0.0.2"), &["read:coils:0:1"]);
    assert_eq!(got, ["0"], "the HMI is served beside the idle sockets");
    // The idle ones are closed after the idle timeout (2 s here): each read ends.
    for mut s in idle {
        s.set_read_timeout(Some(Duration::from_secs(10)))
            .expect("a read timeout");
        let mut buf = [0u8; 8];
        match s.read(&mut buf) {
            Ok(0) => {}
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => {}
            other => panic!("an idle socket was left open: {other:?}"),
        }
    }
    let s = stop(plc);
    assert!(s["modbus_server"]["refused"].as_u64().unwrap() >= 6, "{s}");
}
