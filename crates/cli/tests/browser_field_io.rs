//! Field I/O on the dashboard, in a real browser: `cetratus run` reads a pymodbus remote I/O
//! device (installed by scripts/test) with the embedded broker and the dashboard, and the page's
//! execution table shows the device's input quality.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::browser::{require_chromium, Browser};
use cetratus_testkit::modbus;
use cetratus_testkit::paths::example;
use cetratus_testkit::ports::{free_port, wait_for_port};
use cetratus_testkit::process::{login_link, stderr_lines, ChildGuard};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_dashboard_shows_the_input_quality_of_each_field_device() {
    require_chromium();
    let dir = tempfile::tempdir().expect("temp dir");
    let (device, mqtt, http) = (free_port(), free_port(), free_port());
    let _device = modbus::device(device, &["--di", "1"]);
    let io = dir.path().join("io.toml");
    std::fs::write(
        &io,
        format!("[[device]]\nname = \"cell\"\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:{device}\"\ntimeout = \"500ms\"\nserves = [{{ from = \"%IX0.0\", to = \"%IX0.7\" }}, {{ from = \"%QX0.0\", to = \"%QX0.7\" }}]\n"),
    )
    .expect("write io.toml");
    let mut plc = ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(example("vernadat/vernadat.toml"))
            .arg("--io")
            .arg(&io)
            .args(["--for", "10min", "--cold", "--plc", "cell1"])
            .args(["--mqtt", &format!("127.0.0.1:{mqtt}")])
            .args(["--http", &format!("127.0.0.1:{http}")])
            .arg("--state-dir")
            .arg(dir.path().join("state"))
            .arg("--config")
            .arg(dir.path().join("config"))
            .stdout(Stdio::null())
            .stderr(Stdio::piped()),
    );
    wait_for_port(http, "the dashboard", Duration::from_secs(60));
    let link = login_link(&stderr_lines(&mut plc.0), Duration::from_secs(30));
    let c = Browser::start().await;
    c.goto(&link).await.expect("the page loads");
    let end = Instant::now() + Duration::from_secs(60);
    let mut table = String::new();
    while Instant::now() < end {
        table = c.text_of("exec-info").await;
        if table.contains("input quality cell") && table.contains("good (link up") {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(
        table.contains("input quality cell") && table.contains("good (link up"),
        "{table}"
    );
    c.close().await;
}
