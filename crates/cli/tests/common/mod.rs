//! What the MQTT tests of the binary share: an MQTT 5 client that sends commands with a response
//! topic and correlation data, and collects the replies.

#![allow(dead_code)]

pub mod raw_mqtt;

use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::ChildGuard;
use rumqttc::v5::mqttbytes::v5::{Packet, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{Client, Event, MqttOptions};
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// `cetratus run` of the Vernadat example in real time, on its embedded broker and with its
/// dashboard, with a state directory and an empty configuration of its own.
pub struct RunningPlc {
    /// The process.
    pub process: ChildGuard,
    /// The embedded broker's port.
    pub mqtt: u16,
    /// The dashboard's port.
    pub http: u16,
    /// The state directory.
    pub state: tempfile::TempDir,
    _config: tempfile::TempDir,
}

impl RunningPlc {
    /// Starts the PLC `plc` with `extra` arguments and waits until its broker and dashboard
    /// listen.
    pub fn start(plc: &str, extra: &[&str]) -> Self {
        Self::spawn(plc, extra, Stdio::null())
    }

    /// As [`RunningPlc::start`], with the lines of the PLC's log (standard error, `RUST_LOG`'s
    /// default level) as they come.
    pub fn start_logged(plc: &str, extra: &[&str]) -> (Self, std::sync::mpsc::Receiver<String>) {
        let mut plc = Self::spawn(plc, extra, Stdio::piped());
        let log = cetratus_testkit::process::stderr_lines(&mut plc.process.0);
        (plc, log)
    }

    fn spawn(plc: &str, extra: &[&str], stderr: Stdio) -> Self {
        let state = tempfile::tempdir().expect("a state directory");
        let config = tempfile::tempdir().expect("an empty configuration directory");
        let (mqtt, http) = (free_port(), free_port());
        let program = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../examples/vernadat/vernadat.toml"
        );
        let process = ChildGuard::spawn(
            Command::new(BIN)
                .args(["run", program, "--twin", "vernadat", "--plc", plc])
                .args(["--mqtt", &format!("127.0.0.1:{mqtt}")])
                .args(["--http", &format!("127.0.0.1:{http}")])
                .arg("--state-dir")
                .arg(state.path())
                .arg("--config")
                .arg(config.path())
                .args(extra)
                .stdout(Stdio::null())
                .stderr(stderr),
        );
        wait_for_port(mqtt, "the embedded broker", Duration::from_secs(30));
        wait_for_port(http, "the embedded dashboard", Duration::from_secs(30));
        RunningPlc {
            process,
            mqtt,
            http,
            state,
            _config: config,
        }
    }
}

/// Where a PLC's replies to this client go: under the PLC's own reply namespace.
pub fn reply_topic(plc: &str) -> String {
    format!("cetratus/{plc}/reply/test-{}", std::process::id())
}

/// The replies seen, by correlation data.
pub type Replies = Arc<Mutex<BTreeMap<Vec<u8>, Value>>>;

/// An MQTT 5 client subscribed to [`reply_topic`], and the replies it receives.
pub fn client(port: u16, id: &str, plc: &str) -> (Client, Replies) {
    let mut opts = MqttOptions::new(id, "127.0.0.1", port);
    opts.set_max_packet_size(Some(8 << 20));
    opts.set_keep_alive(Duration::from_secs(30));
    let (client, mut conn) = Client::new(opts, 64);
    let replies: Replies = Arc::default();
    let subscribed = Arc::new(AtomicBool::new(false));
    let (r, sub) = (replies.clone(), subscribed.clone());
    std::thread::spawn(move || {
        for ev in conn.iter() {
            match ev {
                Ok(Event::Incoming(Packet::SubAck(_))) => sub.store(true, Ordering::Release),
                Ok(Event::Incoming(Packet::Publish(p))) => {
                    let corr = p
                        .properties
                        .and_then(|pr| pr.correlation_data)
                        .map(|c| c.to_vec())
                        .unwrap_or_default();
                    let v = serde_json::from_slice(&p.payload).unwrap_or(Value::Null);
                    r.lock().expect("replies").insert(corr, v);
                }
                Ok(_) => {}
                Err(_) => std::thread::sleep(Duration::from_millis(50)),
            }
        }
    });
    client
        .subscribe(reply_topic(plc), QoS::AtLeastOnce)
        .expect("subscribe to the replies");
    wait_for(
        "the subscription to the replies",
        Duration::from_secs(10),
        || subscribed.load(Ordering::Acquire),
    );
    (client, replies)
}

/// Sends `verb` to `plc` at QoS 0 with a response topic and correlation data `corr`.
pub fn request(client: &Client, plc: &str, verb: &str, corr: &[u8], payload: Vec<u8>) {
    let props = PublishProperties {
        response_topic: Some(reply_topic(plc)),
        correlation_data: Some(corr.to_vec().into()),
        ..PublishProperties::default()
    };
    client
        .publish_with_properties(
            format!("cetratus/{plc}/cmd/{verb}"),
            QoS::AtMostOnce,
            false,
            payload,
            props,
        )
        .expect("the client queues a command");
}

/// Waits until `ok`, or panics saying `what` did not happen.
pub fn wait_for(what: &str, within: Duration, mut ok: impl FnMut() -> bool) {
    let end = Instant::now() + within;
    while Instant::now() < end {
        if ok() {
            return;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    panic!("{what} within {within:?}");
}

/// Waits until the reply with correlation data `corr` is in, and returns it.
pub fn reply(replies: &Replies, corr: &[u8], within: Duration) -> Value {
    poll_reply(replies, corr, within).unwrap_or_else(|| {
        panic!(
            "a reply to `{}` within {within:?}",
            String::from_utf8_lossy(corr)
        )
    })
}

/// The reply with correlation data `corr`, if it comes in within `within`.
pub fn poll_reply(replies: &Replies, corr: &[u8], within: Duration) -> Option<Value> {
    let end = Instant::now() + within;
    loop {
        if let Some(v) = replies.lock().expect("replies").get(corr) {
            return Some(v.clone());
        }
        if Instant::now() >= end {
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Sends `exec_info` to `plc` once a second until it answers (a command sent before the PLC has
/// subscribed is lost), and returns the answer.
pub fn first_answer(client: &Client, replies: &Replies, plc: &str, within: Duration) -> Value {
    let end = Instant::now() + within;
    for k in 0u32.. {
        let corr = format!("hello-{k}").into_bytes();
        request(client, plc, "exec_info", &corr, b"{}".to_vec());
        let until = Instant::now() + Duration::from_secs(1);
        while Instant::now() < until {
            if let Some(v) = replies.lock().expect("replies").get(&corr) {
                return v.clone();
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(
            Instant::now() < end,
            "`{plc}` did not answer within {within:?}"
        );
    }
    Value::Null
}

/// The resident memory of the process `pid`, in kB.
pub fn rss_kb(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
}

/// Samples a process's resident memory every 20 ms; returns the peak when stopped.
pub struct RssSampler {
    stop: Arc<AtomicBool>,
    peak: Arc<AtomicU64>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl RssSampler {
    /// Starts sampling `pid`.
    pub fn start(pid: u32) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let peak = Arc::new(AtomicU64::new(0));
        let (s, p) = (stop.clone(), peak.clone());
        let thread = std::thread::spawn(move || {
            while !s.load(Ordering::Relaxed) {
                if let Some(kb) = rss_kb(pid) {
                    p.fetch_max(kb, Ordering::Relaxed);
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        });
        RssSampler {
            stop,
            peak,
            thread: Some(thread),
        }
    }

    /// Stops sampling; the peak seen, in kB.
    pub fn peak_kb(mut self) -> u64 {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.peak.load(Ordering::Relaxed)
    }
}

/// The camera: publishes `n` images of `size` bytes at `qos`, `per_s` a second, the k-th on
/// `topics[k % topics.len()]`; with `tiny`, each image is followed at once by a message of 64
/// bytes on that topic, at QoS 1, and the image goes to a topic no one reads.
pub fn camera(port: u16, topics: &[String], size: usize, per_s: u32, n: u32, qos: QoS, tiny: bool) {
    let mut opts = MqttOptions::new("camera", "127.0.0.1", port);
    opts.set_max_packet_size(Some(8 << 20));
    opts.set_keep_alive(Duration::from_secs(30));
    let (c, mut conn) = Client::new(opts, 64);
    std::thread::spawn(move || {
        for ev in conn.iter() {
            if ev.is_err() {
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    });
    let image = vec![0xA5u8; size];
    let t0 = Instant::now();
    for k in 0..n {
        let topic = &topics[k as usize % topics.len()];
        if tiny {
            c.publish("plant/unread", qos, false, image.clone())
                .expect("the camera queues an image");
            c.publish(topic, QoS::AtLeastOnce, false, vec![0x5Au8; 64])
                .expect("the camera queues a tiny message");
        } else {
            c.publish(topic, qos, false, image.clone())
                .expect("the camera queues an image");
        }
        let next = t0 + Duration::from_secs(1) * (k + 1) / per_s;
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
    let _ = c.disconnect();
}

/// The primary's cycle count in an `exec_info` reply.
pub fn primary_cycles(v: &Value) -> u64 {
    v["result"][0]["cycles"]
        .as_u64()
        .unwrap_or_else(|| panic!("exec_info names the primary's cycles: {v}"))
}

/// Asks the PLC `plc` for `exec_info` (correlations `corr`, `corr-1`, …) until its primary has
/// run more than `before` cycles, within 30 s: the PLC cycles on and answers an operator. The
/// figures of a reply may be those of the last publication, so a PLC asked at once may answer
/// with the count it answered before.
pub fn assert_cycles_on(ops: &Client, replies: &Replies, plc: &str, corr: &[u8], before: u64) {
    let end = Instant::now() + Duration::from_secs(30);
    let mut after = before;
    for k in 0u32.. {
        let mut c = corr.to_vec();
        c.extend_from_slice(format!("-{k}").as_bytes());
        request(ops, plc, "exec_info", &c, b"{}".to_vec());
        after = primary_cycles(&reply(replies, &c, Duration::from_secs(30)));
        if after > before || Instant::now() > end {
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    assert!(
        after > before,
        "the PLC cycles on: {before} cycles, then {after}"
    );
}

/// Every payload published on `topic` while the returned client lives.
pub fn watch(port: u16, topic: &str) -> (Client, Arc<Mutex<Vec<Vec<u8>>>>) {
    watch_all(port, "watcher", &[topic])
}

/// Every payload published on any of `topics`, seen by the client `id`, while it lives.
pub fn watch_all(port: u16, id: &str, topics: &[&str]) -> (Client, Arc<Mutex<Vec<Vec<u8>>>>) {
    let mut opts = MqttOptions::new(id, "127.0.0.1", port);
    opts.set_keep_alive(Duration::from_secs(30));
    let (c, mut conn) = Client::new(opts, 64);
    let seen: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let s = seen.clone();
    std::thread::spawn(move || {
        for ev in conn.iter() {
            match ev {
                Ok(Event::Incoming(Packet::Publish(p))) => {
                    s.lock().expect("seen").push(p.payload.to_vec())
                }
                Ok(_) => {}
                Err(_) => std::thread::sleep(Duration::from_millis(50)),
            }
        }
    });
    for topic in topics {
        c.subscribe(*topic, QoS::AtLeastOnce).expect("subscribes");
    }
    (c, seen)
}
