//! `cetratus bench st`: the scan time of Structured Text programs run by Cetratus (imported as
//! `cetratus import st` does, scanned by a container as a PLC scans them) against the same
//! programs compiled by MATIEC to C and by `cc -O2`, in the same run; and the time to import
//! and compile a 5 000-line ST file.
//!
//! The four programs stand for what plants run (docs/performance.md, *Structured Text*):
//!
//! * `pid`: a PID loop in REAL arithmetic with anti-windup and a first-order plant;
//! * `rungs`: 200 rungs of boolean logic (seal-ins, interlocks), one in ten a TON;
//! * `machine`: a CASE state machine of a machining cycle with timers, a counter and an edge;
//! * `filter`: a 32-sample ring buffer of REAL, its mean, maximum and a count, in a FOR loop.
//!
//! Each runs the same number of scans on both sides, its inputs held, the scan's time advancing
//! by the tick; both sides must end with the same outputs, or the figure is refused: a scan
//! that computes something else is not the same program.

use std::fmt::Write as _;
use std::hint::black_box;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use cetratus_matiec::{Case, IecType, Matiec};
use cetratus_program::{Program, Value};
use cetratus_runtime::Container;
use serde::Serialize;

use crate::harness::BenchError;

/// The tick both sides advance the scan's time by.
const TICK: Duration = Duration::from_millis(10);

/// One benchmark program: its source, its inputs (held) and the outputs compared at the end.
pub struct StBench {
    /// Its name in the figures.
    pub name: &'static str,
    /// What it is, in a line.
    pub about: &'static str,
    /// The ST text, with one PROGRAM.
    pub source: String,
    /// Inputs and the value each holds, in MATIEC's canonical text.
    pub inputs: Vec<(&'static str, IecType, &'static str)>,
    /// The outputs compared after the last scan.
    pub outputs: Vec<(&'static str, IecType)>,
}

/// The figures of one program.
#[derive(Debug, Serialize)]
pub struct StFigure {
    /// The program.
    pub name: String,
    /// Scans per run.
    pub scans: u64,
    /// Median ns of one Cetratus scan (the container: the ST pass and the net around it).
    pub cetratus_ns: f64,
    /// Median ns of one pass of the compiled ST alone, as a scan runs it (in machine code where
    /// this machine has a code generator; no net).
    pub pass_ns: f64,
    /// Median ns of the same pass on the register machine's interpreter.
    pub interpreted_ns: f64,
    /// Whether the pass ran in machine code.
    pub machine_code: bool,
    /// Median ns of one scan of MATIEC's C (`cc -O2`), when MATIEC was given.
    pub matiec_ns: Option<f64>,
    /// `cetratus_ns / matiec_ns`.
    pub ratio: Option<f64>,
}

/// What `cetratus bench st` measured.
#[derive(Debug, Serialize)]
pub struct StFigures {
    /// Per program.
    pub programs: Vec<StFigure>,
    /// Lines of the generated file imported and compiled.
    pub import_lines: usize,
    /// Median ms to import and compile it (parse, type-check, compile, build the program).
    pub import_ms: f64,
    /// Instructions of its compiled body.
    pub translate_ops: usize,
    /// Median ms to translate that body into machine code (what a load does once, off the
    /// scan thread); `None` where there is no machine code (a build without the `jit`
    /// feature, a machine Cranelift has no code generator for).
    pub translate_ms: Option<f64>,
    /// Why MATIEC's side was not measured, when it was not.
    pub matiec_skipped: Option<String>,
}

/// The four programs.
pub fn programs() -> Vec<StBench> {
    use IecType::*;
    vec![
        StBench {
            name: "pid",
            about: "PID loop, REAL math, anti-windup, first-order plant",
            source: PID.to_string(),
            inputs: vec![("sp", Real, "r42c80000")],
            outputs: vec![("pv", Real), ("u", Real)],
        },
        StBench {
            name: "rungs",
            about: "200 rungs of boolean logic, 20 TON",
            source: rungs(200),
            inputs: (0..8)
                .map(|i| {
                    (
                        ["a0", "a1", "a2", "a3", "a4", "a5", "a6", "a7"][i],
                        Bool,
                        "TRUE",
                    )
                })
                .collect(),
            outputs: (0..8)
                .map(|i| (["q0", "q1", "q2", "q3", "q4", "q5", "q6", "q7"][i], Bool))
                .collect(),
        },
        StBench {
            name: "machine",
            about: "CASE state machine, TON, CTU, R_TRIG",
            source: MACHINE.to_string(),
            inputs: vec![("start", Bool, "TRUE"), ("part", Bool, "TRUE")],
            outputs: vec![("state", Int), ("motor", Bool), ("done", Dint)],
        },
        StBench {
            name: "filter",
            about: "32-sample REAL ring buffer: mean, maximum, count, FOR loop",
            source: FILTER.to_string(),
            inputs: vec![("x", Real, "r3fc00000")],
            outputs: vec![("avg", Real), ("hi", Real), ("n_over", Int)],
        },
    ]
}

const PID: &str = "
PROGRAM PidLoop
  VAR_INPUT sp : REAL; END_VAR
  VAR_OUTPUT pv : REAL; u : REAL; END_VAR
  VAR
    kp : REAL := 2.0; ki : REAL := 0.5; kd : REAL := 0.1; tsample : REAL := 0.01;
    e : REAL; e_prev : REAL; integ : REAL; deriv : REAL;
  END_VAR
  e := sp - pv;
  integ := integ + e * tsample;
  IF integ > REAL#100.0 THEN
    integ := 100.0;
  ELSIF integ < REAL#-100.0 THEN
    integ := -100.0;
  END_IF;
  deriv := (e - e_prev) / tsample;
  u := LIMIT(REAL#-10.0, kp * e + ki * integ + kd * deriv, REAL#10.0);
  e_prev := e;
  pv := pv + (u - pv) * REAL#0.05;
END_PROGRAM
";

const MACHINE: &str = "
PROGRAM Machine
  VAR_INPUT start : BOOL; part : BOOL; END_VAR
  VAR_OUTPUT state : INT; motor : BOOL; clamp : BOOL; done : DINT; END_VAR
  VAR t : TON; c : CTU; edge : R_TRIG; feed : BOOL; END_VAR
  edge(CLK := feed);
  CASE state OF
    0:
      motor := FALSE;
      clamp := FALSE;
      IF start AND part THEN state := 1; END_IF;
    1:
      clamp := TRUE;
      t(IN := TRUE, PT := T#30ms);
      IF t.Q THEN t(IN := FALSE); state := 2; END_IF;
    2:
      motor := TRUE;
      t(IN := TRUE, PT := T#100ms);
      IF t.Q THEN t(IN := FALSE); state := 3; END_IF;
    3..4:
      motor := FALSE;
      feed := NOT feed;
      state := state + 1;
    5:
      clamp := FALSE;
      c(CU := edge.Q, R := c.Q, PV := 100);
      done := done + 1;
      state := 0;
  ELSE
    state := 0;
  END_CASE;
END_PROGRAM
";

const FILTER: &str = "
PROGRAM Filter
  VAR_INPUT x : REAL; END_VAR
  VAR_OUTPUT avg : REAL; hi : REAL; n_over : INT; END_VAR
  VAR buf : ARRAY[0..31] OF REAL; k : INT; i : INT; s : REAL; END_VAR
  buf[k] := x + INT_TO_REAL(k) * REAL#0.25;
  k := (k + 1) MOD 32;
  s := 0.0;
  hi := buf[0];
  n_over := 0;
  FOR i := 0 TO 31 DO
    s := s + buf[i];
    IF buf[i] > hi THEN hi := buf[i]; END_IF;
    IF buf[i] > x THEN n_over := n_over + 1; END_IF;
  END_FOR;
  avg := s / REAL#32.0;
END_PROGRAM
";

/// `n` rungs of boolean logic over eight inputs: seal-in circuits with interlocks, and every
/// tenth rung a TON on the rung before it; eight outputs read rungs spread over the ladder.
pub fn rungs(n: usize) -> String {
    let timers = n.div_ceil(10);
    let mut s =
        String::from("PROGRAM Rungs\n  VAR_INPUT a0, a1, a2, a3, a4, a5, a6, a7 : BOOL; END_VAR\n");
    s.push_str("  VAR_OUTPUT q0, q1, q2, q3, q4, q5, q6, q7 : BOOL; END_VAR\n  VAR\n");
    for k in 0..n {
        let _ = writeln!(s, "    m{k} : BOOL;");
    }
    for j in 0..timers {
        let _ = writeln!(s, "    t{j} : TON;");
    }
    s.push_str("  END_VAR\n");
    for k in 0..n {
        let (a, b) = (k % 8, (k + 3) % 8);
        let prev = if k == 0 {
            "a7".to_string()
        } else {
            format!("m{}", k - 1)
        };
        if k % 10 == 9 {
            let j = k / 10;
            let _ = writeln!(
                s,
                "  t{j}(IN := {prev} AND NOT m{k}, PT := T#{}ms);\n  m{k} := t{j}.Q;",
                20 + 10 * (j % 5)
            );
        } else {
            let _ = writeln!(
                s,
                "  m{k} := (a{a} AND {prev} OR m{k}) AND NOT (a{b} AND m{k} AND NOT {prev});"
            );
        }
    }
    for q in 0..8 {
        let _ = writeln!(s, "  q{q} := m{};", (q * n / 8 + n / 8 - 1).min(n - 1));
    }
    s.push_str("END_PROGRAM\n");
    s
}

/// Runs of each side; the figure is the median.
pub(crate) const RUNS: usize = 5;

/// Measures every program on Cetratus, and on MATIEC when `matiec` is its install dir (a
/// missing or broken install is reported in [`StFigures::matiec_skipped`], not an error).
pub fn figures(matiec: Option<&Path>, quick: bool) -> Result<StFigures, BenchError> {
    let scans: u64 = if quick { 2_000 } else { 20_000 };
    let compiler = match matiec.map(|dir| Matiec::at(dir.to_path_buf())) {
        None => Err("no MATIEC install dir was given (`--matiec DIR`)".to_string()),
        Some(Err(e)) => Err(e.to_string()),
        Some(Ok(m)) => Ok(m),
    };
    let mut out = Vec::new();
    for p in programs() {
        let (program, inputs) = imported(&p)?;
        let (cetratus_ns, ours) = cetratus_side(&p, &program, &inputs, scans)?;
        let pass = pass_ns(&program, &inputs, scans)?;
        let matiec_ns = match &compiler {
            Ok(m) => Some(matiec_side(m, &p, scans, &ours)?),
            Err(_) => None,
        };
        out.push(StFigure {
            name: p.name.to_string(),
            scans,
            cetratus_ns,
            pass_ns: pass.native,
            interpreted_ns: pass.interpreted,
            machine_code: pass.machine_code,
            matiec_ns,
            ratio: matiec_ns.map(|m| cetratus_ns / m),
        });
    }
    let (import_lines, import_ms) = import_figure(quick)?;
    let (translate_ops, translate_ms) = translation_figure(quick)?;
    Ok(StFigures {
        programs: out,
        import_lines,
        import_ms,
        translate_ops,
        translate_ms,
        matiec_skipped: compiler.err(),
    })
}

/// `p` imported as `cetratus import st` does, and the input image its inputs hold.
fn imported(p: &StBench) -> Result<(Arc<Program>, Vec<Value>), BenchError> {
    let imported = cetratus_sfc::structured::import_st(&p.source, p.name, None)?;
    let program = Arc::new(imported.program);
    let inputs = program
        .inputs()
        .iter()
        .map(|s| {
            let (_, ty, text) = p
                .inputs
                .iter()
                .find(|(n, _, _)| n.eq_ignore_ascii_case(&s.name))
                .ok_or_else(|| format!("{}: input `{}` has no value", p.name, s.name))?;
            value_of(*ty, text)
        })
        .collect::<Result<Vec<Value>, BenchError>>()?;
    Ok((program, inputs))
}

/// Median ns of a Cetratus scan of `program`, its inputs held at `inputs`, and the outputs after
/// the last scan in MATIEC's canonical text.
fn cetratus_side(
    p: &StBench,
    program: &Arc<Program>,
    inputs: &[Value],
    scans: u64,
) -> Result<(f64, Vec<String>), BenchError> {
    let fresh = Container::new(program.clone(), 0);
    let (ns, last) = time_scans(&fresh, inputs, TICK.as_micros() as u64, scans);
    let outputs = p
        .outputs
        .iter()
        .map(|(name, ty)| {
            let i = program
                .outputs()
                .iter()
                .position(|s| s.name.eq_ignore_ascii_case(name))
                .ok_or_else(|| format!("{}: no output `{name}`", p.name))?;
            Ok(canonical(*ty, last.outputs()[i]))
        })
        .collect::<Result<Vec<String>, BenchError>>()?;
    Ok((ns, outputs))
}

/// Median ns of one scan of a copy of `fresh` over `scans` scans (of [`RUNS`] runs), `inputs`
/// held and the scan's time advancing by `period_us`; and the container after the last run.
pub(crate) fn time_scans(
    fresh: &Container,
    inputs: &[Value],
    period_us: u64,
    scans: u64,
) -> (f64, Container) {
    let mut last = fresh.clone();
    let ns = median((0..RUNS).map(|_| {
        let mut c = fresh.clone();
        let t0 = Instant::now();
        for k in 0..scans {
            black_box(c.scan(k * period_us, inputs).map(|o| o.fired).ok());
        }
        let took = t0.elapsed();
        last = c;
        took
    }));
    (ns / scans as f64, last)
}

/// Median ns of one pass of the compiled ST alone, as a scan runs it and interpreted.
struct Pass {
    native: f64,
    interpreted: f64,
    machine_code: bool,
}

/// [`Pass`] of `program`, as its scan runs it: the same input image, copied in, the POU run,
/// its outputs copied out.
fn pass_ns(program: &Program, inputs: &[Value], scans: u64) -> Result<Pass, BenchError> {
    let st = program
        .st()
        .ok_or_else(|| format!("{} has no Structured Text", program.name()))?;
    let unit = st.unit();
    unit.prepare_machine_code();
    let time = |interpret: bool| {
        let ns = median((0..RUNS).map(|_| {
            let mut state = unit.new_state();
            let mut outputs: Vec<Value> = program.outputs().iter().map(|s| s.initial).collect();
            let t0 = Instant::now();
            for k in 0..scans {
                let mut work = cetratus_st::Work::unlimited();
                let now = (k * TICK.as_nanos() as u64) as i64;
                let r = st.run_with(
                    inputs,
                    &mut outputs,
                    &mut state,
                    |unit, state| match interpret {
                        true => unit.run_interpreted(state, now, &mut work),
                        false => unit.run(state, now, &mut work),
                    },
                );
                black_box(r.is_ok());
            }
            t0.elapsed()
        }));
        ns / scans as f64
    };
    Ok(Pass {
        native: time(false),
        interpreted: time(true),
        machine_code: unit.in_machine_code(),
    })
}

/// Median ns of one scan of MATIEC's C, after checking that its outputs after the last scan
/// are `ours`.
fn matiec_side(m: &Matiec, p: &StBench, scans: u64, ours: &[String]) -> Result<f64, BenchError> {
    let case = Case {
        program: program_name(&p.source),
        inputs: p
            .inputs
            .iter()
            .map(|(n, t, _)| (n.to_string(), *t))
            .collect(),
        outputs: p.outputs.iter().map(|(n, t)| (n.to_string(), *t)).collect(),
        scans: vec![p.inputs.iter().map(|(_, _, v)| v.to_string()).collect()],
    };
    let cases = [case];
    let batch = m.compile(&p.source, &cases, TICK)?;
    time_batch(&batch, &cases, scans, ours, p.name)
}

/// Median ns of one scan of a compiled batch of one case over `scans` scans (of [`RUNS`] runs),
/// after checking that its outputs after the last scan are `ours`.
pub(crate) fn time_batch(
    batch: &cetratus_matiec::Batch,
    cases: &[Case],
    scans: u64,
    ours: &[String],
    name: &str,
) -> Result<f64, BenchError> {
    let mut last = Vec::new();
    let mut took = Vec::with_capacity(RUNS);
    for _ in 0..RUNS {
        let (t, outputs) = batch.time(cases, scans)?;
        took.push(t);
        last = outputs;
    }
    if last.first().map(Vec::as_slice) != Some(ours) {
        return Err(format!(
            "{name}: after {scans} scans MATIEC's outputs are {last:?} and Cetratus's {ours:?}; \
             the two do not run the same program, so their times do not compare"
        )
        .into());
    }
    Ok(median(took.into_iter()) / scans as f64)
}

/// Lines of ST and median ms to import and compile them: [`rungs`] grown to 5 000 lines.
fn import_figure(quick: bool) -> Result<(usize, f64), BenchError> {
    let text = rungs(2_180);
    let lines = text.lines().count();
    cetratus_sfc::structured::import_st(&text, "rungs", None)?;
    let batch = Duration::from_millis(if quick { 100 } else { 500 });
    let ns = crate::measure::median_ns(
        || {
            black_box(cetratus_sfc::structured::import_st(&text, "rungs", None).is_ok());
        },
        batch,
        5,
    );
    Ok((lines, ns / 1e6))
}

/// Instructions of the file of [`import_figure`] and the median ms to translate them into
/// machine code, each run on a program imported afresh (a program translates once).
fn translation_figure(quick: bool) -> Result<(usize, Option<f64>), BenchError> {
    let text = rungs(2_180);
    let (mut ops, mut took) = (0, Vec::new());
    for _ in 0..if quick { 3 } else { 5 } {
        let imported = cetratus_sfc::structured::import_st(&text, "rungs", None)?;
        let unit = (imported.program.st())
            .ok_or("the generated rungs have no Structured Text")?
            .unit();
        ops = unit.code.ops.len();
        let t0 = Instant::now();
        if !unit.prepare_machine_code() {
            return Ok((ops, None));
        }
        took.push(t0.elapsed());
    }
    Ok((ops, Some(median(took.into_iter()) / 1e6)))
}

/// The median of `runs`, in ns.
pub(crate) fn median(runs: impl Iterator<Item = Duration>) -> f64 {
    let mut ns: Vec<f64> = runs.map(|d| d.as_nanos() as f64).collect();
    ns.sort_by(|a, b| a.total_cmp(b));
    ns.get(ns.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The name of the source's PROGRAM.
fn program_name(source: &str) -> String {
    source
        .split_whitespace()
        .skip_while(|w| *w != "PROGRAM")
        .nth(1)
        .unwrap_or_default()
        .to_string()
}

/// A held input, from MATIEC's canonical text into a signal's value.
fn value_of(ty: IecType, text: &str) -> Result<Value, BenchError> {
    let bad = || format!("`{text}` is not a {} value the bench knows", ty.name());
    Ok(match ty {
        IecType::Bool => Value::Bool(text == "TRUE"),
        IecType::Real => {
            let bits = text.strip_prefix('r').ok_or_else(bad)?;
            Value::Real(f32::from_bits(u32::from_str_radix(bits, 16)?) as f64)
        }
        _ => Value::Int(text.parse()?),
    })
}

/// A signal's value in MATIEC's canonical text for `ty`.
pub(crate) fn canonical(ty: IecType, v: Value) -> String {
    match (ty, v) {
        (_, Value::Bool(b)) => if b { "TRUE" } else { "FALSE" }.to_string(),
        (IecType::Real, Value::Real(r)) => format!("r{:08x}", (r as f32).to_bits()),
        (_, Value::Real(r)) => format!("l{:016x}", r.to_bits()),
        (_, Value::Int(i)) => i.to_string(),
    }
}
