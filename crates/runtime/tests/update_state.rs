//! What an update carries besides the marking, and what a restarted container recomputes: found
//! in review and kept as regression tests. Each scenario runs on a three-place net.

use std::collections::BTreeMap;
use std::sync::Arc;

use cetratus_program::{PackageMeta, Program, Projection, ResolvedUpdate, StateTransform, Value};
use cetratus_runtime::{
    Command, Container, Dispatcher, InstallTiming, ManualStopwatch, Plc, Provider, Slot,
    SubstituteMode, SubstituteRequest, UpdateContext,
};
use cetratus_testkit::nets;

fn program(name: &str, guards: &str, extra: &str) -> Arc<Program> {
    let src = format!(
        "[program]\nname = \"{name}\"\nversion = \"1\"\n\
         [[input]]\nname = \"x\"\ntype = \"bool\"\n\
         [[input]]\nname = \"y\"\ntype = \"bool\"\n\
         [[input]]\nname = \"n\"\ntype = \"int\"\n\
         [[output]]\nname = \"o\"\ntype = \"bool\"\n\
         [[variable]]\nname = \"flag\"\ntype = \"bool\"\n\
         {extra}\n[guards]\n{guards}\n"
    );
    Arc::new(Program::from_sources(&src, "t.toml", nets::small()).unwrap_or_else(|e| panic!("{e}")))
}

fn img(x: bool, y: bool) -> Vec<Value> {
    vec![Value::Bool(x), Value::Bool(y), Value::Int(0)]
}

/// After set_state, the second scan is taken as quiet on a stale `quiet` flag, and a guard
/// reading a variable that the first scan's actions wrote is never evaluated again.
#[test]
fn after_set_state_a_guard_on_a_variable_its_actions_wrote_is_evaluated_again() {
    let p = program(
        "p",
        "T1 = \"x\"\nT2 = \"flag\"\nT3 = \"n > 100\"",
        "[[action]]\nplace = \"B\"\nqualifier = \"N\"\ntarget = \"flag\"\n",
    );
    let mut quick = Container::new(p.clone(), 0);
    let mut full = Container::new(p.clone(), 0);
    full.set_always_full(true);
    let mut now = 0;
    for _ in 0..5 {
        now += 10_000;
        quick.scan(now, &img(false, false)).unwrap();
        full.scan(now, &img(false, false)).unwrap();
    }
    // marking B=1
    let m = [0, 1, 2];
    let since = [None, Some(now), Some(0)];
    quick.set_state(&m, &since).unwrap();
    full.set_state(&m, &since).unwrap();
    for _ in 0..5 {
        now += 10_000;
        quick.scan(now, &img(false, false)).unwrap();
        full.scan(now, &img(false, false)).unwrap();
    }
    assert_eq!(quick.marking(), full.marking());
}

/// After set_state, outputs_may_have_changed() is false although the first scan rewrote them.
#[test]
fn after_set_state_the_first_scan_reports_its_outputs_as_changed() {
    let p = program(
        "p",
        "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 100\"",
        "[[action]]\nplace = \"B\"\nqualifier = \"N\"\ntarget = \"o\"\n",
    );
    let mut c = Container::new(p.clone(), 0);
    let mut now = 0;
    for _ in 0..5 {
        now += 10_000;
        c.scan(now, &img(false, false)).unwrap();
    }
    assert_eq!(c.outputs()[0], Value::Bool(false));
    c.set_state(&[0, 1, 2], &[None, Some(now), Some(0)])
        .unwrap();
    now += 10_000;
    c.scan(now, &img(false, false)).unwrap();
    assert_eq!(c.outputs()[0], Value::Bool(true));
    assert!(
        c.outputs_may_have_changed(),
        "outputs changed but the container says they did not"
    );
}

/// A PLC on the three-place net, driven by an input image the test sets.
struct Rig {
    plc: Plc,
    io: Io,
    now: u64,
}

struct Io {
    inputs: Vec<Value>,
}

impl Provider for Io {
    fn read_inputs(&mut self, _: u64, i: &mut [Value]) {
        i.copy_from_slice(&self.inputs);
    }
}

impl Dispatcher for Io {
    fn write_outputs(&mut self, _: u64, _: &[Value]) {}
}

impl Rig {
    fn new(program: &Arc<Program>) -> Self {
        let mut plc = Plc::new(program.clone(), 0, Box::new(ManualStopwatch::new()));
        plc.set_install_timing(InstallTiming::Model { ns_per_entry: 0 });
        Rig {
            plc,
            io: Io {
                inputs: img(false, false),
            },
            now: 0,
        }
    }

    /// `k` cycles with this input image.
    fn run(&mut self, inputs: Vec<Value>, k: usize) {
        self.io.inputs = inputs;
        for _ in 0..k {
            self.now += 10_000;
            self.plc.cycle(self.now, &mut self.io);
        }
    }

    /// Loads `new` with the generated transform; it is installed at the next cycle.
    fn load(&mut self, old: &Arc<Program>, new: &Arc<Program>) {
        let transform = StateTransform::generated(old, new, &BTreeMap::new()).expect("transform");
        let meta = PackageMeta {
            name: "u".into(),
            version: "2".into(),
            author: String::new(),
            description: String::new(),
            created: String::new(),
            base_program_hash: old.hash_hex().to_string(),
            changes_throughput: false,
            changes: Default::default(),
        };
        let up = UpdateContext {
            primary: old.clone(),
            io_inputs: self.plc.io_inputs().to_vec(),
            io_outputs: self.plc.io_outputs().to_vec(),
            primary_marking: self.plc.primary_container().marking().to_vec(),
            cycle: self.plc.cycles(),
            admission: None,
        }
        .prepare(ResolvedUpdate {
            program: new.clone(),
            transform,
            projection: Projection::generated(old.net(), new.net()).expect("projection"),
            meta,
        })
        .expect("prepared");
        self.plc
            .command(Command::Load(Box::new(up)))
            .expect("load accepted");
    }

    fn substitute(&mut self) {
        self.plc
            .command(Command::Substitute(SubstituteRequest {
                mode: SubstituteMode::Retransform,
                when: None,
                within_us: None,
                force: false,
            }))
            .expect("substitute accepted");
    }
}

#[test]
fn after_a_retransform_substitution_the_dispatcher_gets_the_new_primarys_outputs() {
    let act = "[[action]]\nplace = \"B\"\nqualifier = \"N\"\ntarget = \"o\"\n";
    let old = program("old", "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 100\"", act);
    let new = program(
        "new",
        "T1 = \"x\"\nT2 = \"y && n > 5\"\nT3 = \"n > 100\"",
        act,
    );
    let mut r = Rig::new(&old);
    r.run(img(false, false), 3);
    r.load(&old, &new);
    // The candidate drifts to B (its T2 needs n > 5); the primary goes back to A.
    r.run(img(false, false), 2);
    r.run(img(true, false), 1);
    r.run(img(false, false), 3);
    r.run(img(false, true), 1);
    r.run(img(false, false), 5);
    r.substitute();
    r.run(img(false, false), 3);
    let c = r.plc.container(Slot::B).expect("B is primary");
    assert_eq!(
        r.plc.dispatched()[0],
        c.outputs()[0],
        "dispatcher out of step with the primary's own outputs"
    );
}

/// S on B and no R: the token passes through B and the output stays latched, across the install
/// and the substitution.
#[test]
fn a_latched_output_stays_latched_across_install_and_substitution() {
    let act = "[[action]]\nplace = \"B\"\nqualifier = \"S\"\ntarget = \"o\"\n";
    let old = program("old", "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 100\"", act);
    let new = program("new", "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 101\"", act);
    let mut r = Rig::new(&old);
    r.run(img(true, false), 1);
    r.run(img(false, true), 1);
    r.run(img(false, false), 3);
    r.load(&old, &new);
    r.run(img(false, false), 3);
    r.substitute();
    r.run(img(false, false), 3);
    assert_eq!(
        r.plc.dispatched()[0],
        Value::Bool(true),
        "the latched output dropped at the switch"
    );
}

#[test]
fn after_substitution_a_primary_fault_drives_the_new_programs_safe_values() {
    let old = program("old", "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 100\"", "");
    let new = {
        let src = "[program]\nname = \"new\"\nversion = \"1\"\n\
             [[input]]\nname = \"x\"\ntype = \"bool\"\n\
             [[input]]\nname = \"y\"\ntype = \"bool\"\n\
             [[input]]\nname = \"n\"\ntype = \"int\"\n\
             [[output]]\nname = \"o\"\ntype = \"bool\"\nsafe = true\n\
             [[variable]]\nname = \"flag\"\ntype = \"bool\"\n\
             [[action]]\nplace = \"B\"\nqualifier = \"N\"\ntarget = \"o\"\n\
             [guards]\nT1 = \"x\"\nT2 = \"y\"\nT3 = \"100 / n > 1000\"\n";
        Arc::new(Program::from_sources(src, "t.toml", nets::small()).expect("program"))
    };
    let n = |v: i64| vec![Value::Bool(false), Value::Bool(false), Value::Int(v)];
    let mut r = Rig::new(&old);
    r.run(n(1), 2);
    r.load(&old, &new);
    r.run(n(1), 2);
    r.substitute();
    r.run(n(1), 2);
    // Division by zero in T3's guard: a primary fault, with the new program's safe values.
    r.run(n(0), 2);
    assert_eq!(r.plc.status(), cetratus_runtime::Status::Fault);
    assert_eq!(
        r.plc.dispatched()[0],
        Value::Bool(true),
        "new primary's safe value"
    );
}

/// exec_info counts a container's cycles and its firings over the same window: since its
/// install, across the retransform at the substitution.
#[test]
fn after_a_retransform_the_new_primarys_cycles_and_firings_count_over_the_same_window() {
    let act = "[[action]]\nplace = \"B\"\nqualifier = \"N\"\ntarget = \"o\"\n";
    let old = program("old", "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 100\"", act);
    let new = program("new", "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 101\"", act);
    let mut r = Rig::new(&old);
    r.run(img(false, false), 3);
    r.load(&old, &new);
    let (mut scans, mut fired) = (0u64, 0u64);
    for k in 0..40 {
        if k == 20 {
            r.substitute();
        }
        r.io.inputs = img(k % 4 == 1, k % 4 == 3);
        r.now += 10_000;
        r.plc.cycle(r.now, &mut r.io);
        let b = r.plc.container(Slot::B).expect("B is installed");
        scans += 1;
        fired += b.fired().len() as u64;
    }
    assert_eq!(r.plc.primary(), Slot::B, "substituted");
    let info = r.plc.exec_info()[1].clone().expect("B's exec_info");
    let counted: u64 = info.firings.values().sum();
    assert_eq!(
        (info.cycles, counted),
        (scans, fired),
        "cycles and firings since B's install"
    );
}
