//! A valid candidate in quarantine must not take the primary's time, against the real binary:
//! a package whose program runs action bodies of 15 KiB on a place that stays marked.
//!
//! * Its scans are charged the instructions of the guards and bodies they run, so at a 2 ms
//!   period (a budget of 50,000 instructions) eight such bodies are stopped by the budget, in a
//!   virtual run, and the fault names the body. Counting guard evaluations alone, as before,
//!   let it run in quarantine for ever.
//! * With the budget raised out of the way, in real time at 5 ms, a candidate whose scans make
//!   the primary overrun more cycles than before the load is faulted for it.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/vernadat")
        .join(name)
}

/// One statement of about 400 bytes: `w := w * 1 * 1 …`, 202 instructions.
fn heavy_statement() -> String {
    format!("w := w{}\n", " * 1".repeat(100))
}

/// Builds, unsigned, U.1 with `bodies` action bodies of nearly 16 KiB, each run by an `N`
/// action on `H` (the buffer's free slots, never all taken in this run).
fn heavy_package(dir: &Path, bodies: usize) -> PathBuf {
    for f in [
        "u1.package.toml",
        "u1.pnml",
        "vernadat.toml",
        "vernadat.pnml",
    ] {
        std::fs::copy(example(f), dir.join(f)).expect("copy the example");
    }
    let mut toml = std::fs::read_to_string(example("u1.toml")).expect("u1.toml");
    toml.push_str("\n[[variable]]\nname = \"w\"\ntype = \"int\"\n");
    for k in 0..bodies {
        toml.push_str(&format!(
            "\n[[action]]\nplace = \"H\"\nqualifier = \"N\"\nbody = \"Heavy{k}\"\n"
        ));
    }
    toml.push_str("\n[bodies]\n");
    let body = heavy_statement().repeat(37);
    assert!(body.len() < 16 * 1024, "{}", body.len());
    for k in 0..bodies {
        toml.push_str(&format!("Heavy{k} = '''\n{body}'''\n"));
    }
    std::fs::write(dir.join("u1.toml"), toml).expect("write u1.toml");
    let pkg = dir.join("heavy.cpkg");
    let out = Command::new(BIN)
        .args(["package", "build", "--unsigned", "-o"])
        .arg(&pkg)
        .arg(dir.join("u1.package.toml"))
        .output()
        .expect("package build");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    pkg
}

/// A configuration directory that takes unsigned packages, with `more` added.
fn config(dir: &Path, more: &str) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let c = dir.join("config");
    std::fs::create_dir(&c).expect("mkdir config");
    std::fs::write(
        c.join("config.toml"),
        format!("allow_unsigned = true\n{more}"),
    )
    .expect("config.toml");
    std::fs::set_permissions(&c, std::fs::Permissions::from_mode(0o700)).expect("chmod");
    c
}

/// Runs the Vernadat cell on its twin with `args`, loading `pkg` at `load_at`; returns the
/// audit log's records.
fn run(dir: &Path, cfg: &Path, pkg: &Path, args: &[&str], load_at: &str) -> Vec<Value> {
    let state = dir.join("state");
    let out = Command::new(BIN)
        .arg("run")
        .arg(example("vernadat.toml"))
        .args(["--twin", "vernadat", "--no-dashboard"])
        .args(args)
        .arg("--config")
        .arg(cfg)
        .args(["--at", &format!("{load_at} load {}", pkg.display())])
        .arg("--state-dir")
        .arg(&state)
        .output()
        .expect("cetratus run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::read_to_string(state.join("audit.jsonl"))
        .expect("the audit log")
        .lines()
        .map(|l| serde_json::from_str(l).expect("an audit record"))
        .collect()
}

/// Held by each test of this file: the real-time one measures the primary's overruns against
/// their level before the load, which the other one's busy virtual run would raise.
static TURN: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn records<'a>(audit: &'a [Value], what: &str) -> Vec<&'a Value> {
    audit.iter().filter(|r| r["what"] == what).collect()
}

#[test]
fn a_candidate_whose_bodies_pass_its_instruction_budget_is_stopped_and_the_body_named() {
    let _turn = TURN.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().expect("a temporary directory");
    let pkg = heavy_package(dir.path(), 8);
    let cfg = config(dir.path(), "");
    let audit = run(
        dir.path(),
        &cfg,
        &pkg,
        &["--virtual", "--for", "3s", "--period", "2ms"],
        "1s",
    );
    assert_eq!(
        records(&audit, "quarantine_started").len(),
        1,
        "the package was loaded: {audit:?}"
    );
    let faults = records(&audit, "candidate_fault");
    let [fault] = faults.as_slice() else {
        panic!("the candidate was not stopped by its budget: {audit:?}")
    };
    let said = fault["message"].as_str().unwrap_or_default().to_string();
    assert!(
        said.contains("action body `Heavy") && said.contains("work budget of 50000 units"),
        "{said}"
    );
}

#[test]
fn a_candidate_that_makes_the_primary_overrun_is_faulted_in_real_time() {
    let _turn = TURN.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().expect("a temporary directory");
    // About 180,000 instructions a scan: 8 to 16 ms in a debug build, past the 5 ms period and
    // within the candidate's time budget of ten periods, with room for a preemption.
    let pkg = heavy_package(dir.path(), 24);
    let cfg = config(
        dir.path(),
        "[updates]\ncandidate_instruction_budget = 1000000000\n",
    );
    let audit = run(
        dir.path(),
        &cfg,
        &pkg,
        &["--for", "12s", "--period", "5ms"],
        "2s",
    );
    let faults = records(&audit, "candidate_fault");
    let [fault] = faults.as_slice() else {
        panic!("the candidate was not faulted: {audit:?}")
    };
    let said = fault["message"].as_str().unwrap_or_default().to_string();
    assert!(said.contains("takes the primary's time"), "{said}");
}
