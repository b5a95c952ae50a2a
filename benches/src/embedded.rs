//! The files the workloads read, embedded in the binary so that `cetratus bench` runs from any
//! directory, source tree or not. They are written once per process into a directory of the
//! system's temporary directory, named after the process.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The Festo station, which `cetratus bench export` exports.
const FESTO: [(&str, &str); 2] = [
    (
        "festo.toml",
        include_str!("../../examples/festo/festo.toml"),
    ),
    (
        "festo.pnml",
        include_str!("../../examples/festo/festo.pnml"),
    ),
];

/// The Vernadat cell as an SFC chart, which `cetratus bench export` exports back as a chart.
pub const VERNADAT_SFC: &str = include_str!("../../examples/vernadat-sfc/vernadat-sfc.xml");

/// The plain-Python BFS baseline of the analysis figures.
const BFS_BASELINE: &str = include_str!("../../scripts/bfs_baseline.py");

/// Where the embedded files are: `examples/vernadat/*`, the Festo station and
/// `scripts/bfs_baseline.py`, as in the
/// source tree.
pub fn root() -> &'static Path {
    static ROOT: OnceLock<PathBuf> = OnceLock::new();
    ROOT.get_or_init(|| {
        let root =
            std::env::temp_dir().join(format!("cetratus-bench-files-{}", std::process::id()));
        let write = |rel: &str, text: &str| {
            let path = root.join(rel);
            if let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir)
                    .unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
            }
            std::fs::write(&path, text)
                .unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
        };
        for (name, text) in cetratus_node::demo::FILES {
            write(&format!("examples/vernadat/{name}"), text);
        }
        for (name, text) in FESTO {
            write(&format!("examples/festo/{name}"), text);
        }
        write("scripts/bfs_baseline.py", BFS_BASELINE);
        root
    })
}

/// The examples directory (`vernadat/` in it).
pub fn examples_dir() -> PathBuf {
    root().join("examples")
}

/// The Python baseline script.
pub fn bfs_baseline() -> PathBuf {
    root().join("scripts/bfs_baseline.py")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_embedded_examples_load_outside_the_source_tree() {
        let p = cetratus_program::Program::load(&examples_dir().join("vernadat/vernadat.toml"));
        assert!(p.is_ok(), "{:?}", p.err());
        assert!(bfs_baseline().is_file());
    }

    #[test]
    fn building_the_packages_leaves_the_embedded_examples_in_place() {
        let _ = crate::update::packages();
        assert!(examples_dir().join("vernadat/vernadat.toml").is_file());
    }
}
