//! A revert never disturbs the plant (docs/live-update.md, *Probation and rollback*), on the
//! Vernadat twin in virtual time:
//!
//! * an operator's `revert` at every 100 ms of a 60 s probation (600 instants) of U.1 and of
//!   U.2: each one reverts to a marking that agrees with the plant, or is refused with its
//!   reason;
//! * an automatic revert (a U.1 that breaks an invariant it declares), substituted at several
//!   instants of the cell's cycle.
//!
//! Every run must end with no twin fault, no part scrapped, and as many parts as the runs
//! without the revert make, give or take one.

mod updates;

use cetratus_runtime::{Command, EventDetail, EventKind, Status, SubstituteMode};
use cetratus_twin::Plant;
use updates::{Cell, Workshop};

const WINDOW_US: u64 = 60_000_000;
/// The cell runs this long before the update is loaded.
const WARMUP_US: u64 = 3_000_000;
/// Every run goes on this long after its revert was asked for, then is counted.
const TAIL_US: u64 = 10_000_000;
/// The instants of the operator's revert: every 100 ms of the window.
const STEP_US: u64 = 100_000;

/// What a run left: its twin faults and scrapped parts, in words, and its finished parts.
struct Ran {
    trouble: Vec<String>,
    parts: u64,
}

fn ran(cell: &Cell) -> Ran {
    let mut trouble: Vec<String> = cell
        .io
        .plant()
        .faults()
        .iter()
        .map(|f| format!("{f:?}"))
        .collect();
    let scrapped = cell
        .io
        .plant()
        .counters()
        .get("parts_scrapped")
        .unwrap_or(0);
    if scrapped > 0 {
        trouble.push(format!("{scrapped} parts scrapped"));
    }
    Ran {
        trouble,
        parts: cell.parts(),
    }
}

/// The program each package replaces: U.2 follows U.1.
fn base_of(package: &Package) -> &'static str {
    if package.manifest.starts_with("u2") {
        "u1.toml"
    } else {
        "vernadat.toml"
    }
}

/// An update package, built in the workshop.
struct Package {
    manifest: &'static str,
    bytes: Vec<u8>,
}

/// A cell that took `package` through quarantine and substituted it, on probation for
/// [`WINDOW_US`]; its clock at the substitution. An install the transform refuses at that
/// moment (a part on its way into the buffer, for the U.1 that breaks an invariant) is tried
/// again a cycle later.
fn on_probation(w: &Workshop, package: &Package, warmup_us: u64) -> (Cell, u64) {
    let mut cell = Cell::new(w.program(base_of(package)));
    let mut limits = cell.plc.limits();
    limits.probation_us = WINDOW_US;
    cell.plc.set_limits(limits);
    cell.run_for(warmup_us);
    for _ in 0..1000 {
        cell.load(&package.bytes, &w.trust)
            .expect("the package loads");
        cell.step();
        if cell.plc.status() == Status::Quarantine {
            break;
        }
    }
    assert_eq!(cell.plc.status(), Status::Quarantine, "{:#?}", cell.events);
    cell.substitute(SubstituteMode::Retransform, false)
        .expect("substitute accepted");
    cell.step();
    assert_eq!(cell.plc.status(), Status::Probation, "{:#?}", cell.events);
    let at = cell.now;
    (cell, at)
}

/// Finished parts at every [`STEP_US`] of a run from its substitution on: with the update kept
/// (no revert), and without the update at all.
fn references(w: &Workshop, package: &Package) -> [Vec<u64>; 2] {
    let span = WINDOW_US + TAIL_US + 2 * STEP_US;
    let (mut kept, from) = on_probation(w, package, WARMUP_US);
    let mut plain = Cell::new(w.program(base_of(package)));
    plain.run_for(from);
    let mut curves = [Vec::new(), Vec::new()];
    for _ in 0..span / STEP_US {
        for (curve, cell) in curves.iter_mut().zip([&mut kept, &mut plain]) {
            curve.push(cell.parts());
            cell.run_for(STEP_US);
        }
    }
    for cell in [&kept, &plain] {
        let r = ran(cell);
        assert!(r.trouble.is_empty(), "a reference run: {:?}", r.trouble);
    }
    curves
}

/// How the operator's revert at `at_us` into probation ended.
enum Outcome {
    Reverted { outputs_differing: u32 },
    Refused(String),
}

/// Substitutes `package`, asks for a revert `at_us` into probation, and runs [`TAIL_US`] on.
fn operator_revert(w: &Workshop, package: &Package, at_us: u64) -> (Outcome, Ran) {
    let (mut cell, _) = on_probation(w, package, WARMUP_US);
    cell.run_for(at_us);
    let seen = cell.events.len();
    cell.plc.command(Command::Revert).expect("revert accepted");
    let mut outcome = None;
    let end = cell.now + TAIL_US;
    while cell.now < end {
        cell.step();
        if outcome.is_none() {
            outcome = cell.events[seen..].iter().find_map(|e| match e.kind {
                EventKind::Reverted => match e.detail {
                    Some(EventDetail::Revert {
                        outputs_differing, ..
                    }) => Some(Outcome::Reverted { outputs_differing }),
                    _ => panic!("a revert without its detail: {e:?}"),
                },
                EventKind::Refused => Some(Outcome::Refused(e.message.clone())),
                _ => None,
            });
        }
    }
    let outcome = outcome.unwrap_or_else(|| panic!("no outcome: {:#?}", &cell.events[seen..]));
    (outcome, ran(&cell))
}

/// Sweeps the operator's revert over the window, in two threads, and checks every run.
fn sweep(manifest: &'static str) {
    let w = Workshop::new();
    let package = Package {
        manifest,
        bytes: w.package(manifest),
    };
    let [kept, plain] = references(&w, &package);
    let instants: Vec<u64> = (0..WINDOW_US / STEP_US).collect();
    let (mut reverted, mut refused) = (0, Vec::new());
    let results: Vec<(u64, Outcome, Ran)> = std::thread::scope(|s| {
        let halves: Vec<_> = instants
            .chunks(instants.len().div_ceil(2))
            .map(|part| {
                let (w, package) = (&w, &package);
                s.spawn(move || {
                    part.iter()
                        .map(|&k| {
                            let (o, r) = operator_revert(w, package, k * STEP_US);
                            (k, o, r)
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        halves
            .into_iter()
            .flat_map(|h| h.join().expect("a sweep thread"))
            .collect()
    });
    for (k, outcome, r) in results {
        let at = format!("{manifest}, revert at {:.1} s", (k * STEP_US) as f64 / 1e6);
        assert!(r.trouble.is_empty(), "{at}: {:?}", r.trouble);
        // Counted where the run was counted: the tail after the request, from the substitution.
        let i = ((k * STEP_US + TAIL_US) / STEP_US) as usize;
        let (lo, hi) = (kept[i].min(plain[i]), kept[i].max(plain[i]));
        assert!(
            r.parts + 1 >= lo && r.parts <= hi + 1,
            "{at}: {} parts, {lo} to {hi} without the revert",
            r.parts
        );
        match outcome {
            Outcome::Reverted { outputs_differing } => {
                assert_eq!(outputs_differing, 0, "{at}: an operator's revert agreed");
                reverted += 1;
            }
            Outcome::Refused(why) => {
                assert!(
                    why.starts_with("revert refused: ") && why.contains("agreed with the plant"),
                    "{at}: {why}"
                );
                refused.push(k);
            }
        }
    }
    // Most instants find a marking that agrees within the wait: the refusals are the moments
    // a full buffer or a lubrication leaves the old program no marking of its own.
    assert!(
        reverted >= instants.len() / 2,
        "{manifest}: {reverted} reverted, refused at {refused:?}"
    );
    eprintln!("{manifest}: {reverted} reverted, {} refused", refused.len());
}

#[test]
fn an_operators_revert_at_every_100_ms_of_u1s_probation_never_disturbs_the_plant() {
    sweep("u1.package.toml");
}

#[test]
fn an_operators_revert_at_every_100_ms_of_u2s_probation_never_disturbs_the_plant() {
    sweep("u2.package.toml");
}

#[test]
fn an_automatic_revert_at_any_phase_of_the_cell_never_disturbs_the_plant() {
    let w = Workshop::new();
    let package = Package {
        manifest: "u1-wrong.package.toml",
        bytes: w.u1_breaking_an_invariant(),
    };
    let mut plain = Cell::new(w.program("vernadat.toml"));
    // Substituted at 25 instants 1.37 s apart, across the cell's cycle of about 8 s.
    for k in 0..25u64 {
        let warmup = WARMUP_US + k * 1_370_000;
        let (mut cell, _) = on_probation(&w, &package, warmup);
        let seen = cell.events.len();
        cell.run_for(30_000_000);
        let e = cell.events[seen..]
            .iter()
            .find(|e| e.kind == EventKind::Reverted)
            .unwrap_or_else(|| panic!("no revert after {warmup} µs: {:#?}", cell.events));
        let Some(EventDetail::Revert {
            outputs_differing, ..
        }) = e.detail
        else {
            panic!("{e:?}")
        };
        assert_eq!(outputs_differing, 0, "{}", e.message);
        let r = ran(&cell);
        assert!(r.trouble.is_empty(), "after {warmup} µs: {:?}", r.trouble);
        while plain.now < cell.now {
            plain.step();
        }
        assert!(
            r.parts + 1 >= plain.parts() && r.parts <= plain.parts() + 1,
            "after {warmup} µs: {} parts, {} without the update",
            r.parts,
            plain.parts()
        );
    }
}
