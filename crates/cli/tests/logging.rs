//! The libraries' diagnostics reach stderr: `cetratus` installs a subscriber, so a dashboard that
//! cannot reach or loses its broker says so, without `RUST_LOG` being set.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpListener;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// A child process killed when the test ends, pass or fail.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `cetratus dashboard` watching `broker` and waits up to ten seconds for a stderr line that
/// contains `needle`; returns that line, or panics with all the stderr seen.
fn mct_stderr_line(broker: &str, needle: &str) -> String {
    let mut child = Command::new(BIN)
        .args(["dashboard", "--broker", broker, "--http", "127.0.0.1:0"])
        // The default filter is what an operator gets.
        .env_remove("RUST_LOG")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start cetratus dashboard");
    let stderr = child.stderr.take().expect("stderr is piped");
    let proc = Proc(child);
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let end = Instant::now() + Duration::from_secs(10);
    let mut seen = Vec::new();
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        match rx.recv_timeout(left) {
            Ok(line) if line.contains(needle) => return line,
            Ok(line) => seen.push(line),
            Err(_) => break,
        }
    }
    drop(proc);
    panic!(
        "no `{needle}` on stderr within 10 s; stderr was:\n{}",
        seen.join("\n")
    );
}

#[test]
fn mct_whose_broker_does_not_exist_warns_on_stderr() {
    // Nothing listens on port 1 of the loopback, and only root could make something.
    let line = mct_stderr_line("mqtt://127.0.0.1:1", "dashboard cannot reach the broker");
    assert!(line.contains("WARN"), "{line}");
    assert!(line.contains("broker=mqtt://127.0.0.1:1"), "{line}");
}

#[test]
fn mct_whose_broker_hangs_up_warns_that_it_lost_the_broker() {
    // A broker that lets one client connect (an MQTT 5 CONNACK: no session, success, no
    // properties), then closes the connection and stops listening.
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind a free port");
    let port = listener.local_addr().expect("local address").port();
    std::thread::spawn(move || {
        let Ok((mut client, _)) = listener.accept() else {
            return;
        };
        let mut connect = [0u8; 512];
        let _ = client.read(&mut connect);
        let _ = client.write_all(&[0x20, 0x03, 0x00, 0x00, 0x00]);
        std::thread::sleep(Duration::from_millis(300));
    });
    let line = mct_stderr_line(
        &format!("mqtt://127.0.0.1:{port}"),
        "dashboard lost the broker",
    );
    assert!(line.contains("WARN"), "{line}");
}
