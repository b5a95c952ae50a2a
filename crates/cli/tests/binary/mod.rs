//! What the tests that run the `cetratus` binary on files share: running it, reading its
//! outcome, and the PLCopen fixtures beside the workspace.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// A PLCopen fixture of `../shared/fixtures/plcopen`.
pub fn fixture(name: &str) -> PathBuf {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/fixtures/plcopen")
        .join(name);
    assert!(
        path.exists(),
        "{} is missing; the PLCopen fixtures live beside the workspace in ../shared/fixtures",
        path.display()
    );
    path
}

/// Runs the binary with `args`.
pub fn cetratus(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("cetratus runs")
}

/// What a run that succeeded printed on stdout.
pub fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// What a run that failed printed on stderr.
pub fn refused(out: &Output) -> String {
    assert!(
        !out.status.success(),
        "accepted: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A path as an argument.
pub fn path(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}
