//! Differential tests against MATIEC, the IEC 61131-3 compiler of OpenPLC and Beremiz: random
//! well-typed programs (testkit's `stgen`) run on MATIEC's compiled C and on this crate, scan by
//! scan, with the same inputs and the same time; every output of every scan must be equal.
//!
//! A difference is a bug in one of the two. The deliberate ones (docs/st.md, *Where Cetratus
//! and MATIEC differ*) are kept out of the generated programs, not papered over here.

use cetratus_st::types::{Elem, Ty};
use cetratus_st::{compile, parse, Source, State, Unit, Var, Work};
use cetratus_testkit::matiec::{Case, IecType, Matiec};
use cetratus_testkit::stgen;

mod common;
use common::write_input;

/// The task interval both sides run at.
const TICK_MS: u64 = 10;

/// A variable's value in the harness's canonical text.
fn canonical(unit: &Unit, state: &State, v: &Var) -> String {
    match v.ty {
        Ty::String(_) => {
            let at = v.at.text as usize;
            let len = u16::from_le_bytes([state.text[at], state.text[at + 1]]) as usize;
            let mut s = String::from("'");
            for &b in &state.text[at + 2..at + 2 + len] {
                match b {
                    b'$' => s.push_str("$$"),
                    b'\'' => s.push_str("$'"),
                    0x20..=0x7e => s.push(b as char),
                    _ => s.push_str(&format!("${b:02X}")),
                }
            }
            s.push('\'');
            s
        }
        Ty::Elem(e) => {
            let bits = state.slots[v.at.slots as usize];
            match e {
                Elem::Bool => if bits != 0 { "TRUE" } else { "FALSE" }.to_string(),
                Elem::Real => format!("r{:08x}", bits as u32),
                Elem::Lreal => format!("l{bits:016x}"),
                Elem::Time => format!("t{}", bits as i64),
                e if e.is_signed() => (bits as i64).to_string(),
                _ => bits.to_string(),
            }
        }
        other => format!("<{}>", unit.describe(other)),
    }
}

/// The IEC type the harness uses for a variable of this crate.
fn iec(ty: Ty) -> Option<IecType> {
    let name = match ty {
        Ty::Elem(e) => e.name(),
        Ty::String(_) => "STRING",
        _ => return None,
    };
    let all = [
        IecType::Bool,
        IecType::Sint,
        IecType::Int,
        IecType::Dint,
        IecType::Lint,
        IecType::Usint,
        IecType::Uint,
        IecType::Udint,
        IecType::Ulint,
        IecType::Byte,
        IecType::Word,
        IecType::Dword,
        IecType::Lword,
        IecType::Real,
        IecType::Lreal,
        IecType::Time,
        IecType::String,
    ];
    all.into_iter().find(|t| t.name() == name)
}

/// Runs a case on this crate: per scan, its outputs in canonical text.
fn run_here(unit: &Unit, case: &Case) -> Vec<Vec<String>> {
    let mut state = unit.new_state();
    let var = |name: &str| {
        let v = unit
            .var(name)
            .unwrap_or_else(|| panic!("{}: no variable {name}", case.program));
        assert!(
            iec(v.ty).is_some(),
            "{name}: type {:?} has no harness type",
            v.ty
        );
        v.clone()
    };
    let inputs: Vec<Var> = case.inputs.iter().map(|(n, _)| var(n)).collect();
    let outputs: Vec<Var> = case.outputs.iter().map(|(n, _)| var(n)).collect();
    let mut out = Vec::new();
    for (k, values) in case.scans.iter().enumerate() {
        for (v, text) in inputs.iter().zip(values) {
            write_input(&mut state, v, text);
        }
        let now = k as i64 * TICK_MS as i64 * 1_000_000;
        if let Err(f) = unit.run(&mut state, now, &mut Work::unlimited()) {
            out.push(vec![format!("fault {:?}", f.kind)]);
            break;
        }
        out.push(outputs.iter().map(|v| canonical(unit, &state, v)).collect());
    }
    out
}

/// Generates `count` programs from `seed`, runs them on both, and lists every difference.
fn differences(seed: u64, count: usize, scans: usize) -> Vec<String> {
    let batch = stgen::generate(seed, count, scans);
    if let Ok(path) = std::env::var("CETRATUS_DUMP_BATCH") {
        std::fs::write(path, &batch.source).expect("dump the batch");
    }
    // -O0: the semantics are fixed by -fwrapv and -ffp-contract=off, and cc -O2 would take
    // most of the test's time.
    let matiec = Matiec::get()
        .unwrap_or_else(|e| panic!("MATIEC is needed: {e}"))
        .with_optimisation("-O0");
    let tick = std::time::Duration::from_millis(TICK_MS);
    let started = std::time::Instant::now();
    let (expected, timings) = matiec
        .run_timed(&batch.source, &batch.cases, tick)
        .unwrap_or_else(|e| panic!("{e}"));
    if std::env::var_os("CETRATUS_TIMINGS").is_some() {
        eprintln!("MATIEC {timings:?} in {:?}", started.elapsed());
    }
    let src = Source {
        origin: "generated.st",
        text: &batch.source,
    };
    let lib = parse::parse_library(&batch.source).unwrap_or_else(|d| panic!("{}", src.error(d)));
    let mut diffs = Vec::new();
    for (case, want) in batch.cases.iter().zip(&expected) {
        let unit = match compile(&lib, Some(&case.program)) {
            Ok(u) => u,
            Err(d) => {
                diffs.push(format!(
                    "{} (seed {seed}): refused: {}",
                    case.program,
                    src.error(d)
                ));
                continue;
            }
        };
        // What a scan runs: the machine code where there is a code generator
        // (machine_code.rs holds it to the interpreter).
        unit.prepare_machine_code();
        let got = run_here(&unit, case);
        let first = got.iter().zip(want).position(|(g, w)| g != w);
        if let Some(k) = first.or((got.len() != want.len()).then_some(got.len().min(want.len()))) {
            let names: Vec<&str> = case.outputs.iter().map(|o| o.0.as_str()).collect();
            diffs.push(format!(
                "{} (seed {seed}) differs at scan {k}: outputs {names:?}\n  MATIEC:   {:?}\n  Cetratus: {:?}\n  inputs: {:?}",
                case.program,
                want.get(k),
                got.get(k),
                case.scans.get(k)
            ));
        }
    }
    diffs
}

/// Batches of the test: eight of 250 programs, 2,000 in all.
const BATCHES: u64 = 8;
const PER_BATCH: usize = 250;

#[test]
fn two_thousand_random_programs_agree_with_matiec_at_every_scan() {
    // Two batches at a time: iec2c runs on one core, and the machine has two.
    let all: Vec<String> = std::thread::scope(|s| {
        let halves: Vec<_> = (0..2u64)
            .map(|h| {
                s.spawn(move || {
                    (0..BATCHES)
                        .filter(|b| b % 2 == h)
                        .flat_map(|b| differences(0x5eed_0000 + b, PER_BATCH, 50))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        halves
            .into_iter()
            .flat_map(|t| t.join().expect("a batch thread"))
            .collect()
    });
    assert!(
        all.is_empty(),
        "{} of {} programs differ from MATIEC; the first:\n{}",
        all.len(),
        BATCHES as usize * PER_BATCH,
        all.iter().take(5).cloned().collect::<Vec<_>>().join("\n")
    );
}

/// A probe for soaks and debugging: `N` programs of seed `SEED`, differences printed
/// (`CETRATUS_DUMP_BATCH=FILE` keeps the source, `CETRATUS_TIMINGS=1` prints MATIEC's times).
#[test]
#[ignore]
fn probe() {
    let n: usize = std::env::var("N")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(50);
    let seed: u64 = std::env::var("SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    let d = differences(seed, n, 30);
    for x in d.iter().take(40) {
        eprintln!("{x}\n");
    }
    eprintln!("{} of {n} differ", d.len());
}

#[test]
fn every_generated_program_compiles() {
    for b in 0..BATCHES {
        let seed = 0x5eed_0000 + b;
        let batch = stgen::generate(seed, PER_BATCH, 1);
        let src = Source {
            origin: "generated.st",
            text: &batch.source,
        };
        let lib =
            parse::parse_library(&batch.source).unwrap_or_else(|d| panic!("{}", src.error(d)));
        for case in &batch.cases {
            if let Err(d) = compile(&lib, Some(&case.program)) {
                let e = src.error(d);
                let line = batch.source.lines().nth(e.line as usize - 1).unwrap_or("");
                panic!("{} (seed {seed}): {e}\n  {line}", case.program);
            }
        }
    }
}

/// STRING_TO_* and TIME_TO_STRING on strings and durations chosen at MATIEC's edges: based
/// literals, underscores, signs, more digits than fit, text after a number, reals with and
/// without a dot, negative durations and fractions of a millisecond. (STRING_TO_TIME is a
/// deliberate difference, docs/st.md, and binary or octal literals of more than 31 bits are
/// undefined behaviour in MATIEC's C.)
#[test]
fn string_conversions_agree_with_matiec() {
    use IecType::*;
    let source = "
PROGRAM Conversions
  VAR_INPUT s : STRING; t : TIME; END_VAR
  VAR_OUTPUT
    b : BOOL; i : INT; d : DINT; l : LINT; w : WORD; u : UDINT; ul : ULINT;
    r : REAL; lr : LREAL; ts : STRING;
  END_VAR
  b := STRING_TO_BOOL(s);
  i := STRING_TO_INT(s);
  d := STRING_TO_DINT(s);
  l := STRING_TO_LINT(s);
  w := STRING_TO_WORD(s);
  u := STRING_TO_UDINT(s);
  ul := STRING_TO_ULINT(s);
  r := STRING_TO_REAL(s);
  lr := STRING_TO_LREAL(s);
  ts := TIME_TO_STRING(t);
END_PROGRAM
";
    let strings = [
        "",
        "0",
        "1",
        "TRUE",
        "true",
        "True ",
        "FALSE",
        "42",
        "-42",
        "+42",
        "1_000",
        "2#1010",
        "2#1111_0000",
        "8#777",
        "16#FF",
        "16#dead_BEEF",
        "16#FFFFFFFFFFFFFFFF",
        "99999",
        "-32769",
        "12345678901234567890123",
        "3.14",
        "-2.5e3",
        "1.5abc",
        "abc",
        " 7",
        "7 ",
        ".5",
        "1.",
        "12.34.56",
        "1e5",
        "0.000001",
        "-0.0",
    ];
    let times: [i64; 8] = [
        0,
        1_500_000_000,
        86_400_000_000_000,
        5_400_000_000_000,
        -90_000_000_000,
        123_456_789,
        3_723_000_250_000,
        -1_250_000,
    ];
    let scans: Vec<Vec<std::string::String>> = strings
        .iter()
        .enumerate()
        .map(|(k, s)| vec![format!("'{s}'"), format!("t{}", times[k % times.len()])])
        .collect();
    let outputs = [
        ("b", Bool),
        ("i", Int),
        ("d", Dint),
        ("l", Lint),
        ("w", Word),
        ("u", Udint),
        ("ul", Ulint),
        ("r", Real),
        ("lr", Lreal),
        ("ts", String),
    ];
    let case = Case {
        program: "Conversions".into(),
        inputs: vec![("s".into(), String), ("t".into(), Time)],
        outputs: outputs.iter().map(|(n, t)| (n.to_string(), *t)).collect(),
        scans,
    };
    let matiec = Matiec::get().unwrap_or_else(|e| panic!("MATIEC is needed: {e}"));
    let tick = std::time::Duration::from_millis(TICK_MS);
    let want = matiec
        .run(source, std::slice::from_ref(&case), tick)
        .unwrap_or_else(|e| panic!("{e}"));
    let lib = parse::parse_library(source).unwrap_or_else(|d| panic!("{}", d.message));
    let unit = compile(&lib, None).unwrap_or_else(|d| panic!("{}", d.message));
    let got = run_here(&unit, &case);
    for (k, (g, w)) in got.iter().zip(&want[0]).enumerate() {
        assert_eq!(g, w, "scan {k}: s = {:?}, outputs {outputs:?}", strings[k]);
    }
    assert_eq!(got.len(), want[0].len());
    // Spot checks, so that agreeing on nothing cannot pass: 16#FF, and 1.5 s printed.
    let ff = strings.iter().position(|s| *s == "16#FF").expect("16#FF");
    assert_eq!(got[ff][4], "255");
    assert_eq!(got[1][9], "'T#0d0h0m1s500ms'");
    assert_eq!(got[4][9], "'T#0d0h-1m-30s'");
}
