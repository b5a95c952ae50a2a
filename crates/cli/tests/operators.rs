//! Operator keys: with keys in the local configuration, every MQTT command must be a signed
//! envelope; an unsigned one is refused, a signed one is carried out, and the audit log records
//! which key gave it.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{login_link, stdout_lines, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// The tests of this file run one at a time: the auto-substitution's quarantine is compared with
/// the twin's fork at ten times the wall clock, and a PLC that a second test's processes slow
/// down falls behind its plant, so that it meets divergences the fork never shows
/// (docs/live-update.md, *The twin against the quarantine*).
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn cetratus(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().expect("run cetratus")
}

fn path(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

#[test]
fn with_operator_keys_only_signed_commands_are_carried_out_and_the_audit_log_names_the_key() {
    let _alone = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let work = tempfile::tempdir().expect("temp dir");
    let pk = work.path().join("pk");
    let out = cetratus(&["demo", "--scripted", "--json", "--dir", path(&pk)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // The local configuration: the demo's package key is trusted, one operator key; both named
    // in capitals, which a key file's extension may be (`OP.PUB` was once silently ignored).
    let cfg = work.path().join("config");
    std::fs::create_dir_all(cfg.join("trusted")).expect("mkdir");
    std::fs::create_dir_all(cfg.join("operators")).expect("mkdir");
    std::fs::copy(pk.join("trusted/demo.pub"), cfg.join("trusted/DEMO.PUB")).expect("copy");
    let key = work.path().join("alice.key");
    let out = cetratus(&["package", "keygen", "--out", path(&key)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::copy(
        work.path().join("alice.key.pub"),
        cfg.join("operators/ALICE.PUB"),
    )
    .expect("copy");
    let key_id = std::fs::read_to_string(work.path().join("alice.key.pub"))
        .expect("pub")
        .lines()
        .find_map(|l| {
            l.strip_prefix("key-id")
                .map(|r| r.trim_start_matches([':', ' ', '=']).trim().to_string())
        })
        .expect("a key-id line");

    let port = free_port();
    let state = work.path().join("state");
    let mqtt = format!("127.0.0.1:{port}");
    let _plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(pk.join("vernadat.toml"))
            .args([
                "--twin",
                "vernadat",
                "--speed",
                "10",
                "--for",
                "1h",
                "--plc",
                "ops1",
                "--http",
                "127.0.0.1:0",
            ])
            .args([
                "--mqtt",
                &mqtt,
                "--config",
                path(&cfg),
                "--state-dir",
                path(&state),
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    wait_for_port(port, "the PLC's embedded broker", Duration::from_secs(20));
    let client = |extra: &[&str]| {
        let mut a = vec!["--plc", "ops1", "--mqtt", &mqtt];
        a.extend_from_slice(extra);
        a.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    };

    // Unsigned: refused, whatever the verb.
    let mut args = vec!["exec-info".to_string()];
    args.extend(client(&[]));
    let out = Command::new(BIN).args(&args).output().expect("exec-info");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unauthorised") || err.contains("signed"),
        "{err}"
    );

    // Signed: carried out.
    let mut args = vec!["load".to_string(), path(&pk.join("u1.cpkg")).to_string()];
    args.extend(client(&["--key", path(&key)]));
    let out = Command::new(BIN).args(&args).output().expect("load");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // The dashboard signs the page's commands with its own operator key; without one the PLC
    // refuses them.
    let ask_dashboard = |key: Option<&Path>, verb: &str| -> String {
        let http = free_port();
        let mut cmd = Command::new(BIN);
        cmd.args([
            "dashboard",
            "--http",
            &format!("127.0.0.1:{http}"),
            "--broker",
            &format!("mqtt://{mqtt}"),
        ]);
        if let Some(k) = key {
            cmd.args(["--key", path(k)]);
        }
        let mut dashboard = ChildGuard::spawn(cmd.stdout(Stdio::piped()).stderr(Stdio::null()));
        let cookie = cetratus_testkit::http::login(&login_link(
            &stdout_lines(&mut dashboard.0),
            Duration::from_secs(20),
        ));
        let addr = std::net::SocketAddr::from(([127, 0, 0, 1], http));
        let end = Instant::now() + Duration::from_secs(20);
        let mut reply = String::new();
        while Instant::now() < end {
            let r = cetratus_testkit::http::request(
                addr,
                "POST",
                &format!("/api/ops1/{verb}"),
                &[
                    &format!("Host: {addr}"),
                    "Content-Type: application/json",
                    &cookie,
                ],
                b"{}",
            );
            reply = format!("{}\r\n\r\n{}", r.head, r.body);
            // 503 while the dashboard is still connecting to the broker.
            if r.status != 503 && r.status != 0 {
                break;
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        reply
    };
    let signed = ask_dashboard(Some(&key), "exec_info");
    assert!(signed.contains("\"ok\":true"), "{signed}");
    let unsigned = ask_dashboard(None, "exec_info");
    assert!(unsigned.contains("unauthorised"), "{unsigned}");

    // The audit log says who: the operator's key id.
    let end = Instant::now() + Duration::from_secs(10);
    let mut audit = String::new();
    while Instant::now() < end {
        audit = std::fs::read_to_string(state.join("audit.jsonl")).unwrap_or_default();
        if audit.contains("load_accepted") {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let line = audit
        .lines()
        .find(|l| l.contains("load_accepted"))
        .unwrap_or_else(|| panic!("no load_accepted in the audit log:\n{audit}"));
    assert!(line.contains(&format!("mqtt:{key_id}")), "{line}");

    // A command from the page names the key and the session's account (`local`: a login link).
    let aborted = ask_dashboard(Some(&key), "abort");
    assert!(aborted.contains("\"ok\":true"), "{aborted}");
    let end = Instant::now() + Duration::from_secs(10);
    while Instant::now() < end {
        audit = std::fs::read_to_string(state.join("audit.jsonl")).unwrap_or_default();
        if audit.contains("\"aborted\"") {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let line = audit
        .lines()
        .find(|l| l.contains("\"aborted\""))
        .unwrap_or_else(|| panic!("no aborted in the audit log:\n{audit}"));
    assert!(line.contains(&format!("\"mqtt:{key_id}/local\"")), "{line}");
}

/// A new operator key: its secret file and its key id.
fn operator_key(dir: &Path, name: &str, cfg: &Path) -> (std::path::PathBuf, String) {
    let key = dir.join(format!("{name}.key"));
    let out = cetratus(&["package", "keygen", "--out", path(&key)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let public = dir.join(format!("{name}.key.pub"));
    std::fs::copy(&public, cfg.join(format!("operators/{name}.pub"))).expect("copy");
    let id = std::fs::read_to_string(&public)
        .expect("pub")
        .lines()
        .find_map(|l| {
            l.strip_prefix("key-id")
                .map(|r| r.trim_start_matches([':', ' ', '=']).trim().to_string())
        })
        .expect("a key-id line");
    (key, id)
}

/// The PLC runs in real time, so each load is forked at a moment the test does not choose: over
/// two minutes of plant time U.1's verdict passes from any cycle of the cell
/// (`cetratus-node`'s `u1_forked_at_any_cycle_passes_over_two_minutes_of_plant_time`).
#[test]
fn auto_substitute_on_pass_substitutes_only_loads_signed_by_an_allowed_operator_key() {
    let _alone = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let work = tempfile::tempdir().expect("temp dir");
    let pk = work.path().join("pk");
    let out = cetratus(&["demo", "--scripted", "--json", "--dir", path(&pk)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cfg = work.path().join("config");
    std::fs::create_dir_all(cfg.join("trusted")).expect("mkdir");
    std::fs::create_dir_all(cfg.join("operators")).expect("mkdir");
    std::fs::copy(pk.join("trusted/demo.pub"), cfg.join("trusted/demo.pub")).expect("copy");
    let (alice, alice_id) = operator_key(work.path(), "alice", &cfg);
    let (bob, _) = operator_key(work.path(), "bob", &cfg);
    std::fs::write(
        cfg.join("config.toml"),
        format!(
            "[updates]\nvalidation = \"fork\"\nhorizon = \"2min\"\nauto_substitute = \"on-pass\"\nauto_substitute_keys = [\"{alice_id}\"]\n"
        ),
    )
    .expect("config.toml");
    let port = free_port();
    let mqtt = format!("127.0.0.1:{port}");
    let _plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(pk.join("vernadat.toml"))
            .args([
                "--twin", "vernadat", "--speed", "10", "--for", "1h", "--plc", "auto1",
            ])
            .args([
                "--http",
                "127.0.0.1:0",
                "--mqtt",
                &mqtt,
                "--config",
                path(&cfg),
            ])
            .arg("--state-dir")
            .arg(work.path().join("state"))
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    wait_for_port(port, "the PLC's embedded broker", Duration::from_secs(20));
    let run = |args: &[&str], key: &Path| {
        Command::new(BIN)
            .args(args)
            .args(["--plc", "auto1", "--mqtt", &mqtt, "--key", path(key)])
            .output()
            .expect("the client")
    };
    let state = || -> serde_json::Value {
        let out = Command::new(BIN)
            .args(["status", "--json", "--plc", "auto1", "--mqtt", &mqtt])
            .output()
            .expect("status");
        serde_json::from_slice(&out.stdout).unwrap_or_default()
    };
    let u1 = pk.join("u1.cpkg");
    let wait_primary = |want: &str, within: Duration| -> serde_json::Value {
        let end = Instant::now() + within;
        loop {
            let s = state();
            if s["primary"] == want || Instant::now() > end {
                return s;
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    };

    // Bob's load passes validation but is not substituted: his key is not allowed.
    let out = run(&["load", path(&u1)], &bob);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = wait_primary("B", Duration::from_secs(6));
    assert_eq!(
        (s["primary"].as_str(), s["status"].as_str()),
        (Some("A"), Some("quarantine")),
        "{s}"
    );
    let info = run(&["exec-info", "--json"], &bob);
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).expect("exec_info");
    let twin = info["result"][1]["verdicts"]
        .as_array()
        .and_then(|v| v.iter().find(|x| x["kind"] == "twin").cloned())
        .unwrap_or_else(|| panic!("a twin verdict: {info}"));
    assert_eq!(twin["result"], "pass", "{twin}");
    assert!(run(&["abort"], &bob).status.success());

    // Alice's: substituted by the PLC itself once the verdict passes.
    let out = run(&["load", path(&u1)], &alice);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = wait_primary("B", Duration::from_secs(120));
    let info = run(&["exec-info", "--json"], &bob);
    assert_eq!(
        s["primary"],
        "B",
        "{s}\n{}",
        String::from_utf8_lossy(&info.stdout)
    );
}
