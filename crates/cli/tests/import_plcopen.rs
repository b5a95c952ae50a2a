//! `cetratus import plcopen` writes a program that `check`, `sim` and `run --virtual` accept, and
//! refuses a chart outside the mapping with the construct and its position.

use std::path::Path;

mod binary;
use binary::{cetratus, fixture, ok};

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
    // Beremiz's traffic light with a condition in IL (`cetratus_testkit::paths`).
    let file = dir.path().join("light.xml");
    std::fs::write(&file, cetratus_testkit::paths::traffic_light_il()).expect("written");
    let out = cetratus(&[
        "import",
        "plcopen",
        file.to_str().expect("UTF-8"),
        "-o",
        dir.path().to_str().expect("UTF-8"),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("light.xml:"), "{err}");
    assert!(err.contains("an inline IL condition"), "{err}");
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
            "unknown variable `Nowhere`",
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

/// Imports `file` with the binary into `dir` and loads the program it wrote.
fn import_and_load(
    file: &Path,
    dir: &Path,
    stem: &str,
) -> (String, std::sync::Arc<cetratus_program::Program>) {
    let printed = ok(&cetratus(&[
        "import",
        "plcopen",
        file.to_str().expect("UTF-8"),
        "-o",
        dir.to_str().expect("UTF-8"),
    ]));
    let program = cetratus_program::Program::load(&dir.join(format!("{stem}.toml")))
        .expect("the imported program loads");
    (printed, std::sync::Arc::new(program))
}

#[test]
fn the_nested_codesys_chart_runs_only_while_its_action_is_set() {
    use cetratus_program::Value;
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (printed, p) = import_and_load(&fixture("codesys-nested-sfc.xml"), dir.path(), "PLC_PRG");
    assert!(
        printed.contains("7 steps, 6 transitions, 6 actions (with the nested charts of sub_sfc1)"),
        "{printed}"
    );
    let check = ok(&cetratus(&[
        "check",
        dir.path().join("PLC_PRG.toml").to_str().expect("UTF-8"),
    ]));
    assert!(check.contains("unreachable steps: none"), "{check}");
    let net = p.net();
    let place = |id: &str| net.place_by_id(id).expect(id).index();
    let (step1, step4) = (place("Step1"), place("Step4"));
    let (nested, held) = (
        place("sub_sfc1__Init_sub_sfc1"),
        place("sub_sfc1__Init_sub_sfc1__held"),
    );
    // The action's `Q` and the counters are variables of the chart's ST.
    let read = |c: &cetratus_runtime::Container, name: &str| c.watch(name).expect(name);
    let mut c = cetratus_runtime::Container::new(p.clone(), 0);
    let (mut was_on, mut was_active, mut last_k) = (false, false, 0i64);
    let (mut scans_on, mut k_while_off_after) = (0u32, None::<i64>);
    let (mut entered_step1, mut entered_step4) = (false, false);
    // 30 s of 10 ms scans: Init, then Step0 and Step1 (S sub_sfc1) in parallel, Step1.t > 6s
    // to Step5, Step3 then the join to Step4 (R sub_sfc1), where the chart stays (FALSE).
    for n in 1..=3_000u64 {
        c.scan(n * 10_000, &[]).expect("scans");
        let m = c.marking();
        let now_on = read(&c, "sub_sfc1") == Value::Bool(true);
        let Value::Int(k_now) = read(&c, "k") else {
            panic!("k is an int")
        };
        entered_step1 |= m[step1] == 1;
        entered_step4 |= m[step4] == 1;
        // The nested step is active exactly when the action was on after the previous scan,
        // and otherwise waits in its held place.
        assert_eq!(
            m[nested] == 1,
            was_on,
            "scan {n}: nested step follows sub_sfc1"
        );
        assert_eq!(
            m[nested] + m[held],
            1,
            "scan {n}: one token, active or held"
        );
        // Its N action (k := k + 1) runs while it is active, once more the scan it is left.
        if m[nested] == 1 {
            assert_eq!(
                k_now,
                last_k + 1,
                "scan {n}: k counts while the nested step is active"
            );
            scans_on += 1;
        } else if was_active {
            // The scan the nested step is held: the IEC final run of its N action.
            assert_eq!(k_now, last_k + 1, "scan {n}: the final run");
        } else if let Some(frozen) = k_while_off_after {
            assert_eq!(k_now, frozen, "scan {n}: k stays while sub_sfc1 is off");
        }
        was_active = m[nested] == 1;
        if !now_on && entered_step4 && m[nested] == 0 {
            k_while_off_after.get_or_insert(k_now);
        }
        was_on = now_on;
        last_k = k_now;
    }
    assert!(
        entered_step1 && entered_step4,
        "the chart went through Step1 and Step4"
    );
    // Set at Step1, reset at Step4 about 10 s later: about 1000 scans of the nested chart.
    assert!(
        (900..1_100).contains(&scans_on),
        "{scans_on} scans with sub_sfc1 set"
    );
    assert!(k_while_off_after.is_some(), "sub_sfc1 was reset");
    assert!(!was_on, "sub_sfc1 is reset at the end");
    let Value::Int(i_end) = read(&c, "i") else {
        panic!("i is an int")
    };
    assert!(
        i_end > last_k,
        "i counts in Step0 and in the nested step: {i_end}"
    );
}

/// A POU whose step `Run` sets the action `Sub` while the input `go` holds, and whose step `Off`
/// resets it; `Sub`'s chart goes A → B → A, one step per scan.
const TOGGLE: &str = r#"<?xml version="1.0"?>
<project xmlns="http://www.plcopen.org/xml/tc6_0201"><types><pous>
<pou name="P" pouType="program"><interface><inputVars>
<variable name="go"><type><BOOL/></type></variable>
</inputVars></interface>
<actions><action name="Sub"><body><SFC>
<step localId="1" name="A" initialStep="true"/>
<transition localId="2"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<condition><inline name=""><ST><p>TRUE</p></ST></inline></condition></transition>
<step localId="3" name="B"><connectionPointIn><connection refLocalId="2"/></connectionPointIn></step>
<transition localId="4"><connectionPointIn><connection refLocalId="3"/></connectionPointIn>
<condition><inline name=""><ST><p>A.T &lt; T#1h</p></ST></inline></condition></transition>
<jumpStep localId="5" targetName="A"><connectionPointIn><connection refLocalId="4"/></connectionPointIn></jumpStep>
</SFC></body></action></actions>
<body><SFC>
<step localId="1" name="Idle" initialStep="true"/>
<transition localId="2"><connectionPointIn><connection refLocalId="1"/></connectionPointIn>
<condition><inline name=""><ST><p>go</p></ST></inline></condition></transition>
<step localId="3" name="Run"><connectionPointIn><connection refLocalId="2"/></connectionPointIn></step>
<actionBlock localId="4"><connectionPointIn><connection refLocalId="3"/></connectionPointIn><action localId="0" qualifier="S"><reference name="Sub"/></action></actionBlock>
<transition localId="5"><connectionPointIn><connection refLocalId="3"/></connectionPointIn>
<condition><inline name=""><ST><p>NOT go</p></ST></inline></condition></transition>
<step localId="6" name="Off"><connectionPointIn><connection refLocalId="5"/></connectionPointIn></step>
<actionBlock localId="7"><connectionPointIn><connection refLocalId="6"/></connectionPointIn><action localId="0" qualifier="R"><reference name="Sub"/></action></actionBlock>
<transition localId="8"><connectionPointIn><connection refLocalId="6"/></connectionPointIn>
<condition><inline name=""><ST><p>go</p></ST></inline></condition></transition>
<jumpStep localId="9" targetName="Run"><connectionPointIn><connection refLocalId="8"/></connectionPointIn></jumpStep>
</SFC></body></pou></pous></types></project>"#;

#[test]
fn a_nested_chart_evolves_while_its_action_is_set_and_resumes_where_it_stopped() {
    use cetratus_program::Value;
    let dir = tempfile::tempdir().expect("a temporary directory");
    let file = dir.path().join("toggle.xml");
    std::fs::write(&file, TOGGLE).expect("writes");
    let (_, p) = import_and_load(&file, dir.path(), "P");
    let net = p.net();
    let t = |id: &str| net.transition_by_id(id).expect(id).index();
    let (a_to_b, b_to_a) = (t("Sub__T2"), t("Sub__T4"));
    let place = |id: &str| net.place_by_id(id).expect(id).index();
    let (a, b) = (place("Sub__A"), place("Sub__B"));
    let (a_held, b_held) = (place("Sub__A__held"), place("Sub__B__held"));
    let mut c = cetratus_runtime::Container::new(p.clone(), 0);
    let mut now = 0;
    let mut run = |c: &mut cetratus_runtime::Container, go: bool, scans: u64| {
        for _ in 0..scans {
            now += 10_000;
            c.scan(now, &[Value::Bool(go)]).expect("scans");
        }
    };
    let nested_firings =
        |c: &cetratus_runtime::Container| c.firings()[a_to_b] + c.firings()[b_to_a];
    // Off: the nested chart waits at its initial step, held.
    run(&mut c, false, 10);
    assert_eq!(nested_firings(&c), 0);
    assert_eq!(c.marking()[a_held], 1);
    // On for 11 scans: Run is entered (S), the chart resumes the scan after, then fires once a
    // scan: A → B, B → A, …
    run(&mut c, true, 11);
    let on_firings = nested_firings(&c);
    assert!(
        (8..=10).contains(&on_firings),
        "{on_firings} nested firings"
    );
    // Off: Off is entered (R), the active step is held; nothing fires however long it stays off.
    run(&mut c, false, 3);
    let stopped = nested_firings(&c);
    let held_at = if c.marking()[b_held] == 1 { "B" } else { "A" };
    assert_eq!(
        c.marking()[a] + c.marking()[b],
        0,
        "no nested step active while off"
    );
    assert_eq!(c.marking()[a_held] + c.marking()[b_held], 1);
    run(&mut c, false, 200);
    assert_eq!(
        nested_firings(&c),
        stopped,
        "the nested chart does not evolve while off"
    );
    // On again: it resumes at the step where it stopped, not at its initial step.
    run(&mut c, true, 2);
    let resumed_at = if c.marking()[b] == 1 { "B" } else { "A" };
    assert_eq!(resumed_at, held_at, "resumed where it stopped");
    run(&mut c, true, 10);
    assert!(nested_firings(&c) > stopped, "and evolves again");
}

#[test]
fn check_on_a_plcopen_file_runs_the_chart_checks_of_the_imported_program() {
    let file = fixture("codesys-nested-sfc.xml");
    let check = ok(&cetratus(&["check", file.to_str().expect("UTF-8")]));
    assert!(
        check.contains("net PLC_PRG: 8 places, 8 transitions"),
        "{check}"
    );
    assert!(check.contains("states: 12"), "{check}");
    assert!(check.contains("sfc chart"), "{check}");
    assert!(check.contains("unreachable steps: none"), "{check}");
    assert!(
        check.contains("parallel branches that never join: none"),
        "{check}"
    );
    // --pou chooses the POU as the import does: an unknown one lists the file's POUs with the
    // language of each.
    let beremiz = fixture("beremiz-first-steps.xml");
    let out = cetratus(&["check", beremiz.to_str().expect("UTF-8"), "--pou", "Nope"]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no POU `Nope`"), "{err}");
    assert!(err.contains("CounterSFC (SFC)"), "{err}");
    assert!(err.contains("CounterLD (LD)"), "{err}");
    // A POU of another language is checked as the program it imports as: one step, no chart.
    let ld = ok(&cetratus(&[
        "check",
        beremiz.to_str().expect("UTF-8"),
        "--pou",
        "CounterLD",
    ]));
    assert!(ld.contains("net CounterLD: 1 places"), "{ld}");
    assert!(!ld.contains("sfc chart"), "{ld}");
    let check = ok(&cetratus(&[
        "check",
        beremiz.to_str().expect("UTF-8"),
        "--pou",
        "CounterSFC",
    ]));
    assert!(check.contains("sfc chart"), "{check}");
    // A chart the import refuses is the same refusal.
    let dir = tempfile::tempdir().expect("a temporary directory");
    let light = dir.path().join("light.xml");
    std::fs::write(&light, cetratus_testkit::paths::traffic_light_il()).expect("written");
    let out = cetratus(&["check", light.to_str().expect("UTF-8")]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("an inline IL condition"), "{err}");
}

#[test]
fn a_chart_that_starts_itself_is_refused_by_the_binary_not_a_recursion() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    // Step B of `Sub`'s chart starts `Sub` again: a chart in a chart, without end.
    let text = TOGGLE.replacen(
        r#"<transition localId="4">"#,
        r#"<actionBlock localId="9"><connectionPointIn><connection refLocalId="3"/></connectionPointIn><action localId="0" qualifier="N"><reference name="Sub"/></action></actionBlock><transition localId="4">"#,
        1,
    );
    let file = dir.path().join("self.xml");
    std::fs::write(&file, text).expect("writes");
    for args in [
        vec![
            "import",
            "plcopen",
            file.to_str().expect("UTF-8"),
            "-o",
            dir.path().join("out").to_str().expect("UTF-8"),
        ],
        vec!["check", file.to_str().expect("UTF-8")],
    ] {
        let out = cetratus(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(err.contains("self.xml:"), "{err}");
        assert!(
            err.contains(
                "the action `Sub` with a SFC body inside the nested chart of action `Sub`"
            ),
            "{err}"
        );
        assert!(err.contains("one level deep"), "{err}");
    }
    assert!(!dir.path().join("out").join("P.toml").exists());
}

/// The press of `examples/press-sfc`, a chart as CODESYS writes it (a TON called in an action,
/// its VAR_INPUT assigned there, an `END_IF` without `;`), imported and run by the binary from
/// the example's replayed trace: the lamp is Run's `Q`, and the SINT stroke counter wraps.
#[test]
fn the_codesys_press_chart_imports_on_the_st_compiler_and_runs_from_a_replay() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let example = |f: &str| cetratus_testkit::paths::example(&format!("press-sfc/{f}"));
    let out = cetratus(&[
        "import",
        "plcopen",
        example("press.xml").to_str().expect("UTF-8"),
        "-o",
        dir.path().to_str().expect("UTF-8"),
    ]);
    let said =
        String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{said}");
    let trace = dir.path().join("out.csv");
    let run = cetratus(&[
        "run",
        dir.path().join("Press.toml").to_str().expect("UTF-8"),
        "--replay",
        example("start.csv").to_str().expect("UTF-8"),
        "--virtual",
        "--for",
        "150ms",
        "--trace",
        trace.to_str().expect("UTF-8"),
        "--no-mqtt",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let csv = std::fs::read_to_string(&trace).expect("the trace");
    assert_eq!(
        csv.lines().next(),
        Some("scan,time_ms,start,lamp,strokes"),
        "{csv}"
    );
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let lamp_on = rows.iter().find(|r| r[3] == "1").map(|r| r[0]);
    assert_eq!(
        lamp_on,
        Some("2"),
        "Run entered with start, at scan 2: {csv}"
    );
    assert!(
        rows.iter().any(|r| r[4] == "-128"),
        "the SINT wrapped: {csv}"
    );
    assert!(
        rows.last().is_some_and(|r| r[3] == "0"),
        "back in Idle at the end: {csv}"
    );
}

/// A chart of thousands of networks imports in time that grows with its size: each network was
/// lowered by walking the whole file again (its POUs, its names, the chart's elements), and
/// each note placed by counting the lines before it, hours of CPU at the size limit.
#[test]
#[cfg(feature = "bench")]
fn a_chart_of_thousands_of_networks_imports_in_time_linear_in_its_size() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let n = 6000;
    let file = dir.path().join("ring.xml");
    std::fs::write(&file, cetratus_bench::program::plcopen_networks(n)).expect("write");
    let out = cetratus_testkit::process::output_within(
        std::process::Command::new(binary::BIN).args([
            "import",
            "plcopen",
            file.to_str().expect("UTF-8"),
            "-o",
            dir.path().to_str().expect("UTF-8"),
        ]),
        std::time::Duration::from_secs(120),
    );
    let printed = ok(&out);
    let what = format!("{n} steps, {n} transitions, {n} actions");
    assert!(printed.contains(&what), "{printed}");
    let notes = String::from_utf8_lossy(&out.stderr);
    let last = format!("the block instance `E{}` (R_TRIG) is not declared", n - 1);
    assert!(notes.contains(&last), "{}", &notes[..notes.len().min(2000)]);
}
