//! `cetratus bench` carries its workloads: it runs from a directory that is not the source tree,
//! as a deployed binary does.

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

#[test]
fn bench_jitter_runs_from_a_directory_outside_the_source_tree() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = Command::new(BIN)
        .current_dir(dir.path())
        // The embedded workloads are written under the temporary directory: here, so that the
        // test sees that they came from the binary and not from a source tree.
        .env("TMPDIR", dir.path())
        .args([
            "bench", "jitter", "--period", "10ms", "--for", "300ms", "--json",
        ])
        .output()
        .expect("run cetratus");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert!(v["cycles"].as_u64().is_some_and(|n| n > 0), "{v}");
    let written = std::fs::read_dir(dir.path())
        .expect("list")
        .filter_map(Result::ok)
        .any(|e| e.path().join("examples/vernadat/vernadat.toml").is_file());
    assert!(written, "the program came from the binary's embedded copy");
}
