//! What an update carries besides the marking, and what a restarted container recomputes: found
//! in review and kept as regression tests. Each scenario runs on a three-place net.

use std::collections::BTreeMap;
use std::sync::Arc;

use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition};
use cetratus_program::{PackageMeta, Program, Projection, ResolvedUpdate, StateTransform, Value};
use cetratus_runtime::plc::ModelStopwatch;
use cetratus_runtime::{
    Command, Container, Dispatcher, Plc, Provider, Slot, SubstituteMode, SubstituteRequest,
};

fn net() -> Net {
    let mut b = NetBuilder::new("small");
    for (id, m) in [("A", 1), ("B", 0), ("C", 2)] {
        b.add_place(Place::new(id, m)).unwrap();
    }
    for id in ["T1", "T2", "T3"] {
        b.add_transition(Transition::new(id)).unwrap();
    }
    for (id, s, t) in [
        ("a1", "A", "T1"),
        ("a2", "T1", "B"),
        ("a3", "B", "T2"),
        ("a4", "T2", "A"),
        ("a5", "C", "T3"),
        ("a6", "T3", "C"),
    ] {
        b.add_arc(id, s, t, 1, ArcKind::Normal).unwrap();
    }
    b.build().unwrap()
}

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
    Arc::new(Program::from_sources(&src, "t.toml", net()).unwrap_or_else(|e| panic!("{e}")))
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

struct Io {
    inputs: Vec<Value>,
    out: Vec<Value>,
}
impl Provider for Io {
    fn read_inputs(&mut self, _: u64, i: &mut [Value]) {
        i.copy_from_slice(&self.inputs);
    }
}
impl Dispatcher for Io {
    fn write_outputs(&mut self, _: u64, o: &[Value]) {
        self.out = o.to_vec();
    }
}

/// Plc: after a retransform substitution the Dispatcher writes the candidate's pre-retransform outputs.
#[test]
fn after_a_retransform_substitution_the_dispatcher_gets_the_new_primarys_outputs() {
    let act = "[[action]]\nplace = \"B\"\nqualifier = \"N\"\ntarget = \"o\"\n";
    let old = program("old", "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 100\"", act);
    let new = program(
        "new",
        "T1 = \"x\"\nT2 = \"y && n > 5\"\nT3 = \"n > 100\"",
        act,
    );
    let mut plc = Plc::new(old.clone(), 0);
    plc.set_stopwatch(Box::new(ModelStopwatch { ns_per_unit: 0 }));
    let mut io = Io {
        inputs: img(false, false),
        out: vec![],
    };
    let mut now = 0;
    let mut step = |plc: &mut Plc, io: &mut Io, x: bool, y: bool, k: usize| {
        for _ in 0..k {
            now += 10_000;
            io.inputs = img(x, y);
            plc.cycle(now, io);
        }
    };
    step(&mut plc, &mut io, false, false, 3);
    let transform = StateTransform::generated(&old, &new, &BTreeMap::new()).unwrap();
    let projection = Projection::generated(old.net(), new.net());
    let meta = PackageMeta {
        name: "u".into(),
        version: "2".into(),
        author: String::new(),
        description: String::new(),
        created: String::new(),
        base_program_hash: old.hash_hex().to_string(),
    };
    let up = Plc::prepare(
        &old,
        plc.io_inputs(),
        plc.io_outputs(),
        ResolvedUpdate {
            program: new.clone(),
            transform,
            projection,
            meta,
        },
    )
    .unwrap();
    plc.command(Command::Load(Box::new(up))).unwrap();
    step(&mut plc, &mut io, false, false, 2);
    step(&mut plc, &mut io, true, false, 1);
    step(&mut plc, &mut io, false, false, 3);
    step(&mut plc, &mut io, false, true, 1);
    step(&mut plc, &mut io, false, false, 5);
    plc.command(Command::Substitute(SubstituteRequest {
        mode: SubstituteMode::Retransform,
        when: None,
        within_us: None,
        force: false,
    }))
    .unwrap();
    step(&mut plc, &mut io, false, false, 3);
    let c = plc.container(Slot::B).unwrap();
    assert_eq!(
        plc.dispatched()[0],
        c.outputs()[0],
        "dispatcher out of step with the primary's own outputs"
    );
}

/// S latch set by the primary on P=B, reset on C... here: S on B, R never; token leaves B. The
/// primary's output stays latched; the candidate installed from the primary's marking does not.
#[test]
fn a_latched_output_stays_latched_across_install_and_substitution() {
    let act = "[[action]]\nplace = \"B\"\nqualifier = \"S\"\ntarget = \"o\"\n";
    let old = program("old", "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 100\"", act);
    let new = program("new", "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 101\"", act);
    let mut plc = Plc::new(old.clone(), 0);
    plc.set_stopwatch(Box::new(ModelStopwatch { ns_per_unit: 0 }));
    let mut io = Io {
        inputs: img(false, false),
        out: vec![],
    };
    let mut now = 0;
    let mut step = |plc: &mut Plc, io: &mut Io, x: bool, y: bool, k: usize| {
        for _ in 0..k {
            now += 10_000;
            io.inputs = img(x, y);
            plc.cycle(now, io);
        }
    };
    step(&mut plc, &mut io, true, false, 1);
    step(&mut plc, &mut io, false, true, 1);
    step(&mut plc, &mut io, false, false, 3);
    let transform = StateTransform::generated(&old, &new, &BTreeMap::new()).unwrap();
    let projection = Projection::generated(old.net(), new.net());
    let meta = PackageMeta {
        name: "u".into(),
        version: "2".into(),
        author: String::new(),
        description: String::new(),
        created: String::new(),
        base_program_hash: old.hash_hex().to_string(),
    };
    let up = Plc::prepare(
        &old,
        plc.io_inputs(),
        plc.io_outputs(),
        ResolvedUpdate {
            program: new.clone(),
            transform,
            projection,
            meta,
        },
    )
    .unwrap();
    plc.command(Command::Load(Box::new(up))).unwrap();
    step(&mut plc, &mut io, false, false, 3);
    plc.command(Command::Substitute(SubstituteRequest {
        mode: SubstituteMode::Retransform,
        when: None,
        within_us: None,
        force: false,
    }))
    .unwrap();
    step(&mut plc, &mut io, false, false, 3);
    assert_eq!(
        plc.dispatched()[0],
        Value::Bool(true),
        "the latched output dropped at the switch"
    );
}

#[test]
fn after_substitution_a_primary_fault_drives_the_new_programs_safe_values() {
    let old = program("old", "T1 = \"x\"\nT2 = \"y\"\nT3 = \"n > 100\"", "");
    let src_new = "[[action]]\nplace = \"B\"\nqualifier = \"N\"\ntarget = \"o\"\n";
    let new = {
        let src = format!(
            "[program]\nname = \"new\"\nversion = \"1\"\n\
             [[input]]\nname = \"x\"\ntype = \"bool\"\n\
             [[input]]\nname = \"y\"\ntype = \"bool\"\n\
             [[input]]\nname = \"n\"\ntype = \"int\"\n\
             [[output]]\nname = \"o\"\ntype = \"bool\"\nsafe = true\n\
             [[variable]]\nname = \"flag\"\ntype = \"bool\"\n{src_new}\n[guards]\nT1 = \"x\"\nT2 = \"y\"\nT3 = \"100 / n > 1000\"\n");
        Arc::new(Program::from_sources(&src, "t.toml", net()).unwrap())
    };
    let mut plc = Plc::new(old.clone(), 0);
    plc.set_stopwatch(Box::new(ModelStopwatch { ns_per_unit: 0 }));
    let mut io = Io {
        inputs: vec![],
        out: vec![],
    };
    let mut now = 0;
    let mut step = |plc: &mut Plc, io: &mut Io, n: i64, k: usize| {
        for _ in 0..k {
            now += 10_000;
            io.inputs = vec![Value::Bool(false), Value::Bool(false), Value::Int(n)];
            plc.cycle(now, io);
        }
    };
    step(&mut plc, &mut io, 1, 2);
    let transform = StateTransform::generated(&old, &new, &BTreeMap::new()).unwrap();
    let projection = Projection::generated(old.net(), new.net());
    let meta = PackageMeta {
        name: "u".into(),
        version: "2".into(),
        author: String::new(),
        description: String::new(),
        created: String::new(),
        base_program_hash: old.hash_hex().to_string(),
    };
    let up = Plc::prepare(
        &old,
        plc.io_inputs(),
        plc.io_outputs(),
        ResolvedUpdate {
            program: new.clone(),
            transform,
            projection,
            meta,
        },
    )
    .unwrap();
    plc.command(Command::Load(Box::new(up))).unwrap();
    step(&mut plc, &mut io, 1, 2);
    plc.command(Command::Substitute(SubstituteRequest {
        mode: SubstituteMode::Retransform,
        when: None,
        within_us: None,
        force: false,
    }))
    .unwrap();
    step(&mut plc, &mut io, 1, 2);
    step(&mut plc, &mut io, 0, 2);
    assert_eq!(
        plc.dispatched()[0],
        Value::Bool(true),
        "new primary's safe value"
    );
}
