//! Stopping and restarting a PLC as a service manager does: SIGTERM is a clean stop with a final
//! snapshot, and a restart on the same port starts at once, even while the last run's
//! connections linger in TIME_WAIT.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use cetratus_testkit::mqtt;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{stderr_lines, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn start(state: &Path, cfg: &Path, port: u16) -> (Child, mpsc::Receiver<String>) {
    let example =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/vernadat/vernadat.toml");
    let mut child = Command::new(BIN)
        .arg("run")
        .arg(example)
        .args([
            "--twin",
            "vernadat",
            "--for",
            "1h",
            "--plc",
            "svc",
            "--no-dashboard",
        ])
        .args(["--mqtt", &format!("127.0.0.1:{port}"), "--progress", "10"])
        .arg("--state-dir")
        .arg(state)
        .arg("--config")
        .arg(cfg)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the PLC starts");
    let rx = stderr_lines(&mut child);
    (child, rx)
}

/// The first stderr line containing `what` within `within`, or every line seen.
fn wait_line(rx: &mpsc::Receiver<String>, what: &str, within: Duration) -> Result<String, String> {
    let end = Instant::now() + within;
    let mut seen = Vec::new();
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        match rx.recv_timeout(left) {
            Ok(l) if l.contains(what) => return Ok(l),
            Ok(l) => seen.push(l),
            Err(_) => break,
        }
    }
    Err(seen.join("\n"))
}

#[test]
fn sigterm_stops_cleanly_with_a_final_snapshot_and_a_restart_on_the_same_port_starts_at_once() {
    let work = tempfile::tempdir().expect("temp dir");
    let (state, cfg) = (work.path().join("state"), work.path().join("config"));
    std::fs::create_dir_all(&cfg).expect("mkdir");
    let port = free_port();
    let (mut plc, rx) = start(&state, &cfg, port);
    wait_for_port(port, "the embedded broker", Duration::from_secs(20));
    // A client stays connected, so that the stop leaves the broker's side of the connection in
    // TIME_WAIT on the port.
    let _client = ChildGuard::spawn(
        Command::new(mqtt::tool("mosquitto_sub"))
            .args([
                "-h",
                "127.0.0.1",
                "-p",
                &port.to_string(),
                "-t",
                "cetratus/svc/#",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    wait_line(&rx, "progress cycle=", Duration::from_secs(20)).expect("the PLC runs");
    std::thread::sleep(Duration::from_millis(300));

    let kill = Command::new("kill")
        .args(["-TERM", &plc.id().to_string()])
        .status()
        .expect("kill");
    assert!(kill.success());
    let end = Instant::now() + Duration::from_secs(20);
    let status = loop {
        if let Some(s) = plc.try_wait().expect("wait") {
            break s;
        }
        assert!(Instant::now() < end, "the PLC did not stop on SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut out = String::new();
    std::io::Read::read_to_string(&mut plc.stdout.take().expect("stdout"), &mut out)
        .expect("stdout");
    assert!(
        status.success(),
        "SIGTERM is a clean stop, not a kill: {status}"
    );
    assert!(
        out.contains("snapshots committed"),
        "the closing summary: {out}"
    );

    // At once, on the same port.
    let (again, rx) = start(&state, &cfg, port);
    let again = ChildGuard::new(again);
    match wait_line(&rx, "warm start", Duration::from_secs(20)) {
        Ok(_) => {}
        Err(seen) => panic!("the restart did not warm start:\n{seen}"),
    }
    wait_for_port(port, "the embedded broker, again", Duration::from_secs(5));
    drop(again);
}
