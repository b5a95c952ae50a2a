//! The twin against the quarantine in a real browser: `cetratus run` drives the Vernadat twin in
//! real time, at the wall clock's pace, with fork validation on; the operator loads U.1 through
//! the page, and the dashboard shows what its package declares it changes, the twin verdict, how
//! far the quarantine's comparison with the twin's divergence signature has come, and then the
//! quarantine verdict (docs/live-update.md, *The twin against the quarantine*). (Ten times
//! faster, a loaded machine falls behind the plant, and the quarantine meets divergences that
//! the fork of the twin, which never falls behind, did not show.)

use std::process::{Command, Stdio};
use std::time::Duration;

use cetratus_testkit::browser::{require_chromium, Browser};
use cetratus_testkit::paths::example;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{login_link, signed_package, stderr_lines, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_dashboard_shows_the_declared_changes_the_twin_verdict_and_the_quarantine_coverage_and_verdict(
) {
    require_chromium();
    let dir = tempfile::tempdir().expect("temp dir");
    let config = dir.path().join("config");
    // U.1 as the example has it, its package declaring that DM1 may differ.
    let src = dir.path().join("src");
    std::fs::create_dir_all(&src).expect("a source directory");
    for name in [
        "vernadat.toml",
        "vernadat.pnml",
        "u1.toml",
        "u1.pnml",
        "u1.package.toml",
    ] {
        std::fs::copy(example(&format!("vernadat/{name}")), src.join(name)).expect("copy");
    }
    let manifest = src.join("u1.package.toml");
    let text = std::fs::read_to_string(&manifest).expect("the manifest");
    std::fs::write(
        &manifest,
        format!("{text}\n[changes]\noutputs = [\"DM1\"]\n"),
    )
    .expect("write the manifest");
    let package = signed_package(BIN, &manifest, "u1", dir.path(), &config.join("trusted"));
    // Two minutes of plant time from the load on a fork of the twin the PLC drives: what U.1
    // does there is what it does in quarantine, and the quarantine passes after 500 cycles and
    // whatever the twin showed diverging.
    std::fs::write(
        config.join("config.toml"),
        "[updates]\nvalidation = \"fork\"\nhorizon = \"120s\"\n",
    )
    .expect("config.toml");

    let (mqtt, http) = (free_port(), free_port());
    let mut plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(example("vernadat/vernadat.toml"))
            .args([
                "--twin", "vernadat", "--speed", "1", "--for", "2h", "--plc", "val1",
            ])
            .args(["--mqtt", &format!("127.0.0.1:{mqtt}")])
            .args(["--http", &format!("127.0.0.1:{http}")])
            .arg("--config")
            .arg(&config)
            .arg("--state-dir")
            .arg(dir.path().join("state"))
            .stdout(Stdio::null())
            .stderr(Stdio::piped()),
    );
    wait_for_port(http, "the dashboard", Duration::from_secs(30));
    let link = login_link(&stderr_lines(&mut plc.0), Duration::from_secs(30));
    let c = Browser::start().await;
    c.goto(&link).await.expect("the page loads");
    c.wait_text("status", "idle", Duration::from_secs(30)).await;

    c.load_package(&package).await;
    c.wait_text("status", "quarantine", Duration::from_secs(20))
        .await;
    c.wait_exec_info("verdicts", "B", "twin pass", Duration::from_secs(30))
        .await;
    c.wait_exec_info(
        "declared changes",
        "B",
        "outputs DM1",
        Duration::from_secs(10),
    )
    .await;
    let coverage = c
        .wait_exec_info(
            "quarantine coverage",
            "B",
            "outputs the twin showed diverging; 0 unexplained",
            Duration::from_secs(60),
        )
        .await;
    assert!(coverage.contains(" cycles; "), "{coverage}");
    let verdicts = c
        .wait_exec_info("verdicts", "B", "quarantine pass", Duration::from_secs(120))
        .await;
    assert!(
        verdicts.contains("no divergence the twin did not show"),
        "{verdicts}"
    );
    c.close().await;
}
