//! What the PLC trusts from its disk is its user's alone, tried against the real binary: the
//! state directory decides what the next warm start runs as PRIMARY (docs/persistence.md, *Who
//! may write it*), the key files which packages and commands are taken, the TLS key who may pose
//! as the PLC (docs/configuration.md). One that others may change, or a TLS key others may read,
//! stops the start with what to run; what the PLC creates is its user's alone.

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

/// A configuration directory of this user's, mode 0700, holding `config` as `config.toml`.
fn private_config(work: &Path, config: &str) -> std::path::PathBuf {
    let dir = work.join("config");
    std::fs::create_dir_all(dir.join("trusted")).expect("mkdir");
    for d in [dir.clone(), dir.join("trusted")] {
        std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o700)).expect("chmod");
    }
    let file = dir.join("config.toml");
    std::fs::write(&file, config).expect("write");
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).expect("chmod");
    dir
}

#[test]
fn a_key_file_others_may_change_or_a_tls_key_others_may_read_stops_the_start() {
    let work = tempfile::tempdir().expect("a directory");
    let state = work.path().join("state");
    // A world-writable `trusted/*.pub` was once taken without a word.
    let config = private_config(work.path(), "");
    let key = config.join("trusted/theirs.pub");
    std::fs::write(&key, "not even a key").expect("write");
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o666)).expect("chmod");
    let out = run(&state, &config);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("theirs.pub") && err.contains("writable by others"),
        "{err}"
    );
    std::fs::remove_file(&key).expect("rm");

    // A TLS key that everyone may read.
    let config = private_config(
        work.path(),
        "[mqtt]\ntls_cert = \"cert.pem\"\ntls_key = \"key.pem\"\n",
    );
    std::fs::write(config.join("cert.pem"), "a certificate").expect("write");
    std::fs::write(config.join("key.pem"), "a key").expect("write");
    std::fs::set_permissions(
        config.join("key.pem"),
        std::fs::Permissions::from_mode(0o644),
    )
    .expect("chmod");
    let out = run(&state, &config);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("key.pem is readable by others") && err.contains("chmod 600"),
        "{err}"
    );
}
