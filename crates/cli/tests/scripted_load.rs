//! Scripted loads (`run --at "10s load PKG"`): the package is read, verified and built away from
//! the scan thread, and a virtual run stays deterministic: the load takes effect at the cycle its
//! time names, whatever the preparation took.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use cetratus_testkit::process::{demo_files, ChildGuard};
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn p(path: &Path) -> String {
    path.display().to_string()
}

/// The audit log's records as `(cycle, time_us, what)`, in order.
fn audit(state: &Path) -> Vec<(u64, u64, String)> {
    std::fs::read_to_string(state.join("audit.jsonl"))
        .expect("the audit log")
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).expect("an audit record"))
        .map(|r| {
            (
                r["cycle"].as_u64().unwrap_or(0),
                r["time_us"].as_u64().unwrap_or(0),
                r["what"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect()
}

#[test]
fn a_virtual_run_with_scripted_loads_gives_the_same_event_cycles_every_time() {
    let demo = demo_files(BIN);
    let d = demo.path();
    let runs: Vec<Vec<(u64, u64, String)>> = (0..3)
        .map(|_| {
            let state = tempfile::tempdir().expect("a state directory");
            let out = Command::new(BIN)
                .arg("run")
                .arg(d.join("vernadat.toml"))
                .args(["--twin", "vernadat", "--virtual", "--for", "40s", "--json"])
                .args(["--trust", &p(&d.join("trusted"))])
                .args(["--config", &p(&d.join("config"))])
                .args(["--at", &format!("10s load {}", p(&d.join("u1.cpkg")))])
                .args(["--at", "20s substitute"])
                .args(["--at", "22s accept"])
                .args(["--at", &format!("25s load {}", p(&d.join("u2.cpkg")))])
                .arg("--state-dir")
                .arg(state.path())
                .output()
                .expect("cetratus run");
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            audit(state.path())
        })
        .collect();
    let installs: Vec<&(u64, u64, String)> = runs[0]
        .iter()
        .filter(|(_, _, what)| what == "quarantine_started")
        .collect();
    assert_eq!(installs.len(), 2, "{:?}", runs[0]);
    // The time of each `--at` names the cycle: the load is taken at the boundary before the
    // cycle of 10 s (and of 25 s), and installed in it, at the 10 ms period.
    assert_eq!(
        (installs[0].0, installs[0].1),
        (1000, 10_000_000),
        "{:?}",
        runs[0]
    );
    assert_eq!(
        (installs[1].0, installs[1].1),
        (2500, 25_000_000),
        "{:?}",
        runs[0]
    );
    assert_eq!(runs[0], runs[1]);
    assert_eq!(runs[0], runs[2]);
}

#[test]
fn a_scripted_load_whose_file_cannot_be_read_yet_does_not_stop_the_scans() {
    // A named pipe blocks whoever opens it until a writer comes: if the scan thread read the
    // package, the scans would stop at the load's time.
    let demo = demo_files(BIN);
    let d = demo.path();
    let fifo: PathBuf = d.join("late.cpkg");
    let made = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo runs");
    assert!(made.success());
    let state = tempfile::tempdir().expect("a state directory");
    let mut child = Command::new(BIN)
        .arg("run")
        .arg(d.join("vernadat.toml"))
        .args(["--twin", "vernadat", "--no-mqtt", "--for", "10min"])
        .args(["--trust", &p(&d.join("trusted"))])
        .args(["--config", &p(&d.join("config"))])
        .args(["--at", &format!("200ms load {}", p(&fifo))])
        .args(["--progress", "10"])
        .arg("--state-dir")
        .arg(state.path())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("cetratus run starts");
    let stderr = child.stderr.take().expect("stderr");
    let _guard = ChildGuard::new(child);
    let (tx, rx) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    let wait_line = |what: &str, ok: &dyn Fn(&str) -> bool| {
        let end = Instant::now() + Duration::from_secs(30);
        let mut seen = Vec::new();
        while let Some(left) = end.checked_duration_since(Instant::now()) {
            match rx.recv_timeout(left) {
                Ok(l) if ok(&l) => return,
                Ok(l) => seen.push(l),
                Err(_) => break,
            }
        }
        panic!("{what}; the run said:\n{}", seen.join("\n"));
    };
    let cycle_at_least = |n: u64| {
        move |l: &str| {
            l.strip_prefix("progress cycle=")
                .and_then(|r| r.split_whitespace().next())
                .and_then(|c| c.parse::<u64>().ok())
                .is_some_and(|c| c >= n)
        }
    };
    // The load is due at cycle 20; the scans go on well past it while the file waits.
    wait_line(
        "the scans went on past the load's time",
        &cycle_at_least(150),
    );
    let package = std::fs::read(d.join("u1.cpkg")).expect("u1.cpkg");
    std::fs::OpenOptions::new()
        .write(true)
        .open(&fifo)
        .and_then(|mut f| f.write_all(&package))
        .expect("the package goes through the pipe");
    wait_line("the package, once read, is loaded", &|l| {
        l.contains("quarantine_started")
    });
}

#[test]
fn a_json_run_summary_lists_the_runs_events_in_order() {
    let demo = demo_files(BIN);
    let d = demo.path();
    let out = Command::new(BIN)
        .arg("run")
        .arg(d.join("vernadat.toml"))
        .args(["--twin", "vernadat", "--virtual", "--for", "25s", "--json"])
        .args(["--trust", &p(&d.join("trusted"))])
        .args(["--config", &p(&d.join("config"))])
        .args(["--at", &format!("10s load {}", p(&d.join("u1.cpkg")))])
        .args(["--at", "20s substitute"])
        .output()
        .expect("cetratus run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: Value = serde_json::from_slice(&out.stdout).expect("one JSON summary");
    let kinds: Vec<&str> = summary["events"]
        .as_array()
        .unwrap_or_else(|| panic!("the summary has events: {summary}"))
        .iter()
        .map(|e| e["kind"].as_str().unwrap_or(""))
        .collect();
    assert_eq!(
        kinds,
        [
            "cold_start",
            "load_accepted",
            "verdict",
            "quarantine_started",
            "substitute_accepted",
            "substituted",
            "probation_started"
        ],
        "{summary}"
    );
    let substituted = &summary["events"][5];
    assert_eq!(substituted["time_us"], 20_000_000, "{substituted}");
    assert!(
        substituted["message"]
            .as_str()
            .is_some_and(|m| m.contains("PRIMARY = B")),
        "{substituted}"
    );
    assert_eq!(summary["events_left_out"], 0);
}

/// The kinds and messages of the events in a `run --json` summary.
fn summary_events(out: &std::process::Output) -> Vec<(String, String)> {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: Value = serde_json::from_slice(&out.stdout).expect("one JSON summary");
    summary["events"]
        .as_array()
        .unwrap_or_else(|| panic!("the summary has events: {summary}"))
        .iter()
        .map(|e| {
            (
                e["kind"].as_str().unwrap_or("").to_string(),
                e["message"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect()
}

#[test]
fn the_analysis_gate_reports_at_load_and_refuses_a_deadlocking_package_when_told_to() {
    let demo = demo_files(BIN);
    let d = demo.path();
    // U.1 without T24: machine 2's part is never unloaded, and the cell comes to a dead stop.
    let net = std::fs::read_to_string(d.join("u1.pnml")).expect("u1.pnml");
    let start = net.find("<transition id=\"T24\">").expect("T24");
    let end = start + net[start..].find("</transition>").expect("end") + "</transition>".len();
    let mut cut = format!("{}{}", &net[..start], &net[end..]);
    for arc in [
        "P23-T24\" source=\"P23\" target=\"T24\"/>",
        "R-T24\" source=\"R\" target=\"T24\"/>",
        "T24-P24\" source=\"T24\" target=\"P24\"/>",
    ] {
        cut = cut.replace(&format!("<arc id=\"{arc}"), "");
    }
    std::fs::write(d.join("u1.pnml"), cut).expect("write");
    let built = Command::new(BIN)
        .args(["package", "build"])
        .arg(d.join("u1.package.toml"))
        .arg("--key")
        .arg(d.join("demo.key"))
        .arg("-o")
        .arg(d.join("stuck.cpkg"))
        .output()
        .expect("cetratus package build");
    assert!(
        built.status.success(),
        "{}",
        String::from_utf8_lossy(&built.stderr)
    );
    let strict = d.join("strict");
    std::fs::create_dir(&strict).expect("a configuration directory");
    std::fs::write(
        strict.join("config.toml"),
        "[updates]\ngate_deadlock = \"refuse\"\n",
    )
    .expect("config.toml");
    let run = |config: &Path, package: &str| {
        Command::new(BIN)
            .arg("run")
            .arg(d.join("vernadat.toml"))
            .args(["--twin", "vernadat", "--virtual", "--for", "12s", "--json"])
            .args(["--trust", &p(&d.join("trusted"))])
            .args(["--config", &p(config)])
            .args(["--at", &format!("10s load {}", p(&d.join(package)))])
            .output()
            .expect("cetratus run")
    };

    // By default a finding is a warning: the load goes on, and the verdict is an event.
    let events = summary_events(&run(&d.join("config"), "stuck.cpkg"));
    let verdict = events
        .iter()
        .find(|(k, _)| k == "verdict")
        .unwrap_or_else(|| panic!("{events:?}"));
    assert!(
        verdict.1.starts_with("analysis verdict on U.1"),
        "{}",
        verdict.1
    );
    assert!(verdict.1.contains(": warn: deadlock"), "{}", verdict.1);
    assert!(
        events.iter().any(|(k, _)| k == "quarantine_started"),
        "{events:?}"
    );

    // With `gate_deadlock = "refuse"` the package is refused before the scan thread sees it; a
    // scripted load that is refused ends the run, as any scripted package that cannot load.
    let out = run(&strict, "stuck.cpkg");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("refused by the analysis gate: deadlock"),
        "{err}"
    );
    // From the marking the install transforms at 10 s, where a part waits in the buffer for
    // T20; from the cold start's marking the sequence would begin with T10.
    assert!(
        err.contains("a shortest firing sequence to one: T20 "),
        "{err}"
    );
    assert!(
        !err.contains("lost transitions"),
        "only deadlocks refuse: {err}"
    );

    // The intact U.1 passes, under the same policy.
    let events = summary_events(&run(&strict, "u1.cpkg"));
    assert!(
        events
            .iter()
            .any(|(k, m)| k == "verdict" && m.ends_with(": pass")),
        "{events:?}"
    );
}

#[test]
fn twin_validation_gives_verdicts_in_quarantine_and_probation_and_require_verdict_holds_substitution(
) {
    let demo = demo_files(BIN);
    let d = demo.path();
    let config = |name: &str, text: &str| {
        let dir = d.join(name);
        std::fs::create_dir(&dir).expect("a configuration directory");
        std::fs::write(dir.join("config.toml"), text).expect("config.toml");
        dir
    };
    let run = |config: &Path| {
        Command::new(BIN)
            .arg("run")
            .arg(d.join("vernadat.toml"))
            .args(["--twin", "vernadat", "--virtual", "--for", "25s", "--json"])
            .args(["--trust", &p(&d.join("trusted"))])
            .args(["--config", &p(config)])
            .args(["--at", &format!("10s load {}", p(&d.join("u1.cpkg")))])
            .args(["--at", "20s substitute"])
            .output()
            .expect("cetratus run")
    };

    // Thirty seconds of plant time from the load: U.1 does not diverge from the old program
    // in them (its buffer fills later), so the quarantine verdict passes after its 500 cycles
    // and the substitution at 20 s is allowed.
    let fork = config(
        "fork",
        "[updates]\nvalidation = \"fork\"\nhorizon = \"30s\"\nrequire_verdict = true\n",
    );
    let events = summary_events(&run(&fork));
    let twin: Vec<&(String, String)> = events
        .iter()
        .filter(|(k, m)| k == "verdict" && m.starts_with("twin verdict"))
        .collect();
    assert_eq!(
        twin.len(),
        2,
        "one in quarantine, one in probation: {events:?}"
    );
    assert!(twin.iter().all(|(_, m)| m.contains(": pass")), "{twin:?}");
    let quarantine: Vec<&(String, String)> = events
        .iter()
        .filter(|(k, m)| k == "verdict" && m.starts_with("quarantine verdict"))
        .collect();
    assert!(
        quarantine.len() == 1 && quarantine[0].1.contains(": pass"),
        "{quarantine:?}"
    );
    let order: Vec<&str> = events.iter().map(|(k, _)| k.as_str()).collect();
    let q = order
        .iter()
        .position(|k| *k == "quarantine_started")
        .expect("quarantine");
    let s = order
        .iter()
        .position(|k| *k == "substituted")
        .expect("substituted: the verdict passed");
    assert!(q < s, "{order:?}");

    // Without validation, a PLC that requires a verdict refuses the substitution.
    let strict = config("strict", "[updates]\nrequire_verdict = true\n");
    let events = summary_events(&run(&strict));
    assert!(
        !events.iter().any(|(k, _)| k == "substituted"),
        "{events:?}"
    );
    assert!(
        events
            .iter()
            .any(|(k, m)| k == "refused" && m.contains("requires a passing twin verdict")),
        "{events:?}"
    );
}

/// `demo --scripted` gates its loads as a run does: each has an analysis verdict (U.1 passes,
/// U.2 warns that it changes the old machine invariants), in its events and in the candidate's
/// `exec_info`; and the configuration's policy holds, so `gate_broken_invariants = "refuse"`
/// refuses U.2 and the experiment stops with the gate's reason.
#[test]
fn the_scripted_demo_gates_its_loads_as_a_run_does() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let config = dir.path().join("config");
    std::fs::create_dir(&config).expect("a configuration directory");
    let demo = |config: &Path| {
        Command::new(BIN)
            .args(["demo", "--scripted", "--json", "--dir"])
            .arg(dir.path().join("demo"))
            .args(["--config", &p(config)])
            .output()
            .expect("cetratus demo")
    };
    let out = demo(&config);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rec: Value = serde_json::from_slice(&out.stdout).expect("the record");
    let verdicts: Vec<String> = rec["events"]
        .as_array()
        .expect("events")
        .iter()
        .filter(|e| e["kind"] == "verdict")
        .filter_map(|e| e["message"].as_str().map(str::to_string))
        .collect();
    assert_eq!(verdicts.len(), 2, "{verdicts:?}");
    assert!(
        verdicts[0].starts_with("analysis verdict on U.1") && verdicts[0].ends_with(": pass"),
        "{verdicts:?}"
    );
    assert!(
        verdicts[1].starts_with("analysis verdict on U.2")
            && verdicts[1].contains(": warn: broken invariants"),
        "{verdicts:?}"
    );
    let in_quarantine = &rec["exec_info"][0];
    let candidate = in_quarantine
        .as_array()
        .and_then(|c| c.iter().find(|c| c["role"] == "candidate"))
        .unwrap_or_else(|| panic!("{in_quarantine}"));
    assert_eq!(candidate["verdicts"][0]["kind"], "analysis", "{candidate}");

    let strict = dir.path().join("strict");
    std::fs::create_dir(&strict).expect("a configuration directory");
    std::fs::write(
        strict.join("config.toml"),
        "[updates]\ngate_broken_invariants = \"refuse\"\n",
    )
    .expect("config.toml");
    let out = demo(&strict);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("refused by the analysis gate: broken invariants"),
        "{err}"
    );
}

/// A plant that is not the model, from the command line: `--twin-param m2_machining=24s` makes
/// machine 2 four times slower than the commissioning twin's. U.1 with a timeout bug (it unloads
/// M2 after 10 s whether or not M2 is done) passes on the twin, where M2 is always done first,
/// and fails in quarantine on the plant with the divergence the twin never showed; on a plant
/// like the model its quarantine passes. A parameter the twin lacks is refused, naming those it
/// has.
#[test]
fn a_plant_given_other_twin_parameters_fails_the_quarantine_of_a_candidate_the_twin_passed() {
    let demo = demo_files(BIN);
    let d = demo.path();
    let u1 = std::fs::read_to_string(d.join("u1.toml")).expect("u1.toml");
    std::fs::write(
        d.join("u1.toml"),
        u1.replace("T22 = \"FPM2\"", "T22 = \"FPM2 || P21.t >= 10s\""),
    )
    .expect("write");
    let pkg = d.join("u1-timeout.cpkg");
    let out = Command::new(BIN)
        .args(["package", "build", &p(&d.join("u1.package.toml"))])
        .args(["--key", &p(&d.join("demo.key")), "-o", &p(&pkg)])
        .output()
        .expect("cetratus package build");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let config = d.join("commission");
    std::fs::create_dir(&config).expect("a configuration directory");
    std::fs::write(
        config.join("config.toml"),
        "[updates]\nvalidation = \"commission\"\nvalidation_twin = \"vernadat\"\n",
    )
    .expect("config.toml");
    let run = |params: &[&str]| {
        Command::new(BIN)
            .arg("run")
            .arg(d.join("vernadat.toml"))
            .args(["--twin", "vernadat", "--virtual", "--for", "120s", "--json"])
            .args(params)
            .args(["--trust", &p(&d.join("trusted"))])
            .args(["--config", &p(&config)])
            .args(["--at", &format!("2s load {}", p(&pkg))])
            .output()
            .expect("cetratus run")
    };
    let quarantine = |out: &std::process::Output| -> Vec<String> {
        summary_events(out)
            .into_iter()
            .filter(|(k, m)| k == "verdict" && m.starts_with("quarantine verdict"))
            .map(|(_, m)| m)
            .collect()
    };
    let slow = quarantine(&run(&["--twin-param", "m2_machining=24s"]));
    assert!(
        slow.iter().any(|m| m.contains(": fail")
            && m.contains("T22 fired in the candidate only")
            && m.contains("the twin never showed it")),
        "{slow:#?}"
    );
    let like = quarantine(&run(&[]));
    assert!(
        !like.is_empty() && like.iter().all(|m| m.contains(": pass")),
        "{like:#?}"
    );
    let out = run(&["--twin-param", "m3_machining=24s"]);
    assert!(!out.status.success());
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(
        said.contains("m3_machining") && said.contains("m2_machining"),
        "{said}"
    );
}
