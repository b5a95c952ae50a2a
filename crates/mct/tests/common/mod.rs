//! Shared test helpers: MQTT 5 and 3.1.1 clients that collect what they receive, a fake scan loop
//! answering commands through the MctLink, and a real mosquitto on a free port.
#![allow(dead_code)]

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use cetratus_mct::{refused, MctLink, Outgoing, Request};
use cetratus_proto::{CycleFigures, IoMsg, IoNames, ProgramInfo, Programs, Slot, StateMsg, Status};
use rumqttc::v5::mqttbytes::v5::Packet;
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{Client, Event, MqttOptions};
use serde_json::{json, Value};

pub use cetratus_testkit::mqtt::Mosquitto;
pub use cetratus_testkit::ports::free_addr;

/// A received MQTT 5 publish.
#[derive(Debug, Clone)]
pub struct Got {
    pub topic: String,
    pub payload: Vec<u8>,
    pub retain: bool,
    pub response_topic: Option<String>,
    pub correlation: Option<Vec<u8>>,
}

impl Got {
    pub fn json(&self) -> Value {
        serde_json::from_slice(&self.payload).expect("JSON payload")
    }
}

/// An MQTT 5 client whose event loop runs in a thread and forwards publishes.
pub struct V5 {
    pub client: Client,
    pub rx: Receiver<Got>,
    pub subacks: Receiver<()>,
    dead: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

static NEXT: AtomicU32 = AtomicU32::new(0);

pub fn unique(prefix: &str) -> String {
    format!(
        "{prefix}-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    )
}

pub fn v5(addr: SocketAddr, creds: Option<(&str, &str)>) -> V5 {
    let mut o = MqttOptions::new(unique("test"), addr.ip().to_string(), addr.port());
    o.set_max_packet_size(Some(8 << 20));
    if let Some((u, p)) = creds {
        o.set_credentials(u, p);
    }
    v5_with(o)
}

pub fn v5_with(o: MqttOptions) -> V5 {
    let (client, mut conn) = Client::new(o, 64);
    let (tx, rx) = std::sync::mpsc::channel();
    let (stx, subacks) = std::sync::mpsc::channel();
    let dead = Arc::new(AtomicBool::new(false));
    let d = dead.clone();
    let thread = std::thread::spawn(move || {
        // The first poll runs to its end: cutting it short (as the loop's timeout does) would
        // drop a connection whose login takes longer, and start another.
        match conn.recv() {
            Ok(Ok(_)) => {}
            Ok(Err(e)) => {
                eprintln!("mqtt client: {e}");
                return;
            }
            Err(_) => return,
        }
        while !d.load(Ordering::Relaxed) {
            let ev = match conn.recv_timeout(Duration::from_millis(50)) {
                Ok(ev) => ev,
                Err(_) => continue,
            };
            match ev {
                Ok(Event::Incoming(Packet::Publish(p))) => {
                    let props = p.properties.clone().unwrap_or_default();
                    let _ = tx.send(Got {
                        topic: String::from_utf8_lossy(&p.topic).into_owned(),
                        payload: p.payload.to_vec(),
                        retain: p.retain,
                        response_topic: props.response_topic,
                        correlation: props.correlation_data.map(|b| b.to_vec()),
                    });
                }
                Ok(Event::Incoming(Packet::SubAck(_))) => {
                    let _ = stx.send(());
                }
                Ok(_) => {}
                Err(e) => {
                    eprintln!("mqtt client: {e}");
                    break;
                }
            }
        }
    });
    V5 {
        client,
        rx,
        subacks,
        dead,
        thread: Some(thread),
    }
}

impl V5 {
    /// Closes the socket without DISCONNECT, as a crash would: the broker sends the last will.
    pub fn kill(mut self) {
        self.dead.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
    pub fn subscribe(&self, filter: &str) {
        self.client
            .subscribe(filter, QoS::AtLeastOnce)
            .expect("subscribe");
        self.subacks
            .recv_timeout(Duration::from_secs(5))
            .expect("suback");
    }
    /// The next publish on `topic`, skipping others.
    pub fn next_on(&self, topic: &str, timeout: Duration) -> Option<Got> {
        next_matching(&self.rx, timeout, |g: &Got| g.topic == topic)
    }
}

pub fn next_matching<T>(
    rx: &Receiver<T>,
    timeout: Duration,
    mut f: impl FnMut(&T) -> bool,
) -> Option<T> {
    let end = Instant::now() + timeout;
    loop {
        let left = end.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(g) if f(&g) => return Some(g),
            Ok(_) => {}
            Err(RecvTimeoutError::Timeout) | Err(RecvTimeoutError::Disconnected) => return None,
        }
    }
}

/// An MQTT 3.1.1 client whose event loop runs in a thread and forwards `(topic, payload)`.
pub struct V311 {
    pub client: rumqttc::Client,
    pub rx: Receiver<(String, Vec<u8>)>,
}

/// The topic under which [`V311`] reports a SUBACK, so that `subscribe` can wait for it.
const SUBACK: &str = "$suback";

/// A client connected to the broker at `addr` with MQTT 3.1.1.
pub fn v311(addr: SocketAddr) -> V311 {
    let mut o = rumqttc::MqttOptions::new(unique("v311"), addr.ip().to_string(), addr.port());
    o.set_keep_alive(Duration::from_secs(5));
    let (client, mut conn) = rumqttc::Client::new(o, 16);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for ev in conn.iter() {
            match ev {
                Ok(rumqttc::Event::Incoming(rumqttc::Packet::Publish(p))) => {
                    let _ = tx.send((p.topic, p.payload.to_vec()));
                }
                Ok(rumqttc::Event::Incoming(rumqttc::Packet::SubAck(_))) => {
                    let _ = tx.send((SUBACK.into(), vec![]));
                }
                Ok(_) => {}
                Err(e) => {
                    eprintln!("mqtt client: {e}");
                    break;
                }
            }
        }
    });
    V311 { client, rx }
}

impl V311 {
    /// Subscribes at QoS 1 and waits for the broker's SUBACK.
    pub fn subscribe(&self, filter: &str) {
        self.client
            .subscribe(filter, rumqttc::QoS::AtLeastOnce)
            .expect("subscribe");
        next_matching(&self.rx, Duration::from_secs(5), |(t, _)| t == SUBACK)
            .expect("MQTT 3.1.1 suback");
    }
    /// The payload of the next publish on `topic`, skipping others.
    pub fn next_on(&self, topic: &str, timeout: Duration) -> Option<Vec<u8>> {
        next_matching(&self.rx, timeout, |(t, _)| t == topic).map(|(_, p)| p)
    }
}

/// A stand-in for the lead's scan loop: polls commands without blocking and answers them.
pub struct FakeScan {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<u64>>,
}

pub fn state(primary: &str, status: &str) -> StateMsg {
    StateMsg {
        online: true,
        primary: primary.parse::<Slot>().expect("A or B"),
        status: status.parse::<Status>().expect("a status"),
        programs: Programs {
            a: Some(ProgramInfo {
                name: "vernadat".into(),
                version: "1.0".into(),
                hash: "ab".repeat(32),
            }),
            b: None,
        },
        cycle: CycleFigures::default(),
        control: Default::default(),
        persist_fault: None,
        labels: Default::default(),
        updates: None,
    }
}

/// An `io` message of program time `cycle` ms, with no signals.
pub fn io(cycle: u64) -> IoMsg {
    IoMsg {
        dispatched: Default::default(),
        inputs: Default::default(),
        names: IoNames::default(),
        outputs_a: None,
        outputs_b: None,
        samples: Vec::new(),
        time_ms: cycle,
        unix_ms: None,
    }
}

impl FakeScan {
    pub fn start(link: MctLink) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut answered = 0u64;
            let _ = link.send(Outgoing::State(Box::new(state("A", "idle"))));
            let mut cycle = 0u64;
            while !s.load(Ordering::Relaxed) {
                cycle += 1;
                while let Some(cmd) = link.try_command() {
                    let result = match &cmd.request {
                        Request::ExecInfo => Ok(Some(json!({"A": {"cycles": cycle}, "B": null}))),
                        Request::Load(package) => Err(refused(format!(
                            "package of {} bytes is not a valid update package",
                            package.len()
                        ))),
                        r => Ok(Some(json!({"verb": r.verb()}))),
                    };
                    let mut msg = Outgoing::Reply(cmd.reply, result);
                    // A scan loop would keep it for the next cycle; the fake one retries.
                    while let Err(m) = link.send(msg) {
                        msg = m;
                        std::thread::sleep(Duration::from_millis(1));
                    }
                    answered += 1;
                }
                if cycle.is_multiple_of(10) {
                    let _ = link.send(Outgoing::Io(io(cycle)));
                    let _ = link.send(Outgoing::ExecInfo(Box::default()));
                }
                std::thread::sleep(Duration::from_millis(2));
            }
            answered
        });
        FakeScan {
            stop,
            thread: Some(thread),
        }
    }
    pub fn stop(mut self) -> u64 {
        self.stop.store(true, Ordering::Relaxed);
        self.thread
            .take()
            .map(|t| t.join().expect("fake scan"))
            .unwrap_or(0)
    }
}

/// A mosquitto on a free port, or `None`, said loudly, when mosquitto or its clients are missing.
pub fn mosquitto() -> Option<Mosquitto> {
    if !cetratus_testkit::mqtt::installed() {
        eprintln!("\n!!!!!!!! SKIPPED: mosquitto, mosquitto_sub or mosquitto_pub missing (apt-get install -y mosquitto mosquitto-clients) !!!!!!!!\n");
        return None;
    }
    Some(Mosquitto::start())
}
