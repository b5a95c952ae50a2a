//! `cetratus import plcopen` of POUs whose body is LD, FBD or ST, run by the real binary in
//! virtual time from replayed inputs: the public fixtures behave as IEC 61131-3 makes them
//! (docs/st.md, *PLCopen XML*), and what cannot be imported is refused by name and place.

use std::path::Path;
use std::process::Output;

mod binary;
use binary::{cetratus, fixture, ok, path, refused};

/// Imports POU `pou` of `file` into `dir`; what the importer printed.
fn import(dir: &Path, file: &Path, pou: &str) -> Output {
    cetratus(&[
        "import",
        "plcopen",
        path(file),
        "--pou",
        pou,
        "-o",
        path(dir),
    ])
}

/// Runs `program` in virtual time for `length` on the inputs of `replay` (CSV text), with
/// `extra` arguments; the trace's rows, each a list of its cells, header first.
fn run(dir: &Path, program: &str, length: &str, replay: &str, extra: &[&str]) -> Vec<Vec<String>> {
    let inputs = dir.join("inputs.csv");
    std::fs::write(&inputs, replay).expect("write the replayed inputs");
    let trace = dir.join("trace.csv");
    let program = dir.join(program);
    let mut args = vec![
        "run",
        path(&program),
        "--virtual",
        "--for",
        length,
        "--replay",
        path(&inputs),
        "--trace",
        path(&trace),
    ];
    args.extend_from_slice(extra);
    ok(&cetratus(&args));
    let text = std::fs::read_to_string(&trace).expect("the trace");
    text.lines()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

/// The value of column `col` at every scan below `n`: a trace writes a row only when something
/// changed, and a value holds until the next row.
fn per_scan(rows: &[Vec<String>], col: usize, n: u64) -> Vec<i64> {
    let mut out = Vec::new();
    let mut at = 1;
    for scan in 0..n {
        while at + 1 < rows.len() && rows[at + 1][0].parse::<u64>().expect("a scan") <= scan {
            at += 1;
        }
        out.push(rows[at][col].parse().expect("an integer"));
    }
    out
}

/// The trace's rows as `(time_ms, values)`, where the values are the columns `from..`.
fn changes(rows: &[Vec<String>], from: usize) -> Vec<(String, Vec<String>)> {
    rows[1..]
        .iter()
        .map(|r| (r[1].clone(), r[from..].to_vec()))
        .collect()
}

#[test]
fn blink_oscillates_with_its_two_500_ms_timers() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let printed = ok(&import(
        dir.path(),
        &fixture("openplc-blink-ld.xml"),
        "Blink",
    ));
    // The TASK of the file runs Blink every 20 ms.
    assert!(printed.contains("scan period 20ms"), "{printed}");
    let rows = run(
        dir.path(),
        "Blink.toml",
        "3s",
        "scan,time_ms\n0,0\n",
        &["--watch", "blink_led", "--watch", "TON0.ET"],
    );
    assert_eq!(rows[0], ["scan", "time_ms", "blink_led", "TON0.ET"]);
    let led: Vec<(String, String)> = rows[1..].iter().map(|r| (r[1].clone(), r[2].clone())).fold(
        Vec::new(),
        |mut kept, (t, v)| {
            if kept.last().is_none_or(|(_, last)| *last != v) {
                kept.push((t, v));
            }
            kept
        },
    );
    // TON0 runs while the lamp is off and turns it on after 500 ms; TOF0 keeps it on for 500 ms
    // after TON0 lets go, one scan later (TON0 restarts from the lamp it reads): 520 ms off.
    let expected = [
        ("0.000", "0"),
        ("500.000", "1"),
        ("1020.000", "0"),
        ("1540.000", "1"),
        ("2060.000", "0"),
        ("2580.000", "1"),
    ];
    let led: Vec<(&str, &str)> = led.iter().map(|(t, v)| (t.as_str(), v.as_str())).collect();
    assert_eq!(led, expected);
}

#[test]
fn the_traffic_light_follows_its_chain_of_tof_and_f_trig() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let file = fixture("openplc-traffic-light-fbd.xml");
    let printed = ok(&import(dir.path(), &file, "Trafic_light"));
    assert!(printed.contains("0 inputs, 4 outputs"), "{printed}");
    let toml = std::fs::read_to_string(dir.path().join("Trafic_light.toml")).expect("toml");
    assert!(toml.contains("address = \"%QX0.0\""), "{toml}");
    let rows = run(
        dir.path(),
        "Trafic_light.toml",
        "40s",
        "scan,time_ms\n0,0\n",
        &[],
    );
    assert_eq!(
        rows[0],
        [
            "scan",
            "time_ms",
            "O_LEDRed",
            "O_LEDOrange",
            "O_LEDGreen",
            "First_cycle"
        ]
    );
    // Red, orange, green as 0/1, at each change (docs/st.md, *The traffic light*).
    let lamps: Vec<(String, String)> = changes(&rows, 2)
        .into_iter()
        .map(|(t, v)| (t, v[..3].concat()))
        .collect();
    let expected = [
        ("0.000", "110"),
        ("4020.000", "100"),
        ("10060.000", "001"),
        ("16080.000", "000"),
        ("16100.000", "010"),
        ("20120.000", "000"),
        ("20140.000", "100"),
        ("26160.000", "001"),
        ("32180.000", "000"),
        ("32200.000", "010"),
        ("36220.000", "000"),
        ("36240.000", "100"),
    ];
    let lamps: Vec<(&str, &str)> = lamps
        .iter()
        .map(|(t, v)| (t.as_str(), v.as_str()))
        .collect();
    assert_eq!(lamps, expected);
}

#[test]
fn every_counter_of_first_steps_but_the_il_one_counts_and_resets_to_the_global_value() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let file = fixture("beremiz-first-steps.xml");
    // Reset is held for five scans: the SFC counter's chart needs a scan to reach its step.
    let replay = "scan,time_ms,Reset\n0,0,0\n30,300,1\n35,350,0\n";
    for pou in ["CounterST", "CounterFBD", "CounterLD", "CounterSFC"] {
        let sub = dir.path().join(pou);
        ok(&import(&sub, &file, pou));
        let rows = run(&sub, &format!("{pou}.toml"), "500ms", replay, &[]);
        let count = per_scan(&rows, 3, 45);
        // One per scan from 1, then ResetCounterValue (a CONSTANT global of 17) while Reset is
        // held, then on from there, one per scan again.
        assert_eq!(&count[..3], [1, 2, 3], "{pou}: {count:?}");
        assert_eq!(count[29], 30, "{pou}: {count:?}");
        assert_eq!(count[33], 17, "{pou}: {count:?}");
        let again = (35..40).find(|&s| count[s] == 18).expect("counting again");
        assert_eq!(&count[again..again + 3], [18, 19, 20], "{pou}: {count:?}");
    }
    let il = refused(&import(dir.path(), &file, "CounterIL"));
    assert!(il.contains("IL body is not supported"), "{il}");
    assert!(il.contains("Instruction List is deprecated"), "{il}");
    // The program that instantiates every counter needs the IL one too.
    let main = refused(&import(dir.path(), &file, "plc_prg"));
    assert!(main.contains("beremiz-first-steps.xml:"), "{main}");
    assert!(
        main.contains("CounterSFC") || main.contains("CounterIL"),
        "{main}"
    );
}

#[test]
fn a_function_imports_as_a_program_that_calls_it_every_scan() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let printed = ok(&import(
        dir.path(),
        &fixture("beremiz-first-steps.xml"),
        "AverageVal",
    ));
    assert!(
        printed.contains("POU AverageVal_CALL, 5 inputs, 1 outputs"),
        "{printed}"
    );
    let rows = run(
        dir.path(),
        "AverageVal_CALL.toml",
        "100ms",
        "scan,time_ms,Cnt1,Cnt2,Cnt3,Cnt4,Cnt5\n0,0,1,2,3,4,5\n5,50,10,10,10,10,15\n",
        &[],
    );
    assert_eq!(rows[1][7], "3", "{rows:?}");
    assert_eq!(rows[2][7], "11", "{rows:?}");
}

#[test]
fn the_ld_and_fbd_functions_of_the_iec_checker_example_compute_their_networks() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let file = fixture("iec-checker-example.xml");
    let ld = dir.path().join("ld");
    ok(&import(&ld, &file, "LDTest"));
    // LDTest := (NOT IN1 OR (IN3 AND NOT IN4)) AND IN2, drawn as two parallel branches.
    let replay = "scan,time_ms,IN1,IN2,IN3,IN4\n0,0,0,1,0,0\n1,10,1,1,0,0\n2,20,1,1,1,0\n\
                  3,30,1,1,1,1\n4,40,0,0,0,0\n";
    let rows = run(&ld, "LDTest_CALL.toml", "50ms", replay, &[]);
    let result: Vec<&str> = rows[1..].iter().map(|r| r[6].as_str()).collect();
    assert_eq!(result, ["1", "0", "1", "0", "0"], "{rows:?}");

    let fbd = dir.path().join("fbd");
    let out = import(&fbd, &file, "FBDTest");
    ok(&out);
    let notes = String::from_utf8_lossy(&out.stderr);
    // The instance SR1 is drawn but not declared, and IN2 has an array for its initial value.
    assert!(notes.contains("iec-checker-example.xml:210:25"), "{notes}");
    assert!(notes.contains("`SR1` (SR) is not declared"), "{notes}");
    assert!(notes.contains("the initial value of `IN2`"), "{notes}");
    // A function keeps nothing between calls, so SR1 and the R_TRIG of IN1's rising-edge input
    // start afresh in every call: the trigger sees IN1 itself, and the set-dominant SR gives
    // its set input, the negated AND of the edge and IN2: NOT (IN1 AND IN2).
    let replay = "scan,time_ms,IN1,IN2,IN3\n0,0,1,1,0\n1,10,0,1,0\n2,20,1,0,1\n";
    let rows = run(&fbd, "FBDTest_CALL.toml", "30ms", replay, &[]);
    let result: Vec<&str> = rows[1..].iter().map(|r| r[5].as_str()).collect();
    assert_eq!(result, ["0", "1", "1"], "{rows:?}");
}

#[test]
fn watch_names_a_variable_of_the_program_or_is_refused_with_the_variables_it_has() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    ok(&import(
        dir.path(),
        &fixture("openplc-blink-ld.xml"),
        "Blink",
    ));
    let program = dir.path().join("Blink.toml");
    let inputs = dir.path().join("in.csv");
    std::fs::write(&inputs, "scan,time_ms\n0,0\n").expect("inputs");
    let trace = dir.path().join("t.csv");
    let base = [
        "run",
        path(&program),
        "--virtual",
        "--for",
        "100ms",
        "--replay",
        path(&inputs),
    ];
    let mut args = base.to_vec();
    args.extend(["--trace", path(&trace), "--watch", "no_such"]);
    let err = refused(&cetratus(&args));
    assert!(err.contains("--watch no_such"), "{err}");
    assert!(err.contains("blink_led"), "{err}");
    let mut args = base.to_vec();
    args.extend(["--watch", "blink_led"]);
    let err = refused(&cetratus(&args));
    assert!(err.contains("add --trace"), "{err}");
}
