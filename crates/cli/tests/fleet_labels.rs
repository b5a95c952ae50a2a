//! Labels through the real binary and a real Mosquitto: a PLC publishes the `[labels]` of its
//! local configuration in its retained `state`, a selector picks it by them, a PLC without
//! labels leaves them out, and a `[labels]` section that breaks the rules stops the PLC at
//! start with what is wrong and where.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_proto::{Labels, Selector};
use cetratus_testkit::mqtt::{self, Mosquitto};
use cetratus_testkit::paths::example;
use cetratus_testkit::process::ChildGuard;
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// A local configuration directory with `config` as its `config.toml`.
fn config_dir(root: &Path, name: &str, config: &str) -> std::path::PathBuf {
    let dir = root.join(name);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("config.toml"), config).unwrap();
    dir
}

/// The Vernadat cell on its twin as PLC `plc`, on the broker at `port`.
fn plc(root: &Path, plc: &str, port: u16, config: &Path) -> ChildGuard {
    ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(example("vernadat/vernadat.toml"))
            .args(["--twin", "vernadat", "--speed", "10", "--no-dashboard"])
            .args([
                "--plc",
                plc,
                "--broker",
                &format!("mqtt://127.0.0.1:{port}"),
            ])
            .arg("--config")
            .arg(config)
            .arg("--state-dir")
            .arg(root.join(format!("state-{plc}")))
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    )
}

/// The retained `state` of `plc`, once it is online.
fn online_state(port: u16, plc: &str) -> Value {
    let end = Instant::now() + Duration::from_secs(30);
    while Instant::now() < end {
        if let Some(v) = mqtt::sub_one(port, &format!("cetratus/{plc}/state"), 2, true) {
            if v["online"] == true {
                return v;
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    panic!("{plc} never published an online state");
}

#[test]
fn a_plc_publishes_its_labels_and_a_selector_picks_it_by_them() {
    let broker = Mosquitto::start();
    let root = tempfile::tempdir().unwrap();
    let labelled = config_dir(
        root.path(),
        "press4",
        "[labels]\nline = \"2\"\ncell = \"press-4\"\n",
    );
    let plain = config_dir(root.path(), "plain", "");
    let _a = plc(root.path(), "press4", broker.port(), &labelled);
    let _b = plc(root.path(), "weld1", broker.port(), &plain);
    let a = online_state(broker.port(), "press4");
    let b = online_state(broker.port(), "weld1");
    assert_eq!(
        a["labels"],
        serde_json::json!({"line": "2", "cell": "press-4"})
    );
    assert!(b.get("labels").is_none(), "{b}");
    let labels_of = |v: &Value| -> Labels {
        serde_json::from_value(v.get("labels").cloned().unwrap_or_default()).unwrap_or_default()
    };
    let pick = |sel: &str| -> Vec<&str> {
        let sel: Selector = sel.parse().unwrap();
        [("press4", &a), ("weld1", &b)]
            .into_iter()
            .filter(|(id, v)| sel.matches(id, &labels_of(v)))
            .map(|(id, _)| id)
            .collect()
    };
    assert_eq!(pick("line=2"), ["press4"]);
    assert_eq!(pick("cell=press-*"), ["press4"]);
    assert_eq!(pick("weld*"), ["weld1"]);
    assert_eq!(pick("*"), ["press4", "weld1"]);
    assert!(pick("line=1").is_empty());
}

#[test]
fn labels_that_break_the_rules_stop_the_plc_at_start_saying_why() {
    let root = tempfile::tempdir().unwrap();
    for (name, section, says) in [
        (
            "space",
            "[labels]\n\"bad key\" = \"x\"\n",
            "must start with a letter",
        ),
        ("id", "[labels]\nid = \"x\"\n", "the PLC's id in a selector"),
        ("newline", "[labels]\ncell = \"a\\nb\"\n", "printable text"),
        ("number", "[labels]\nline = 2\n", "invalid type"),
    ] {
        let dir = config_dir(root.path(), name, section);
        let out = Command::new(BIN)
            .arg("run")
            .arg(example("vernadat/vernadat.toml"))
            .args(["--twin", "vernadat", "--virtual", "--for", "1s", "--config"])
            .arg(&dir)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{name}: started");
        assert!(
            err.contains("config.toml") && err.contains(says),
            "{name}: {err}"
        );
    }
}
