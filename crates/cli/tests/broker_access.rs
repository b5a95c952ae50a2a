//! Who may use a PLC's embedded broker, tried against the real binary: accounts with hashed
//! passwords and the PLCs each may command, the dashboard of `run` logged in on its own, and no
//! broker beyond loopback without TLS and accounts (docs/security.md).

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{login_link, stderr_lines, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");
const PROGRAM: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../examples/vernadat/vernadat.toml"
);

fn hash(password: &str) -> String {
    let mut child = Command::new(BIN)
        .arg("hash-password")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("hash-password starts");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(password.as_bytes())
        .expect("writes");
    let out = child.wait_with_output().expect("hash-password ends");
    String::from_utf8(out.stdout)
        .expect("utf-8")
        .trim()
        .to_string()
}

/// A configuration directory, owner-only, holding `config`.
fn config_dir(config: &str) -> tempfile::TempDir {
    use std::os::unix::fs::PermissionsExt;
    let d = tempfile::tempdir().expect("a configuration directory");
    std::fs::set_permissions(d.path(), std::fs::Permissions::from_mode(0o700)).expect("chmod");
    let file = d.path().join("config.toml");
    std::fs::write(&file, config).expect("writes");
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).expect("chmod");
    d
}

fn run(config: &Path, mqtt: &str, http: &str) -> Command {
    let mut c = Command::new(BIN);
    c.args([
        "run", PROGRAM, "--twin", "vernadat", "--plc", "acc1", "--for", "1h",
    ])
    .args(["--mqtt", mqtt, "--http", http, "--config"])
    .arg(config)
    .arg("--state-dir")
    .arg(config.join("state"));
    c
}

/// `cetratus exec-info` for acc1 as `user`.
fn exec_info_as(mqtt: &str, user: &str) -> std::process::Output {
    Command::new(BIN)
        .args([
            "exec-info",
            "--plc",
            "acc1",
            "--mqtt",
            mqtt,
            "--timeout",
            "3s",
        ])
        .args(["--user", user, "--password", "pw"])
        .output()
        .expect("exec-info runs")
}

#[test]
fn with_broker_accounts_only_an_allowed_account_commands_and_the_dashboard_of_run_still_works() {
    let h = hash("pw");
    let cfg = config_dir(&format!(
        "[mqtt]\nusers = [\n  {{ name = \"ops\", password_hash = \"{h}\", plcs = [\"acc1\"] }},\n  \
         {{ name = \"other\", password_hash = \"{h}\", plcs = [\"acc2\"] }},\n]\n"
    ));
    let (port, http) = (free_port(), free_port());
    let mqtt = format!("127.0.0.1:{port}");
    let mut plc = ChildGuard::spawn(
        run(cfg.path(), &mqtt, &format!("127.0.0.1:{http}"))
            .stdout(Stdio::null())
            .stderr(Stdio::piped()),
    );
    let link = login_link(&stderr_lines(&mut plc.0), Duration::from_secs(30));
    wait_for_port(port, "the embedded broker", Duration::from_secs(30));

    // An account of the plant that was not given this PLC cannot command it.
    let out = exec_info_as(&mqtt, "other");
    assert!(
        !out.status.success(),
        "`other` commanded acc1: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    let out = exec_info_as(&mqtt, "ops");
    assert!(
        out.status.success(),
        "`ops` may command acc1: {}",
        String::from_utf8_lossy(&out.stderr)
    );

    // The dashboard beside it logs in to its broker on its own, and commands through it.
    let cookie = cetratus_testkit::http::login(&link);
    let addr = std::net::SocketAddr::from(([127, 0, 0, 1], http));
    let end = Instant::now() + Duration::from_secs(20);
    let mut last = String::new();
    while Instant::now() < end {
        let r = cetratus_testkit::http::request(
            addr,
            "POST",
            "/api/acc1/exec_info",
            &[
                &format!("Host: {addr}"),
                "Content-Type: application/json",
                &cookie,
            ],
            b"{}",
        );
        last = format!("{}\r\n\r\n{}", r.head, r.body);
        if r.status == 200 {
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    assert!(last.contains("\"ok\":true"), "{last}");
}

#[test]
fn a_last_will_is_refused_at_connect_when_its_account_could_not_publish_it() {
    use cetratus_testkit::raw_mqtt::{try_connect, ConnectOptions};
    let h = hash("pw");
    let cfg = config_dir(&format!(
        "[mqtt]\nusers = [\n  {{ name = \"ops\", password_hash = \"{h}\", plcs = [\"acc1\"] }},\n  \
         {{ name = \"viewer\", password_hash = \"{h}\", plcs = [] }},\n]\n"
    ));
    let port = free_port();
    let _plc = ChildGuard::spawn(
        run(cfg.path(), &format!("127.0.0.1:{port}"), "127.0.0.1:0")
            .arg("--no-dashboard")
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    wait_for_port(port, "the embedded broker", Duration::from_secs(30));
    // A read-only account got a package loaded, then substituted, by dropping its connection.
    for (user, topic, code) in [
        ("viewer", "cetratus/acc1/cmd/load", 5),
        ("viewer", "cetratus/acc1/cmd/substitute", 5),
        ("ops", "cetratus/acc1/state", 5),
        ("ops", "cetratus/acc2/cmd/abort", 5),
        ("ops", "cetratus/acc1/cmd/abort", 0),
        ("viewer", "plant/viewer/alive", 0),
    ] {
        let options = ConnectOptions {
            login: Some((user, "pw")),
            will: Some((topic, b"{}", false)),
        };
        let (_s, got) = try_connect(("127.0.0.1", port), "will-test", options);
        assert_eq!(got, code, "{user} with a will on {topic}");
    }
}

#[test]
fn a_broker_beyond_loopback_without_tls_stops_the_start_and_says_what_to_set() {
    let cfg = config_dir("");
    let out = run(
        cfg.path(),
        &format!("0.0.0.0:{}", free_port()),
        "127.0.0.1:0",
    )
    .args(["--no-dashboard"])
    .output()
    .expect("run ends");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("beyond this machine")
            && err.contains("tls_cert")
            && err.contains("[mqtt] users"),
        "{err}"
    );
}

#[test]
fn a_clear_text_broker_password_stops_the_start_and_says_how_to_hash_it() {
    let cfg = config_dir("[mqtt]\nusers = [{ name = \"ops\", password = \"s3cret\" }]\n");
    let out = run(cfg.path(), "127.0.0.1:0", "127.0.0.1:0")
        .output()
        .expect("run ends");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("password_hash") && err.contains("hash-password"),
        "{err}"
    );
}

#[test]
fn wrong_logins_by_the_hundred_do_not_lock_out_an_account_that_logged_in_before() {
    use cetratus_testkit::raw_mqtt::{try_connect, ConnectOptions};
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;

    let h = hash("pw");
    let cfg = config_dir(&format!(
        "[mqtt]\nusers = [{{ name = \"ops\", password_hash = \"{h}\", plcs = [\"acc1\"] }}]\n"
    ));
    let port = free_port();
    let _plc = ChildGuard::spawn(
        run(cfg.path(), &format!("127.0.0.1:{port}"), "127.0.0.1:0")
            .arg("--no-dashboard")
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    wait_for_port(port, "the embedded broker", Duration::from_secs(30));
    let login = |user: &str, password: &str, id: &str| {
        let options = ConnectOptions {
            login: Some((user, password)),
            will: None,
        };
        try_connect(("127.0.0.1", port), id, options).1
    };
    assert_eq!(login("ops", "pw", "ops-1"), 0, "the operator logs in");

    // Guessers on another account, from four connections at once: far past the login rate.
    let stop = Arc::new(AtomicBool::new(false));
    let guessers: Vec<_> = (0..4)
        .map(|k| {
            let stop = stop.clone();
            std::thread::spawn(move || {
                let mut n = 0u32;
                while !stop.load(Ordering::Relaxed) {
                    let options = ConnectOptions {
                        login: Some(("admin", "guess")),
                        will: None,
                    };
                    try_connect(("127.0.0.1", port), &format!("guess-{k}"), options);
                    n += 1;
                }
                n
            })
        })
        .collect();
    std::thread::sleep(Duration::from_secs(2));
    let during = login("ops", "pw", "ops-2");
    stop.store(true, Ordering::Relaxed);
    let guesses: u32 = guessers
        .into_iter()
        .map(|g| g.join().expect("a guesser"))
        .sum();
    assert!(guesses > 40, "the flood guessed {guesses} times");
    assert_eq!(
        during, 0,
        "the account that logged in before was refused during {guesses} guesses"
    );
}
