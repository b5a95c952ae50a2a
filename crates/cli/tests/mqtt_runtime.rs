//! The real runtime over MQTT, with real clients: `cetratus demo` on a Mosquitto started by the test
//! and on its embedded broker; Mosquitto's own tools (`mosquitto_sub`, `mosquitto_pub`,
//! `mosquitto_rr`) and a paho-mqtt MQTT 5 client as the operator's side; fuzzed commands that must
//! all get error replies while the primary goes on.

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::mqtt::{self, Mosquitto};
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::ChildGuard;
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// `cetratus demo` in real time at speed 10, its MQTT on `broker_args`.
fn demo(dir: &Path, plc: &str, broker_args: &[String]) -> ChildGuard {
    ChildGuard::spawn(
        Command::new(BIN)
            .args([
                "demo",
                "--speed",
                "10",
                "--http",
                "127.0.0.1:0",
                "--for",
                "30min",
                "--plc",
                plc,
                "--dir",
            ])
            .arg(dir)
            .args(broker_args)
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    )
}

fn wait_state(port: u16, plc: &str, pred: impl Fn(&Value) -> bool) -> Value {
    let end = Instant::now() + Duration::from_secs(30);
    let mut last = Value::Null;
    while Instant::now() < end {
        if let Some(v) = mqtt::sub_one(port, &format!("cetratus/{plc}/state"), 2, false) {
            if pred(&v) {
                return v;
            }
            last = v;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    panic!("state never matched; last: {last}");
}

/// MQTT 3.1.1: `mosquitto_pub` with a `reply_to` field, `mosquitto_sub` on that topic.
fn request_v311(port: u16, plc: &str, verb: &str, payload: Value) -> Value {
    let reply = format!(
        "cetratus/{plc}/reply/test-{}-{verb}-{}",
        std::process::id(),
        free_port()
    );
    mqtt::request_v311(port, &format!("cetratus/{plc}/cmd/{verb}"), payload, &reply)
}

/// MQTT 5 request/reply with `mosquitto_rr`: the response topic and correlation data properties.
/// The payload goes on the command line (`-m`; its `-f` sends an empty message in 2.0.11), so it
/// holds no NUL byte and stays under the kernel's 128 KiB limit for one argument.
fn request_v5(port: u16, plc: &str, verb: &str, payload: &[u8]) -> Output {
    use std::os::unix::ffi::OsStrExt;
    Command::new(mqtt::tool("mosquitto_rr"))
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &port.to_string(),
            "-t",
            &format!("cetratus/{plc}/cmd/{verb}"),
            "-e",
        ])
        .arg(format!(
            "cetratus/{plc}/reply/rr-{}-{}",
            std::process::id(),
            free_port()
        ))
        .args(["-W", "15", "-m"])
        .arg(std::ffi::OsStr::from_bytes(payload))
        .output()
        .expect("run mosquitto_rr")
}

fn packages() -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = Command::new(BIN)
        .args(["demo", "--scripted", "--json", "--dir"])
        .arg(dir.path())
        .output()
        .expect("cetratus demo --scripted");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir
}

fn buffer_invariant(info: &Value, slot: usize) -> i64 {
    let m = &info["result"][slot]["marking"];
    ["H", "B", "P14"]
        .iter()
        .map(|p| m[p].as_i64().expect("place"))
        .sum()
}

fn scenario(port: u16, plc: &str, dir: &Path) {
    // The retained state, read by mosquitto_sub.
    let state = wait_state(port, plc, |v| v["primary"] == "A" && v["status"] == "idle");
    assert_eq!(state["online"], true);
    assert_eq!(state["programs"]["A"]["name"], "vernadat-cell");

    // MQTT 3.1.1 command with reply_to.
    let info = request_v311(port, plc, "exec_info", serde_json::json!({}));
    assert_eq!(info["ok"], true, "{info}");
    let cycles0 = info["result"][0]["cycles"].as_u64().expect("cycles");
    assert_eq!(buffer_invariant(&info, 0), 7);

    // Fuzzed commands: each gets an error reply, and the PLC does not notice.
    let fuzz: Vec<(&str, Vec<u8>)> = vec![
        (
            "load",
            (0..300u32)
                .map(|i| ((i.wrapping_mul(2654435761) >> 24) as u8).max(1))
                .collect(),
        ),
        ("load", b"{\"package_b64\": 42".to_vec()),
        (
            "load",
            b"{\"package_b64\": \"bm90IGEgcGFja2FnZQ==\"}".to_vec(),
        ),
        ("substitute", b"{\"mode\": \"sideways\"}".to_vec()),
        ("frobnicate", b"{}".to_vec()),
        (
            "load",
            b"{\"package_b64\": \"AAAA\", \"allow_unsigned\": true}".to_vec(),
        ),
    ];
    for (verb, bytes) in &fuzz {
        let out = request_v5(port, plc, verb, bytes);
        let reply: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|_| {
            panic!(
                "{verb} ({} bytes): no JSON reply: {}",
                bytes.len(),
                String::from_utf8_lossy(&out.stderr)
            )
        });
        assert_eq!(reply["ok"], false, "{verb}: {reply}");
        assert!(
            reply["error"]["code"].is_string() && reply["error"]["message"].is_string(),
            "{reply}"
        );
    }
    // A huge payload (2 MiB) over 3.1.1, with its reply_to inside.
    let huge = request_v311(
        port,
        plc,
        "load",
        serde_json::json!({"package_b64": "x".repeat(2 << 20)}),
    );
    assert_eq!(huge["ok"], false, "{huge}");
    let info = request_v311(port, plc, "exec_info", serde_json::json!({}));
    assert!(
        info["result"][0]["cycles"].as_u64().expect("cycles") > cycles0,
        "the scans go on"
    );
    assert_eq!(
        buffer_invariant(&info, 0),
        7,
        "the primary's marking is consistent"
    );
    assert!(info["result"][1].is_null(), "nothing was loaded");

    // A real update: U.1 through MQTT 5 request/reply, then substitute through 3.1.1.
    let b64 = {
        use std::fmt::Write as _;
        let bytes = std::fs::read(dir.join("u1.cpkg")).expect("u1.cpkg");
        let engine = base64_encode(&bytes);
        let mut s = String::new();
        let _ = write!(s, "{{\"package_b64\": \"{engine}\"}}");
        s
    };
    let out = request_v5(port, plc, "load", b64.as_bytes());
    let reply: Value = serde_json::from_slice(&out.stdout).expect("load reply");
    assert_eq!(reply["ok"], true, "{reply}");
    wait_state(port, plc, |v| {
        v["status"] == "quarantine" && v["programs"]["B"]["version"] == "1.1.0"
    });
    let r = request_v311(
        port,
        plc,
        "substitute",
        serde_json::json!({"mode": "retransform"}),
    );
    assert_eq!(r["ok"], true, "{r}");
    // The old program stays as a shadow for the default minute of probation; `accept` ends it.
    wait_state(port, plc, |v| {
        v["primary"] == "B" && v["status"] == "probation"
    });
    let r = request_v311(port, plc, "accept", serde_json::json!({}));
    assert_eq!(r["ok"], true, "{r}");
    wait_state(port, plc, |v| v["primary"] == "B" && v["status"] == "idle");
    let info = request_v311(port, plc, "exec_info", serde_json::json!({}));
    assert_eq!(
        buffer_invariant(&info, 1),
        9,
        "U.1 gave the buffer two more slots"
    );

    // A paho-mqtt MQTT 5 client does request/reply.
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scripts/mqtt_request.py");
    let out = Command::new("python3")
        .arg(&script)
        .args([
            "--port",
            &port.to_string(),
            "--topic",
            &format!("cetratus/{plc}/cmd/exec_info"),
            "--payload",
            "{}",
        ])
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "paho request/reply failed ({:?}); install paho-mqtt (./scripts/test does): {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
}

fn base64_encode(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len() * 4 / 3 + 4);
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for i in 0..4 {
            if i <= c.len() {
                s.push(T[((n >> (18 - 6 * i)) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[test]
fn the_runtime_on_a_real_mosquitto_answers_mosquitto_clients_and_paho() {
    let pk = packages();
    let broker = Mosquitto::start();
    let port = broker.port();
    let _plc = demo(
        pk.path(),
        "mosq1",
        &["--broker".into(), format!("mqtt://127.0.0.1:{port}")],
    );
    scenario(port, "mosq1", pk.path());
}

#[test]
fn the_runtime_on_its_embedded_broker_answers_mosquitto_clients_and_paho() {
    let pk = packages();
    let port = free_port();
    let _plc = demo(
        pk.path(),
        "emb1",
        &["--mqtt".into(), format!("127.0.0.1:{port}")],
    );
    wait_for_port(port, "the embedded broker", Duration::from_secs(10));
    scenario(port, "emb1", pk.path());
}

#[test]
fn a_taken_port_is_a_clear_error_that_says_what_to_do() {
    let l = TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = l.local_addr().expect("addr").port();
    let dir = tempfile::tempdir().expect("temp");
    let out = Command::new(BIN)
        .args(["demo", "--http", "127.0.0.1:0", "--dir"])
        .arg(dir.path())
        .args(["--mqtt", &format!("127.0.0.1:{port}")])
        .output()
        .expect("cetratus demo");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&port.to_string()) && err.contains("--mqtt") && err.contains("--broker"),
        "{err}"
    );
}
