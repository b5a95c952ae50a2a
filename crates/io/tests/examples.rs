//! The example programs run by the runtime against their digital twins, seen from outside: a virtual
//! hour each, a broken program caught by the twin, and repeatable traces.

mod common;

use std::sync::Arc;

use cetratus_io::TwinDriver;
use cetratus_program::{Program, Value};
use cetratus_runtime::trace::Trace;
use cetratus_twin::{
    FaultKind, FestoParams, FestoStation, Plant, VernadatCell, VernadatParams, SECOND_US,
};
use common::{
    connect, counter, load, place, start_festo, FESTO, HOUR_US, VERNADAT, VERNADAT_BROKEN,
};

/// The twin's faults, one per line, for an assertion message.
fn faults_of<P: Plant>(plant: &P) -> String {
    plant
        .faults()
        .iter()
        .map(|f| f.to_string())
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn vernadat_program_runs_an_hour_without_fault_and_keeps_its_four_invariants_after_every_scan() {
    let program = load(VERNADAT);
    let p = |id| place(&program, id);
    // docs/design.md §6, as (weighted places, constant); checked by hand rather than through the program's
    // own declarations, so that a wrong declaration cannot hide a wrong net.
    let invariants: [(&str, Vec<usize>, u64); 4] = [
        (
            "R + P11 + P14 + P22 + P24 = 1",
            vec![p("R"), p("P11"), p("P14"), p("P22"), p("P24")],
            1,
        ),
        ("H + B + P14 = 7", vec![p("H"), p("B"), p("P14")], 7),
        (
            "P10 + P11 + P12 + P13 + P14 = 1",
            vec![p("P10"), p("P11"), p("P12"), p("P13"), p("P14")],
            1,
        ),
        (
            "P20 + P21 + P22 + P23 + P24 = 1",
            vec![p("P20"), p("P21"), p("P22"), p("P23"), p("P24")],
            1,
        ),
    ];
    let (mut cycle, mut io) = connect(&program, VernadatCell::with_defaults(1));
    let mut broken: Option<String> = None;
    let end = cycle
        .run_virtual(0, HOUR_US, &mut io, |c, now, _| {
            if broken.is_some() {
                return;
            }
            let m = c.container().marking();
            for (name, places, constant) in &invariants {
                let sum: u64 = places.iter().map(|&i| u64::from(m[i])).sum();
                if sum != *constant {
                    broken = Some(format!("{name} is {sum} after the scan at {now} µs"));
                    return;
                }
            }
        })
        .expect("no scan error");
    assert_eq!(end, HOUR_US);
    assert_eq!(broken, None);
    let cell = io.plant();
    assert!(cell.faults().is_empty(), "faults:\n{}", faults_of(cell));
    let finished = counter(cell, "parts_finished");
    assert!(
        (300..=450).contains(&finished),
        "{finished} parts finished; machine 2 bounds the hour at 450"
    );
}

#[test]
fn festo_program_runs_an_hour_without_fault_and_tests_drills_and_ejects_every_part() {
    let program = load(FESTO);
    let mut station = FestoStation::with_defaults(1);
    start_festo(&mut station);
    let (mut cycle, mut io) = connect(&program, station);
    let mut violation: Option<String> = None;
    cycle
        .run_virtual(0, HOUR_US, &mut io, |c, now, _| {
            if violation.is_none() {
                if let Err(v) = c
                    .container()
                    .program()
                    .check_invariants(c.container().marking())
                {
                    violation = Some(format!("at {now} µs: {v}"));
                }
            }
        })
        .expect("no scan error");
    assert_eq!(violation, None);
    let st = io.plant();
    assert!(st.faults().is_empty(), "faults:\n{}", faults_of(st));
    let supplied = counter(st, "parts_supplied");
    let tested = counter(st, "parts_tested");
    let drilled = counter(st, "parts_drilled");
    let ejected = counter(st, "parts_ejected");
    assert_eq!(counter(st, "parts_ejected_incomplete"), 0);
    // A part arrives every 5 s: 720 in the hour. The table holds at most four parts between the
    // input and the ejector, so at most that many are still on it when the hour ends.
    assert!(supplied >= 715, "only {supplied} parts supplied");
    assert!(
        supplied - ejected <= 4,
        "{supplied} supplied, {ejected} ejected"
    );
    assert!(ejected <= drilled && drilled <= tested && tested <= supplied);
}

#[test]
fn vernadat_program_whose_t13_ignores_the_free_slots_overflows_the_buffer_within_an_hour() {
    let program = load(VERNADAT_BROKEN);
    let t13 = program
        .net()
        .transition_by_id("T13")
        .expect("the broken net has T13");
    let h = program
        .net()
        .place_by_id("H")
        .expect("the broken net has H");
    assert!(
        program.net().pre(t13).iter().all(|&(p, _)| p != h),
        "the broken program's T13 must not take a free slot from H"
    );
    let (mut cycle, mut io) = connect(&program, VernadatCell::with_defaults(1));
    let mut now = 0;
    let overflow = |io: &TwinDriver<VernadatCell>| {
        io.plant()
            .faults()
            .iter()
            .find(|f| f.kind == FaultKind::BufferOverflow)
            .map(|f| f.at_us)
    };
    while now < HOUR_US && overflow(&io).is_none() {
        cycle.cycle(now, &mut io).expect("no scan error");
        now += cycle.period_us();
    }
    let at = overflow(&io).unwrap_or_else(|| {
        panic!(
            "no buffer overflow in an hour; faults:\n{}",
            faults_of(io.plant())
        )
    });
    assert!(at < HOUR_US);
}

/// Runs `program` against `plant` for `for_us` and records the I/O trace.
fn trace_of<P: Plant>(program: &Arc<Program>, plant: P, for_us: u64) -> Trace {
    let (mut cycle, mut io) = connect(program, plant);
    let mut trace = Trace::new(
        program.inputs().iter().map(|s| s.name.clone()).collect(),
        program.outputs().iter().map(|s| s.name.clone()).collect(),
    );
    cycle
        .run_virtual(0, for_us, &mut io, |c, now, _| {
            let k = c.container();
            trace.observe(k.scans() - 1, now, k.inputs(), k.outputs());
        })
        .expect("no scan error");
    trace
}

/// A trace row as a comparable tuple: scan, time, inputs, outputs.
type Row = (u64, u64, Vec<Value>, Vec<Value>);

/// The rows of a trace.
fn rows(t: &Trace) -> Vec<Row> {
    t.rows
        .iter()
        .map(|r| (r.scan, r.time_us, r.inputs.clone(), r.outputs.clone()))
        .collect()
}

#[test]
fn two_runs_with_the_same_seed_produce_identical_traces_and_another_seed_does_not() {
    // Jitter on every duration makes the seed matter; without it every seed gives the same run.
    const TEN_MINUTES: u64 = 600 * SECOND_US;
    let vernadat = load(VERNADAT);
    let cell = |seed| {
        let params = VernadatParams {
            jitter_us: 50_000,
            ..VernadatParams::default()
        };
        VernadatCell::new(params, seed).expect("valid parameters")
    };
    let a = trace_of(&vernadat, cell(7), TEN_MINUTES);
    let b = trace_of(&vernadat, cell(7), TEN_MINUTES);
    let c = trace_of(&vernadat, cell(8), TEN_MINUTES);
    assert!(a.rows.len() > 100, "the cell barely moved");
    assert!(rows(&a) == rows(&b), "same seed, different Vernadat traces");
    assert!(
        rows(&a) != rows(&c),
        "the seed had no effect on the Vernadat cell"
    );

    let festo = load(FESTO);
    let station = |seed| {
        let params = FestoParams {
            jitter_us: 50_000,
            ..FestoParams::default()
        };
        let mut st = FestoStation::new(params, seed).expect("valid parameters");
        start_festo(&mut st);
        st
    };
    let a = trace_of(&festo, station(7), TEN_MINUTES);
    let b = trace_of(&festo, station(7), TEN_MINUTES);
    let c = trace_of(&festo, station(8), TEN_MINUTES);
    assert!(a.rows.len() > 100, "the station barely moved");
    assert!(rows(&a) == rows(&b), "same seed, different Festo traces");
    assert!(
        rows(&a) != rows(&c),
        "the seed had no effect on the Festo station"
    );
}
