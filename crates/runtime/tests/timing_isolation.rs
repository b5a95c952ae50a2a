//! Timing isolation of the candidate (docs/design.md §2): the Dispatcher writes the primary's outputs
//! before the candidate is scanned, a candidate over its time budget is removed after its scan,
//! and a runaway candidate scan is stopped midway by its work budget, not by a clock.
//!
//! Time here is a stopwatch that moves 1 ms at every reading, so each scan "takes" 1 ms and the
//! point of the cycle at which the outputs are written is a deterministic number.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use cetratus_net::{ArcKind, NetBuilder, Place, Transition};
use cetratus_program::{PackageMeta, Program, Projection, ResolvedUpdate, StateTransform, Value};
use cetratus_runtime::{
    Command, Dispatcher, EventKind, InstallTiming, Limits, Plc, Provider, Status, Stopwatch,
};
use cetratus_testkit::nets;

const TICK_NS: u64 = 1_000_000;
const PERIOD: u64 = 10_000;

/// A stopwatch that moves one tick at every reading.
struct Ticking(Arc<AtomicU64>);

impl Stopwatch for Ticking {
    fn now_ns(&mut self) -> u64 {
        self.0.fetch_add(TICK_NS, Ordering::Relaxed)
    }
}

/// Inputs that toggle x every cycle; records how far the stopwatch moved between reading the
/// inputs and writing the outputs.
struct Io {
    clock: Arc<AtomicU64>,
    k: u64,
    read_at: u64,
    latencies: Vec<u64>,
}

impl Provider for Io {
    fn read_inputs(&mut self, _: u64, i: &mut [Value]) {
        self.read_at = self.clock.load(Ordering::Relaxed);
        i[0] = Value::Bool(self.k % 2 == 1);
        i[1] = Value::Bool(false);
        i[2] = Value::Int(0);
    }
}

impl Dispatcher for Io {
    fn write_outputs(&mut self, _: u64, _: &[Value]) {
        let at = self.clock.load(Ordering::Relaxed);
        self.latencies.push(at - self.read_at);
    }
}

const SIGNALS: &str = "[[input]]\nname = \"x\"\ntype = \"bool\"\n\
     [[input]]\nname = \"y\"\ntype = \"bool\"\n\
     [[input]]\nname = \"n\"\ntype = \"int\"\n\
     [[output]]\nname = \"o\"\ntype = \"bool\"\n\
     [[action]]\nplace = \"B\"\nqualifier = \"N\"\ntarget = \"o\"\n";

fn small(name: &str) -> Arc<Program> {
    let src = format!(
        "[program]\nname = \"{name}\"\nversion = \"1\"\n{SIGNALS}\
         [guards]\nT1 = \"x\"\nT2 = \"!x\"\nT3 = \"n > 100\"\n"
    );
    Arc::new(Program::from_sources(&src, "t.toml", nets::small()).unwrap_or_else(|e| panic!("{e}")))
}

/// The small net plus `width` self-loops U0, U1, … on places W0, W1, … that are always marked:
/// every scan evaluates and fires all of them.
fn wide(width: usize) -> Arc<Program> {
    let mut b = NetBuilder::new("wide");
    for (id, m) in [("A", 1), ("B", 0), ("C", 2)] {
        b.add_place(Place::new(id, m)).expect("place");
    }
    for id in ["T1", "T2", "T3"] {
        b.add_transition(Transition::new(id)).expect("transition");
    }
    for (id, s, t) in [
        ("a1", "A", "T1"),
        ("a2", "T1", "B"),
        ("a3", "B", "T2"),
        ("a4", "T2", "A"),
        ("a5", "C", "T3"),
        ("a6", "T3", "C"),
    ] {
        b.add_arc(id, s, t, 1, ArcKind::Normal).expect("arc");
    }
    for i in 0..width {
        let (w, u) = (format!("W{i}"), format!("U{i}"));
        b.add_place(Place::new(&w, 1)).expect("place");
        b.add_transition(Transition::new(&u)).expect("transition");
        b.add_arc(&format!("w{i}"), &w, &u, 1, ArcKind::Normal)
            .expect("arc");
        b.add_arc(&format!("u{i}"), &u, &w, 1, ArcKind::Normal)
            .expect("arc");
    }
    let src = format!(
        "[program]\nname = \"wide\"\nversion = \"1\"\n{SIGNALS}\
         [guards]\nT1 = \"x\"\nT2 = \"!x\"\nT3 = \"n > 100\"\n"
    );
    Arc::new(
        Program::from_sources(&src, "t.toml", b.build().expect("net"))
            .unwrap_or_else(|e| panic!("{e}")),
    )
}

struct Rig {
    plc: Plc,
    io: Io,
    events: Vec<cetratus_runtime::Event>,
}

impl Rig {
    fn new(primary: &Arc<Program>) -> Self {
        let clock = Arc::new(AtomicU64::new(0));
        let mut plc = Plc::new(primary.clone(), 0, Box::new(Ticking(clock.clone())));
        plc.set_install_timing(InstallTiming::Model { ns_per_entry: 0 });
        // The ticking stopwatch makes every scan 1 ms: far from the primary's watchdog.
        plc.set_limits(Limits {
            watchdog_ns: 1_000 * TICK_NS,
            candidate_budget_ns: 1_000 * TICK_NS,
            ..plc.limits()
        });
        Rig {
            plc,
            io: Io {
                clock,
                k: 0,
                read_at: 0,
                latencies: Vec::new(),
            },
            events: Vec::new(),
        }
    }

    fn run(&mut self, cycles: u64) {
        for _ in 0..cycles {
            self.io.k += 1;
            self.plc.cycle(self.io.k * PERIOD, &mut self.io);
            self.events.extend(self.plc.drain_events());
            drop(self.plc.take_retired());
        }
    }

    fn load(&mut self, new: &Arc<Program>) {
        let old = self.plc.primary_program().clone();
        let meta = PackageMeta {
            name: new.name().into(),
            version: "2".into(),
            author: String::new(),
            description: String::new(),
            created: String::new(),
            base_program_hash: old.hash_hex().to_string(),
            changes_throughput: false,
            changes: Default::default(),
        };
        let up = self
            .plc
            .update_context()
            .prepare(ResolvedUpdate {
                program: new.clone(),
                transform: StateTransform::generated(&old, new, &BTreeMap::new())
                    .expect("transform"),
                projection: Projection::generated(old.net(), new.net()).expect("projection"),
                meta,
            })
            .expect("prepared");
        self.plc
            .command(Command::Load(Box::new(up)))
            .expect("load accepted");
    }

    fn event(&self, kind: EventKind) -> Option<&cetratus_runtime::Event> {
        self.events.iter().find(|e| e.kind == kind)
    }
}

#[test]
fn the_dispatcher_writes_the_primarys_outputs_as_early_in_the_cycle_with_a_candidate_as_without() {
    let p = small("p");
    let mut r = Rig::new(&p);
    r.run(5);
    let alone = *r.io.latencies.last().expect("dispatched");
    r.load(&small("candidate"));
    r.run(5);
    assert_eq!(r.plc.status(), Status::Quarantine);
    assert!(
        r.io.latencies[5..].iter().all(|&l| l == alone),
        "the outputs were written {:?} ns after the inputs were read with a candidate, {alone} \
         ns without: the candidate's scan delayed the plant",
        &r.io.latencies[5..]
    );
}

#[test]
fn a_candidate_over_its_time_budget_is_removed_after_its_scan_without_delaying_the_outputs() {
    let p = small("p");
    let mut r = Rig::new(&p);
    r.run(5);
    let alone = *r.io.latencies.last().expect("dispatched");
    r.plc.set_limits(Limits {
        candidate_budget_ns: TICK_NS / 2,
        ..r.plc.limits()
    });
    r.load(&small("candidate"));
    r.run(3);
    assert_eq!(r.plc.status(), Status::Idle, "the candidate is removed");
    let e = r.event(EventKind::CandidateFault).expect("candidate_fault");
    assert!(e.message.contains("over its budget"), "{}", e.message);
    assert!(
        r.io.latencies.iter().all(|&l| l == alone),
        "latencies {:?}, {alone} ns without a candidate",
        r.io.latencies
    );
}

/// The work a scan of [`wide`] does before its first U when B is marked and x is false: T2's
/// guard (which holds, and T2 fires) and T3's.
fn guards_cost(p: &Program) -> u64 {
    let cost = |id| p.guard_cost(p.net().transition_by_id(id).expect("transition"));
    cost("T2") + 1 + cost("T3")
}

#[test]
fn a_runaway_candidate_scan_is_stopped_midway_by_its_work_budget_and_the_primary_goes_on() {
    let p = small("p");
    let mut r = Rig::new(&p);
    r.run(4);
    // B is marked at this cycle and x is false: T2 (`!x`) is evaluated and fires, T3 is
    // evaluated, false ([`guards_cost`]); each U is looked at and fires: 2 units. U0..U47 fit,
    // and U48 would pass the budget.
    let w = wide(1000);
    r.plc.set_limits(Limits {
        candidate_instruction_budget: guards_cost(&w) + 2 * 48,
        ..r.plc.limits()
    });
    r.load(&w);
    r.run(1);
    assert_eq!(
        r.plc.status(),
        Status::Idle,
        "the runaway candidate is removed"
    );
    let e = r.event(EventKind::CandidateFault).expect("candidate_fault");
    assert!(
        e.message.contains("stopped at transition `U48`"),
        "the scan went past its budget: {}",
        e.message
    );
    let before = r.plc.primary_container().scans();
    r.run(3);
    assert_eq!(r.plc.primary_container().scans(), before + 3);
    assert_eq!(r.plc.status(), Status::Idle);
}

#[test]
fn a_candidate_within_its_work_budget_runs_in_quarantine() {
    let p = small("p");
    let mut r = Rig::new(&p);
    r.run(4);
    let w = wide(1000);
    r.plc.set_limits(Limits {
        candidate_instruction_budget: guards_cost(&w) + 2 * 1000,
        ..r.plc.limits()
    });
    r.load(&w);
    r.run(5);
    assert_eq!(r.plc.status(), Status::Quarantine, "{:?}", r.events);
}
