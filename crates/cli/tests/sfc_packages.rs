//! Package manifests that name PLCopen files: the package binds to the hash `cetratus import
//! plcopen` gives, added steps start inactive, and a reachable removed step without a mapping
//! refuses the build, naming the step. Through the real binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/fixtures/plcopen")
        .join(name)
}

fn cetratus(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .env("SOURCE_DATE_EPOCH", "1700000000")
        .output()
        .expect("cetratus runs")
}

fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// A directory holding the two TwinCAT versions as `v1.xml` and `v6.xml`.
fn versions() -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("a temporary directory");
    for (from, to) in [
        ("twincat-sfc-evolution-1.xml", "v1.xml"),
        ("twincat-sfc-evolution-6.xml", "v6.xml"),
    ] {
        std::fs::copy(fixture(from), dir.path().join(to)).expect("copies the fixture");
    }
    dir
}

fn manifest(dir: &Path, program: &str, base: &str, extra: &str) -> String {
    let path = dir.join("m.package.toml");
    std::fs::write(
        &path,
        format!(
            "[package]\nname = \"sfc\"\nversion = \"2\"\nprogram = \"{program}\"\npou = \"Main\"\n\
             base = \"{base}\"\nbase_pou = \"main\"\n{extra}"
        ),
    )
    .expect("writes the manifest");
    path.to_str().expect("UTF-8").to_string()
}

fn import_hash(dir: &Path, file: &str) -> String {
    let out = cetratus(&[
        "import",
        "plcopen",
        dir.join(file).to_str().expect("UTF-8"),
        "-o",
        dir.join(format!("out-{file}")).to_str().expect("UTF-8"),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    String::from_utf8_lossy(&out.stdout)
        .rsplit("program hash ")
        .next()
        .expect("a hash")
        .trim()
        .to_string()
}

#[test]
fn a_manifest_naming_plcopen_files_binds_to_the_hashes_the_import_gives() {
    let dir = versions();
    let (h1, h6) = (
        import_hash(dir.path(), "v1.xml"),
        import_hash(dir.path(), "v6.xml"),
    );
    let m = manifest(dir.path(), "v6.xml", "v1.xml", "");
    let pkg = dir.path().join("p.json");
    let out = cetratus(&[
        "package",
        "build",
        &m,
        "--unsigned",
        "--out",
        pkg.to_str().expect("UTF-8"),
    ]);
    let printed = text(&out);
    assert!(out.status.success(), "{printed}");
    assert!(printed.contains(&format!("Main 1  {h6}")), "{printed}");
    assert!(
        printed.contains(&format!("base        Main 1  {h1}")),
        "{printed}"
    );
    // v6 adds Step2 and Step3 after Step1: they start inactive (their ST_base is 0), whatever
    // the old chart's state.
    for step in ["Step2", "Step3"] {
        let row = printed
            .lines()
            .find(|l| l.starts_with(step))
            .unwrap_or_else(|| panic!("no row {step}: {printed}"));
        assert!(row.ends_with("|    0") && !row.contains('1'), "{printed}");
    }
}

#[test]
fn a_removed_step_the_old_chart_can_reach_refuses_the_build_unless_it_is_mapped() {
    let dir = versions();
    let pkg = dir.path().join("p.json");
    let pkg = pkg.to_str().expect("UTF-8");
    let m = manifest(dir.path(), "v1.xml", "v6.xml", "");
    let out = cetratus(&["package", "build", &m, "--unsigned", "--out", pkg]);
    let printed = text(&out);
    assert!(!out.status.success(), "{printed}");
    assert!(
        printed.contains("step `Step2` is removed by the new version"),
        "{printed}"
    );
    assert!(printed.contains("[transform.removed] Step2"), "{printed}");
    let m = manifest(
        dir.path(),
        "v1.xml",
        "v6.xml",
        "[transform]\nkind = \"generated\"\n[transform.removed]\nStep2 = \"Step1\"\nStep3 = \"Step1\"\n",
    );
    let out = cetratus(&["package", "build", &m, "--unsigned", "--out", pkg]);
    assert!(out.status.success(), "{}", text(&out));
}

#[test]
fn a_pou_for_a_program_that_is_not_plcopen_is_refused_at_its_line() {
    let dir = versions();
    std::fs::write(dir.path().join("x.toml"), "").expect("writes");
    let m = manifest(dir.path(), "x.toml", "v1.xml", "");
    let out = cetratus(&["package", "build", &m, "--unsigned", "--out", "/dev/null"]);
    let printed = text(&out);
    assert!(!out.status.success());
    assert!(printed.contains("m.package.toml:5:"), "{printed}");
    assert!(
        printed.contains("`pou` is for a `program` in PLCopen XML"),
        "{printed}"
    );
}
