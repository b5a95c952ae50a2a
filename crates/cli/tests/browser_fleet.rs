//! The fleet page in real headless Chromium: three PLCs (the Vernadat cell on its twin, ten
//! times real time) on a real Mosquitto, one `cetratus dashboard --plans DIR` on the same
//! broker. An operator logs in with the link the dashboard prints, sees every PLC with its
//! program, PRIMARY and STATUS, starts the rollout of U.1 on the page, and watches its stages
//! advance to the end; the page's rollout is the one `cetratus rollout status` reads.

#[path = "common/fleet.rs"]
mod fleet;

use std::io::{BufRead as _, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::browser::{require_chromium, Browser};
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::ChildGuard;
use fleet::{u1_declared, Fleet, BIN};

/// The dashboard on the fleet's broker with `plans`; the process and its login link.
fn dashboard(fleet: &Fleet, plans: &std::path::Path) -> (ChildGuard, String) {
    let http = free_port();
    let mut child = ChildGuard::spawn(
        Command::new(BIN)
            .arg("dashboard")
            .args([
                "--http",
                &format!("127.0.0.1:{http}"),
                "--broker",
                &fleet.url(),
            ])
            .arg("--plans")
            .arg(plans)
            .arg("--rollout-state")
            .arg(fleet.root.path().join("rollout"))
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    );
    wait_for_port(http, "the dashboard", Duration::from_secs(30));
    let out = child.0.stdout.take().expect("its stdout");
    let line = BufReader::new(out).lines().map_while(Result::ok).next();
    let line = line.expect("the dashboard prints its login link");
    let link = line
        .split_whitespace()
        .find(|w| w.contains("/login?token="))
        .unwrap_or_else(|| panic!("no login link in {line:?}"))
        .to_string();
    (child, link)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_operator_starts_a_rollout_on_the_fleet_page_and_sees_its_stages_advance() {
    require_chromium();
    let mut fleet = Fleet::new();
    let u1 = fleet.package(&u1_declared(&fleet.root.path().join("u1")), "u1");
    fleet.start(3, "vernadat/vernadat.toml");
    fleet.wait_online();
    let plans = fleet.root.path().join("plans");
    std::fs::create_dir_all(&plans).unwrap();
    let plan = fleet.plan(&u1, "line=1", r#"["1", "100%"]"#, "on_failure = \"stop\"\n");
    std::fs::copy(&plan, plans.join("u1-line1.toml")).unwrap();
    let (_dash, link) = dashboard(&fleet, &plans);

    let c = Browser::start().await;
    c.goto(&link).await.expect("the page loads");
    // Every PLC, with its program and STATUS.
    let rows = "return [...document.querySelectorAll('#fleet-table tbody tr')]\
                .map(r => [...r.cells].map(c => c.textContent));";
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let v = c.js(rows).await;
        let n = v.as_array().map_or(0, |a| {
            (a.iter())
                .filter(|r| {
                    r[1].as_str()
                        .is_some_and(|p| p.starts_with("vernadat-cell"))
                        && r[3] == "idle"
                })
                .count()
        });
        if n == 3 {
            break;
        }
        assert!(
            Instant::now() < end,
            "the fleet table never listed 3 idle PLCs: {v}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    assert_eq!(
        c.js("return document.getElementById('rollout-plan').value;")
            .await,
        "u1-line1.toml"
    );
    c.click_and_confirm("rollout-start").await;
    // The stages advance on the page: stage 1 (the canary), then stage 2, then done.
    let mut seen: Vec<String> = Vec::new();
    let end = Instant::now() + Duration::from_secs(120);
    loop {
        let text = c.text_of("rollout-progress").await;
        if seen.last() != Some(&text) {
            seen.push(text.clone());
        }
        if text.starts_with("done") {
            break;
        }
        assert!(!text.starts_with("halted"), "{seen:#?}");
        assert!(
            Instant::now() < end,
            "the rollout did not end on the page: {seen:#?}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let stage = |k: &str| {
        seen.iter()
            .position(|t| t.starts_with("running") && t.contains(k))
    };
    let (one, two) = (stage("stage 1/2"), stage("stage 2/2"));
    assert!(one.is_some() && two.is_some() && one < two, "{seen:#?}");
    assert!(seen.iter().any(|t| t.contains("quarantine")), "{seen:#?}");
    let steps = c
        .js("return [...document.querySelectorAll('#fleet-table tbody tr')].map(r => r.cells[5].textContent);")
        .await;
    assert_eq!(steps, serde_json::json!(["done", "done", "done"]));
    c.close().await;
    // The same record, from the command line.
    let out = Command::new(BIN)
        .args(["rollout", "status", "--json", "--state-dir"])
        .arg(fleet.root.path().join("rollout"))
        .output()
        .unwrap();
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(r["outcome"], "done", "{r}");
}
