//! The dialects that cannot be compiled here (Siemens TIA SCL, OMRON Sysmac ST) against golden
//! files: they prove only that the output is stable, so a change to them is made on purpose.
//! `CETRATUS_UPDATE_GOLDEN=1 cargo test -p cetratus-export --test dialects` rewrites them
//! after a deliberate change; the diff then shows what changed for a vendor's PLC.

use std::path::{Path, PathBuf};

use cetratus_export::{to_st, Dialect};
use cetratus_program::Program;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn golden(program: &str, dialect: Dialect, file: &str) {
    let p = Program::load(&workspace().join(program)).expect("the example loads");
    let text = to_st(&p, dialect).expect("it exports").text;
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(file);
    if std::env::var_os("CETRATUS_UPDATE_GOLDEN").is_some() {
        std::fs::write(&path, &text).expect("the golden file is written");
    }
    let want = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e}; write it with CETRATUS_UPDATE_GOLDEN=1",
            path.display()
        )
    });
    if text != want {
        let line = text.lines().zip(want.lines()).position(|(a, b)| a != b);
        panic!(
            "{file}: the {dialect} export of {program} changed (first at line {}); if that is meant, rewrite it with CETRATUS_UPDATE_GOLDEN=1",
            line.map_or(text.lines().count().min(want.lines().count()), |l| l) + 1
        );
    }
}

#[test]
fn tia_scl_is_stable() {
    golden("examples/vernadat/u2.toml", Dialect::Tia, "vernadat-u2.scl");
    golden("examples/festo/festo.toml", Dialect::Tia, "festo.scl");
}

#[test]
fn omron_st_is_stable() {
    golden(
        "examples/vernadat/u2.toml",
        Dialect::Omron,
        "vernadat-u2.omron.st",
    );
    golden(
        "examples/festo/festo.toml",
        Dialect::Omron,
        "festo.omron.st",
    );
}

#[test]
fn the_dialects_differ_from_iec_only_where_listed() {
    let p = Program::load(&workspace().join("examples/vernadat/u2.toml")).unwrap();
    let iec = to_st(&p, Dialect::Iec).unwrap().text;
    let codesys = to_st(&p, Dialect::Codesys).unwrap().text;
    let omron = to_st(&p, Dialect::Omron).unwrap().text;
    let tia = to_st(&p, Dialect::Tia).unwrap().text;
    // The interpretation's statements are the same text in IEC, CODESYS and OMRON, but for the
    // short-circuit words of CODESYS.
    let body = |t: &str| {
        let from = t
            .find("FUNCTION_BLOCK vernadat_cell_LOGIC")
            .expect("the interpretation");
        t[from..from + t[from..].find("END_FUNCTION_BLOCK").unwrap()].to_string()
    };
    assert_eq!(body(&iec), body(&omron));
    assert_eq!(
        body(&iec)
            .replace(" AND ", " AND_THEN ")
            .replace(" OR ", " OR_ELSE "),
        body(&codesys)
    );
    assert!(iec.contains("CONFIGURATION CETRATUS_CONFIG") && iec.contains("VAR_EXTERNAL CONSTANT"));
    for vendor in [&codesys, &omron, &tia] {
        assert!(!vendor.contains("CONFIGURATION") && !vendor.contains("VAR_EXTERNAL CONSTANT"));
    }
    assert!(
        codesys.contains("PE AT %IX0.0 : BOOL;")
            && omron.contains("PE : BOOL;  (* input %IX0.0 *)")
    );
    assert!(
        tia.contains("DATA_BLOCK \"CETRATUS_NET\"")
            && tia.contains("#M[#P] := \"CETRATUS_NET\".NET_M0[#P];")
    );
    assert!(
        tia.contains("#LOGIC(PE := \"PE\""),
        "formal parameters keep their names"
    );
}
