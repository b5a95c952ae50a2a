//! A flood of wrong dashboard logins against `cetratus dashboard`: refused without a hash once past
//! the rate limit, and logged thinly (the 1st, 2nd, 4th… refusal), so that guessing neither
//! logs in nor floods the operator's log.

use std::process::{Command, Stdio};
use std::time::Duration;

use cetratus_testkit::http;
use cetratus_testkit::mqtt::Mosquitto;
use cetratus_testkit::ports::{self, free_port, wait_for_port};
use cetratus_testkit::process::{login_link, stderr_lines, stdout_lines, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// `cetratus dashboard` on a Mosquitto broker with the account `ops` (password `correct
/// horse`): the process, its address, its log lines, and what must live as long.
fn dashboard_with_ops(
    dir: &std::path::Path,
) -> (
    ChildGuard,
    std::net::SocketAddr,
    std::sync::mpsc::Receiver<String>,
    Mosquitto,
) {
    let mut hash = Command::new(BIN)
        .arg("hash-password")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("cetratus hash-password");
    {
        use std::io::Write;
        let mut stdin = hash.stdin.take().expect("stdin");
        stdin.write_all(b"correct horse\n").expect("the password");
    }
    let out = hash.wait_with_output().expect("the hash");
    let hash = String::from_utf8(out.stdout).expect("UTF-8");
    assert!(hash.starts_with("$argon2id$"), "{hash}");
    let config = dir.join("config");
    std::fs::create_dir(&config).expect("config dir");
    std::fs::write(
        config.join("config.toml"),
        format!(
            "[dashboard]\naccounts = [{{ name = \"ops\", password_hash = \"{}\" }}]\n",
            hash.trim()
        ),
    )
    .expect("config.toml");

    let broker = Mosquitto::start();
    let port = free_port();
    let mut mct = ChildGuard::spawn(
        Command::new(BIN)
            .args(["mct", "--http", &format!("127.0.0.1:{port}")])
            .args(["--broker", &format!("mqtt://127.0.0.1:{}", broker.port())])
            .arg("--config")
            .arg(&config)
            .env_remove("RUST_LOG")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    let stderr = stderr_lines(&mut mct.0);
    let _link = login_link(&stdout_lines(&mut mct.0), Duration::from_secs(30));
    wait_for_port(port, "the dashboard", Duration::from_secs(30));
    let addr = std::net::SocketAddr::from(([127, 0, 0, 1], port));
    (mct, addr, stderr, broker)
}

/// A login as `ops` with `password` from `source`: the HTTP status.
fn login_from(source: [u8; 4], addr: std::net::SocketAddr, password: &str) -> u16 {
    let body = format!("{{\"account\": \"ops\", \"password\": \"{password}\"}}");
    http::exchange(
        ports::connect_from(source.into(), addr),
        "POST",
        "/api/login",
        &[&format!("Host: {addr}"), "Content-Type: application/json"],
        body.as_bytes(),
    )
    .status
}

#[test]
fn three_hundred_wrong_logins_are_refused_and_logged_a_handful_of_times() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (mct, addr, stderr, _broker) = dashboard_with_ops(dir.path());
    let login = |password: &str| login_from([127, 0, 0, 1], addr, password);
    let statuses: Vec<u16> = (0..300).map(|k| login(&format!("guess-{k}"))).collect();
    assert!(
        statuses.iter().all(|s| *s == 401 || *s == 429),
        "{statuses:?}"
    );
    let refused = statuses.iter().filter(|s| **s == 429).count();
    assert!(
        refused > 250,
        "most guesses are refused unchecked: {refused}"
    );
    drop(mct);
    // Every line, up to the end of the killed process's output.
    let lines: Vec<String> = stderr.iter().collect();
    let logged = lines
        .iter()
        .filter(|l| l.contains("too many attempts"))
        .count();
    assert!(
        (1..=12).contains(&logged),
        "{refused} refusals gave {logged} log lines:\n{}",
        lines.join("\n")
    );
}

#[test]
fn guesses_from_forty_addresses_do_not_lock_out_an_operator_who_logged_in_before() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;

    let dir = tempfile::tempdir().expect("temp dir");
    let (_mct, addr, _stderr, _broker) = dashboard_with_ops(dir.path());
    assert_eq!(login_from([127, 0, 0, 1], addr, "correct horse"), 200);

    // Forty other hosts guess, each as fast as its replies come: twenty times the rate for all.
    let stop = Arc::new(AtomicBool::new(false));
    let guessers: Vec<_> = (2..42u8)
        .map(|k| {
            let stop = stop.clone();
            std::thread::spawn(move || {
                let mut n = 0;
                while !stop.load(Ordering::Relaxed) {
                    login_from([127, 0, 0, k], addr, "guess");
                    n += 1;
                }
                n
            })
        })
        .collect();
    std::thread::sleep(Duration::from_secs(2));
    let during = login_from([127, 0, 0, 1], addr, "correct horse");
    stop.store(true, Ordering::Relaxed);
    let guesses: u32 = guessers
        .into_iter()
        .map(|g| g.join().expect("a guesser"))
        .sum();
    assert!(guesses > 100, "the flood guessed {guesses} times");
    assert_eq!(
        during, 200,
        "the operator who logged in before was refused during {guesses} guesses"
    );
}
