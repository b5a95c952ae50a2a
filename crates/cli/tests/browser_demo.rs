//! The whole system in a real browser: `cetratus demo` (the Vernadat cell in real time, its twin,
//! the embedded broker and the dashboard), driven in headless Chromium through ChromeDriver. The
//! operator uploads U.1 through the page, sees quarantine, substitutes, and sees PRIMARY flip.

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use fantoccini::{Client, ClientBuilder, Locator};
use serde_json::{json, Value};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");
const CHROMIUM: &str = "/usr/bin/chromium";
const CHROMEDRIVER: &str = "/usr/bin/chromedriver";

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

fn wait_port(port: u16, what: &str) {
    let end = Instant::now() + Duration::from_secs(30);
    while Instant::now() < end {
        if std::net::TcpStream::connect(("127.0.0.1", port)).is_ok() {
            return;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    panic!("{what} never listened on port {port}");
}

struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn require(path: &str, package: &str) {
    assert!(
        Path::new(path).exists(),
        "{path} is missing: install the Debian package {package} (apt-get install -y chromium chromium-driver; ./scripts/test does)"
    );
}

fn artifacts_dir() -> PathBuf {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/test-artifacts");
    std::fs::create_dir_all(&d).expect("artifacts dir");
    d
}

async fn js(c: &Client, script: &str) -> Value {
    c.execute(script, Vec::new())
        .await
        .unwrap_or_else(|e| panic!("script failed: {e}\n{script}"))
}

async fn text_of(c: &Client, id: &str) -> String {
    js(
        c,
        &format!("const e = document.getElementById('{id}'); return e ? e.textContent : null;"),
    )
    .await
    .as_str()
    .unwrap_or("")
    .trim()
    .to_string()
}

async fn wait_text(c: &Client, id: &str, want: &str, within: Duration) {
    let end = Instant::now() + within;
    let mut seen = String::new();
    while Instant::now() < end {
        seen = text_of(c, id).await;
        if seen == want {
            return;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let reply = text_of(c, "reply").await;
    panic!("#{id} is {seen:?}, not {want:?}, after {within:?} (#reply: {reply:?})");
}

async fn click_and_confirm(c: &Client, button: &str) {
    c.find(Locator::Id(button))
        .await
        .expect("button")
        .click()
        .await
        .expect("click");
    c.wait()
        .at_most(Duration::from_secs(5))
        .for_element(Locator::Css("#confirm:not([hidden]) #confirm-yes"))
        .await
        .expect("the confirmation dialog opens")
        .click()
        .await
        .expect("confirm");
}

async fn tokens(c: &Client, slot: &str) -> String {
    js(c, &format!("return [...document.querySelectorAll('#net-{slot} .place')].map(p => p.id + '=' + p.getAttribute('data-tokens')).join(',');"))
        .await
        .as_str()
        .unwrap_or("")
        .to_string()
}

async fn timing(c: &Client) -> (u64, String) {
    let v = js(c, "const t = document.getElementById('timing'); return [Number(t.dataset.samples || 0), t.innerHTML];").await;
    (
        v[0].as_u64().unwrap_or(0),
        v[1].as_str().unwrap_or("").to_string(),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_operator_loads_u1_in_the_browser_sees_quarantine_substitutes_and_primary_flips() {
    require(CHROMIUM, "chromium");
    require(CHROMEDRIVER, "chromium-driver");
    let dir = tempfile::tempdir().expect("temp dir");
    let (mqtt, http, driver_port) = (free_port(), free_port(), free_port());
    let _demo = Guard(
        Command::new(BIN)
            .args(["demo", "--speed", "20", "--plc", "web1", "--for", "2h"])
            .args([
                "--mqtt",
                &format!("127.0.0.1:{mqtt}"),
                "--http",
                &format!("127.0.0.1:{http}"),
                "--dir",
            ])
            .arg(dir.path())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start cetratus demo"),
    );
    let _driver = Guard(
        Command::new(CHROMEDRIVER)
            .arg(format!("--port={driver_port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start chromedriver"),
    );
    wait_port(http, "the dashboard");
    wait_port(driver_port, "chromedriver");
    let profile = dir.path().join("chromium-profile");
    let args = [
        "--headless".to_string(),
        "--no-sandbox".into(),
        "--disable-gpu".into(),
        "--disable-dev-shm-usage".into(),
        "--disable-quic".into(),
        "--no-first-run".into(),
        "--disable-background-networking".into(),
        "--disable-component-update".into(),
        "--disable-sync".into(),
        "--window-size=1400,1800".into(),
        format!("--user-data-dir={}", profile.display()),
    ];
    let mut caps = serde_json::Map::new();
    caps.insert(
        "goog:chromeOptions".into(),
        json!({"binary": CHROMIUM, "args": args}),
    );
    let c = ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
        .capabilities(caps)
        .connect(&format!("http://127.0.0.1:{driver_port}"))
        .await
        .expect("chromedriver starts a Chromium session");
    c.goto(&format!("http://127.0.0.1:{http}/"))
        .await
        .expect("the page loads");

    wait_text(&c, "primary", "A", Duration::from_secs(30)).await;
    wait_text(&c, "status", "idle", Duration::from_secs(5)).await;

    // Live: the tokens move and the timing diagram scrolls, in the DOM.
    let tok1 = tokens(&c, "A").await;
    assert!(tok1.contains("place-P10="), "net A is drawn: {tok1}");
    let (n1, svg1) = timing(&c).await;
    let mut moved = false;
    let end = Instant::now() + Duration::from_secs(10);
    while Instant::now() < end && !moved {
        tokio::time::sleep(Duration::from_millis(200)).await;
        moved = tokens(&c, "A").await != tok1;
    }
    assert!(moved, "the tokens of net A never moved: {tok1}");
    let (n2, svg2) = timing(&c).await;
    assert!(n2 > n1, "the timing diagram gained samples ({n1} -> {n2})");
    assert_ne!(svg1, svg2, "the timing diagram was redrawn");
    assert!(
        svg2.contains("PE") && svg2.contains("CM1"),
        "the diagram has the cell's signals"
    );

    // Load U.1 through the page.
    let u1 = dir.path().join("u1.cpkg");
    assert!(u1.exists(), "the demo wrote its packages");
    c.find(Locator::Id("package-file"))
        .await
        .expect("file input")
        .send_keys(&u1.display().to_string())
        .await
        .expect("choose the package");
    click_and_confirm(&c, "load").await;
    wait_text(&c, "status", "quarantine", Duration::from_secs(20)).await;
    let b = js(&c, "return !!document.querySelector('#net-B svg .place');").await;
    assert_eq!(
        b,
        json!(true),
        "the candidate's net is drawn in container B"
    );
    // Let the candidate run beside the primary for a while of plant time.
    tokio::time::sleep(Duration::from_secs(2)).await;

    click_and_confirm(&c, "substitute").await;
    wait_text(&c, "primary", "B", Duration::from_secs(20)).await;
    wait_text(&c, "status", "idle", Duration::from_secs(10)).await;
    tokio::time::sleep(Duration::from_millis(1500)).await;

    let png = c.screenshot().await.expect("screenshot");
    std::fs::write(artifacts_dir().join("demo-dashboard.png"), &png).expect("screenshot written");
    c.close().await.expect("the browser closes");
}
