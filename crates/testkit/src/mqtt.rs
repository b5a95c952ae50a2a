//! A real Mosquitto broker on a free port, and Mosquitto's own command-line clients as the
//! operator's tools: the other side of the MQTT interoperability tests.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use serde_json::Value;

use crate::ports::{free_port, wait_for_port};
use crate::process::{find_program, require_program, ChildGuard};

/// The Debian package of each Mosquitto program the tests run.
const PACKAGES: [(&str, &str); 4] = [
    ("mosquitto", "mosquitto"),
    ("mosquitto_sub", "mosquitto-clients"),
    ("mosquitto_pub", "mosquitto-clients"),
    ("mosquitto_rr", "mosquitto-clients"),
];

/// `mosquitto_sub` has no "subscribed" signal: a command published sooner than this after it
/// starts may pass before its subscription.
const SUBSCRIBE_DELAY: Duration = Duration::from_millis(500);

/// Where the Mosquitto program `name` (`mosquitto`, `mosquitto_sub`, ...) is installed.
///
/// # Panics
///
/// When it is not, saying which Debian package to install.
pub fn tool(name: &str) -> PathBuf {
    let package = PACKAGES
        .iter()
        .find(|(program, _)| *program == name)
        .map_or("mosquitto-clients", |(_, package)| package);
    require_program(name, package)
}

/// Whether the broker and the clients are all installed.
pub fn installed() -> bool {
    PACKAGES
        .iter()
        .all(|(name, _)| find_program(name).is_some())
}

/// A Mosquitto broker on a free loopback port, anonymous and without persistence; stopped, and
/// its configuration removed, when dropped.
#[derive(Debug)]
pub struct Mosquitto {
    port: u16,
    // Declared before the directory, so the broker stops before its configuration goes.
    _process: ChildGuard,
    _dir: tempfile::TempDir,
}

impl Mosquitto {
    /// Starts a broker and waits until it accepts connections.
    ///
    /// # Panics
    ///
    /// When Mosquitto is not installed (saying what to install) or does not start.
    pub fn start() -> Self {
        Self::start_with("allow_anonymous true\npersistence false\n")
    }

    /// Starts a broker with the configuration lines `settings` (which must not name a
    /// listener) on a free loopback port, and waits until it accepts connections.
    ///
    /// # Panics
    ///
    /// As [`Mosquitto::start`].
    pub fn start_with(settings: &str) -> Self {
        let bin = tool("mosquitto");
        let port = free_port();
        let dir = tempfile::tempdir().expect("a temporary directory for mosquitto.conf");
        let conf = dir.path().join("mosquitto.conf");
        std::fs::write(&conf, format!("listener {port} 127.0.0.1\n{settings}"))
            .expect("mosquitto.conf is written");
        let process = ChildGuard::spawn(
            Command::new(bin)
                .arg("-c")
                .arg(&conf)
                .stdout(Stdio::null())
                .stderr(Stdio::null()),
        );
        wait_for_port(port, "mosquitto", Duration::from_secs(10));
        Mosquitto {
            port,
            _process: process,
            _dir: dir,
        }
    }

    /// The port it listens on, on 127.0.0.1.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], self.port))
    }
}

/// A `mosquitto_sub` running in the background until it has received `count` messages or
/// waited its time.
#[derive(Debug)]
pub struct Sub(Child);

impl Sub {
    /// Subscribes to `topics` on 127.0.0.1:`port`, for `count` messages or `wait_secs` seconds,
    /// and returns once the subscription has most likely reached the broker.
    pub fn start(port: u16, topics: &[&str], count: u32, wait_secs: u32) -> Self {
        let child = sub_command(port, topics, count, wait_secs)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("mosquitto_sub starts");
        std::thread::sleep(SUBSCRIBE_DELAY);
        Sub(child)
    }

    /// The messages received, one JSON value each, in order.
    ///
    /// # Panics
    ///
    /// When a message is not JSON.
    pub fn messages(self) -> Vec<Value> {
        let out = self.0.wait_with_output().expect("mosquitto_sub's output");
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
            .collect()
    }
}

fn sub_command(port: u16, topics: &[&str], count: u32, wait_secs: u32) -> Command {
    let mut cmd = Command::new(tool("mosquitto_sub"));
    cmd.args(["-h", "127.0.0.1", "-p", &port.to_string()]);
    for topic in topics {
        cmd.args(["-t", topic]);
    }
    cmd.args(["-C", &count.to_string(), "-W", &wait_secs.to_string()]);
    cmd
}

/// The first message on `topic`, as JSON, within `wait_secs` seconds; with `retained_only`, only
/// a retained one counts.
pub fn sub_one(port: u16, topic: &str, wait_secs: u32, retained_only: bool) -> Option<Value> {
    let mut cmd = sub_command(port, &[topic], 1, wait_secs);
    if retained_only {
        cmd.arg("--retained-only");
    }
    let out = cmd.output().expect("mosquitto_sub runs");
    serde_json::from_slice(&out.stdout).ok()
}

/// Publishes `payload` on `topic` at QoS 1 with `mosquitto_pub`, which reads it from standard
/// input so that a payload of any size fits.
pub fn publish(port: u16, topic: &str, payload: &[u8]) {
    use std::io::Write as _;

    let mut child = Command::new(tool("mosquitto_pub"))
        .args(["-h", "127.0.0.1", "-p", &port.to_string(), "-t", topic])
        .args(["-q", "1", "-s"])
        .stdin(Stdio::piped())
        .spawn()
        .expect("mosquitto_pub starts");
    child
        .stdin
        .take()
        .expect("mosquitto_pub's standard input")
        .write_all(payload)
        .expect("the payload reaches mosquitto_pub");
    let status = child.wait().expect("mosquitto_pub ends");
    assert!(
        status.success(),
        "mosquitto_pub failed on {topic}: {status}"
    );
}

/// An MQTT 3.1.1 command with a reply: sets `reply_to` in `payload` (docs/mqtt.md), publishes it
/// on `topic` and returns the reply, waiting up to 15 s.
///
/// # Panics
///
/// When no JSON reply comes.
pub fn request_v311(port: u16, topic: &str, mut payload: Value, reply_topic: &str) -> Value {
    payload["reply_to"] = Value::String(reply_topic.to_string());
    let sub = Sub::start(port, &[reply_topic], 1, 15);
    publish(port, topic, payload.to_string().as_bytes());
    sub.messages()
        .into_iter()
        .next()
        .unwrap_or_else(|| panic!("no reply to {topic} on {reply_topic} within 15 s"))
}
