//! `cetratus package inspect --base` shows a signed package's matrices resolved against a
//! program, whoever signed it: inspecting trusts nothing and loads nothing.

use std::process::Command;

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

#[test]
fn inspect_with_a_base_resolves_a_signed_package_whose_key_nobody_trusted() {
    let dir = cetratus_testkit::process::demo_files(BIN);
    let (u1, base) = (dir.path().join("u1.cpkg"), dir.path().join("vernadat.toml"));

    let out = Command::new(BIN)
        .args(["package", "inspect"])
        .arg(&u1)
        .arg("--base")
        .arg(&base)
        .output()
        .expect("inspect");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("signed by"), "{stdout}");
    assert!(
        stdout.contains("state transform (dense), resolved against vernadat-cell 1.0.0"),
        "{stdout}"
    );

    let out = Command::new(BIN)
        .args(["package", "inspect", "--json"])
        .arg(&u1)
        .arg("--base")
        .arg(&base)
        .output()
        .expect("inspect --json");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(v["resolved"]["base"]["is_the_packages_base"], true, "{v}");
    assert_eq!(v["signature_checked"], false, "{v}");
    assert!(
        v["resolved"]["transform"].is_string() || v["resolved"]["transform"].is_object(),
        "{v}"
    );
}
