//! Update F.1 of the Festo station in a real browser: `cetratus run` drives the station's twin in
//! real time (20 times faster than the wall clock, one defective part in five) with the embedded
//! broker and the dashboard; the operator loads F.1 through the page, substitutes it, and sees its
//! new output, REJECT_BIN_FULL, reach the plant in the timing diagram.

use std::process::{Command, Stdio};
use std::time::Duration;

use cetratus_testkit::browser::{require_chromium, Browser};
use cetratus_testkit::paths::{artifacts_dir, example};
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{login_link, signed_package, stderr_lines, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");
const LAMP: &str = "REJECT_BIN_FULL";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_operator_loads_f1_substitutes_it_and_the_dashboard_shows_the_reject_bin_lamp_lit() {
    require_chromium();
    let dir = tempfile::tempdir().expect("temp dir");
    let trusted = dir.path().join("trusted");
    let package = signed_package(
        BIN,
        &example("festo/f1.package.toml"),
        "f1",
        dir.path(),
        &trusted,
    );

    let (mqtt, http) = (free_port(), free_port());
    let mut plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(example("festo/festo.toml"))
            .args(["--twin", "festo", "--speed", "20", "--for", "2h"])
            .args(["--defect-rate", "20%", "--seed", "4", "--plc", "festo1"])
            .args(["--mqtt", &format!("127.0.0.1:{mqtt}")])
            .args(["--http", &format!("127.0.0.1:{http}")])
            .arg("--trust")
            .arg(&trusted)
            .arg("--state-dir")
            .arg(dir.path().join("state"))
            .stdout(Stdio::null())
            .stderr(Stdio::piped()),
    );
    wait_for_port(http, "the dashboard", Duration::from_secs(30));
    // The one-time login link `run` printed logs the browser in.
    let link = login_link(&stderr_lines(&mut plc.0), Duration::from_secs(30));
    let c = Browser::start().await;
    c.goto(&link).await.expect("the page loads");
    c.wait_text("primary", "A", Duration::from_secs(30)).await;
    c.wait_text("status", "idle", Duration::from_secs(5)).await;
    // festo.toml declares the lamp and drives it with no action: it is drawn, and off.
    c.wait_lane_level("dispatched", LAMP, false, Duration::from_secs(20))
        .await;

    c.load_package(&package).await;
    c.wait_text("status", "quarantine", Duration::from_secs(20))
        .await;
    // F.1's net is drawn in container B.
    c.wait_net_drawn("B", Duration::from_secs(10)).await;
    // In quarantine the candidate counts rejects; its lamp is withheld from the plant.
    tokio::time::sleep(Duration::from_secs(2)).await;
    assert_eq!(
        c.lane_level("dispatched", LAMP).await,
        Some(false),
        "a candidate's output is withheld"
    );

    c.click_and_confirm("substitute").await;
    c.wait_text("primary", "B", Duration::from_secs(20)).await;
    // Five rejects after the switch (about 25 parts, two virtual minutes) light the lamp.
    c.wait_lane_level("dispatched", LAMP, true, Duration::from_secs(120))
        .await;
    let png = c.screenshot().await.expect("screenshot");
    std::fs::write(artifacts_dir().join("festo-f1-dashboard.png"), &png)
        .expect("screenshot written");
    c.close().await;
}
