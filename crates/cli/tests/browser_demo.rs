//! The whole system in a real browser: `cetratus demo` (the Vernadat cell in real time, its twin,
//! the embedded broker and the dashboard), driven in headless Chromium through ChromeDriver. The
//! operator uploads U.1 through the page, sees quarantine, substitutes, sees PRIMARY flip and
//! probation, and accepts the update; another operator substitutes and reverts with the page's
//! Revert, and the old program drives the cell again.

use std::process::{Command, Stdio};
use std::time::Duration;

use cetratus_testkit::browser::{require_chromium, Browser};
use cetratus_testkit::paths::artifacts_dir;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{login_link, stdout_lines, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_operator_loads_u1_in_the_browser_sees_quarantine_substitutes_and_primary_flips() {
    require_chromium();
    let dir = tempfile::tempdir().expect("temp dir");
    let (mqtt, http) = (free_port(), free_port());
    let mut demo = ChildGuard::spawn(
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
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    wait_for_port(http, "the dashboard", Duration::from_secs(30));
    // As a newcomer does: the one-time link the demo printed logs the browser in.
    let link = login_link(&stdout_lines(&mut demo.0), Duration::from_secs(30));
    assert!(
        link.starts_with(&format!("http://127.0.0.1:{http}/login?token=")),
        "{link}"
    );
    let c = Browser::start().await;
    c.goto(&link).await.expect("the page loads");

    c.wait_text("primary", "A", Duration::from_secs(30)).await;
    c.wait_text("status", "idle", Duration::from_secs(5)).await;

    // Live: the tokens move and the timing diagram scrolls, in the DOM.
    let t1 = c.timing().await;
    let drawn = c.wait_tokens_move("A", Duration::from_secs(10)).await;
    assert!(drawn.contains("place-P10="), "net A is drawn: {drawn}");
    let t2 = c.timing().await;
    t2.assert_scrolled_since(&t1);
    assert!(
        t2.svg.contains("PE") && t2.svg.contains("CM1"),
        "the diagram has the cell's signals"
    );

    // Load U.1 through the page.
    let u1 = dir.path().join("u1.cpkg");
    assert!(u1.exists(), "the demo wrote its packages");
    c.load_package(&u1).await;
    c.wait_text("status", "quarantine", Duration::from_secs(20))
        .await;
    wait_reply(&c, "load: quarantine_started").await;
    // The candidate's net is drawn in container B.
    c.wait_net_drawn("B", Duration::from_secs(10)).await;
    // Let the candidate run beside the primary for a while of plant time.
    tokio::time::sleep(Duration::from_secs(2)).await;

    c.click_and_confirm("substitute").await;
    c.wait_text("primary", "B", Duration::from_secs(20)).await;
    // The page says what happened, as `cetratus substitute` does, not only that it was accepted.
    wait_reply(&c, "substitute: substituted: PRIMARY = B").await;
    // A minute of probation by default: the old program runs on in A as a shadow, and the
    // operator ends probation with the page's Accept.
    c.wait_text("status", "probation", Duration::from_secs(10))
        .await;
    c.click_and_confirm("accept").await;
    wait_reply(&c, "accept: accepted:").await;
    c.wait_text("status", "idle", Duration::from_secs(10)).await;
    tokio::time::sleep(Duration::from_millis(1500)).await;

    let png = c.screenshot().await.expect("screenshot");
    std::fs::write(artifacts_dir().join("demo-dashboard.png"), &png).expect("screenshot written");
    c.close().await;
}

/// The demo started with its dashboard at `speed` times the wall clock, and a headless Chromium
/// logged in with its one-time link.
async fn demo_in_browser(plc: &str, speed: &str) -> (tempfile::TempDir, ChildGuard, Browser) {
    require_chromium();
    let dir = tempfile::tempdir().expect("temp dir");
    let (mqtt, http) = (free_port(), free_port());
    let mut demo = ChildGuard::spawn(
        Command::new(BIN)
            .args(["demo", "--speed", speed, "--plc", plc, "--for", "2h"])
            .args([
                "--mqtt",
                &format!("127.0.0.1:{mqtt}"),
                "--http",
                &format!("127.0.0.1:{http}"),
                "--dir",
            ])
            .arg(dir.path())
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    wait_for_port(http, "the dashboard", Duration::from_secs(30));
    let link = login_link(&stdout_lines(&mut demo.0), Duration::from_secs(30));
    let c = Browser::start().await;
    c.goto(&link).await.expect("the page loads");
    c.wait_text("primary", "A", Duration::from_secs(30)).await;
    (dir, demo, c)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_operator_reverts_a_substituted_update_with_the_pages_revert_button() {
    // Twice the wall clock: the operator reverts before U.1 has filled its two extra buffer
    // slots. With more parts in the buffer than the old program's seven, no marking of the old
    // program agrees with the plant, and the revert is refused with the reason
    // (`crates/io/tests/revert_sweep.rs` sweeps every instant).
    let (dir, _demo, c) = demo_in_browser("web2", "2").await;
    // Revert and Accept are for probation only: idle, the page offers neither.
    assert_eq!(
        c.js("return document.getElementById('revert').disabled")
            .await,
        true
    );
    assert_eq!(
        c.js("return document.getElementById('accept').disabled")
            .await,
        true
    );
    c.load_package(&dir.path().join("u1.cpkg")).await;
    c.wait_text("status", "quarantine", Duration::from_secs(20))
        .await;
    assert_eq!(
        c.js("return document.getElementById('revert').disabled")
            .await,
        true
    );
    c.click_and_confirm("substitute").await;
    c.wait_text("primary", "B", Duration::from_secs(20)).await;
    c.wait_text("status", "probation", Duration::from_secs(10))
        .await;
    assert_eq!(
        c.js("return document.getElementById('revert').disabled")
            .await,
        false
    );
    assert_eq!(
        c.js("return document.getElementById('accept').disabled")
            .await,
        false
    );

    c.click_and_confirm("revert").await;
    // The page says what the PLC did, from its `reverted` event, not only that it was accepted.
    wait_reply(&c, "revert: reverted:").await;
    c.wait_text("primary", "A", Duration::from_secs(10)).await;
    c.wait_text("status", "idle", Duration::from_secs(10)).await;
    assert!(
        c.text_of("reply").await.contains("operator"),
        "the reply gives the revert's reason: {}",
        c.text_of("reply").await
    );
    // The old program drives the cell again: its tokens move in A.
    let drawn = c.wait_tokens_move("A", Duration::from_secs(10)).await;
    assert!(drawn.contains("place-P10="), "{drawn}");
    c.close().await;
}

/// Waits until the dashboard's reply line starts with `want`.
async fn wait_reply(c: &Browser, want: &str) {
    let end = std::time::Instant::now() + Duration::from_secs(20);
    let mut seen = String::new();
    while std::time::Instant::now() < end {
        seen = c.text_of("reply").await;
        if seen.starts_with(want) {
            return;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    panic!("the reply line reads {seen:?}, not {want:?}…");
}
