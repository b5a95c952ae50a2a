//! What anyone on the broker can send the dashboard, in a real browser and against the real
//! server: a retained `net` drawing that tries to restyle the page and run script, and forged
//! replies to the dashboard's commands.
//!
//! Needs Debian's `chromium`, `chromium-driver` and `mosquitto`; it fails (never skips) when they
//! are missing.

use std::io::{Read, Write};
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use cetratus_dashboard::{serve, DashboardConfig, DashboardHandle};
use cetratus_testkit::browser::{require_chromium, Browser};
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
    let state = json!({
        "online": true, "primary": "A", "status": "idle",
        "programs": {"A": {"name": "evil", "version": "1", "hash": "ab"}, "B": null},
        "cycle": {"cycles": 1},
    });
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
    c.goto(&dash.url()).await.expect("the page loads");
    c.wait_text("status", "idle", Duration::from_secs(15)).await;
    c.wait_text("primary", "A", Duration::from_secs(5)).await;
    // The drawing arrives with the snapshot; give it a moment to be drawn and to try.
    let end = Instant::now() + Duration::from_secs(10);
    while !c.net_drawn("A").await {
        assert!(Instant::now() < end, "the net's shapes are drawn");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
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

/// `POST /api/<plc>/<verb>` with a JSON body, over a plain TCP connection; the status and body.
fn post(addr: SocketAddr, path: &str, body: &str) -> (u16, Value) {
    let mut s = std::net::TcpStream::connect(addr).expect("the dashboard accepts");
    write!(
        s,
        "POST {path} HTTP/1.0\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .expect("the request is sent");
    let mut text = String::new();
    s.read_to_string(&mut text).expect("the response is read");
    let status = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    (status, serde_json::from_str(body).unwrap_or(Value::Null))
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
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let (status, body) =
        tokio::task::spawn_blocking(move || post(addr, &format!("/api/{PLC}/abort"), "{}"))
            .await
            .expect("the request runs");
    assert_eq!(status, 504, "a forged reply answered the command: {body}");
    assert_ne!(body["result"]["forged"], true, "{body}");
    dash.stop();
}
