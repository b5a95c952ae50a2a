//! Fleet rollouts through the real binary: real `cetratus run` PLCs (the Vernadat cell on its
//! twin, ten times real time) on a real Mosquitto, driven by `cetratus rollout`. The fleets are
//! heavy, so the tests take turns.

#[path = "common/fleet.rs"]
mod fleet;

use std::process::Stdio;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use cetratus_testkit::process::ChildGuard;
use fleet::{broken_u1, report, u1_declared, Fleet};
use serde_json::Value;

/// One fleet at a time: two cores run them.
static TURN: Mutex<()> = Mutex::new(());

fn turn() -> std::sync::MutexGuard<'static, ()> {
    TURN.lock().unwrap_or_else(|p| p.into_inner())
}

/// The alarms a PLC of a rollout must never raise.
const ALARMS: [&str; 4] = ["primary_fault", "stall_alarm", "deadlock_alarm", "reverted"];

#[test]
fn twenty_plcs_take_the_good_u1_in_four_cumulative_stages_and_keep_producing() {
    let _t = turn();
    let mut fleet = Fleet::new();
    let u1 = fleet.package(&u1_declared(&fleet.root.path().join("u1")), "u1");
    fleet.start(20, "vernadat/vernadat.toml");
    fleet.wait_online();
    let plan = fleet.plan(
        &u1,
        "line=1",
        r#"["1", "3", "10", "20"]"#,
        "on_failure = \"stop\"\n",
    );
    let state = fleet.root.path().join("rollout");
    let out = fleet
        .rollout(&["start"], &state)
        .arg(&plan)
        .args(["--wait", "--json"])
        .output()
        .unwrap();
    let r = report(&out);
    assert_eq!(r["outcome"], "done", "{r}");
    let plcs = r["plcs"].as_object().unwrap();
    assert_eq!(plcs.len(), 20);
    let mut per_stage = [0usize; 4];
    for (id, p) in plcs {
        assert_eq!(p["step"], "done", "{id}: {p}");
        per_stage[p["stage"].as_u64().unwrap() as usize - 1] += 1;
    }
    assert_eq!(per_stage, [1, 2, 7, 10]);
    let loads = fleet.events.count("load_accepted");
    assert_eq!(loads.len(), 20, "{loads:?}");
    assert!(loads.values().all(|n| *n == 1), "{loads:?}");
    assert_eq!(fleet.events.count("accepted").len(), 20);
    for alarm in ALARMS {
        assert!(fleet.events.count(alarm).is_empty(), "{alarm}");
    }
    // Every PLC runs U.1 as primary and goes on producing: its outfeed keeps firing.
    let hash = r["program_hash"].as_str().unwrap();
    for id in fleet.plcs.keys() {
        let s = fleet.state(id);
        let primary = s["primary"].as_str().unwrap();
        assert_eq!(s["programs"][primary]["hash"], hash, "{id}");
        assert_eq!(s["status"], "idle", "{id}");
    }
    let outfeed = |id: &str| -> u64 {
        let info = fleet_exec_info(&fleet, id);
        (info.as_array().unwrap().iter())
            .find(|c| c["role"] == "primary")
            .map_or(0, |c| c["firings"]["T24"].as_u64().unwrap_or(0))
    };
    let before: Vec<u64> = fleet.plcs.keys().map(|id| outfeed(id)).collect();
    std::thread::sleep(Duration::from_secs(4));
    for (id, b) in fleet.plcs.keys().zip(before) {
        assert!(outfeed(id) > b, "{id} stopped producing");
    }
}

/// `cetratus exec-info --json` of one PLC of the fleet: `[A, B]`.
fn fleet_exec_info(fleet: &Fleet, id: &str) -> Value {
    let out = std::process::Command::new(fleet::BIN)
        .args(["exec-info", "--json", "--plc", id, "--broker", &fleet.url()])
        .output()
        .unwrap();
    let v: Value = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
    v["result"].clone()
}

#[test]
fn the_broken_u1_stops_at_the_canary_which_is_reverted_and_the_others_never_see_it() {
    let _t = turn();
    let mut fleet = Fleet::new();
    let broken = fleet.package(&broken_u1(&fleet.root.path().join("broken")), "broken");
    fleet.start(5, "vernadat/vernadat.toml");
    fleet.wait_online();
    let plan = fleet.plan(&broken, "*", r#"["1", "100%"]"#, "on_failure = \"stop\"\n");
    // Probation as long as the PLCs' window: the stall must end it, not the clock.
    let text = std::fs::read_to_string(&plan)
        .unwrap()
        .replace("probation = \"10s\"", "probation = \"20s\"");
    std::fs::write(&plan, text).unwrap();
    let state = fleet.root.path().join("rollout");
    let out = fleet
        .rollout(&["start"], &state)
        .arg(&plan)
        .args(["--wait", "--json"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let r = report(&out);
    assert_eq!(r["outcome"], "halted", "{r}");
    let canary = &r["plcs"]["plc-00"];
    assert_eq!(canary["step"], "reverted", "{r}");
    let why = canary["reason"].as_str().unwrap_or("");
    assert!(why.contains("reverted"), "{why}");
    for k in 1..5 {
        assert_eq!(r["plcs"][format!("plc-{k:02}")]["step"], "untouched", "{r}");
    }
    let loads = fleet.events.count("load_accepted");
    assert_eq!(loads.keys().collect::<Vec<_>>(), ["plc-00"], "{loads:?}");
    assert_eq!(fleet.events.count("reverted").get("plc-00"), Some(&1));
    let s = fleet.state("plc-00");
    assert_eq!(s["status"], "idle");
    let primary = s["primary"].as_str().unwrap();
    assert_ne!(s["programs"][primary]["hash"], r["program_hash"]);
}

#[test]
fn a_plc_on_another_base_is_skipped_and_one_already_updated_counts_as_done() {
    let _t = turn();
    let mut fleet = Fleet::new();
    let u1 = fleet.package(&u1_declared(&fleet.root.path().join("u1")), "u1");
    fleet.start(2, "vernadat/vernadat.toml");
    fleet.add("plc-u2", "vernadat/u2.toml", "line = \"1\"");
    fleet.add("plc-u1", "vernadat/u1.toml", "line = \"1\"");
    fleet.wait_online();
    let plan = fleet.plan(&u1, "line=1", r#"["1", "100%"]"#, "on_failure = \"stop\"\n");
    let state = fleet.root.path().join("rollout");
    let out = fleet
        .rollout(&["start"], &state)
        .arg(&plan)
        .args(["--wait", "--json"])
        .output()
        .unwrap();
    let r = report(&out);
    assert_eq!(r["outcome"], "done", "{r}");
    assert_eq!(r["plcs"]["plc-u2"]["step"], "skipped", "{r}");
    let why = r["plcs"]["plc-u2"]["reason"].as_str().unwrap_or("");
    assert!(why.contains("not the package's base"), "{why}");
    assert_eq!(r["plcs"]["plc-u1"]["step"], "done");
    let loads = fleet.events.count("load_accepted");
    assert_eq!(
        loads.keys().collect::<Vec<_>>(),
        ["plc-00", "plc-01"],
        "{loads:?}"
    );
}

#[test]
fn a_rollout_killed_mid_stage_resumes_and_loads_no_plc_twice() {
    let _t = turn();
    let mut fleet = Fleet::new();
    let u1 = fleet.package(&u1_declared(&fleet.root.path().join("u1")), "u1");
    fleet.start(6, "vernadat/vernadat.toml");
    fleet.wait_online();
    let plan = fleet.plan(&u1, "*", r#"["1", "100%"]"#, "on_failure = \"stop\"\n");
    let state = fleet.root.path().join("rollout");
    let first = ChildGuard::spawn(
        fleet
            .rollout(&["start"], &state)
            .arg(&plan)
            .args(["--wait", "--json"])
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    );
    // Kill it once the second stage has PLCs in quarantine.
    let end = Instant::now() + Duration::from_secs(90);
    loop {
        let rec: Value = std::fs::read(state.join("rollout.json"))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or(Value::Null);
        let in_quarantine = (rec["plcs"].as_object().into_iter().flatten())
            .filter(|(_, p)| p["stage"] == 2 && p["step"] == "quarantine")
            .count();
        if in_quarantine >= 2 {
            break;
        }
        assert!(
            Instant::now() < end,
            "stage 2 never reached quarantine: {rec}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    drop(first); // SIGKILL
    let out = fleet
        .rollout(&["resume"], &state)
        .args(["--wait", "--json"])
        .output()
        .unwrap();
    let r = report(&out);
    assert_eq!(r["outcome"], "done", "{r}");
    let loads = fleet.events.count("load_accepted");
    assert_eq!(loads.len(), 6, "{loads:?}");
    assert!(
        loads.values().all(|n| *n == 1),
        "a PLC loaded twice: {loads:?}"
    );
}

#[test]
fn a_plc_killed_during_its_stage_halts_the_rollout_after_the_plans_silent_time() {
    let _t = turn();
    let mut fleet = Fleet::new();
    let u1 = fleet.package(&u1_declared(&fleet.root.path().join("u1")), "u1");
    fleet.start(4, "vernadat/vernadat.toml");
    fleet.wait_online();
    let plan = fleet.plan(
        &u1,
        "*",
        r#"["1", "100%"]"#,
        "on_failure = \"stop\"\nsilent = \"3s\"\n",
    );
    let text = std::fs::read_to_string(&plan)
        .unwrap()
        .replace("\"15s\"", "\"60s\"");
    std::fs::write(&plan, text).unwrap();
    let state = fleet.root.path().join("rollout");
    let mut rollout = fleet.rollout(&["start"], &state);
    let rollout = rollout
        .arg(&plan)
        .args(["--wait", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let end = Instant::now() + Duration::from_secs(60);
    loop {
        let rec: Value = std::fs::read(state.join("rollout.json"))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or(Value::Null);
        if rec["plcs"]["plc-02"]["step"] == "quarantine" {
            break;
        }
        assert!(
            Instant::now() < end,
            "plc-02 never reached quarantine: {rec}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    drop(fleet.plcs.remove("plc-02"));
    let out = rollout.wait_with_output().unwrap();
    let r = report(&out);
    assert_eq!(r["outcome"], "halted", "{r}");
    let why = r["reason"].as_str().unwrap_or("");
    assert!(why.starts_with("plc-02: offline for"), "{why}");
    // The others of its stage were taken back out of quarantine; the canary stays done.
    assert_eq!(r["plcs"]["plc-00"]["step"], "done", "{r}");
    for id in ["plc-01", "plc-03"] {
        assert_eq!(r["plcs"][id]["step"], "removed", "{r}");
        assert_eq!(fleet.state(id)["status"], "idle", "{id}");
    }
}

/// `cetratus rollout start PLAN --wait --json` on the fleet with state in `dir`: its output.
fn start(fleet: &Fleet, plan: &std::path::Path, dir: &str) -> std::process::Output {
    let state = fleet.root.path().join(dir);
    fleet
        .rollout(&["start"], &state)
        .arg(plan)
        .args(["--wait", "--json", "--discover", "1s"])
        .output()
        .unwrap()
}

/// Every plan the rollout cannot follow is refused before anything is sent, with the file, the
/// key and what to write; hostile files (one that never ends, one nested 30 000 deep, binary)
/// cost no more than a refusal.
#[test]
fn bad_plans_are_refused_before_anything_is_sent() {
    let _t = turn();
    let mut fleet = Fleet::new();
    let u1 = fleet.package(&u1_declared(&fleet.root.path().join("u1")), "u1");
    fleet.start(2, "vernadat/vernadat.toml");
    fleet.add("plc-u2", "vernadat/u2.toml", "line = \"2\"");
    fleet.wait_online();
    let good = std::fs::read_to_string(fleet.plan(
        &u1,
        "line=1",
        r#"["1", "100%"]"#,
        "on_failure = \"stop\"\n",
    ))
    .unwrap();
    let path = fleet.root.path().join("bad.toml");
    let nested = format!("stages = {}{}\n", "[".repeat(30_000), "]".repeat(30_000));
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (b"stages = [\n".to_vec(), "bad.toml: TOML parse error"),
        (
            format!("{good}colour = \"red\"\n").into_bytes(),
            "unknown field `colour`",
        ),
        (
            good.replace("\"15s\"", "\"15\"").into_bytes(),
            "`quarantine` `15`",
        ),
        (nested.into_bytes(), "bad.toml"),
        (vec![0xff, 0xfe, 0x00, 0x01], "not UTF-8 text"),
        (
            vec![b'#'; 70_000],
            "more than the 65536 bytes a plan may have",
        ),
        (
            good.replace("line=1", "line=9").into_bytes(),
            "picks no PLC of the fleet",
        ),
        (
            good.replace("select = \"line=1\"", "select = \"line=2\"")
                .into_bytes(),
            "no PLC the selector `line=2` picks runs the package's base",
        ),
        (
            good.replace("probation = \"10s\"", "probation = \"30s\"")
                .into_bytes(),
            "plc-00: its probation window is 20 s, shorter than the plan's probation of 30 s",
        ),
        (
            good.replace(&u1.display().to_string(), "/dev/zero")
                .into_bytes(),
            "more than the 67108864 bytes a package may have",
        ),
    ];
    for (text, says) in cases {
        std::fs::write(&path, &text).unwrap();
        let out = start(&fleet, &path, "refused");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{says}: started");
        assert!(err.contains(says), "{says}: {err}");
    }
    let out = start(&fleet, std::path::Path::new("/dev/zero"), "refused");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("more than the 65536 bytes"), "{err}");
    assert!(
        fleet.events.count("load_accepted").is_empty(),
        "a refused plan loaded a PLC"
    );
    assert!(
        !fleet.root.path().join("refused/rollout.json").exists(),
        "a refused plan was recorded"
    );
}

/// A second rollout from the same state directory is refused at once; one from another reaches
/// a PLC with an update under way and halts there, touching nothing. The first is paused,
/// resumed and aborted from other processes, and its canary is removed.
#[test]
fn a_second_rollout_is_refused_or_halted_and_the_first_is_paused_and_aborted_from_outside() {
    let _t = turn();
    let mut fleet = Fleet::new();
    let u1 = fleet.package(&u1_declared(&fleet.root.path().join("u1")), "u1");
    fleet.start(3, "vernadat/vernadat.toml");
    fleet.wait_online();
    let plan = fleet.plan(&u1, "*", r#"["1", "100%"]"#, "on_failure = \"stop\"\n");
    let text = std::fs::read_to_string(&plan)
        .unwrap()
        .replace("\"15s\"", "\"600s\"");
    std::fs::write(&plan, text).unwrap();
    let first_dir = fleet.root.path().join("first");
    let first = fleet
        .rollout(&["start"], &first_dir)
        .arg(&plan)
        .args(["--wait", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let record = |dir: &std::path::Path| -> Value {
        std::fs::read(dir.join("rollout.json"))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or(Value::Null)
    };
    let end = Instant::now() + Duration::from_secs(60);
    while record(&first_dir)["plcs"]["plc-00"]["step"] != "quarantine" {
        assert!(Instant::now() < end, "the canary never reached quarantine");
        std::thread::sleep(Duration::from_millis(100));
    }
    let same = start(&fleet, &plan, "first");
    let err = String::from_utf8_lossy(&same.stderr);
    assert!(err.contains("a rollout process (pid"), "{err}");
    let other = start(&fleet, &plan, "second");
    let r = report(&other);
    assert_eq!(r["outcome"], "halted", "{r}");
    let why = r["reason"].as_str().unwrap_or("");
    assert!(
        why.starts_with("plc-00: an update is already under way"),
        "{why}"
    );
    assert!(
        r["plcs"]
            .as_object()
            .unwrap()
            .values()
            .all(|p| p["step"] == "untouched"),
        "{r}"
    );
    // Pause and resume from another process, then abort.
    let ask = |verb: &str| {
        let out = fleet.rollout(&[verb], &first_dir).output().unwrap();
        assert!(
            out.status.success(),
            "{verb}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let status = std::process::Command::new(fleet::BIN)
        .args(["rollout", "pause", "--state-dir"])
        .arg(&first_dir)
        .output()
        .unwrap();
    assert!(status.status.success());
    let end = Instant::now() + Duration::from_secs(10);
    while record(&first_dir)["paused"] != true {
        assert!(Instant::now() < end, "the pause was not taken");
        std::thread::sleep(Duration::from_millis(100));
    }
    ask("abort");
    let out = first.wait_with_output().unwrap();
    let r = report(&out);
    assert_eq!(r["outcome"], "aborted", "{r}");
    assert_eq!(r["plcs"]["plc-00"]["step"], "removed", "{r}");
    assert_eq!(r["plcs"]["plc-01"]["step"], "untouched", "{r}");
    let loads = fleet.events.count("load_accepted");
    assert_eq!(loads.keys().collect::<Vec<_>>(), ["plc-00"], "{loads:?}");
    assert_eq!(fleet.state("plc-00")["status"], "idle");
}

/// Two sites, each with its broker, bridged as two plants' brokers would be: half the PLCs on
/// each, the rollout connected to one. It sees every PLC's state through the bridge, its
/// commands reach the other site's PLCs, and their replies and events come back.
#[test]
fn a_rollout_on_one_of_two_bridged_brokers_updates_the_plcs_of_both() {
    let _t = turn();
    let mut fleet = Fleet::new();
    let u1 = fleet.package(&u1_declared(&fleet.root.path().join("u1")), "u1");
    let other = fleet.site();
    fleet.start(2, "vernadat/vernadat.toml");
    for id in ["plc-10", "plc-11"] {
        fleet.add_at(id, "vernadat/vernadat.toml", "line = \"1\"", &other);
    }
    fleet.wait_online();
    let plan = fleet.plan(&u1, "line=1", r#"["1", "100%"]"#, "on_failure = \"stop\"\n");
    let out = start(&fleet, &plan, "rollout");
    let r = report(&out);
    assert_eq!(r["outcome"], "done", "{r}");
    for id in ["plc-00", "plc-01", "plc-10", "plc-11"] {
        assert_eq!(r["plcs"][id]["step"], "done", "{id}: {r}");
    }
    let loads = fleet.events.count("load_accepted");
    assert_eq!(loads.len(), 4, "{loads:?}");
    assert!(loads.values().all(|n| *n == 1), "{loads:?}");
}

/// A publisher as anyone on the broker could run one: `mosquitto_pub -l`, one connection that
/// publishes each line written to it on `topic`, with MQTT 5 correlation data when given.
fn forger(port: u16, topic: &str, correlation: Option<&str>) -> std::process::Child {
    let mut cmd = std::process::Command::new(cetratus_testkit::mqtt::tool("mosquitto_pub"));
    cmd.args(["-h", "127.0.0.1", "-p", &port.to_string(), "-V", "mqttv5"])
        .args(["-t", topic, "-l"]);
    if let Some(c) = correlation {
        cmd.args(["-D", "publish", "correlation-data", c]);
    }
    cmd.stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("mosquitto_pub starts")
}

/// Anyone who may publish on an anonymous broker sends, all through a rollout: `ok: false`
/// replies on the rollout's own reply topic (with no correlation data, and with made-up ones),
/// and garbage `state`, `exec_info` and `events` of its PLCs and of PLCs that do not exist. The
/// rollout takes none of it: both PLCs are updated, and no forged word reaches the report.
#[test]
fn forged_replies_and_garbage_on_the_broker_do_not_stop_a_rollout() {
    let _t = turn();
    let mut fleet = Fleet::new();
    let u1 = fleet.package(&u1_declared(&fleet.root.path().join("u1")), "u1");
    fleet.start(2, "vernadat/vernadat.toml");
    fleet.wait_online();
    let plan = fleet.plan(&u1, "line=1", r#"["1", "100%"]"#, "on_failure = \"stop\"\n");
    let state = fleet.root.path().join("rollout");
    let child = fleet
        .rollout(&["start"], &state)
        .arg(&plan)
        .args(["--wait", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id();
    let port = fleet.broker.port();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    // Blind forgers: `ok: false` replies on the rollout's reply topic with no correlation data
    // or made-up ones, sent the moment the attacker sees a command go to a PLC (racing the
    // PLC's own reply), and garbage of every kind all along.
    let attacker = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            use std::io::{BufRead as _, Write as _};
            let forged = r#"{"ok":false,"request_id":1,"verb":"load","error":{"code":"refused","message":"FORGED"}}"#;
            let big = format!("[{}]", "7,".repeat(300_000) + "7");
            let mut replies = std::collections::BTreeMap::new();
            let mut garbage: Vec<(std::process::Child, String, u32)> = Vec::new();
            for plc in ["plc-00", "plc-01"] {
                let reply = format!("cetratus/{plc}/reply/rollout-{pid}");
                let forgers: Vec<_> = [None, Some("rollout-load-1"), Some("")]
                    .into_iter()
                    .map(|c| forger(port, &reply, c))
                    .collect();
                replies.insert(plc.to_string(), forgers);
                for (leaf, text) in [("state", "{\"online\": 7"), ("events", "{\"kind\": []}")] {
                    let topic = format!("cetratus/{plc}/{leaf}");
                    garbage.push((forger(port, &topic, None), text.to_string(), 1));
                }
                let topic = format!("cetratus/{plc}/exec_info");
                garbage.push((forger(port, &topic, None), big.clone(), 50));
            }
            let ghost = forger(port, "cetratus/ghost/state", None);
            garbage.push((ghost, "{\"online\": true}".into(), 10));
            let mut watch =
                std::process::Command::new(cetratus_testkit::mqtt::tool("mosquitto_sub"))
                    .args([
                        "-h",
                        "127.0.0.1",
                        "-p",
                        &port.to_string(),
                        "-t",
                        "cetratus/+/cmd/#",
                    ])
                    .args(["-F", "%t"])
                    .stdout(Stdio::piped())
                    .spawn()
                    .expect("mosquitto_sub starts");
            let commands = watch.stdout.take().expect("stdout");
            let (seen_tx, seen_rx) = std::sync::mpsc::channel::<String>();
            std::thread::spawn(move || {
                for line in std::io::BufReader::new(commands)
                    .lines()
                    .map_while(Result::ok)
                {
                    let plc = line.split('/').nth(1).unwrap_or("").to_string();
                    if seen_tx.send(plc).is_err() {
                        return;
                    }
                }
            });
            let mut round = 0u32;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                while let Ok(plc) = seen_rx.try_recv() {
                    for f in replies.get_mut(&plc).into_iter().flatten() {
                        let stdin = f.stdin.as_mut().expect("stdin");
                        for _ in 0..20 {
                            let _ = writeln!(stdin, "{forged}");
                        }
                    }
                }
                for (child, text, every) in &mut garbage {
                    if round.is_multiple_of(*every) {
                        let stdin = child.stdin.as_mut().expect("stdin");
                        let _ = writeln!(stdin, "{text}");
                    }
                }
                round += 1;
                std::thread::sleep(Duration::from_millis(2));
            }
            let all = garbage.into_iter().map(|g| g.0);
            for mut child in all.chain(replies.into_values().flatten()).chain([watch]) {
                let _ = child.kill();
                let _ = child.wait();
            }
        })
    };
    let out = child.wait_with_output().unwrap();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    attacker.join().unwrap();
    let r = report(&out);
    assert_eq!(r["outcome"], "done", "{r}");
    for id in ["plc-00", "plc-01"] {
        assert_eq!(r["plcs"][id]["step"], "done", "{id}: {r}");
    }
    assert!(!r.to_string().contains("FORGED"), "{r}");
    assert!(r["plcs"].get("ghost").is_none(), "{r}");
}
