//! The MATIEC harness against the real MATIEC: outputs known by hand, a batch of a hundred
//! programs, and each stage's failure. MATIEC missing is a failure, not a skip: CI builds it.

use std::time::Duration;

use cetratus_testkit::matiec::{Case, IecType, Matiec, MatiecError};

const TICK: Duration = Duration::from_millis(10);

fn matiec() -> Matiec {
    Matiec::get().unwrap_or_else(|e| panic!("{e}"))
}

fn real(x: f32) -> String {
    format!("r{:08x}", x.to_bits())
}

fn texts(values: &[&str]) -> Vec<String> {
    values.iter().map(|v| v.to_string()).collect()
}

const MIXED: &str = "
PROGRAM Mixed
  VAR_INPUT
    i : INT; d : DINT; r : REAL; b : BOOL; s : STRING; t : TIME;
  END_VAR
  VAR_OUTPUT
    i1 : INT; d2 : DINT; rsum : REAL; nb : BOOL; s2 : STRING; t2 : TIME; q : BOOL; et : TIME;
  END_VAR
  VAR
    acc : REAL;
    timer : TON;
  END_VAR
  i1 := i + 1;
  d2 := d * 2;
  acc := acc + r;
  rsum := acc;
  nb := NOT b;
  s2 := CONCAT(s, '!$N');
  t2 := t + T#5ms;
  timer(IN := b, PT := T#30ms);
  q := timer.Q;
  et := timer.ET;
END_PROGRAM
";

/// The TON sees its rising edge in scan 0 (time 0) and starts there; its `Q` goes TRUE in
/// scan 3, the first scan whose time (3 × 10 ms) is PT after the start, with ET = PT; in scan
/// 4 the input falls and both reset. (`T#30ms` and `T#5ms` are literals that MATIEC computes
/// exactly; many are 1 ns short, `T#1ms` for one, as its long-double arithmetic truncates.)
#[test]
fn a_program_gives_the_outputs_known_by_hand_scan_for_scan() {
    use IecType::*;
    let case = Case {
        program: "Mixed".into(),
        inputs: [
            ("i", Int),
            ("d", Dint),
            ("r", Real),
            ("b", Bool),
            ("s", String),
            ("t", Time),
        ]
        .map(|(n, t)| (n.to_string(), t))
        .to_vec(),
        outputs: [
            ("i1", Int),
            ("d2", Dint),
            ("rsum", Real),
            ("nb", Bool),
            ("s2", String),
            ("t2", Time),
            ("q", Bool),
            ("et", Time),
        ]
        .map(|(n, t)| (n.to_string(), t))
        .to_vec(),
        scans: vec![
            texts(&[
                "32767",
                "1000000000",
                &real(1.5),
                "TRUE",
                "'It$'s'",
                "t1500000000",
            ]),
            texts(&["0", "2000000000", &real(2.25), "TRUE", "'$$5'", "t-2000000"]),
            texts(&["-32768", "-7", &real(0.125), "TRUE", "''", "t0"]),
            texts(&["-1", "0", &real(-3.875), "TRUE", "'a b'", "t0"]),
            texts(&["100", "0", &real(0.0), "FALSE", "'$E9'", "t0"]),
        ],
    };
    let outputs = matiec()
        .run(MIXED, &[case], TICK)
        .unwrap_or_else(|e| panic!("{e}"));
    let expected = vec![
        // INT wraps: 32767 + 1 = -32768.
        texts(&[
            "-32768",
            "2000000000",
            &real(1.5),
            "FALSE",
            "'It$'s!$0A'",
            "t1505000000",
            "FALSE",
            "t0",
        ]),
        // DINT wraps too (-fwrapv): 2 × 2000000000 = 4000000000 - 2^32.
        texts(&[
            "1",
            "-294967296",
            &real(3.75),
            "FALSE",
            "'$$5!$0A'",
            "t3000000",
            "FALSE",
            "t10000000",
        ]),
        texts(&[
            "-32767",
            "-14",
            &real(3.875),
            "FALSE",
            "'!$0A'",
            "t5000000",
            "FALSE",
            "t20000000",
        ]),
        texts(&[
            "0",
            "0",
            &real(0.0),
            "FALSE",
            "'a b!$0A'",
            "t5000000",
            "TRUE",
            "t30000000",
        ]),
        texts(&[
            "101",
            "0",
            &real(0.0),
            "TRUE",
            "'$E9!$0A'",
            "t5000000",
            "FALSE",
            "t0",
        ]),
    ];
    assert_eq!(outputs, vec![expected]);
}

#[test]
fn a_batch_of_a_hundred_programs_runs_each_for_its_own_scans() {
    let mut source = String::new();
    let mut cases = Vec::new();
    for i in 0..100 {
        source.push_str(&format!(
            "PROGRAM P{i}\n  VAR_INPUT x : INT; END_VAR\n  VAR_OUTPUT y : INT; END_VAR\n  \
             y := x + {i};\nEND_PROGRAM\n\n"
        ));
        // Case i gives 1 + i % 3 scans; the shorter ones stop being read.
        let scans = ["0", "1000", "-5"][..1 + i % 3]
            .iter()
            .map(|x| vec![x.to_string()])
            .collect();
        cases.push(Case {
            program: format!("P{i}"),
            inputs: vec![("x".into(), IecType::Int)],
            outputs: vec![("y".into(), IecType::Int)],
            scans,
        });
    }
    let outputs = matiec()
        .run(&source, &cases, TICK)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(outputs.len(), 100);
    for (i, got) in outputs.iter().enumerate() {
        let i = i as i64;
        let expected: Vec<Vec<String>> = [i, 1000 + i, i - 5][..1 + (i as usize) % 3]
            .iter()
            .map(|y| vec![y.to_string()])
            .collect();
        assert_eq!(got, &expected, "case {i}");
    }
}

/// Each run of a compiled batch is a process of its own: the counter starts from its initial
/// value again, and different input sequences need no new compile.
#[test]
fn a_compiled_batch_runs_new_input_sequences_from_the_initial_values() {
    let source = "PROGRAM Counter\n  VAR_INPUT delta : DINT; END_VAR\n  \
                  VAR_OUTPUT total : DINT; END_VAR\n  total := total + delta;\nEND_PROGRAM\n";
    let case = |steps: &[&str]| Case {
        program: "Counter".into(),
        inputs: vec![("delta".into(), IecType::Dint)],
        outputs: vec![("total".into(), IecType::Dint)],
        scans: steps.iter().map(|s| vec![s.to_string()]).collect(),
    };
    let batch = matiec()
        .compile(source, &[case(&[])], TICK)
        .unwrap_or_else(|e| panic!("{e}"));
    let run = |steps: &[&str]| batch.run(&[case(steps)]).unwrap_or_else(|e| panic!("{e}"));
    let totals = |t: &[&str]| vec![t.iter().map(|v| vec![v.to_string()]).collect::<Vec<_>>()];
    assert_eq!(run(&["1", "2", "3"]), totals(&["1", "3", "6"]));
    assert_eq!(run(&["10", "-20"]), totals(&["10", "-10"]));

    let other = Case {
        program: "Other".into(),
        ..case(&["1"])
    };
    let err = batch.run(&[other]).unwrap_err();
    assert!(matches!(err, MatiecError::Invalid { .. }), "{err}");
}

#[test]
fn a_syntax_error_names_iec2c_and_the_line() {
    let source = "PROGRAM Broken\n  VAR_INPUT x : INT; END_VAR\n  VAR_OUTPUT y : INT; END_VAR\n  \
                  y := x + ;\nEND_PROGRAM\n";
    let case = Case {
        program: "Broken".into(),
        inputs: vec![("x".into(), IecType::Int)],
        outputs: vec![("y".into(), IecType::Int)],
        scans: vec![vec!["1".into()]],
    };
    let err = matiec().run(source, &[case], TICK).unwrap_err();
    let MatiecError::Iec2c {
        line, source_line, ..
    } = &err
    else {
        panic!("expected an iec2c error, got {err}");
    };
    assert_eq!(*line, Some(4));
    assert_eq!(source_line.as_deref(), Some("  y := x + ;"));
    let shown = err.to_string();
    assert!(
        shown.starts_with("iec2c rejected the source at line 4"),
        "{shown}"
    );
    assert!(shown.contains("y := x + ;"), "{shown}");
}

#[test]
fn an_input_of_the_wrong_type_fails_in_cc_naming_the_case_and_variable() {
    let source = "PROGRAM Typed\n  VAR_INPUT x : DINT; END_VAR\n  VAR_OUTPUT y : DINT; END_VAR\n  \
                  y := x;\nEND_PROGRAM\n";
    let case = Case {
        program: "Typed".into(),
        inputs: vec![("x".into(), IecType::Int)],
        outputs: vec![("y".into(), IecType::Dint)],
        scans: vec![vec!["1".into()]],
    };
    let err = matiec().run(source, &[case], TICK).unwrap_err();
    assert!(matches!(err, MatiecError::Cc { .. }), "{err}");
    assert!(err.to_string().contains("`x` is not declared INT"), "{err}");
}

#[test]
fn a_division_by_zero_fails_the_run_in_its_scan() {
    let source =
        "PROGRAM Divide\n  VAR_INPUT x : DINT; END_VAR\n  VAR_OUTPUT y : DINT; END_VAR\n  \
                  y := 100 / x;\nEND_PROGRAM\n";
    let case = Case {
        program: "Divide".into(),
        inputs: vec![("x".into(), IecType::Dint)],
        outputs: vec![("y".into(), IecType::Dint)],
        scans: texts(&["5", "-3", "0", "1"])
            .into_iter()
            .map(|x| vec![x])
            .collect(),
    };
    let err = matiec().run(source, &[case], TICK).unwrap_err();
    assert!(
        matches!(err, MatiecError::Run { scan: Some(2), .. }),
        "{err}"
    );
    assert!(err.to_string().contains("SIGFPE"), "{err}");
}

#[test]
fn a_value_not_in_canonical_text_is_refused_before_compiling() {
    let case = |value: &str, ty| Case {
        program: "Never".into(),
        inputs: vec![("x".into(), ty)],
        outputs: vec![],
        scans: vec![vec![value.into()]],
    };
    let m = matiec();
    for (value, ty) in [
        ("+5", IecType::Int),
        ("32768", IecType::Int),
        ("-1", IecType::Uint),
        ("true", IecType::Bool),
        ("r3FC00000", IecType::Real),
        ("1500000000", IecType::Time),
        ("'$41'", IecType::String),
        ("'it's'", IecType::String),
    ] {
        let err = m.run("", &[case(value, ty)], TICK).unwrap_err();
        assert!(matches!(err, MatiecError::Invalid { .. }), "{value}: {err}");
        assert!(err.to_string().contains(value), "{err}");
    }
}

/// The timed loop runs exactly the scans asked for, on the first scan's inputs held, with the
/// time of each scan: a counter counts them, and a TON started in the first scan has run out.
#[test]
fn a_timed_run_runs_the_scans_asked_for_and_reports_the_last_outputs() {
    use IecType::*;
    let source = "
PROGRAM Count
  VAR_INPUT inc : DINT; go : BOOL; END_VAR
  VAR_OUTPUT n : DINT; q : BOOL; END_VAR
  VAR t : TON; END_VAR
  n := n + inc;
  t(IN := go, PT := T#500ms);
  q := t.Q;
END_PROGRAM
";
    let case = Case {
        program: "Count".into(),
        inputs: vec![("inc".into(), Dint), ("go".into(), Bool)],
        outputs: vec![("n".into(), Dint), ("q".into(), Bool)],
        scans: vec![texts(&["3", "TRUE"])],
    };
    let cases = [case];
    let batch = matiec()
        .compile(source, &cases, TICK)
        .unwrap_or_else(|e| panic!("{e}"));
    let (took, last) = batch.time(&cases, 1000).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(last, vec![texts(&["3000", "TRUE"])]);
    assert!(took > Duration::ZERO, "{took:?}");
    let (_, short) = batch.time(&cases, 40).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(short, vec![texts(&["120", "FALSE"])], "40 scans are 390 ms");
}
