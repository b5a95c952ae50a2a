//! The dashboard in a real browser: headless Chromium driven over WebDriver (chromedriver),
//! against a real broker (Mosquitto) and a fake PLC that speaks the MQTT contract of
//! docs/mqtt.md. The operator uploads U.1 through the page, sees STATUS `quarantine`, substitutes
//! and sees PRIMARY flip; the timing diagram and the net's tokens must move on their own.
//!
//! Needs Debian's `chromium`, `chromium-driver` and `mosquitto`; it fails (never skips) when they
//! are missing. Artifacts (a screenshot, the latency figures) go to `target/test-artifacts/`.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use base64::Engine as _;
use cetratus_dashboard::{serve, AccessConfig, DashboardConfig};
use cetratus_testkit::browser::{require_chromium, Browser};
use cetratus_testkit::mqtt::Mosquitto;
use cetratus_testkit::{nets, paths};
use rumqttc::v5::mqttbytes::v5::{Packet, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{AsyncClient, Event, MqttOptions};
use serde_json::{json, Value};

const PLC: &str = "fake1";

fn unix_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1000.0)
}

// ---- the fake PLC -----------------------------------------------------------------------------

struct NetDrawing {
    net: cetratus_net::Net,
    m0: Vec<u32>,
}

impl NetDrawing {
    fn load(file: &str) -> Self {
        let net = nets::example(&format!("vernadat/{file}"));
        let m0 = net.initial_marking().as_slice().to_vec();
        NetDrawing { net, m0 }
    }

    fn index(&self, id: &str) -> Option<usize> {
        self.net.places().iter().position(|p| p.id == id)
    }

    /// The marking at tick `k`: the robot loads M1 on odd ticks (R, P10 -> P11), so tokens move.
    fn marking(&self, k: u64) -> Vec<u32> {
        let mut m = self.m0.clone();
        if k % 2 == 1 {
            if let (Some(r), Some(p10), Some(p11)) =
                (self.index("R"), self.index("P10"), self.index("P11"))
            {
                m[r] = m[r].saturating_sub(1);
                m[p10] = m[p10].saturating_sub(1);
                m[p11] += 1;
            }
        }
        m
    }

    fn marking_json(&self, k: u64) -> Value {
        let m = self.marking(k);
        let obj: serde_json::Map<String, Value> = self
            .net
            .places()
            .iter()
            .zip(m)
            .map(|(p, n)| (p.id.clone(), json!(n)))
            .collect();
        Value::Object(obj)
    }

    fn svg(&self) -> String {
        cetratus_net::export::to_svg(&self.net, Some(&self.m0))
    }
}

struct FakeState {
    primary: &'static str,
    status: &'static str,
    b_loaded: bool,
    a_loaded: bool,
    tick: u64,
}

struct FakePlc {
    state: Mutex<FakeState>,
    client: AsyncClient,
    package: Vec<u8>,
    a: NetDrawing,
    b: NetDrawing,
    request_id: Mutex<u64>,
}

/// A timing summary as the PLC publishes it, over `n` scans.
fn timing(n: u64) -> Value {
    json!({"count": n, "last_ns": 3100, "max_ns": 11200, "mean_ns": 2900, "min_ns": 2000,
           "p50_ns": 2800, "p99_ns": 5000})
}

fn program(name: &str, version: &str) -> Value {
    json!({"name": name, "version": version, "hash": "41aa0b9c3d2e"})
}

impl FakePlc {
    fn topic(leaf: &str) -> String {
        format!("cetratus/{PLC}/{leaf}")
    }

    fn state_json(&self) -> Value {
        let s = self.state.lock().expect("fake state");
        json!({
            "online": true,
            "primary": s.primary,
            "status": s.status,
            "programs": {
                "A": if s.a_loaded { program("vernadat", "1.0.0") } else { Value::Null },
                "B": if s.b_loaded { program("vernadat", "1.1.0") } else { Value::Null },
            },
            "cycle": {"cycle": timing(s.tick * 20), "cycles": s.tick * 20, "latency": timing(s.tick * 20),
                      "overruns": 0, "scan": timing(s.tick * 20), "time_ms": s.tick * 200, "update": null},
        })
    }

    fn net_json(&self) -> Value {
        let s = self.state.lock().expect("fake state");
        json!({
            "A": if s.a_loaded { Value::String(self.a.svg()) } else { Value::Null },
            "B": if s.b_loaded { Value::String(self.b.svg()) } else { Value::Null },
        })
    }

    async fn publish(&self, leaf: &str, retain: bool, v: Value) {
        self.client
            .publish(Self::topic(leaf), QoS::AtLeastOnce, retain, v.to_string())
            .await
            .expect("the fake PLC publishes");
    }

    async fn publish_state_and_net(&self) {
        self.publish("state", true, self.state_json()).await;
        self.publish("net", true, self.net_json()).await;
    }

    fn exec_info(&self, slot: &str, net: &NetDrawing, role: &str, k: u64) -> Value {
        json!({
            "container": slot, "role": role, "program": program("vernadat", "1.0.0"),
            "cycles": k * 20,
            "scan": {"count": k * 20, "last_ns": 3100 + k % 7 * 100, "min_ns": 2000, "mean_ns": 2900,
                     "p50_ns": 2800, "p99_ns": 5000, "max_ns": 11200},
            "firings": {"T10": k.div_ceil(2), "T11": k / 2},
            "marking": net.marking_json(k),
            "outputs": {"CM1": k % 2 == 1, "PM1": false},
            "divergence": if role == "candidate" { json!({"CM1": 0, "PM1": 0}) } else { json!({}) },
            "first_cause": null, "last_cause": null, "drift": 0, "max_drift": 0,
            "deadlock": false, "verdicts": [],
        })
    }

    /// One publish period: `io` and `exec_info`, and `state` now and then.
    async fn tick(&self) {
        let (k, primary, a_loaded, b_loaded) = {
            let mut s = self.state.lock().expect("fake state");
            s.tick += 1;
            (s.tick, s.primary, s.a_loaded, s.b_loaded)
        };
        let role = |slot: &str| {
            if slot == primary {
                "primary"
            } else {
                "candidate"
            }
        };
        let ea = a_loaded.then(|| self.exec_info("A", &self.a, role("A"), k));
        let eb = b_loaded.then(|| self.exec_info("B", &self.b, role("B"), k));
        self.publish("exec_info", false, json!([ea, eb])).await;
        // The runtime's shape (crates/cli's node): the Monitor's records since the last
        // publish as bit masks over `names`, PLC time in ms; plus `unix_ms` for the latency.
        let names_in = ["PE", "FCM1", "FPM1"];
        let names_out = ["CM1", "PM1"];
        let named = |mask: u64, names: &[&str]| -> Value {
            let m: serde_json::Map<String, Value> = names
                .iter()
                .enumerate()
                .map(|(i, n)| (n.to_string(), json!(mask >> i & 1 == 1)))
                .collect();
            Value::Object(m)
        };
        let samples: Vec<Value> = (0..20u64)
            .map(|j| {
                let c = k * 20 + j;
                let inputs = (c / 7) % 8;
                let out = (c / 10) % 4;
                // The candidate lags by one step, so its lanes differ now and then.
                let out_b = ((c / 10) + 1) % 4;
                json!([
                    c * 10,
                    primary,
                    "idle",
                    inputs,
                    a_loaded.then_some(out),
                    b_loaded.then_some(out_b),
                    out
                ])
            })
            .collect();
        let last = (k * 20 + 19) % 4;
        self.publish(
            "io",
            false,
            json!({
                "time_ms": (k * 20 + 19) * 10,
                "unix_ms": unix_ms(),
                "names": {"inputs": names_in, "outputs": names_out},
                "inputs": named(last, &names_in),
                "outputs_a": a_loaded.then(|| named(last, &names_out)),
                "outputs_b": b_loaded.then(|| named(last, &names_out)),
                "dispatched": named(last, &names_out),
                "samples": samples,
            }),
        )
        .await;
        if k % 5 == 0 {
            self.publish("state", true, self.state_json()).await;
        }
    }

    async fn reply(
        &self,
        props: Option<PublishProperties>,
        verb: &str,
        result: Result<Value, String>,
    ) {
        let Some(p) = props else { return };
        let Some(topic) = p.response_topic else {
            return;
        };
        let id = {
            let mut r = self.request_id.lock().expect("request id");
            *r += 1;
            *r
        };
        let body = match result {
            Ok(v) => json!({"ok": true, "verb": verb, "request_id": id, "result": v}),
            Err(m) => json!({"ok": false, "verb": verb, "request_id": id,
                              "error": {"code": "refused", "message": m}}),
        };
        let out = PublishProperties {
            correlation_data: p.correlation_data,
            ..PublishProperties::default()
        };
        self.client
            .publish_with_properties(topic, QoS::AtLeastOnce, false, body.to_string(), out)
            .await
            .expect("the fake PLC replies");
    }

    async fn command(&self, verb: &str, payload: &[u8], props: Option<PublishProperties>) {
        let args: Value = serde_json::from_slice(payload).unwrap_or(Value::Null);
        let result = {
            let mut s = self.state.lock().expect("fake state");
            match verb {
                "load" => {
                    let pkg = args["package_b64"]
                        .as_str()
                        .and_then(|b| base64::engine::general_purpose::STANDARD.decode(b).ok());
                    if s.status != "idle" {
                        Err(format!("load refused: STATUS is {}", s.status))
                    } else if pkg.as_deref() != Some(self.package.as_slice()) {
                        Err("not the package the test wrote".to_string())
                    } else {
                        s.status = "quarantine";
                        if s.primary == "A" {
                            s.b_loaded = true;
                        } else {
                            s.a_loaded = true;
                        }
                        Ok(json!({"setup_us": 21}))
                    }
                }
                "substitute" if s.status == "quarantine" => {
                    let (new, old_loaded) = if s.primary == "A" {
                        ("B", &mut s.a_loaded)
                    } else {
                        ("A", &mut s.b_loaded)
                    };
                    *old_loaded = false;
                    s.primary = new;
                    s.status = "idle";
                    Ok(json!({"mode": args["mode"].as_str().unwrap_or("retransform"), "drift": 0}))
                }
                other => Err(format!("{other} refused in STATUS {}", s.status)),
            }
        };
        if result.is_ok() {
            self.publish_state_and_net().await;
            let tick = self.state.lock().expect("fake state").tick;
            self.publish(
                "events",
                false,
                json!({"cycle": tick * 20, "time_us": tick * 200_000,
                       "kind": match verb {
                           "load" => "quarantine_started",
                           "substitute" => "substituted",
                           other => other,
                       },
                       "message": format!("{verb} done"), "detail": args.get("mode")}),
            )
            .await;
        }
        self.reply(props, verb, result).await;
    }
}

async fn run_fake_plc(broker_port: u16, package: Vec<u8>) -> Arc<FakePlc> {
    let mut opts = MqttOptions::new("fake-plc", "127.0.0.1", broker_port);
    opts.set_max_packet_size(Some(8 << 20));
    let (client, mut eventloop) = AsyncClient::new(opts, 256);
    let plc = Arc::new(FakePlc {
        state: Mutex::new(FakeState {
            primary: "A",
            status: "idle",
            a_loaded: true,
            b_loaded: false,
            tick: 0,
        }),
        client: client.clone(),
        package,
        a: NetDrawing::load("vernadat.pnml"),
        b: NetDrawing::load("u1.pnml"),
        request_id: Mutex::new(0),
    });
    client
        .subscribe(FakePlc::topic("cmd/+"), QoS::AtLeastOnce)
        .await
        .expect("subscribe");
    let me = plc.clone();
    tokio::spawn(async move {
        loop {
            match eventloop.poll().await {
                Ok(Event::Incoming(Packet::Publish(p))) => {
                    let topic = String::from_utf8_lossy(&p.topic).to_string();
                    if let Some(verb) = topic.rsplit('/').next().map(str::to_string) {
                        let me = me.clone();
                        tokio::spawn(async move {
                            me.command(&verb, &p.payload, p.properties).await;
                        });
                    }
                }
                Ok(_) => {}
                Err(_) => tokio::time::sleep(Duration::from_millis(200)).await,
            }
        }
    });
    plc.publish_state_and_net().await;
    let me = plc.clone();
    tokio::spawn(async move {
        loop {
            me.tick().await;
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    });
    plc
}

// ---- the figures ------------------------------------------------------------------------------

/// Count, quantiles and extremes of a list of latencies.
fn stats(v: &Value) -> Value {
    let mut xs: Vec<f64> = v
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    xs.sort_by(f64::total_cmp);
    let q = |p: f64| {
        xs.get(((xs.len() as f64 * p) as usize).min(xs.len().saturating_sub(1)))
            .copied()
    };
    json!({"n": xs.len(), "min": xs.first(), "p50": q(0.5), "p95": q(0.95), "p99": q(0.99), "max": xs.last()})
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn operator_loads_u1_then_substitutes_and_primary_flips_in_the_browser() {
    require_chromium();
    let started = Instant::now();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let broker = Mosquitto::start();
    let broker_port = broker.port();

    let package = b"CPKG fake U.1 package for the browser test\n".to_vec();
    let package_path = dir.path().join("u1.cpkg");
    std::fs::write(&package_path, &package).expect("u1.cpkg");
    let _plc = run_fake_plc(broker_port, package).await;

    let dashboard = serve(DashboardConfig {
        http: SocketAddr::from(([127, 0, 0, 1], 0)),
        broker_url: format!("mqtt://127.0.0.1:{broker_port}"),
        user: None,
        password: None,
        signer: None,
        access: AccessConfig::default(),
        tls: None,
        rollouts: None,
    })
    .expect("the dashboard starts");

    let c = Browser::start().await;
    // As an operator does: the one-time link the dashboard printed logs the browser in.
    let link = dashboard.login_url().expect("a login link");
    c.goto(&link).await.expect("the page loads");

    // The PLC is found on its own and its retained state is shown.
    c.wait_text("primary", "A", Duration::from_secs(15)).await;
    c.wait_text("status", "idle", Duration::from_secs(5)).await;
    let options = c
        .js("return [...document.getElementById('plc-select').options].map(o => o.value);")
        .await;
    assert_eq!(options, json!([PLC]));

    // Live: the diagram scrolls with new samples and the tokens move.
    let t1 = c.timing().await;
    let drawn = c.wait_tokens_move("A", Duration::from_secs(5)).await;
    assert!(drawn.contains("place-P10="), "net A is drawn: {drawn}");
    tokio::time::sleep(Duration::from_millis(600)).await;
    let t2 = c.timing().await;
    t2.assert_scrolled_since(&t1);
    assert_ne!(
        t1.last_time, t2.last_time,
        "the timing diagram shows newer samples"
    );
    let svg2 = &t2.svg;
    for lane in ["PE", "CM1", "outputs A", "dispatched"] {
        assert!(
            svg2.contains(lane),
            "the timing diagram has {lane}: {}",
            &svg2[..svg2.len().min(2000)]
        );
    }

    // Load U.1 through the page.
    c.load_package(&package_path).await;
    c.wait_text("status", "quarantine", Duration::from_secs(10))
        .await;
    let reply = c
        .js("return document.getElementById('reply').dataset.ok;")
        .await;
    assert_eq!(reply, json!("true"), "the load's outcome is shown as ok");
    let reply = c.text_of("reply").await;
    assert!(
        reply.starts_with("load: quarantine_started"),
        "the page shows the outcome, not only the acceptance: {reply}"
    );
    // The candidate's net is drawn in container B.
    c.wait_net_drawn("B", Duration::from_secs(10)).await;

    // Substitute: PRIMARY flips.
    c.click_and_confirm("substitute").await;
    c.wait_text("primary", "B", Duration::from_secs(10)).await;
    c.wait_text("status", "idle", Duration::from_secs(5)).await;
    let events = c.text_of("events").await;
    assert!(
        events.contains("substitute") && events.contains("load"),
        "{events}"
    );
    // Let the diagram show the candidate's lanes and the flip for a moment before the picture.
    tokio::time::sleep(Duration::from_millis(1500)).await;

    let dir_out = paths::artifacts_dir();
    let png = c.screenshot().await.expect("screenshot");
    std::fs::write(dir_out.join("dashboard.png"), &png).expect("screenshot written");
    let lat = c.js("return window.cetratusLatency;").await;
    let figures = json!({
        "what": "update latency in ms: MQTT message at the dashboard -> DOM updated (dom), -> next frame (frame); fake PLC's publish -> DOM (publish)",
        "dom": stats(&lat["dom"]),
        "frame": stats(&lat["frame"]),
        "publish": stats(&lat["publish"]),
        "test_seconds": started.elapsed().as_secs_f64(),
    });
    std::fs::write(
        dir_out.join("dashboard-latency.json"),
        serde_json::to_string_pretty(&figures).unwrap_or_default(),
    )
    .expect("figures written");
    println!("dashboard latency: {figures}");
    assert!(
        figures["dom"]["n"].as_u64().unwrap_or(0) > 10,
        "latency was measured"
    );

    c.close().await;
    dashboard.stop();
}
