//! `cetratus import st` writes a program whose POU runs every scan, and `cetratus run --replay`
//! drives it from a recorded trace; bad ST and bad traces are refused with their place.

use std::path::Path;
use std::process::Output;

mod binary;
use binary::{cetratus, ok, path, refused};

const COUNTER: &str = "\
PROGRAM Counter
VAR_INPUT run : BOOL; END_VAR
VAR_OUTPUT count : INT; q : BOOL; END_VAR
VAR t : TON; END_VAR
count := count + 1;
t(IN := run, PT := T#100ms);
q := t.Q;
END_PROGRAM
";

/// Imports `text` as `name.st` into `dir`; the program file.
fn import(dir: &Path, name: &str, text: &str) -> Output {
    let st = dir.join(format!("{name}.st"));
    std::fs::write(&st, text).expect("write the ST file");
    cetratus(&["import", "st", path(&st), "-o", path(dir)])
}

#[test]
fn an_imported_st_program_runs_every_scan_from_a_replayed_trace() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let printed = ok(&import(dir.path(), "counter", COUNTER));
    assert!(printed.contains("1 inputs, 2 outputs"), "{printed}");
    let replay = dir.path().join("in.csv");
    // `run` rises at scan 3 and holds: rows only where something changes, as --trace writes.
    std::fs::write(&replay, "scan,time_ms,run\n0,0.000,0\n3,30.000,1\n").expect("write");
    let trace = dir.path().join("out.csv");
    let program = dir.path().join("Counter.toml");
    ok(&cetratus(&[
        "run",
        path(&program),
        "--replay",
        path(&replay),
        "--virtual",
        "--for",
        "200ms",
        "--trace",
        path(&trace),
        "--no-mqtt",
    ]));
    let csv = std::fs::read_to_string(&trace).expect("the trace");
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(csv.lines().next(), Some("scan,time_ms,run,count,q"));
    // The body runs in every scan: the count is the scan number plus one.
    for r in &rows {
        let scan: i64 = r[0].parse().expect("scan");
        assert_eq!(r[3].parse::<i64>().expect("count"), scan + 1, "{csv}");
    }
    // The TON started at 30 ms; Q from 130 ms (scan 13), as MATIEC's TON does it.
    let q_from = rows.iter().find(|r| r[4] == "1").map(|r| r[0]);
    assert_eq!(q_from, Some("13"), "{csv}");
}

#[test]
fn st_that_does_not_type_check_is_refused_at_its_line_and_column() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let bad = COUNTER.replace("count := count + 1;", "count := count + DINT#1;");
    let err = refused(&import(dir.path(), "bad", &bad));
    assert!(err.contains("bad.st:5:"), "{err}");
    assert!(err.contains("INT") && err.contains("DINT"), "{err}");
    assert!(!dir.path().join("Counter.toml").exists());
}

#[test]
fn a_trace_that_does_not_fit_the_program_is_refused_before_the_first_scan() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    ok(&import(dir.path(), "counter", COUNTER));
    let program = dir.path().join("Counter.toml");
    let replay = dir.path().join("in.csv");
    let run = |csv: &str, extra: &[&str]| {
        std::fs::write(&replay, csv).expect("write");
        let mut args = vec![
            "run",
            path(&program),
            "--replay",
            path(&replay),
            "--virtual",
            "--for",
            "50ms",
            "--no-mqtt",
        ];
        args.extend_from_slice(extra);
        refused(&cetratus(&args))
    };
    let err = run("scan,time_ms,run\n0,0,maybe\n", &[]);
    assert!(
        err.contains("in.csv:2") && err.contains("`run`") && err.contains("maybe"),
        "{err}"
    );
    let err = run("scan,time_ms,other\n0,0,1\n", &[]);
    assert!(err.contains("no column for the input `run`"), "{err}");
    let err = run("scan,time_ms,run\n0,0,1\n", &["--twin", "vernadat"]);
    assert!(err.contains("--replay"), "{err}");
}

#[test]
fn a_loop_that_never_ends_faults_the_primary_at_its_work_budget_with_safe_outputs() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let spin = "PROGRAM Spin
VAR_INPUT run : BOOL; END_VAR
VAR_OUTPUT count : DINT; lamp : BOOL; END_VAR
lamp := TRUE;
IF run THEN
  WHILE TRUE DO count := count + 1; END_WHILE
END_IF
END_PROGRAM
";
    ok(&import(dir.path(), "spin", spin));
    let replay = dir.path().join("in.csv");
    std::fs::write(&replay, "scan,time_ms,run\n0,0,0\n3,30,1\n").expect("write");
    let trace = dir.path().join("out.csv");
    let program = dir.path().join("Spin.toml");
    let run = cetratus(&[
        "run",
        path(&program),
        "--replay",
        path(&replay),
        "--virtual",
        "--for",
        "100ms",
        "--trace",
        path(&trace),
        "--no-mqtt",
    ]);
    let out = ok(&run) + &String::from_utf8_lossy(&run.stderr);
    assert!(out.contains("Spin on the replayed trace"), "{out}");
    assert!(out.contains("primary_fault"), "{out}");
    assert!(out.contains("work budget of 2500000 units"), "{out}");
    let csv = std::fs::read_to_string(&trace).expect("the trace");
    // From the scan the loop starts in, the outputs are at their safe values (lamp off).
    assert_eq!(csv.lines().last(), Some("3,30.000,1,0,0"), "{csv}");
}

/// A warm restart keeps the RETAIN variables of an ST program and initializes the others, as
/// IEC 61131-3 wants (docs/st.md, *Restarts*): the second run picks up the RETAIN count where
/// the first left it, and the plain count starts again from its initial value.
#[test]
fn a_warm_restart_keeps_the_retain_variables_and_initializes_the_others() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let keep = "\
PROGRAM Keep
VAR_OUTPUT kept : DINT; fresh : DINT; END_VAR
VAR RETAIN total : DINT; END_VAR
VAR plain : DINT; END_VAR
total := total + 1;
plain := plain + 1;
kept := total;
fresh := plain;
END_PROGRAM
";
    ok(&import(dir.path(), "keep", keep));
    let (program, replay) = (dir.path().join("Keep.toml"), dir.path().join("in.csv"));
    std::fs::write(&replay, "scan,time_ms\n0,0.000\n").expect("write");
    let state = dir.path().join("state");
    let run = |for_: &str, trace: &Path| {
        ok(&cetratus(&[
            "run",
            path(&program),
            "--replay",
            path(&replay),
            "--virtual",
            "--for",
            for_,
            "--state-dir",
            path(&state),
            "--trace",
            path(trace),
            "--no-mqtt",
        ]))
    };
    let (first, second) = (dir.path().join("first.csv"), dir.path().join("second.csv"));
    run("200ms", &first);
    run("100ms", &second);
    let rows = |p: &Path| -> Vec<String> {
        let csv = std::fs::read_to_string(p).expect("the trace");
        csv.lines().skip(1).map(str::to_owned).collect()
    };
    let (first, second) = (rows(&first), rows(&second));
    assert_eq!(first.first().map(String::as_str), Some("0,0.000,1,1"));
    assert_eq!(first.last().map(String::as_str), Some("19,190.000,20,20"));
    // Scan 20 is the first of the second run: 21 scans counted in all, one since the restart.
    assert_eq!(
        second.first().map(String::as_str),
        Some("20,200.000,21,1"),
        "{second:?}"
    );
}

/// A saved state is read from disk before the first scan: a RETAIN string whose saved length
/// is longer than its capacity (a damaged or edited `state.json`) is not restored, the warm
/// start says so by name, and the PLC starts; a state file larger than any PLC writes is
/// refused before it is read.
#[test]
fn a_damaged_retained_string_in_the_saved_state_is_not_restored_and_the_plc_starts() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let text = "\
PROGRAM Words
VAR_OUTPUT n : DINT; len_out : INT; END_VAR
VAR RETAIN word : STRING[8] := 'ab'; count : DINT; END_VAR
count := count + 1;
n := count;
len_out := LEN(word);
END_PROGRAM
";
    ok(&import(dir.path(), "words", text));
    let (program, replay) = (dir.path().join("Words.toml"), dir.path().join("in.csv"));
    std::fs::write(&replay, "scan,time_ms\n0,0.000\n").expect("write");
    let state = dir.path().join("state");
    let trace = dir.path().join("t.csv");
    let run = || {
        cetratus(&[
            "run",
            path(&program),
            "--replay",
            path(&replay),
            "--virtual",
            "--for",
            "50ms",
            "--state-dir",
            path(&state),
            "--trace",
            path(&trace),
            "--no-mqtt",
        ])
    };
    ok(&run());
    // The saved string: two bytes of length, then its capacity of characters. Say 65,535.
    let file = state.join("state.json");
    let mut saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).expect("state.json")).expect("JSON");
    let retained = saved["snapshot"]["containers"][0]["st_retained"]
        .as_array_mut()
        .expect("the retained variables");
    let word = retained
        .iter_mut()
        .find(|r| r["name"] == "word")
        .expect("the saved string");
    assert_eq!(word["text"][0], 2, "{word}");
    word["text"][0] = 255.into();
    word["text"][1] = 255.into();
    std::fs::write(&file, serde_json::to_string(&saved).expect("JSON")).expect("write");
    let warm = run();
    let out = ok(&warm) + &String::from_utf8_lossy(&warm.stderr);
    assert!(out.contains("faults          none"), "{out}");
    assert!(
        out.contains("WARNING: 1 saved RETAIN variable(s)") && out.contains("initial values: word"),
        "the warm start says what it did not restore: {out}"
    );
    let csv = std::fs::read_to_string(&trace).expect("the trace");
    let first = csv.lines().nth(1).expect("a row");
    // count kept (6 scans before), word back at its initial 'ab'.
    assert_eq!(first, "5,50.000,6,2", "{csv}");

    let huge = std::fs::File::create(&file).expect("state.json");
    huge.set_len(cetratus_persist::MAX_STATE_BYTES + 1)
        .expect("a sparse file");
    let err = refused(&run());
    assert!(err.contains("state.json"), "{err}");
    assert!(err.contains("more than the"), "{err}");
}
