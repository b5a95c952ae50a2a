//! `cetratus import plcopen` writes a program that `check`, `sim` and `run --virtual` accept, and
//! refuses a chart outside the mapping with the construct and its position.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

fn fixture(name: &str) -> PathBuf {
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

fn cetratus(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("cetratus runs")
}

fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn an_imported_twincat_chart_is_checked_simulated_and_run_in_virtual_time() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let out_dir = dir.path().to_str().expect("a UTF-8 path");
    let file = fixture("twincat-sfc-evolution-6.xml");
    let printed = ok(&cetratus(&[
        "import",
        "plcopen",
        file.to_str().expect("UTF-8"),
        "-o",
        out_dir,
    ]));
    assert!(printed.contains("4 steps, 3 transitions"), "{printed}");
    let program = dir.path().join("Main.toml");
    let program = program.to_str().expect("UTF-8");
    assert!(dir.path().join("Main.pnml").exists());

    let check = ok(&cetratus(&["check", program]));
    assert!(check.contains("states: 3"), "{check}");
    assert!(check.contains("safe: yes"), "{check}");
    // The chart checks: version 6 forks into Step2 and Step3 and joins them again.
    assert!(check.contains("sfc chart"), "{check}");
    assert!(
        check.contains("unsafe steps (active twice through parallel branches): none"),
        "{check}"
    );
    assert!(check.contains("unreachable steps: none"), "{check}");
    assert!(
        check.contains("parallel branches that never join: none"),
        "{check}"
    );
    let sim = ok(&cetratus(&["sim", program, "--steps", "3"]));
    assert!(sim.contains("Step2=1 Step3=1"), "{sim}");
    let run = ok(&cetratus(&[
        "run",
        program,
        "--twin",
        "vernadat",
        "--virtual",
        "--for",
        "1s",
    ]));
    assert!(run.contains("faults          none"), "{run}");
}

#[test]
fn importing_a_chart_twice_writes_the_same_program_hash() {
    let file = fixture("twincat-sfc-evolution-1.xml");
    let hash = |dir: &Path| {
        let printed = ok(&cetratus(&[
            "import",
            "plcopen",
            file.to_str().expect("UTF-8"),
            "--pou",
            "Main",
            "-o",
            dir.to_str().expect("UTF-8"),
        ]));
        printed
            .split("program hash ")
            .nth(1)
            .map(|h| h.trim().to_string())
    };
    let (a, b) = (
        tempfile::tempdir().expect("dir"),
        tempfile::tempdir().expect("dir"),
    );
    let first = hash(a.path());
    assert!(first.is_some());
    assert_eq!(first, hash(b.path()));
}

#[test]
fn a_chart_outside_the_mapping_is_refused_with_its_construct_and_position() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let file = fixture("beremiz-svghmi-traffic-light.xml");
    let out = cetratus(&[
        "import",
        "plcopen",
        file.to_str().expect("UTF-8"),
        "-o",
        dir.path().to_str().expect("UTF-8"),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("beremiz-svghmi-traffic-light.xml:"), "{err}");
    assert!(err.contains("FBD body of transition STOP"), "{err}");
    assert!(!dir.path().join("traffic_light_sequence.toml").exists());
}

#[test]
fn bad_charts_are_clear_errors_from_the_binary_never_a_crash() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let good = std::fs::read_to_string(fixture("twincat-sfc-evolution-1.xml")).expect("reads");
    let jump = good.find("<jumpStep").expect("a jump");
    let jump_end = good.find("</jumpStep>").expect("its end") + "</jumpStep>".len();
    let body = |st: &str| {
        good.replacen(
            "<step localId=\"3\"",
            &format!("<actionBlock localId=\"99\"><connectionPointIn><connection refLocalId=\"3\"/></connectionPointIn><action localId=\"0\" qualifier=\"N\"><inline><ST><p><![CDATA[{st}]]></p></ST></inline></action></actionBlock><step localId=\"3\""),
            1,
        )
    };
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "malformed",
            good.replacen("</transition>", "</transitio>", 1),
            "malformed.xml:",
        ),
        (
            "two-initial",
            good.replace(r#"name="Step1">"#, r#"name="Step1" initialStep="true">"#),
            "one initial step",
        ),
        (
            "no-target",
            format!("{}{}", &good[..jump], &good[jump_end..]),
            "has no target",
        ),
        (
            "unknown-variable",
            body("Nowhere := TRUE;"),
            "unknown name `Nowhere`",
        ),
        (
            "deep-body",
            body(&("IF TRUE THEN ".repeat(2_000) + &" END_IF;".repeat(2_000))),
            "more than",
        ),
    ];
    for (name, text, expected) in cases {
        let file = dir.path().join(format!("{name}.xml"));
        std::fs::write(&file, text).expect("writes");
        let out = cetratus(&[
            "import",
            "plcopen",
            file.to_str().expect("UTF-8"),
            "-o",
            dir.path().join(name).to_str().expect("UTF-8"),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
        assert!(err.contains(expected), "{name}: {err}");
        assert!(
            err.contains(&format!("{name}.xml:")),
            "{name}: the file and position: {err}"
        );
    }
}
