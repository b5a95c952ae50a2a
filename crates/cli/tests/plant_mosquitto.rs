//! A PLC behind a plant Mosquitto, configured as docs/security.md says: the example
//! configuration and ACL of docs/examples/mosquitto, run as they are (on a free loopback port,
//! without their TLS lines), with the real broker, the real PLC and the real CLI.
//!
//! * the PLC logs in as its PLC id and publishes its state;
//! * an operator account commands it;
//! * an account the ACL does not name gets no answer from it;
//! * neither the operator nor an intruder can overwrite its retained state.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::mqtt::{tool, Mosquitto};
use cetratus_testkit::paths::example;
use cetratus_testkit::process::ChildGuard;
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");
const PLC: &str = "cell1";

fn docs_example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../docs/examples/mosquitto")
        .join(name)
}

/// The example configuration with its files in `dir` and without its listener and TLS lines
/// (the test broker adds a loopback listener of its own).
fn example_settings(dir: &Path) -> String {
    let conf = std::fs::read_to_string(docs_example("mosquitto.conf")).expect("the example conf");
    let acl = dir.join("cetratus.acl");
    std::fs::copy(docs_example("cetratus.acl"), &acl).expect("the example ACL");
    let mut out = String::new();
    for line in conf.lines() {
        let key = line.split_whitespace().next().unwrap_or("");
        let line = match key {
            "listener" | "certfile" | "keyfile" => continue,
            "password_file" => format!("password_file {}", dir.join("passwd").display()),
            "acl_file" => format!("acl_file {}", acl.display()),
            "persistence_location" => format!("persistence_location {}/", dir.display()),
            _ => line.to_string(),
        };
        out.push_str(&line);
        out.push('\n');
    }
    assert!(out.contains("allow_anonymous false"), "{out}");
    out
}

/// Adds an account to the Mosquitto password file `passwd`.
fn add_account(passwd: &Path, user: &str, password: &str) {
    let mut cmd = Command::new(tool("mosquitto_passwd"));
    if !passwd.exists() {
        cmd.arg("-c");
    }
    let out = cmd
        .args(["-b"])
        .arg(passwd)
        .args([user, password])
        .output()
        .expect("mosquitto_passwd runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn exec_info(broker: &str, user: &str, password: &str, timeout: &str) -> Output {
    Command::new(BIN)
        .args(["exec-info", "--json", "--plc", PLC, "--broker", broker])
        .args(["--user", user, "--password", password, "--timeout", timeout])
        .output()
        .expect("cetratus exec-info runs")
}

/// The retained state of the PLC as `user` reads it.
fn retained_state(port: u16, user: &str, password: &str) -> Value {
    let out = Command::new(tool("mosquitto_sub"))
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &port.to_string(),
            "-u",
            user,
            "-P",
            password,
        ])
        .args([
            "-t",
            &format!("cetratus/{PLC}/state"),
            "-C",
            "1",
            "-W",
            "10",
        ])
        .output()
        .expect("mosquitto_sub runs");
    serde_json::from_slice(&out.stdout).unwrap_or(Value::Null)
}

/// Publishes a retained `{"online": false}` as `user`, at QoS 1 so that the broker has
/// decided before this returns.
fn forge_state(port: u16, user: &str, password: &str) {
    let _ = Command::new(tool("mosquitto_pub"))
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &port.to_string(),
            "-u",
            user,
            "-P",
            password,
        ])
        .args(["-t", &format!("cetratus/{PLC}/state"), "-q", "1", "-r"])
        .args(["-m", r#"{"online":false}"#])
        .output()
        .expect("mosquitto_pub runs");
}

#[test]
fn a_plc_behind_the_example_mosquitto_answers_its_operator_only_and_keeps_its_state() {
    let dir = tempfile::tempdir().expect("temp dir");
    let passwd = dir.path().join("passwd");
    add_account(&passwd, PLC, "plc-secret");
    add_account(&passwd, "ops", "ops-secret");
    add_account(&passwd, "intruder", "intruder-secret");
    let broker = Mosquitto::start_with(&example_settings(dir.path()));
    let url = format!("mqtt://127.0.0.1:{}", broker.port());

    let config = dir.path().join("config");
    std::fs::create_dir(&config).expect("config dir");
    std::fs::write(
        config.join("config.toml"),
        format!("[mqtt]\nuser = \"{PLC}\"\npassword = \"plc-secret\"\n"),
    )
    .expect("config.toml");
    let _plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(example("vernadat/vernadat.toml"))
            .args(["--twin", "vernadat", "--for", "10min", "--plc", PLC])
            .args(["--broker", &url, "--no-dashboard", "--cold"])
            .arg("--config")
            .arg(&config)
            .arg("--state-dir")
            .arg(dir.path().join("state"))
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );

    // The operator gets an answer once the PLC is connected.
    let end = Instant::now() + Duration::from_secs(60);
    let answer = loop {
        let out = exec_info(&url, "ops", "ops-secret", "3s");
        if out.status.success() {
            break String::from_utf8_lossy(&out.stdout).into_owned();
        }
        assert!(
            Instant::now() < end,
            "the operator got no answer: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        std::thread::sleep(Duration::from_millis(500));
    };
    assert!(answer.contains("cycles"), "{answer}");
    let state = retained_state(broker.port(), "ops", "ops-secret");
    assert_eq!(
        state["online"], true,
        "the PLC publishes its state: {state}"
    );

    // An account the ACL does not name may neither command nor read the reply.
    let out = exec_info(&url, "intruder", "intruder-secret", "3s");
    assert!(
        !out.status.success(),
        "an account the ACL does not name got an answer: {}",
        String::from_utf8_lossy(&out.stdout)
    );

    // Nobody but the PLC overwrites its retained state: not the intruder, not the operator.
    forge_state(broker.port(), "intruder", "intruder-secret");
    forge_state(broker.port(), "ops", "ops-secret");
    let state = retained_state(broker.port(), "ops", "ops-secret");
    assert_eq!(
        state["online"], true,
        "a forged state replaced the PLC's: {state}"
    );
}
