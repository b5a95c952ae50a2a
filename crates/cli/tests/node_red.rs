//! The Machine Configuration Tool as a Node-RED flow (docs/examples/node-red), as it ships: a
//! real Node-RED from npm runs it headless, with its settings, against a real Mosquitto and a
//! real PLC, and the test drives it over its HTTP endpoints as an operator's page would.
//!
//! * `GET /cetratus/plc` shows the PLC's retained state: online, PRIMARY A, STATUS idle;
//! * `GET /cetratus/fleet` lists the PLC, with its labels and the program in PRIMARY;
//! * a state, an event or a reply that is not JSON, or not of its shape, is dropped and counted,
//!   and the flow goes on;
//! * a package outside the flow's packages directory is refused before anything is sent;
//! * `POST /cetratus/load` of a signed U.1 package gets the PLC's reply, `ok`, and the PLC goes
//!   into quarantine; `POST /cetratus/remove` gets its `ok`, and the PLC is idle again.
//!
//! Node-RED 5 comes from `scripts/node-red` (npm, once, into a cache directory, with Node.js 22
//! from npm when the machine's is older), which needs npm.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::http;
use cetratus_testkit::mqtt::{self, Mosquitto};
use cetratus_testkit::paths::{example, workspace_root};
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{signed_package, ChildGuard};
use serde_json::{json, Value};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");
const PLC: &str = "cell1";

/// How long the PLC, Node-RED and the broker get for each step.
const WITHIN: Duration = Duration::from_secs(60);

/// The launcher of Node-RED, as `scripts/node-red` installed it (the first call installs it).
fn node_red() -> PathBuf {
    let out = Command::new("bash")
        .arg(workspace_root().join("scripts/node-red"))
        .output()
        .expect("scripts/node-red runs");
    assert!(
        out.status.success(),
        "scripts/node-red failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    PathBuf::from(stdout.lines().last().unwrap_or_default().trim())
}

/// The Vernadat cell on its twin as PLC `cell1`, labelled `line = "1"`, on the broker at `port`,
/// loading packages signed by a key in `trusted`.
fn plc(root: &Path, port: u16, trusted: &Path) -> ChildGuard {
    let config = root.join("config");
    std::fs::create_dir_all(&config).unwrap();
    std::fs::write(config.join("config.toml"), "[labels]\nline = \"1\"\n").unwrap();
    ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(example("vernadat/vernadat.toml"))
            .args(["--twin", "vernadat", "--speed", "10", "--no-dashboard"])
            .args([
                "--plc",
                PLC,
                "--broker",
                &format!("mqtt://127.0.0.1:{port}"),
            ])
            .arg("--config")
            .arg(&config)
            .arg("--trust")
            .arg(trusted)
            .arg("--state-dir")
            .arg(root.join("state"))
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    )
}

/// Node-RED running the flow, and where to reach it.
struct Flow {
    addr: SocketAddr,
    log: PathBuf,
    _process: ChildGuard,
}

impl Flow {
    /// Node-RED with the flow and its settings, for PLC `cell1` on the broker at `broker`,
    /// loading packages from `packages`; its output goes to `node-red.log` in `root`.
    fn start(root: &Path, broker: u16, packages: &Path) -> Flow {
        let docs = workspace_root().join("docs/examples/node-red");
        let user_dir = root.join("node-red");
        std::fs::create_dir_all(&user_dir).unwrap();
        let log = root.join("node-red.log");
        let out = std::fs::File::create(&log).unwrap();
        let port = free_port();
        let process = ChildGuard::spawn(
            Command::new(node_red())
                .arg("--settings")
                .arg(docs.join("settings.js"))
                .arg("--userDir")
                .arg(&user_dir)
                .args(["--port", &port.to_string()])
                .arg(docs.join("flow.json"))
                .env("CETRATUS_PLC", PLC)
                .env("CETRATUS_BROKER_HOST", "127.0.0.1")
                .env("CETRATUS_BROKER_PORT", broker.to_string())
                .env("CETRATUS_PACKAGES", packages)
                .stdout(out.try_clone().unwrap())
                .stderr(out),
        );
        wait_for_port(port, "node-red", WITHIN);
        Flow {
            addr: SocketAddr::from(([127, 0, 0, 1], port)),
            log,
            _process: process,
        }
    }

    /// `method path` with `body` as JSON: the status and the answer as JSON.
    fn call(&self, method: &str, path: &str, body: &Value) -> (u16, Value) {
        let body = if body.is_null() {
            String::new()
        } else {
            body.to_string()
        };
        let headers = ["Host: 127.0.0.1", "Content-Type: application/json"];
        let r = http::request(self.addr, method, path, &headers, body.as_bytes());
        (r.status, r.json())
    }

    /// Polls `GET path` until its answer is 200 and `done` holds of it; panics with the last
    /// answer and Node-RED's log.
    fn wait_for(&self, path: &str, what: &str, done: impl Fn(&Value) -> bool) -> Value {
        let end = Instant::now() + WITHIN;
        loop {
            let (status, body) = self.call("GET", path, &Value::Null);
            if status == 200 && done(&body) {
                return body;
            }
            assert!(
                Instant::now() < end,
                "{what}: GET {path} still answers {status} {body}\nNode-RED's log:\n{}",
                self.log()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// `POST path` with `body`, and the PLC's reply to it as `/cetratus/replies` shows it.
    fn command(&self, path: &str, body: Value) -> Value {
        let (status, sent) = self.call("POST", path, &body);
        assert_eq!(status, 202, "POST {path}: {sent}\n{}", self.log());
        let correlation = sent["correlation"].clone();
        let is_it = |r: &Value| r["correlation"] == correlation;
        let replies = self.wait_for("/cetratus/replies", &format!("the reply to {path}"), |r| {
            r["recent"].as_array().is_some_and(|a| a.iter().any(is_it))
        });
        let recent = replies["recent"].as_array().cloned().unwrap_or_default();
        recent.into_iter().find(is_it).unwrap_or_default()
    }

    fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }
}

/// Whether `/cetratus/events` holds an event of `kind`.
fn has_event(events: &Value, kind: &str) -> bool {
    events["events"]
        .as_array()
        .is_some_and(|a| a.iter().any(|e| e["kind"] == kind))
}

/// Publishes what is not a state, an event or a reply, and checks that the flow dropped and
/// counted each, and kept the fleet as it was.
fn bad_payloads_are_dropped(broker: u16, flow: &Flow) {
    mqtt::publish(broker, "cetratus/junk/state", b"not json");
    mqtt::publish(broker, "cetratus/junk2/state", br#"{"online": "yes"}"#);
    mqtt::publish(broker, &format!("cetratus/{PLC}/events"), b"[1, 2]");
    mqtt::publish(
        broker,
        &format!("cetratus/{PLC}/reply/nodered"),
        br#"{"ok": 1}"#,
    );
    let at_least = |n: u64| move |v: &Value| v["dropped"].as_u64().is_some_and(|d| d >= n);
    let fleet = flow.wait_for("/cetratus/fleet", "two bad states dropped", at_least(2));
    flow.wait_for("/cetratus/events", "a bad event dropped", at_least(1));
    flow.wait_for("/cetratus/replies", "a bad reply dropped", at_least(1));
    let ids: Vec<&str> = fleet["plcs"]
        .as_array()
        .map(|a| a.iter().filter_map(|p| p["id"].as_str()).collect())
        .unwrap_or_default();
    assert_eq!(ids, [PLC], "{fleet}");
}

#[test]
fn the_node_red_flow_shows_the_plc_and_loads_and_removes_an_update() {
    let root = tempfile::tempdir().unwrap();
    let packages = root.path().join("packages");
    let trusted = root.path().join("trusted");
    std::fs::create_dir_all(&packages).unwrap();
    let manifest = example("vernadat/u1.package.toml");
    signed_package(BIN, &manifest, "u1", &packages, &trusted);
    let broker = Mosquitto::start();
    let _plc = plc(root.path(), broker.port(), &trusted);
    let flow = Flow::start(root.path(), broker.port(), &packages);

    let plc = flow.wait_for("/cetratus/plc", "the PLC online", |p| p["online"] == true);
    assert_eq!(plc["primary"], "A", "{plc}");
    assert_eq!(plc["status"], "idle", "{plc}");
    assert_eq!(plc["programs"]["A"]["name"], "vernadat-cell", "{plc}");
    assert!(plc["programs"]["B"].is_null(), "{plc}");
    let fleet = flow.wait_for("/cetratus/fleet", "the fleet", |f| {
        f["plcs"][0]["id"] == PLC
    });
    let entry = &fleet["plcs"][0];
    assert_eq!(entry["online"], true, "{fleet}");
    assert_eq!(entry["primary"], "A", "{fleet}");
    assert_eq!(entry["status"], "idle", "{fleet}");
    assert_eq!(entry["labels"], json!({"line": "1"}), "{fleet}");
    assert_eq!(
        entry["program"],
        json!({"name": "vernadat-cell", "version": "1.0.0"}),
        "{fleet}"
    );

    bad_payloads_are_dropped(broker.port(), &flow);

    let (status, refused) = flow.call("POST", "/cetratus/load", &json!({"package": "/etc/passwd"}));
    assert_eq!(status, 403, "{refused}");

    let reply = flow.command("/cetratus/load", json!({"package": "u1.cpkg"}));
    assert_eq!(reply["ok"], true, "{reply}");
    assert_eq!(reply["verb"], "load", "{reply}");
    let plc = flow.wait_for("/cetratus/plc", "quarantine", |p| {
        p["status"] == "quarantine"
    });
    assert_eq!(plc["programs"]["B"]["version"], "1.1.0", "{plc}");

    let reply = flow.command("/cetratus/remove", json!({}));
    assert_eq!(reply["ok"], true, "{reply}");
    assert_eq!(reply["verb"], "remove", "{reply}");
    flow.wait_for("/cetratus/plc", "idle again", |p| {
        p["status"] == "idle" && p["programs"]["B"].is_null()
    });
    flow.wait_for("/cetratus/events", "the update's events", |e| {
        has_event(e, "quarantine_started") && has_event(e, "removed")
    });
}
