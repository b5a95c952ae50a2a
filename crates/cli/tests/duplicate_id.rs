//! Two PLCs given the same id on one plant broker take each other's MQTT session, over and over
//! (the broker drops the older connection when the same client id connects again). Each must
//! say so: a line on stderr naming the id and what to do, and an `id_taken_over` event on the
//! PLC's `events` topic once it is back, so that an operator sees it on the dashboard.

use std::fs::File;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use cetratus_testkit::mqtt::{sub_one, Mosquitto, Sub};
use cetratus_testkit::paths::example;
use cetratus_testkit::process::ChildGuard;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");
const PLC: &str = "twin1";

/// A PLC on the plant broker at `url`, its stderr written to `log`.
fn plc(url: &str, dir: &Path, name: &str) -> ChildGuard {
    let config = dir.join(format!("{name}-config"));
    std::fs::create_dir(&config).expect("config dir");
    let log = File::create(dir.join(format!("{name}.log"))).expect("log file");
    ChildGuard::spawn(
        Command::new(BIN)
            .arg("run")
            .arg(example("vernadat/vernadat.toml"))
            .args(["--twin", "vernadat", "--for", "10min", "--plc", PLC])
            .args(["--broker", url, "--no-dashboard", "--cold"])
            .arg("--config")
            .arg(&config)
            .arg("--state-dir")
            .arg(dir.join(format!("{name}-state")))
            .env_remove("RUST_LOG")
            .stdout(Stdio::null())
            .stderr(Stdio::from(log)),
    )
}

#[test]
fn two_plcs_with_one_id_on_a_plant_broker_say_so() {
    let dir = tempfile::tempdir().expect("temp dir");
    let broker = Mosquitto::start();
    let url = format!("mqtt://127.0.0.1:{}", broker.port());
    let _a = plc(&url, dir.path(), "a");
    let end = Instant::now() + Duration::from_secs(60);
    while sub_one(broker.port(), &format!("cetratus/{PLC}/state"), 2, false).is_none() {
        assert!(Instant::now() < end, "the first PLC publishes its state");
    }
    let events = Sub::start(broker.port(), &[&format!("cetratus/{PLC}/events")], 200, 30);
    let _b = plc(&url, dir.path(), "b");

    let said = |name: &str| {
        let log =
            std::fs::read_to_string(dir.path().join(format!("{name}.log"))).unwrap_or_default();
        log.lines()
            .find(|l| l.contains("client id") && l.contains(PLC) && l.contains("--plc"))
            .map(str::to_string)
    };
    let end = Instant::now() + Duration::from_secs(30);
    let line = loop {
        if let Some(l) = said("a").or_else(|| said("b")) {
            break l;
        }
        assert!(
            Instant::now() < end,
            "neither PLC said that another took its client id:\n{}\n{}",
            std::fs::read_to_string(dir.path().join("a.log")).unwrap_or_default(),
            std::fs::read_to_string(dir.path().join("b.log")).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    assert!(line.contains("another"), "{line}");

    let seen = events.messages();
    let alarm = seen.iter().find(|e| e["kind"] == "id_taken_over");
    assert!(
        alarm.is_some(),
        "no id_taken_over event among {} events: {seen:?}",
        seen.len()
    );
    let message = alarm
        .and_then(|e| e["message"].as_str())
        .unwrap_or_default();
    assert!(
        message.contains(PLC) && message.contains("--plc"),
        "{message}"
    );
}
