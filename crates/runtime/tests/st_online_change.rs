//! Online change of a Structured Text program (docs/st.md, *Online change*): variables and
//! function block instances carry over by name and layout at the install, as CODESYS online
//! change does, so a running TON keeps its elapsed time; a new variable starts from its initial
//! value; a changed type or a RETAIN value that would be lost is refused, naming the variable,
//! unless the manifest's `[changes] variables` says what becomes of it.

use std::collections::BTreeMap;
use std::sync::Arc;

use cetratus_net::{NetBuilder, Place};
use cetratus_program::{
    Changes, PackageMeta, Program, Projection, ResolvedUpdate, StateTransform, Value,
};
use cetratus_runtime::{
    Command, Dispatcher, InstallTiming, ManualStopwatch, Plc, PrepareError, PreparedUpdate,
    Provider, Slot, SubstituteMode, SubstituteRequest, UpdateContext,
};

/// A program whose POU `Cell` runs every scan; `outputs` are its `[[output]]` lines.
fn program(version: &str, outputs: &[(&str, &str)], st: &str) -> Arc<Program> {
    let mut b = NetBuilder::new("cell".to_string());
    b.add_place(Place::new("Main", 1)).expect("a place");
    let net = b.build().expect("a net");
    let mut toml = format!("[program]\nname = \"cell\"\nversion = \"{version}\"\n");
    for (name, ty) in outputs {
        toml.push_str(&format!("[[output]]\nname = \"{name}\"\ntype = \"{ty}\"\n"));
    }
    toml.push_str("[[action]]\nplace = \"Main\"\nqualifier = \"N\"\nbody = \"Cell\"\n");
    toml.push_str(&format!("[st]\npou = \"Cell\"\nsource = '''\n{st}'''\n"));
    Arc::new(Program::from_sources(&toml, "cell.toml", net).unwrap_or_else(|e| panic!("{e}")))
}

const V1: &str = "PROGRAM Cell
VAR_OUTPUT count : DINT; q : BOOL; et : TIME; n2 : DINT; END_VAR
VAR RETAIN total : DINT; END_VAR
VAR t : TON; END_VAR
count := count + 1;
total := total + 1;
t(IN := TRUE, PT := T#1s);
q := t.Q;
et := t.ET;
n2 := count;
END_PROGRAM
";

/// Version 2: a new counter (shown on `n2`), and the timer's preset changed from 1 s to 2 s.
const V2: &str = "PROGRAM Cell
VAR_OUTPUT count : DINT; q : BOOL; et : TIME; n2 : DINT; END_VAR
VAR RETAIN total : DINT; END_VAR
VAR t : TON; extra : DINT; END_VAR
count := count + 1;
total := total + 1;
extra := extra + 1;
t(IN := TRUE, PT := T#2s);
q := t.Q;
et := t.ET;
n2 := extra;
END_PROGRAM
";

const OUTPUTS: [(&str, &str); 4] = [
    ("count", "int"),
    ("q", "bool"),
    ("et", "int"),
    ("n2", "int"),
];

fn v1() -> Arc<Program> {
    program("1", &OUTPUTS, V1)
}

struct Io;

impl Provider for Io {
    fn read_inputs(&mut self, _: u64, _: &mut [Value]) {}
}

impl Dispatcher for Io {
    fn write_outputs(&mut self, _: u64, _: &[Value]) {}
}

/// The PLC, its clock, and what an update is prepared against.
struct Rig {
    plc: Plc,
    now: u64,
}

impl Rig {
    fn new(program: &Arc<Program>) -> Self {
        let mut plc = Plc::new(program.clone(), 0, Box::new(ManualStopwatch::new()));
        plc.set_install_timing(InstallTiming::Model { ns_per_entry: 0 });
        Rig { plc, now: 0 }
    }

    /// `k` scans of 10 ms.
    fn run(&mut self, k: usize) {
        for _ in 0..k {
            self.now += 10_000;
            self.plc.cycle(self.now, &mut Io);
        }
    }

    fn prepare(
        &self,
        old: &Arc<Program>,
        new: &Arc<Program>,
        variables: &[(&str, &str)],
    ) -> Result<PreparedUpdate, PrepareError> {
        let changes = Changes {
            variables: variables
                .iter()
                .map(|(a, b)| (a.to_string(), b.to_string()))
                .collect(),
            ..Changes::default()
        };
        UpdateContext {
            primary: old.clone(),
            io_inputs: self.plc.io_inputs().to_vec(),
            io_outputs: self.plc.io_outputs().to_vec(),
            primary_marking: self.plc.primary_container().marking().to_vec(),
            cycle: self.plc.cycles(),
            admission: None,
        }
        .prepare(ResolvedUpdate {
            program: new.clone(),
            transform: StateTransform::generated(old, new, &BTreeMap::new()).expect("transform"),
            projection: Projection::generated(old.net(), new.net()).expect("projection"),
            meta: PackageMeta {
                name: "u".into(),
                version: "2".into(),
                author: String::new(),
                description: String::new(),
                created: String::new(),
                base_program_hash: old.hash_hex().to_string(),
                changes_throughput: false,
                changes,
            },
        })
    }

    fn load(&mut self, up: PreparedUpdate) {
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

    /// The outputs of the container in `slot`, by name.
    fn outputs(&self, slot: Slot) -> BTreeMap<String, Value> {
        let c = self.plc.container(slot).expect("a container");
        let p = c.program();
        p.outputs()
            .iter()
            .zip(c.outputs())
            .map(|(s, v)| (s.name.clone(), *v))
            .collect()
    }
}

#[test]
fn variables_and_a_running_ton_carry_over_and_a_new_variable_starts_from_its_initial_value() {
    let old = v1();
    let new = program("2", &OUTPUTS, V2);
    let mut r = Rig::new(&old);
    r.run(80);
    let before = r.outputs(Slot::A);
    assert_eq!(before["count"], Value::Int(80));
    assert_eq!(before["q"], Value::Bool(false), "790 ms of a 1 s TON");
    let up = r.prepare(&old, &new, &[]).expect("prepared");
    r.load(up);
    r.run(1);
    // The install carried the primary's state into the candidate before its first scan.
    let cand = r.outputs(Slot::B);
    assert_eq!(cand["count"], Value::Int(81), "{cand:?}");
    assert_eq!(cand["n2"], Value::Int(1), "{cand:?}");
    assert_eq!(
        cand["et"],
        Value::Int(800),
        "the TON kept its start: {cand:?}"
    );
    // Past the old preset: the old program's TON is done, the new one's (2 s) is not.
    r.run(30);
    assert_eq!(r.outputs(Slot::A)["q"], Value::Bool(true));
    let cand = r.outputs(Slot::B);
    assert_eq!(
        (cand["q"], cand["et"]),
        (Value::Bool(false), Value::Int(1100))
    );
    r.substitute();
    r.run(100);
    let after = r.outputs(Slot::B);
    assert_eq!(after["count"], Value::Int(211), "{after:?}");
    assert_eq!(after["n2"], Value::Int(131), "{after:?}");
    // A retransforming substitution carries the primary's state again at the switch, the TON
    // with it: it had run out under the old preset, and a TON that has run out stays out while
    // IN holds (MATIEC's and CODESYS's TON alike), whatever its new PT.
    assert_eq!(
        (after["q"], after["et"]),
        (Value::Bool(true), Value::Int(1000))
    );
}

#[test]
fn a_changed_type_is_refused_naming_the_variable_unless_the_manifest_lets_it_go() {
    let old = v1();
    let changed = V1
        .replace("count : DINT", "count : INT")
        .replace("n2 : DINT", "n2 : INT");
    let new = program("2", &OUTPUTS, &changed);
    let mut r = Rig::new(&old);
    r.run(10);
    let e = r
        .prepare(&old, &new, &[])
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("`count` was DINT and is INT"), "{e}");
    assert!(e.contains("[changes] variables"), "{e}");
    let up = r
        .prepare(&old, &new, &[("count", ""), ("n2", "")])
        .expect("let go");
    r.load(up);
    r.run(1);
    assert_eq!(r.outputs(Slot::B)["count"], Value::Int(1), "started again");
    assert_eq!(
        r.outputs(Slot::B)["et"],
        Value::Int(100),
        "the TON still carried"
    );
}

#[test]
fn a_retain_variable_that_would_be_lost_is_refused_unless_given_up_or_renamed() {
    let old = v1();
    let without = V1
        .replace("VAR RETAIN total : DINT; END_VAR\n", "")
        .replace("total := total + 1;\n", "");
    let new = program("2", &OUTPUTS, &without);
    let r = Rig::new(&old);
    let e = r
        .prepare(&old, &new, &[])
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("RETAIN variable `total`"), "{e}");
    r.prepare(&old, &new, &[("total", "")])
        .expect("given up on purpose");
    let renamed = program("2", &OUTPUTS, &V1.replace("total", "parts"));
    let e = r
        .prepare(&old, &renamed, &[])
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("`total`"), "{e}");
    r.prepare(&old, &renamed, &[("total", "parts")])
        .expect("renamed");
    let e = r
        .prepare(&old, &renamed, &[("nothing", "")])
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("`nothing`"), "{e}");
}

/// A chart in Structured Text (`[st.bodies]`, `[st.conditions]`, `[st.steps]`): Run's action
/// runs a TON with preset `pt`; Run is left when its Q comes, and entered again at once.
fn chart(version: &str, pt: &str, extra: &str) -> Arc<Program> {
    let net = cetratus_testkit::nets::sequence(
        &[("Run", 1), ("Idle", 0)],
        &[("T1", "Idle", "Run"), ("T2", "Run", "Idle")],
    );
    let toml = format!(
        r#"[program]
name = "press"
version = "{version}"
chart = "sfc"
[[output]]
name = "et"
type = "int"
[[output]]
name = "n"
type = "int"
[[action]]
place = "Run"
qualifier = "N"
body = "RunAct"
[st]
pou = "Press"
source = '''
TYPE CETRATUS_STEP : STRUCT X : BOOL; T : TIME; END_STRUCT; END_TYPE
FUNCTION_BLOCK Press
VAR_OUTPUT et : TIME; n : DINT; END_VAR
VAR t : TON; Run, Idle : CETRATUS_STEP; {extra} END_VAR
END_FUNCTION_BLOCK
'''
[st.bodies]
RunAct = "t(IN := Run.X, PT := {pt}); et := t.ET; n := n + 1;"
[st.conditions]
T2 = "t.Q"
[st.steps]
Run = "Run"
Idle = "Idle"
"#
    );
    Arc::new(Program::from_sources(&toml, "press.toml", net).unwrap_or_else(|e| panic!("{e}")))
}

#[test]
fn a_chart_in_st_carries_its_running_ton_and_its_counter_into_a_new_version() {
    let old = chart("1", "T#1s", "");
    let new = chart("2", "T#2s", "m : DINT;");
    let mut r = Rig::new(&old);
    r.run(50);
    assert_eq!(
        r.outputs(Slot::A)["et"],
        Value::Int(490),
        "{:?}",
        r.outputs(Slot::A)
    );
    let up = r.prepare(&old, &new, &[]).expect("prepared");
    r.load(up);
    r.run(1);
    // The candidate took the primary's TON and counter before its first scan.
    let cand = r.outputs(Slot::B);
    assert_eq!(
        (cand["et"], cand["n"]),
        (Value::Int(500), Value::Int(51)),
        "{cand:?}"
    );
    // Past the old preset: the old chart left Run and came back (its TON started again), the
    // new one (2 s) is still in its first stroke.
    r.run(60);
    assert!(matches!(r.outputs(Slot::A)["et"], Value::Int(ms) if ms < 200));
    assert_eq!(r.outputs(Slot::B)["et"], Value::Int(1100));
}
