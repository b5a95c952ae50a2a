//! The state directory decides what the next warm start runs as PRIMARY, so only the PLC's user
//! may write it (docs/persistence.md, *Who may write it*): a directory others may write stops
//! the start with what to run, and what the PLC creates there is its user's alone. Tried
//! against the real binary.

use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// A short virtual run of the Vernadat example with `state` as its state directory.
fn run(state: &Path, config: &Path) -> Output {
    Command::new(BIN)
        .arg("run")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../examples/vernadat/vernadat.toml"
        ))
        .args(["--twin", "vernadat", "--virtual", "--for", "2s", "--json"])
        .arg("--state-dir")
        .arg(state)
        .arg("--config")
        .arg(config)
        .output()
        .expect("cetratus runs")
}

fn mode(p: &Path) -> u32 {
    std::fs::metadata(p).expect("metadata").permissions().mode() & 0o777
}

#[test]
fn a_state_directory_that_others_may_write_stops_the_start_and_says_what_to_run() {
    let work = tempfile::tempdir().expect("a directory");
    let config = work.path().join("config");
    std::fs::create_dir(&config).expect("mkdir");
    std::fs::set_permissions(&config, std::fs::Permissions::from_mode(0o700)).expect("chmod");
    let state = work.path().join("state");
    std::fs::create_dir(&state).expect("mkdir");
    // A writable state directory let a local user put an unsigned program into a snapshot.
    std::fs::set_permissions(&state, std::fs::Permissions::from_mode(0o777)).expect("chmod");
    let out = run(&state, &config);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("writable by its group or others") && err.contains("chmod go-w"),
        "{err}"
    );

    // Made private, it starts; and what the PLC made there is its user's alone.
    std::fs::set_permissions(&state, std::fs::Permissions::from_mode(0o700)).expect("chmod");
    let fresh = work.path().join("fresh/state");
    for dir in [&state, &fresh] {
        let out = run(dir, &config);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        for file in ["lock", "state.json", "audit.jsonl"] {
            assert_eq!(mode(&dir.join(file)), 0o600, "{file}");
        }
    }
    assert_eq!(mode(&fresh), 0o700, "a state directory the PLC creates");
    assert_eq!(mode(&fresh.join("programs")), 0o700);
}
