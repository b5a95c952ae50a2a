//! Edge memory and place timers across an install and a substitution: a program replaced by
//! itself must behave, at every instant of the switch, exactly as the program left alone. Each
//! case sweeps the install and the switch over the cycles of an input pattern whose edges fall
//! on many of them.

use std::collections::BTreeMap;
use std::sync::Arc;

use cetratus_program::{PackageMeta, Program, Projection, ResolvedUpdate, StateTransform, Value};
use cetratus_runtime::{
    Command, Dispatcher, InstallTiming, ManualStopwatch, Plc, Provider, Slot, Status,
    SubstituteMode, SubstituteRequest,
};
use cetratus_testkit::nets;

/// A program on the three-place net A ⇄ B (T1: A → B, T2: B → A; T3 never fires), whose output
/// `o` is on while B is marked.
fn program(guards: &str) -> Arc<Program> {
    let src = format!(
        "[program]\nname = \"p\"\nversion = \"1\"\n\
         [[input]]\nname = \"x\"\ntype = \"bool\"\n\
         [[input]]\nname = \"y\"\ntype = \"bool\"\n\
         [[input]]\nname = \"n\"\ntype = \"int\"\n\
         [[output]]\nname = \"o\"\ntype = \"bool\"\n\
         [[action]]\nplace = \"B\"\nqualifier = \"N\"\ntarget = \"o\"\n\
         [guards]\n{guards}\nT3 = \"n > 100\"\n"
    );
    Arc::new(Program::from_sources(&src, "t.toml", nets::small()).unwrap_or_else(|e| panic!("{e}")))
}

/// The input pattern: x toggles every 3 cycles, y every 5, so edges of both fall on most
/// residues of the sweep.
struct Pattern {
    k: u64,
}

impl Provider for Pattern {
    fn read_inputs(&mut self, _: u64, i: &mut [Value]) {
        i[0] = Value::Bool((self.k / 3) % 2 == 1);
        i[1] = Value::Bool((self.k / 5) % 2 == 1);
        i[2] = Value::Int(0);
    }
}

impl Dispatcher for Pattern {
    fn write_outputs(&mut self, _: u64, _: &[Value]) {}
}

const PERIOD: u64 = 10_000;
const CYCLES: u64 = 90;

fn plc(p: &Arc<Program>) -> Plc {
    let mut plc = Plc::new(p.clone(), 0, Box::new(ManualStopwatch::new()));
    plc.set_install_timing(InstallTiming::Model { ns_per_entry: 0 });
    plc
}

fn load_itself(plc: &mut Plc, p: &Arc<Program>) {
    let meta = PackageMeta {
        name: "same".into(),
        version: "1".into(),
        author: String::new(),
        description: String::new(),
        created: String::new(),
        base_program_hash: p.hash_hex().to_string(),
        changes_throughput: false,
        changes: Default::default(),
    };
    let up = plc
        .update_context()
        .prepare(ResolvedUpdate {
            program: p.clone(),
            transform: StateTransform::generated(p, p, &BTreeMap::new()).expect("transform"),
            projection: Projection::generated(p.net(), p.net()).expect("projection"),
            meta,
        })
        .expect("prepared");
    plc.command(Command::Load(Box::new(up)))
        .expect("load accepted");
}

/// Per cycle: the dispatched output and the primary's marking.
type Trace = Vec<(Value, Vec<u32>)>;

/// Runs the pattern; loads the program into the secondary before cycle `load_at` and substitutes
/// it before cycle `switch_at` (when given). In quarantine the candidate must match the primary.
fn run(p: &Arc<Program>, load_at: Option<u64>, switch_at: Option<u64>) -> Trace {
    let mut plc = plc(p);
    let mut io = Pattern { k: 0 };
    let mut trace = Vec::new();
    for k in 0..CYCLES {
        if load_at == Some(k) {
            load_itself(&mut plc, p);
        }
        if switch_at == Some(k) {
            plc.command(Command::Substitute(SubstituteRequest::now(
                SubstituteMode::Retransform,
            )))
            .expect("substitute accepted");
        }
        io.k = k;
        plc.cycle(k * PERIOD, &mut io);
        if plc.status() == Status::Quarantine {
            let (a, b) = (
                plc.container(Slot::A).expect("A"),
                plc.container(Slot::B).expect("B"),
            );
            assert_eq!(
                (a.marking(), a.outputs()),
                (b.marking(), b.outputs()),
                "in quarantine at cycle {k} (installed before cycle {load_at:?}), the candidate \
                 parted from the primary it copies"
            );
        }
        trace.push((
            plc.dispatched()[0],
            plc.primary_container().marking().to_vec(),
        ));
        drop(plc.take_retired());
    }
    trace
}

fn sweep(guards: &str) {
    let p = program(guards);
    let alone = run(&p, None, None);
    let fired = alone.windows(2).filter(|w| w[0].1 != w[1].1).count();
    assert!(
        fired > 10,
        "the pattern makes the net move ({fired} changes)"
    );
    for load_at in 1..31 {
        // Quarantine alone, and every switch instant after it.
        let q = run(&p, Some(load_at), None);
        assert_eq!(q, alone, "`{guards}`: install before cycle {load_at}");
        for switch_at in load_at + 1..load_at + 31 {
            let t = run(&p, Some(load_at), Some(switch_at));
            for (k, (got, want)) in t.iter().zip(&alone).enumerate() {
                assert_eq!(
                    got, want,
                    "`{guards}`: installed before cycle {load_at}, substituted before cycle \
                     {switch_at}: cycle {k} differs from the program left alone"
                );
            }
        }
    }
}

#[test]
fn a_program_substituted_by_itself_sees_every_rising_edge_at_any_switch_instant() {
    sweep("T1 = \"rise(x)\"\nT2 = \"rise(y)\"");
}

#[test]
fn a_program_substituted_by_itself_sees_every_falling_edge_at_any_switch_instant() {
    sweep("T1 = \"fall(x)\"\nT2 = \"fall(y)\"");
}

#[test]
fn a_program_substituted_by_itself_keeps_its_place_timers_at_any_switch_instant() {
    sweep("T1 = \"A.t >= 30ms\"\nT2 = \"B.t >= 50ms\"");
}

#[test]
fn a_program_substituted_by_itself_keeps_edges_and_timers_together_at_any_switch_instant() {
    sweep("T1 = \"rise(x) || A.t >= 70ms\"\nT2 = \"fall(y) && B.t >= 20ms\"");
}
