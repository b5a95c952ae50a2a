//! Attacks on the control plane, replayed against the real binary on a real broker: a signed
//! command replayed to another PLC, an old-style envelope, arguments smuggled beside the
//! signature, a retained command, a reply sent elsewhere, and a local configuration that would
//! silently turn authentication off.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use cetratus_mct::{sign, Signed};
use cetratus_testkit::mqtt::{self, Mosquitto, Sub};
use cetratus_testkit::ports::free_port;
use cetratus_testkit::process::{stderr_lines, ChildGuard};
use serde_json::{json, Value};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn path(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/vernadat/vernadat.toml")
}

/// A configuration directory with one operator key; returns it and the key file.
fn operator_config(dir: &Path) -> (PathBuf, PathBuf) {
    let cfg = dir.join("config");
    std::fs::create_dir_all(cfg.join("operators")).expect("mkdir");
    let key = dir.join("alice.key");
    let out = Command::new(BIN)
        .args(["package", "keygen", "--out", path(&key)])
        .output()
        .expect("keygen");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::copy(dir.join("alice.key.pub"), cfg.join("operators/alice.pub")).expect("copy");
    (cfg, key)
}

/// A PLC in real time on `broker`, its stderr lines sent to the returned channel.
fn plc(id: &str, broker: &str, cfg: &Path, state: &Path) -> (ChildGuard, mpsc::Receiver<String>) {
    let mut child = Command::new(BIN)
        .arg("run")
        .arg(example())
        .args([
            "--twin",
            "vernadat",
            "--for",
            "1h",
            "--plc",
            id,
            "--no-dashboard",
        ])
        .args([
            "--broker",
            broker,
            "--config",
            path(cfg),
            "--state-dir",
            path(state),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the PLC starts");
    let rx = stderr_lines(&mut child);
    (ChildGuard::new(child), rx)
}

/// Waits until the PLC's retained state is on the broker; on failure, says what the PLC said.
fn wait_online(port: u16, id: &str, stderr: &mpsc::Receiver<String>) {
    let state = mqtt::sub_one(port, &format!("cetratus/{id}/state"), 20, false);
    if !state.is_some_and(|s| s["online"] == true) {
        let said: Vec<String> = stderr.try_iter().collect();
        panic!(
            "PLC {id} did not come online; it said:\n{}",
            said.join("\n")
        );
    }
}

fn envelope(
    plc: &str,
    verb: &str,
    correlation: &Value,
    body: &[u8],
    key: &Path,
    nonce: &str,
) -> Value {
    let k = cetratus_program::KeyPair::load(key).expect("the operator key loads");
    let corr = correlation.to_string();
    let signed = Signed {
        plc,
        verb,
        correlation: corr.as_bytes(),
        timestamp: cetratus_mct::unix_now(),
        nonce,
        account: None,
    };
    serde_json::to_value(sign(&signed, body, &k.key_id(), k.signing_key())).expect("JSON")
}

#[test]
fn a_signed_command_replays_to_no_other_plc_and_old_or_padded_envelopes_are_refused() {
    if !mqtt::installed() {
        panic!("mosquitto is missing: ./scripts/test installs it");
    }
    let broker = Mosquitto::start();
    let url = format!("mqtt://127.0.0.1:{}", broker.port());
    let work = tempfile::tempdir().expect("temp dir");
    let (cfg, key) = operator_config(work.path());
    let (_a, a_err) = plc("cellA", &url, &cfg, &work.path().join("a"));
    let (_b, b_err) = plc("cellB", &url, &cfg, &work.path().join("b"));
    wait_online(broker.port(), "cellA", &a_err);
    wait_online(broker.port(), "cellB", &b_err);

    let corr = json!("c-1");
    let env = envelope("cellA", "exec_info", &corr, b"{}", &key, "nonce-replay-1");
    let cmd = json!({"envelope": env, "correlation": corr});
    let ok = mqtt::request_v311(
        broker.port(),
        "cetratus/cellA/cmd/exec_info",
        cmd.clone(),
        "cetratus/cellA/reply/t1",
    );
    assert_eq!(ok["ok"], true, "{ok}");
    // The same signed command, captured and sent to the other PLC inside the window.
    let replay = mqtt::request_v311(
        broker.port(),
        "cetratus/cellB/cmd/exec_info",
        cmd,
        "cetratus/cellB/reply/t1",
    );
    assert_eq!(replay["ok"], false, "{replay}");
    assert_eq!(replay["error"]["code"], "unauthorised", "{replay}");

    // A version-1 envelope: refused, and told to upgrade.
    let mut v1 = envelope("cellA", "exec_info", &corr, b"{}", &key, "nonce-v1-0001");
    v1.as_object_mut().expect("object").remove("v");
    let old = mqtt::request_v311(
        broker.port(),
        "cetratus/cellA/cmd/exec_info",
        json!({"envelope": v1, "correlation": corr}),
        "cetratus/cellA/reply/t2",
    );
    assert_eq!(old["error"]["code"], "unauthorised", "{old}");
    assert!(
        old["error"]["message"]
            .as_str()
            .is_some_and(|m| m.contains("upgrade")),
        "{old}"
    );

    // Arguments beside a valid signature would go unchecked: refused.
    let env = envelope("cellA", "substitute", &corr, b"{}", &key, "nonce-pad-0001");
    let padded = mqtt::request_v311(
        broker.port(),
        "cetratus/cellA/cmd/substitute",
        json!({"envelope": env, "correlation": corr, "mode": "keep", "force": true}),
        "cetratus/cellA/reply/t3",
    );
    assert_eq!(padded["error"]["code"], "not_allowed", "{padded}");
}

#[test]
fn a_retained_command_is_never_executed_and_a_foreign_reply_topic_gets_nothing() {
    if !mqtt::installed() {
        panic!("mosquitto is missing: ./scripts/test installs it");
    }
    let broker = Mosquitto::start();
    let port = broker.port();
    let url = format!("mqtt://127.0.0.1:{port}");
    let work = tempfile::tempdir().expect("temp dir");
    let cfg = work.path().join("config");
    std::fs::create_dir_all(&cfg).expect("mkdir");

    // Left on the broker before the PLC starts: it would run at every start and reconnect.
    let retained = json!({"reply_to": "cetratus/cellR/reply/retained"}).to_string();
    let out = Command::new(mqtt::tool("mosquitto_pub"))
        .args(["-h", "127.0.0.1", "-p", &port.to_string(), "-r", "-q", "1"])
        .args(["-t", "cetratus/cellR/cmd/exec_info", "-m", &retained])
        .output()
        .expect("mosquitto_pub");
    assert!(out.status.success());
    let replies = Sub::start(port, &["cetratus/cellR/reply/retained"], 1, 8);
    let (_plc, stderr) = plc("cellR", &url, &cfg, &work.path().join("r"));
    wait_online(port, "cellR", &stderr);
    assert!(
        replies.messages().is_empty(),
        "a retained command was executed"
    );
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    let mut warned = false;
    while let Some(left) = deadline.checked_duration_since(std::time::Instant::now()) {
        match stderr.recv_timeout(left) {
            Ok(l) if l.contains("retained command was ignored") => {
                warned = true;
                break;
            }
            Ok(_) => {}
            Err(_) => break,
        }
    }
    assert!(warned, "the PLC says it ignored the retained command");

    // A reply topic outside the PLC's own reply level: nothing is published there, and the
    // command is rejected with an event.
    let elsewhere = Sub::start(port, &["cetratus/victim/#", "ops/#"], 1, 5);
    let events = Sub::start(port, &["cetratus/cellR/events"], 1, 10);
    mqtt::publish(
        port,
        "cetratus/cellR/cmd/exec_info",
        json!({"reply_to": "cetratus/victim/state"})
            .to_string()
            .as_bytes(),
    );
    let ev = events.messages();
    assert!(
        ev.iter()
            .any(|e| e["kind"] == "command_rejected" && e["detail"]["code"] == "not_allowed"),
        "{ev:?}"
    );
    assert!(
        elsewhere.messages().is_empty(),
        "the PLC published outside its topics"
    );
}

#[test]
fn a_configuration_that_would_turn_authentication_off_or_that_others_can_write_stops_the_start() {
    let work = tempfile::tempdir().expect("temp dir");
    let run = |cfg: &Path| {
        let port = free_port();
        Command::new(BIN)
            .arg("run")
            .arg(example())
            .args(["--twin", "vernadat", "--virtual", "--for", "1s"])
            .args([
                "--mqtt",
                &format!("127.0.0.1:{port}"),
                "--config",
                path(cfg),
            ])
            .output()
            .expect("run")
    };
    // `operators` is a file: with it read as "no keys", every unsigned command would pass.
    let cfg = work.path().join("file");
    std::fs::create_dir_all(&cfg).expect("mkdir");
    std::fs::write(cfg.join("operators"), "alice").expect("write");
    let out = run(&cfg);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("operators") && err.contains("not a directory"),
        "{err}"
    );

    // A configuration directory anyone may write: anyone could trust their own keys.
    use std::os::unix::fs::PermissionsExt;
    let cfg = work.path().join("open");
    std::fs::create_dir_all(&cfg).expect("mkdir");
    std::fs::set_permissions(&cfg, std::fs::Permissions::from_mode(0o777)).expect("chmod");
    let out = run(&cfg);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("writable by others") && err.contains("chmod go-w"),
        "{err}"
    );
}

#[test]
fn allow_unsigned_in_the_local_configuration_reaches_a_load_over_mqtt() {
    let work = tempfile::tempdir().expect("temp dir");
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/vernadat");
    let pkg = work.path().join("u1-unsigned.cpkg");
    let out = Command::new(BIN)
        .args(["package", "build", "--unsigned", "-o", path(&pkg)])
        .arg(examples.join("u1.package.toml"))
        .output()
        .expect("package build");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cfg = work.path().join("config");
    std::fs::create_dir_all(&cfg).expect("mkdir");
    std::fs::write(cfg.join("config.toml"), "allow_unsigned = true\n").expect("write");
    let port = free_port();
    let mqtt_addr = format!("127.0.0.1:{port}");
    let _plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(example())
            .args([
                "--twin",
                "vernadat",
                "--for",
                "1h",
                "--plc",
                "unsig",
                "--no-dashboard",
            ])
            .args(["--mqtt", &mqtt_addr, "--config", path(&cfg)])
            .arg("--state-dir")
            .arg(work.path().join("state"))
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    cetratus_testkit::ports::wait_for_port(port, "the PLC's broker", Duration::from_secs(20));
    wait_online(port, "unsig", &mpsc::channel().1);
    let out = Command::new(BIN)
        .args(["load", path(&pkg), "--plc", "unsig", "--mqtt", &mqtt_addr])
        .output()
        .expect("load");
    assert!(
        out.status.success(),
        "the configuration accepts unsigned packages, so MQTT does too: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}
