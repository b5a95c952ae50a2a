//! What anyone on the broker can send the dashboard, in a real browser and against the real
//! server: a retained `net` drawing that tries to restyle the page and run script, and forged
//! replies to the dashboard's commands.
//!
//! Needs Debian's `chromium`, `chromium-driver` and `mosquitto`; it fails (never skips) when they
//! are missing.

use std::io::{Read, Write};
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use cetratus_dashboard::{serve, AccessConfig, DashboardConfig, DashboardHandle};
use cetratus_testkit::browser::{require_chromium, Browser};
use cetratus_testkit::http;
use cetratus_testkit::mqtt::Mosquitto;
use rumqttc::v5::mqttbytes::v5::{Packet, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{AsyncClient, Event, EventLoop, MqttOptions};
use serde_json::{json, Value};

const PLC: &str = "evil1";

fn dashboard(broker: &Mosquitto) -> DashboardHandle {
    serve(DashboardConfig {
        http: SocketAddr::from(([127, 0, 0, 1], 0)),
        broker_url: format!("mqtt://127.0.0.1:{}", broker.port()),
        user: None,
        password: None,
        signer: None,
        access: AccessConfig::default(),
        tls: None,
        rollouts: None,
    })
    .expect("the dashboard starts")
}

fn mqtt_client(broker: &Mosquitto, id: &str) -> (AsyncClient, EventLoop) {
    let mut opts = MqttOptions::new(id, "127.0.0.1", broker.port());
    opts.set_max_packet_size(Some(8 << 20));
    AsyncClient::new(opts, 64)
}

/// Publishes retained messages and waits until the broker has them.
async fn publish_retained(broker: &Mosquitto, messages: &[(String, String)]) {
    let (client, mut el) = mqtt_client(broker, "hostile-publisher");
    for (topic, payload) in messages {
        client
            .publish(topic.clone(), QoS::AtLeastOnce, true, payload.clone())
            .await
            .expect("queued");
    }
    let mut acked = 0;
    while acked < messages.len() {
        match tokio::time::timeout(Duration::from_secs(10), el.poll()).await {
            Ok(Ok(Event::Incoming(Packet::PubAck(_)))) => acked += 1,
            Ok(Ok(_)) => {}
            other => panic!("the broker did not take the retained messages: {other:?}"),
        }
    }
    let _ = client.disconnect().await;
}

/// A `net` drawing that tries everything an SVG can do to a page besides drawing.
fn hostile_svg() -> String {
    r##"<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" class="cetratus-net" viewBox="0 0 200 100" width="200" height="100" onload="window.pwned='svg onload'">
  <style>#status, #primary, #summary { display: none !important } body { visibility: hidden }</style>
  <script>window.pwned = 'script';</script>
  <script xlink:href="data:text/javascript,window.pwned='script src'"/>
  <foreignObject width="100" height="100"><div xmlns="http://www.w3.org/1999/xhtml"><img src="x" onerror="window.pwned='foreignObject'"/><style>#status{display:none}</style></div></foreignObject>
  <a xlink:href="javascript:window.pwned='link'"><text id="evil-link" x="10" y="20">click me</text></a>
  <a href="javascript:window.pwned='link2'"><rect id="evil-rect" width="10" height="10"/></a>
  <image href="javascript:window.pwned='image'" width="10" height="10"/>
  <use xlink:href="data:image/svg+xml,&lt;svg onload='window.pwned=1'/&gt;"/>
  <animate attributeName="href" to="javascript:window.pwned='animate'"/>
  <set attributeName="onclick" to="window.pwned='set'"/>
  <g id="status" class="place"><circle class="node" cx="40" cy="40" r="10" style="display:none" onclick="window.pwned='onclick'" fill="url(javascript:alert(1))"/></g>
  <g id="place-P1" class="place" data-tokens="1"><circle class="node" cx="80" cy="40" r="10"/><text x="80" y="70">P1</text></g>
</svg>"##
        .to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hostile_retained_net_neither_restyles_the_page_nor_runs_script() {
    require_chromium();
    let broker = Mosquitto::start();
    // A state as the PLC publishes it (the protocol's golden file), naming the evil program.
    let golden =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../proto/tests/golden/state.json");
    let mut state: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(golden).expect("state.json")).expect("JSON");
    state["programs"]["A"] = json!({"name": "evil", "version": "1", "hash": "ab"});
    publish_retained(
        &broker,
        &[
            (format!("cetratus/{PLC}/state"), state.to_string()),
            (
                format!("cetratus/{PLC}/net"),
                json!({"A": hostile_svg(), "B": hostile_svg()}).to_string(),
            ),
        ],
    )
    .await;
    let dash = dashboard(&broker);
    let c = Browser::start().await;
    c.goto(&dash.login_url().expect("a login link"))
        .await
        .expect("the page loads");
    c.wait_text("status", "idle", Duration::from_secs(15)).await;
    c.wait_text("primary", "A", Duration::from_secs(5)).await;
    // The drawing arrives with the snapshot; give it a moment to be drawn and to try.
    c.wait_net_drawn("A", Duration::from_secs(10)).await;
    // Click whatever the drawing holds, as an operator would.
    c.js(
        "for (const e of document.querySelectorAll('#net-A *, #net-B *')) {
            e.dispatchEvent(new MouseEvent('click', {bubbles: true}));
          } return null;",
    )
    .await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let seen = c
        .js("const s = document.getElementById('status');
             const st = getComputedStyle(s);
             const body = getComputedStyle(document.body);
             return {
               pwned: window.pwned === undefined ? null : String(window.pwned),
               status_tag: s.tagName,
               status_display: st.display,
               status_visible: st.visibility,
               body_visible: body.visibility,
               status_shown: s.getClientRects().length > 0,
               styles: document.querySelectorAll('.net style').length,
               scripts: document.querySelectorAll('.net script').length,
               foreign: document.querySelectorAll('.net foreignObject').length,
               links: document.querySelectorAll('.net a, .net image, .net use, .net animate, .net set').length,
               handlers: [...document.querySelectorAll('.net *')].filter(e =>
                 [...e.attributes].some(a => /^on|^style$|href$/i.test(a.name))).length,
               clobbered: document.querySelectorAll('.net [id=status], .net [id=primary]').length,
               drawn: !!document.querySelector('#net-A #place-P1 circle.node'),
             };")
        .await;
    eprintln!("{seen}");
    assert_eq!(seen["pwned"], Value::Null, "no script ran: {seen}");
    assert_eq!(
        seen["status_tag"], "SPAN",
        "#status is still the page's: {seen}"
    );
    assert_ne!(seen["status_display"], "none", "{seen}");
    assert_eq!(seen["status_visible"], "visible", "{seen}");
    assert_eq!(seen["body_visible"], "visible", "{seen}");
    assert_eq!(seen["status_shown"], true, "{seen}");
    for k in [
        "styles",
        "scripts",
        "foreign",
        "links",
        "handlers",
        "clobbered",
    ] {
        assert_eq!(seen[k], 0, "{k}: {seen}");
    }
    assert_eq!(seen["drawn"], true, "the harmless shapes are drawn: {seen}");
    c.close().await;
    dash.stop();
}

/// `POST /api/<plc>/<verb>` with a JSON body and the session `cookie`, over a plain TCP
/// connection; the status and body.
fn post(addr: SocketAddr, cookie: &str, path: &str, body: &str) -> (u16, Value) {
    let r = http::request(
        addr,
        "POST",
        path,
        &[
            &format!("Host: {addr}"),
            "Content-Type: application/json",
            cookie,
        ],
        body.as_bytes(),
    );
    (r.status, r.json())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_forged_reply_with_a_guessed_correlation_id_does_not_answer_a_command() {
    let broker = Mosquitto::start();
    let dash = dashboard(&broker);
    // The attacker sees the command go out (anyone may subscribe to it) and answers at once with
    // what the dashboard used to trust: small correlation ids, on the topic the command names and
    // on the one the dashboard used to reply on.
    let (attacker, mut el) = mqtt_client(&broker, "forger");
    attacker
        .subscribe(format!("cetratus/{PLC}/cmd/#"), QoS::AtLeastOnce)
        .await
        .expect("subscribe");
    let forger = attacker.clone();
    tokio::spawn(async move {
        loop {
            match el.poll().await {
                Ok(Event::Incoming(Packet::Publish(p))) => {
                    let Some(topic) = p.properties.and_then(|pr| pr.response_topic) else {
                        continue;
                    };
                    let forged = json!({"ok": true, "verb": "abort", "request_id": 1,
                                        "result": {"accepted": true, "forged": true}});
                    let old = topic.split('/').take(2).collect::<Vec<_>>().join("/") + "/reply";
                    for t in [topic.clone(), old] {
                        for guess in 0..5u32 {
                            let props = PublishProperties {
                                correlation_data: Some(guess.to_string().into_bytes().into()),
                                ..PublishProperties::default()
                            };
                            let _ = forger
                                .publish_with_properties(
                                    t.clone(),
                                    QoS::AtLeastOnce,
                                    false,
                                    forged.to_string(),
                                    props,
                                )
                                .await;
                        }
                    }
                }
                Ok(_) => {}
                Err(_) => tokio::time::sleep(Duration::from_millis(100)).await,
            }
        }
    });
    // No PLC answers: the command must time out, whatever the forger sends.
    let addr = dash.local_addr();
    let cookie = http::login(&dash.login_url().expect("a login link"));
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let (status, body) = tokio::task::spawn_blocking(move || {
        post(addr, &cookie, &format!("/api/{PLC}/abort"), "{}")
    })
    .await
    .expect("the request runs");
    assert_eq!(status, 504, "a forged reply answered the command: {body}");
    assert_ne!(body["result"]["forged"], true, "{body}");
    dash.stop();
}

/// Serves `page` to every request on a port of its own: the attacker's site.
fn attacker_site(page: String) -> SocketAddr {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("a port");
    let addr = listener.local_addr().expect("addr");
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let mut s = stream;
            let mut buf = [0u8; 4096];
            let _ = s.read(&mut buf);
            let _ = write!(
                s,
                "HTTP/1.0 200 OK\r\nContent-Type: text/html\r\nContent-Length: {}\r\n\r\n{page}",
                page.len()
            );
        }
    });
    addr
}

/// Counts the commands that reach the broker for [`PLC`].
async fn count_commands(broker: &Mosquitto) -> std::sync::Arc<std::sync::atomic::AtomicUsize> {
    let seen = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let (watcher, mut el) = mqtt_client(broker, "watcher");
    watcher
        .subscribe(format!("cetratus/{PLC}/cmd/#"), QoS::AtLeastOnce)
        .await
        .expect("subscribe");
    let s = seen.clone();
    tokio::spawn(async move {
        let _keep = watcher;
        loop {
            match el.poll().await {
                Ok(Event::Incoming(Packet::Publish(_))) => {
                    s.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                }
                Ok(_) => {}
                Err(_) => tokio::time::sleep(Duration::from_millis(100)).await,
            }
        }
    });
    seen
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_page_of_another_origin_cannot_send_commands_through_a_logged_in_browser() {
    require_chromium();
    let broker = Mosquitto::start();
    let dash = dashboard(&broker);
    let seen = count_commands(&broker).await;
    let c = Browser::start().await;
    c.goto(&dash.login_url().expect("a login link"))
        .await
        .expect("the page loads");
    let want = format!("broker mqtt://127.0.0.1:{}: connected", broker.port());
    c.wait_text("broker", &want, Duration::from_secs(15)).await;
    // The attacker's page, on the same host but another port (so the browser does send the
    // SameSite cookie: ports do not make sites): a text/plain form whose body parses as JSON, a
    // no-cors fetch, and a form-encoded post.
    let target = format!("http://{}/api/{PLC}/abort", dash.local_addr());
    let page = format!(
        r#"<!doctype html><html><body>
<form id="f" method="POST" action="{target}" enctype="text/plain" target="sink"><input name='{{"x":"' value='"}}'></form>
<form id="g" method="POST" action="{target}" target="sink2"><input name="mode" value="keep"></form>
<iframe name="sink"></iframe><iframe name="sink2"></iframe>
<script>
fetch("{target}", {{method: "POST", mode: "no-cors", credentials: "include", body: "{{}}"}});
fetch("{target}", {{method: "POST", mode: "no-cors", credentials: "include", headers: {{"Content-Type": "text/plain"}}, body: "{{}}"}});
document.getElementById("f").submit();
document.getElementById("g").submit();
window.done = true;
</script></body></html>"#
    );
    let site = attacker_site(page);
    c.goto(&format!("http://{site}/"))
        .await
        .expect("the attacker's page loads");
    let end = Instant::now() + Duration::from_secs(10);
    while c.js("return window.done === true").await != Value::Bool(true) && Instant::now() < end {
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    // Time for the requests to go out and, if they got through, for the command to reach MQTT.
    tokio::time::sleep(Duration::from_secs(3)).await;
    assert_eq!(
        seen.load(std::sync::atomic::Ordering::Relaxed),
        0,
        "a page of another origin sent a command through the operator's browser"
    );
    // The operator's own page still commands (the session is good): its abort reaches MQTT.
    c.goto(&dash.url()).await.expect("the page loads");
    c.wait_text("broker", &want, Duration::from_secs(15)).await;
    let cookie = http::login(&dash.login_url().expect("a login link"));
    let addr = dash.local_addr();
    tokio::task::spawn_blocking(move || post(addr, &cookie, &format!("/api/{PLC}/abort"), "{}"))
        .await
        .expect("the request runs");
    assert!(
        seen.load(std::sync::atomic::Ordering::Relaxed) >= 1,
        "the dashboard's own command went out"
    );
    c.close().await;
    dash.stop();
}

#[test]
fn api_requests_need_a_session_the_dashboards_own_host_and_origin_and_json() {
    let broker = Mosquitto::start();
    let dash = dashboard(&broker);
    let addr = dash.local_addr();
    let host = format!("Host: {addr}");
    let cookie = http::login(&dash.login_url().expect("a login link"));
    let json = "Content-Type: application/json";
    let abort = format!("/api/{PLC}/abort");
    let cases: [(&str, Vec<&str>, u16, &str); 6] = [
        ("no session", vec![&host, json], 401, "log in"),
        (
            "text/plain",
            vec![&host, &cookie, "Content-Type: text/plain"],
            415,
            "application/json",
        ),
        (
            "a form",
            vec![
                &host,
                &cookie,
                "Content-Type: application/x-www-form-urlencoded",
            ],
            415,
            "application/json",
        ),
        (
            "another origin",
            vec![&host, &cookie, json, "Origin: http://evil.example"],
            403,
            "evil.example",
        ),
        (
            "a rebound name",
            vec!["Host: evil.example:8080", &cookie, json],
            403,
            "[dashboard]",
        ),
        (
            "cross-site",
            vec![&host, &cookie, json, "Sec-Fetch-Site: cross-site"],
            403,
            "cross-site",
        ),
    ];
    for (what, headers, status, needle) in cases {
        let r = http::request(addr, "POST", &abort, &headers, b"{}");
        assert_eq!(r.status, status, "{what}: {}", r.body);
        assert!(r.body.contains(needle), "{what}: {}", r.body);
    }
    let r = http::request(addr, "GET", "/api/plcs", &[&host], b"");
    assert_eq!(r.status, 401, "reading needs a session too: {}", r.body);
    let r = http::request(addr, "GET", "/api/plcs", &[&host, &cookie], b"");
    assert_eq!(r.status, 200, "{}", r.body);
    // A link logs in once.
    let link = dash.login_url().expect("a login link");
    http::login(&link);
    let path = &link[link.find("/login").expect("path")..];
    let again = http::request(addr, "GET", path, &[&host], b"");
    assert_eq!(again.status, 403, "{}", again.body);
    assert!(again.body.contains("used already"), "{}", again.body);
    dash.stop();
}

#[test]
fn guessing_passwords_is_rate_limited_and_never_logs_in() {
    let broker = Mosquitto::start();
    let hash = cetratus_dashboard::hash_password("correct horse").expect("hash");
    let dash = serve(DashboardConfig {
        http: SocketAddr::from(([127, 0, 0, 1], 0)),
        broker_url: format!("mqtt://127.0.0.1:{}", broker.port()),
        user: None,
        password: None,
        signer: None,
        access: AccessConfig {
            accounts: vec![cetratus_dashboard::Account {
                name: "ops".into(),
                password_hash: hash,
            }],
            hosts: vec![],
        },
        tls: None,
        rollouts: None,
    })
    .expect("the dashboard starts");
    let addr = dash.local_addr();
    let host = format!("Host: {addr}");
    let login = |password: &str| {
        let body = json!({"account": "ops", "password": password}).to_string();
        http::request(
            addr,
            "POST",
            "/api/login",
            &[&host, "Content-Type: application/json"],
            body.as_bytes(),
        )
    };
    let ok = login("correct horse");
    assert_eq!(ok.status, 200, "{}", ok.body);
    assert!(
        ok.header("set-cookie")
            .is_some_and(|c| c.contains("HttpOnly") && c.contains("SameSite=Strict")),
        "{}",
        ok.head
    );
    // Twelve guesses at once, as a script would send them: the limit is taken when a request
    // arrives, before its hash is checked.
    let statuses: Vec<u16> = std::thread::scope(|s| {
        let guesses: Vec<_> = (0..12)
            .map(|k| s.spawn(move || login(&format!("guess{k}")).status))
            .collect();
        guesses
            .into_iter()
            .map(|g| g.join().expect("a guess"))
            .collect()
    });
    assert!(
        statuses.iter().all(|s| *s == 401 || *s == 429),
        "{statuses:?}"
    );
    assert!(
        statuses.contains(&429),
        "guesses are rate-limited: {statuses:?}"
    );
    dash.stop();
}

/// The fleet page's rollout actions, sent as an attacker would: a plan named outside the plans'
/// directory, a file that is no plan, a body that is not the expected JSON, an unknown action,
/// and any action without a session. Each is refused with what to do, and nothing starts.
#[test]
fn rollout_requests_outside_the_plans_directory_or_without_a_session_are_refused() {
    let broker = Mosquitto::start();
    let dir = tempfile::tempdir().expect("a directory");
    let plans = dir.path().join("plans");
    std::fs::create_dir_all(&plans).expect("plans");
    std::fs::write(dir.path().join("outside.toml"), "package = \"x\"").expect("a plan outside");
    std::fs::write(plans.join("notes.txt"), "not a plan").expect("a file that is no plan");
    let dash = serve(DashboardConfig {
        http: SocketAddr::from(([127, 0, 0, 1], 0)),
        broker_url: format!("mqtt://127.0.0.1:{}", broker.port()),
        user: None,
        password: None,
        signer: None,
        access: AccessConfig::default(),
        tls: None,
        rollouts: Some(cetratus_dashboard::RolloutConfig {
            plans: plans.clone(),
            state_dir: dir.path().join("state"),
            link: cetratus_fleet::LinkConfig {
                url: format!("mqtt://127.0.0.1:{}", broker.port()),
                credentials: None,
                key: None,
                timeout: Duration::from_secs(5),
                account: None,
            },
        }),
    })
    .expect("the dashboard starts");
    let addr = dash.local_addr();
    let cookie = http::login(&dash.login_url().expect("a login link"));
    for (path, body, status, says) in [
        (
            "/api/rollout/start",
            r#"{"plan": "../outside.toml"}"#,
            404,
            "no plan `../outside.toml`",
        ),
        (
            "/api/rollout/start",
            r#"{"plan": "/etc/passwd"}"#,
            404,
            "no plan",
        ),
        (
            "/api/rollout/start",
            r#"{"plan": "notes.txt"}"#,
            404,
            "no plan `notes.txt`",
        ),
        (
            "/api/rollout/start",
            r#"{"plan": 7}"#,
            400,
            "expected {\"plan\"",
        ),
        ("/api/rollout/start", "not json", 400, "expected {\"plan\""),
        ("/api/rollout/launch", "{}", 404, "not a rollout action"),
    ] {
        let (got, v) = post(addr, &cookie, path, body);
        let message = v["error"]["message"].as_str().unwrap_or("");
        assert_eq!(got, status, "{path} {body}: {v}");
        assert!(message.contains(says), "{path} {body}: {message}");
    }
    let anonymous = http::request(
        addr,
        "POST",
        "/api/rollout/abort",
        &[&format!("Host: {addr}"), "Content-Type: application/json"],
        b"{}",
    );
    assert_eq!(anonymous.status, 401, "{}", anonymous.body);
    let r = http::request(
        addr,
        "GET",
        "/api/fleet",
        &[&format!("Host: {addr}"), &cookie],
        b"",
    );
    let v = r.json();
    assert_eq!(v["rollout"]["plans"], json!([]), "{v}");
    assert_eq!(v["rollout"]["running"], false, "{v}");
    assert!(
        !dir.path().join("state/rollout.json").exists(),
        "nothing was started"
    );
    dash.stop();
}
