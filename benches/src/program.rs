//! Program-level workloads: the Vernadat program scan, its load, a virtual hour with its twin, and
//! the real-time jitter of the scan cycle.

use std::hint::black_box;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

use cetratus_io::TwinDriver;
use cetratus_node::clock::MonotonicStopwatch;
use cetratus_node::periodic::run_periodic;
use cetratus_program::{Program, Value};
use cetratus_runtime::{Container, CycleFigures, LoopTiming, ScanCycle};
use cetratus_twin::TwinKind;
use serde::Serialize;

use crate::measure::median_ns;

pub use crate::embedded::examples_dir;

/// The Vernadat example program.
pub fn vernadat_program() -> Arc<Program> {
    let path = examples_dir().join("vernadat/vernadat.toml");
    Arc::new(Program::load(&path).expect("the Vernadat example loads"))
}

/// The input images of a virtual run of the Vernadat program on its twin, one per scan.
pub fn recorded_inputs(program: &Arc<Program>, scans: usize) -> Vec<Vec<Value>> {
    let twin = TwinKind::Vernadat.build(1);
    let mut io = TwinDriver::new(twin, program.inputs(), program.outputs()).expect("signals match");
    let mut cycle = ScanCycle::new(
        Container::new(program.clone(), 0),
        MonotonicStopwatch::boxed(),
    );
    let mut images = Vec::with_capacity(scans);
    let until = scans as u64 * cycle.period_us();
    cycle
        .run_virtual(0, until, &mut io, |c, _, _| {
            images.push(c.container().inputs().to_vec())
        })
        .expect("the Vernadat program runs without fault");
    images
}

/// Mean ns of one program scan (guards, enabling, firing, actions, output image), replaying the
/// inputs of a real run on a fresh container; scans in which nothing can fire take the quiet path.
pub fn program_scan_ns(quick: bool) -> f64 {
    program_scan_ns_with(quick, false)
}

/// [`program_scan_ns`] with every scan evaluated in full (no quiet path): the cost of a scan that
/// looks at every enabled transition's guard and recomputes every action.
pub fn program_scan_full_ns(quick: bool) -> f64 {
    program_scan_ns_with(quick, true)
}

fn program_scan_ns_with(quick: bool, always_full: bool) -> f64 {
    let program = vernadat_program();
    let images = recorded_inputs(&program, if quick { 30_000 } else { 360_000 });
    let period = program.scan_period().as_micros() as u64;
    let mut fresh = Container::new(program, 0);
    fresh.set_always_full(always_full);
    let mut runs = Vec::new();
    for _ in 0..if quick { 5 } else { 11 } {
        let mut c = fresh.clone();
        let t0 = Instant::now();
        for (k, img) in images.iter().enumerate() {
            black_box(c.scan(k as u64 * period, img).expect("replay runs"));
        }
        runs.push(t0.elapsed().as_nanos() as f64 / images.len() as f64);
    }
    runs.sort_by(|a, b| a.total_cmp(b));
    runs[runs.len() / 2]
}

/// Median µs to load the Vernadat program from its files (parse, resolve, build).
pub fn program_load_us(quick: bool) -> f64 {
    let path = examples_dir().join("vernadat/vernadat.toml");
    let batch = Duration::from_millis(if quick { 30 } else { 200 });
    median_ns(
        || {
            black_box(Program::load(&path).expect("loads"));
        },
        batch,
        7,
    ) / 1e3
}

/// What one virtual hour of the Vernadat cell gave.
#[derive(Debug, Serialize)]
pub struct HourFigures {
    /// Wall time of the run in ms.
    pub wall_ms: f64,
    /// Parts finished.
    pub parts_finished: u64,
    /// Faults seen.
    pub faults: usize,
}

/// Runs one virtual hour of the Vernadat cell with its program.
pub fn twin_hour() -> HourFigures {
    let program = vernadat_program();
    let twin = TwinKind::Vernadat.build(1);
    let mut io = TwinDriver::new(twin, program.inputs(), program.outputs()).expect("signals match");
    let mut cycle = ScanCycle::new(Container::new(program, 0), MonotonicStopwatch::boxed());
    let t0 = Instant::now();
    cycle
        .run_virtual(0, 3_600_000_000, &mut io, |_, _, _| {})
        .expect("the Vernadat program runs without fault");
    let wall_ms = t0.elapsed().as_secs_f64() * 1e3;
    use cetratus_twin::Plant;
    HourFigures {
        wall_ms,
        parts_finished: io.plant().counters().get("parts_finished").unwrap_or(0),
        faults: io.plant().faults().len(),
    }
}

/// Runs the Vernadat program on its twin in real time at `period_us` for `for_us` of wall time
/// and returns the cycle figures (latency, cycle time, overruns).
pub fn jitter(period_us: u64, for_us: u64, rt: bool) -> (CycleFigures, Option<String>) {
    let status = rt.then(|| cetratus_node::rt::request(80).to_string());
    let program = vernadat_program();
    let twin = TwinKind::Vernadat.build(1);
    let mut io = TwinDriver::new(twin, program.inputs(), program.outputs()).expect("signals match");
    let mut cycle = ScanCycle::new(Container::new(program, 0), MonotonicStopwatch::boxed());
    cycle.set_period_us(period_us);
    let stop = AtomicBool::new(false);
    // The program's timing (robot moves, machining) stays in program time, so a 1 ms period runs
    // the cell ten times as often per program second; speed 1 keeps program time = wall time.
    let mut timing = LoopTiming::default();
    run_periodic(period_us, for_us, 1.0, &stop, &mut timing, |now, _| {
        cycle.cycle(now, &mut io).is_ok()
    });
    cycle.set_timing(timing);
    (cycle.figures(), status)
}

/// A PLCopen TC6 project whose SFC is one loop of `steps` steps, each left by a transition on
/// the variable `go`: the shape of a long sequence as an engineer's tool exports it.
pub fn plcopen_chain(steps: usize) -> String {
    use std::fmt::Write;

    let mut sfc = String::from(r#"<step localId="1" name="S0" initialStep="true"/>"#);
    let (mut id, mut prev) = (2usize, 1usize);
    for k in 1..=steps {
        let condition = if k == steps { "NOT go" } else { "go" };
        let _ = write!(
            sfc,
            r#"<transition localId="{id}"><connectionPointIn><connection refLocalId="{prev}"/></connectionPointIn><condition><inline name=""><ST><p>{condition}</p></ST></inline></condition></transition>"#
        );
        let t = id;
        id += 1;
        if k == steps {
            let _ = write!(
                sfc,
                r#"<jumpStep localId="{id}" targetName="S0"><connectionPointIn><connection refLocalId="{t}"/></connectionPointIn></jumpStep>"#
            );
        } else {
            let _ = write!(
                sfc,
                r#"<step localId="{id}" name="S{k}"><connectionPointIn><connection refLocalId="{t}"/></connectionPointIn></step>"#
            );
        }
        prev = id;
        id += 1;
    }
    format!(
        r#"<?xml version="1.0"?><project xmlns="http://www.plcopen.org/xml/tc6_0201"><types><pous><pou name="P" pouType="program"><interface><localVars><variable name="go"><type><BOOL/></type></variable></localVars></interface><body><SFC>{sfc}</SFC></body></pou></pous></types></project>"#
    )
}

/// A PLCopen TC6 project whose SFC is a ring of `n` steps, each with an action whose body is an LD network, and each
/// transition's condition a network drawn in the chart: an R_TRIG whose instance the interface
/// does not declare (so the import notes each, at its place in the file).
pub fn plcopen_networks(n: usize) -> String {
    let (mut chart, mut actions) = (String::new(), String::new());
    let mut before = String::new();
    for i in 0..n {
        let id = |k: usize| 10 + 5 * i + k;
        let initial = if i == 0 { " initialStep=\"true\"" } else { "" };
        let input = |from: &str| format!("<connectionPointIn>{from}</connectionPointIn>");
        let from = |id: usize| format!("<connection refLocalId=\"{id}\"/>");
        chart += &format!(
            "<step localId=\"{}\" name=\"S{i}\"{initial}>{before}<connectionPointOut/></step>\
             <actionBlock localId=\"{}\">{}<action qualifier=\"N\"><reference name=\"A{i}\"/></action></actionBlock>\
             <inVariable localId=\"{}\"><connectionPointOut/><expression>go</expression></inVariable>\
             <block localId=\"{}\" typeName=\"R_TRIG\" instanceName=\"E{i}\"><inputVariables><variable formalParameter=\"CLK\">{}</variable></inputVariables><inOutVariables/><outputVariables><variable formalParameter=\"Q\"><connectionPointOut/></variable></outputVariables></block>\
             <transition localId=\"{}\">{}<condition>{}</condition></transition>",
            id(0),
            id(1),
            input(&from(id(0))),
            id(2),
            id(3),
            input(&from(id(2))),
            id(4),
            input(&from(id(0))),
            input(&format!("<connection refLocalId=\"{}\" formalParameter=\"Q\"/>", id(3))),
        );
        before = input(&from(id(4)));
        actions += &format!(
            "<action name=\"A{i}\"><body><LD><leftPowerRail localId=\"1\"><connectionPointOut formalParameter=\"\"/></leftPowerRail>\
             <contact localId=\"2\"><connectionPointIn><connection refLocalId=\"1\"/></connectionPointIn><connectionPointOut/><variable>go</variable></contact>\
             <coil localId=\"3\"><connectionPointIn><connection refLocalId=\"2\"/></connectionPointIn><connectionPointOut/><variable>lamp</variable></coil></LD></body></action>"
        );
    }
    chart += &format!("<jumpStep localId=\"1\" targetName=\"S0\">{before}</jumpStep>");
    let var = |name: &str| format!("<variable name=\"{name}\"><type><BOOL/></type></variable>");
    format!(
        "<?xml version=\"1.0\"?>\n<project xmlns=\"http://www.plcopen.org/xml/tc6_0201\"><types><pous>\n\
         <pou name=\"Ring\" pouType=\"program\"><interface><inputVars>{}</inputVars><outputVars>{}</outputVars></interface>\n\
         <actions>{actions}</actions>\n<body><SFC>{chart}</SFC></body></pou></pous></types></project>\n",
        var("go"),
        var("lamp"),
    )
}

/// Milliseconds to import a PLCopen project `text` (parse, read the chart, write the net and
/// the program), the median of `runs`.
pub fn plcopen_import_ms(text: &str, runs: usize) -> f64 {
    let mut took: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let t0 = Instant::now();
            black_box(
                cetratus_sfc::import_str(text, "chain.xml", None, "chain.pnml")
                    .expect("the chart imports"),
            );
            t0.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    took.sort_by(|a, b| a.total_cmp(b));
    took[took.len() / 2]
}

/// Nanoseconds per instruction of compiled guard and body code, the unit of a candidate's work
/// budget (`cetratus_program::Work`): the Vernadat program with T10's guard replaced by one of
/// about a thousand instructions that reads an input and a variable, compares and combines, all
/// of which run; then a body of about 7,500 instructions. The median of 7 timed batches each.
pub fn ns_per_instruction(quick: bool) -> (f64, f64) {
    use cetratus_program::EvalCtx;
    let dir = examples_dir().join("vernadat");
    let toml = std::fs::read_to_string(dir.join("vernadat.toml")).expect("vernadat.toml");
    let net = cetratus_net::pnml::read_file(&dir.join("vernadat.pnml")).expect("the net");
    let guard = (0..125)
        .map(|k| format!("(PE || w >= {k})"))
        .collect::<Vec<_>>()
        .join(" && ");
    let statement = format!("w := w{}\n", " * 1".repeat(100));
    let toml = toml.replace("T10 = \"PE\"", &format!("T10 = \"{guard}\""))
        + "\n[[variable]]\nname = \"w\"\ntype = \"int\"\n\
           \n[[action]]\nplace = \"H\"\nqualifier = \"N\"\nbody = \"Heavy\"\n"
        + &format!("\n[bodies]\nHeavy = '''\n{}'''\n", statement.repeat(37));
    let p = Program::from_sources(&toml, "heavy.toml", net).expect("the heavy program loads");
    let t10 = p.net().transition_by_id("T10").expect("T10");
    // PE false and w past every bound: every instruction of the guard runs, none is jumped.
    let inputs = vec![Value::Bool(false); p.inputs().len()];
    let guard_vars = [Value::Int(1000)];
    let marking = p.net().initial_marking().0;
    let since = vec![Some(0); marking.len()];
    let ctx = EvalCtx {
        inputs: &inputs,
        prev_inputs: &inputs,
        vars: &guard_vars,
        marking: &marking,
        place_since_us: &since,
        place_dwell_us: &[],
        now_us: 0,
    };
    let batch = Duration::from_millis(if quick { 20 } else { 100 });
    let guard_units = p.guard_cost(t10) as f64;
    let guard_ns = median_ns(
        || {
            black_box(p.eval_guard(t10, &ctx).is_ok());
        },
        batch,
        7,
    );
    let body = &p.bodies()[0];
    let mut vars = vec![Value::Int(1)];
    let mut outputs = vec![Value::Bool(false); p.outputs().len()];
    let body_ns = median_ns(
        || {
            black_box(body.run(&ctx, &mut vars, &mut outputs).is_ok());
        },
        batch,
        7,
    );
    (guard_ns / guard_units, body_ns / body.cost() as f64)
}
