//! `cetratus sim` plays a program's net under the program's own firing policy, unless `--policy`
//! says otherwise.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");
const EXAMPLES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/vernadat");

fn sim(file: &Path, extra: &[&str]) -> Value {
    let out = Command::new(BIN)
        .arg("sim")
        .arg(file)
        .args(["--json", "--steps", "20"])
        .args(extra)
        .output()
        .expect("cetratus sim");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON report")
}

fn firings_per_step(report: &Value) -> Vec<usize> {
    report["steps"]
        .as_array()
        .expect("steps")
        .iter()
        .map(|s| s["fired"].as_array().map_or(0, Vec::len))
        .collect()
}

#[test]
fn sim_of_a_program_plays_under_the_programs_own_firing_policy() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    std::fs::copy(
        Path::new(EXAMPLES).join("vernadat.pnml"),
        dir.path().join("vernadat.pnml"),
    )
    .expect("copy the net");
    let toml = std::fs::read_to_string(Path::new(EXAMPLES).join("vernadat.toml"))
        .expect("the example program");
    assert!(toml.contains("policy = \"step\""));
    let single = dir.path().join("single.toml");
    std::fs::write(
        &single,
        toml.replace("policy = \"step\"", "policy = \"single-last\""),
    )
    .expect("write the program");

    let own = sim(&single, &[]);
    assert_eq!(own["policy"], "single-last", "{own}");
    assert!(
        firings_per_step(&own).iter().all(|&n| n == 1),
        "one firing per scan: {:?}",
        firings_per_step(&own)
    );
    assert_eq!(own, sim(&single, &["--policy", "single-last"]));

    // `--policy` still wins, and the step policy fires more than one transition in some scan.
    let step = sim(&single, &["--policy", "step"]);
    assert_eq!(step["policy"], "step");
    assert!(firings_per_step(&step).iter().any(|&n| n > 1), "{step}");
}
