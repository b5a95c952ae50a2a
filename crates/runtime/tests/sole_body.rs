//! A program that is one Structured Text POU run every scan (`cetratus import st`) is scanned by
//! running its body and nothing else (`SoleBody`): scan by scan, it must do exactly what the
//! full path with its qualifiers, latches and timers does. Random programs of `stgen` with their
//! input sequences, and the ways a scan can end early (a fault, the work budget), are run by a
//! container on the short path and one held on the full path, and compared at every scan.

use std::sync::Arc;

use cetratus_program::{Program, Value};
use cetratus_runtime::Container;
use cetratus_sfc::structured::import_st;
use cetratus_testkit::matiec::IecType;
use cetratus_testkit::stgen;

/// One scan's period, in microseconds: timers run through their presets in a few scans.
const PERIOD_US: u64 = 7_000;

/// A value of `ty` in MATIEC's canonical text as a signal's value; `None` for a type that is not
/// a signal (strings and TIME stay inside the program).
fn value_of(ty: IecType, text: &str) -> Option<Value> {
    let bits = |tag| u64::from_str_radix(text.strip_prefix(tag)?, 16).ok();
    match ty {
        IecType::Bool => Some(Value::Bool(text == "TRUE")),
        IecType::Real => Some(Value::Real(f64::from(f32::from_bits(bits('r')? as u32)))),
        IecType::Lreal => Some(Value::Real(f64::from_bits(bits('l')?))),
        IecType::Time | IecType::String => None,
        _ => text.parse().ok().map(Value::Int),
    }
}

/// The program's input image at each scan of `case`: its signals by name, each from the case's
/// value for it, or its initial value.
fn images(program: &Program, case: &cetratus_testkit::matiec::Case) -> Vec<Vec<Value>> {
    case.scans
        .iter()
        .map(|scan| {
            let given = |name: &str| {
                let k = case
                    .inputs
                    .iter()
                    .position(|(n, _)| n.eq_ignore_ascii_case(name))?;
                value_of(case.inputs[k].1, &scan[k])
            };
            program
                .inputs()
                .iter()
                .map(|s| given(&s.name).unwrap_or(s.initial))
                .collect()
        })
        .collect()
}

/// Runs `images` through a container on the short path and one on the full path, each scan
/// within `budget` units of work, and fails at the first scan where they differ.
fn same_scans(program: &Arc<Program>, images: &[Vec<Value>], budget: u64, what: &str) {
    let mut short = Container::new(program.clone(), 0);
    let mut full = Container::new(program.clone(), 0);
    full.set_always_full(true);
    for (k, image) in images.iter().enumerate() {
        let now = k as u64 * PERIOD_US;
        let a = short.scan_within(now, image, false, budget);
        let b = full.scan_within(now, image, false, budget);
        assert_eq!(
            a.as_ref().map_err(ToString::to_string),
            b.as_ref().map_err(ToString::to_string),
            "{what}: scan {k} ended otherwise on the short path"
        );
        assert_eq!(
            short.outputs(),
            full.outputs(),
            "{what}: outputs of scan {k}"
        );
        assert_eq!(
            short.scans(),
            full.scans(),
            "{what}: scans counted by scan {k}"
        );
    }
}

#[test]
fn random_st_programs_scan_alike_on_the_short_and_the_full_path() {
    let batch = stgen::generate(0x50_1E, 120, 40);
    let mut short_path = 0;
    for case in &batch.cases {
        let imported = import_st(&batch.source, "batch.st", Some(&case.program))
            .unwrap_or_else(|e| panic!("{}: {e}", case.program));
        let program = Arc::new(imported.program);
        short_path += usize::from(cetratus_program::SoleBody::of(&program).is_some());
        same_scans(&program, &images(&program, case), u64::MAX, &case.program);
    }
    assert_eq!(
        short_path,
        batch.cases.len(),
        "every imported POU is a sole body"
    );
}

/// A POU that divides by an input, loops as often as another says, and counts with a TON.
const EDGES: &str = "PROGRAM Edge
VAR_INPUT d : DINT; n : DINT; go : BOOL; END_VAR
VAR_OUTPUT q : DINT; done : BOOL; k : DINT; END_VAR
VAR t : TON; i : DINT; END_VAR
t(IN := go, PT := T#20ms);
done := t.Q;
k := 0;
FOR i := 1 TO n DO
  k := k + 1;
END_FOR;
q := 100 / d;
END_PROGRAM
";

#[test]
fn faults_and_the_work_budget_end_a_scan_alike_on_both_paths() {
    let program = Arc::new(
        import_st(EDGES, "edge.st", None)
            .expect("it imports")
            .program,
    );
    assert!(cetratus_program::SoleBody::of(&program).is_some());
    let image = |d, n, go| {
        let by = |name: &str| match name {
            "d" => Value::Int(d),
            "n" => Value::Int(n),
            _ => Value::Bool(go),
        };
        program
            .inputs()
            .iter()
            .map(|s| by(&s.name))
            .collect::<Vec<_>>()
    };
    // Division by zero at scan 3 and 4, then a loop too long for the budget at scan 6, then
    // back to normal: each failed scan makes the next one run in full, on both sides.
    let images = [
        image(1, 1, false),
        image(2, 3, true),
        image(5, 2, true),
        image(0, 2, true),
        image(0, 2, false),
        image(4, 2, true),
        image(4, 100_000, true),
        image(4, 3, true),
        image(7, 3, true),
        image(7, 3, true),
        image(7, 3, false),
    ];
    same_scans(&program, &images, 20_000, "edge");
}
