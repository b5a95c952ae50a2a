//! Paths the tests share: the workspace, its examples, the reference nets, and where tests leave
//! artifacts.

use std::path::{Path, PathBuf};

/// The root of the workspace.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The file `rel` of the workspace's `examples/` directory, e.g. `vernadat/u1.toml`.
pub fn example(rel: &str) -> PathBuf {
    workspace_root().join("examples").join(rel)
}

/// The reference net `rel` of the fixtures shared with the other Petri net tools, e.g.
/// `pipe/ClassicGSPN.xml`; they live beside the workspace, in `../shared/fixtures`.
pub fn fixture(rel: &str) -> PathBuf {
    workspace_root().join("../shared/fixtures").join(rel)
}

/// `test-artifacts/` in the target directory, created if needed: screenshots and measured
/// figures that a person looks at after the run.
pub fn artifacts_dir() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_root().join("target"));
    let dir = target.join("test-artifacts");
    std::fs::create_dir_all(&dir)
        .unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
    dir
}
