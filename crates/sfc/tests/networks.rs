//! LD and FBD networks of PLCopen XML, imported as Structured Text and run scan by scan: each
//! element means what IEC 61131-3 says (coils with negation, set/reset and edges, edge contacts,
//! wired OR, blocks with EN/ENO and negated or edge inputs, connectors, feedback), and what the
//! importer cannot write is refused with the element's place. Hostile networks (a chain as long
//! as the file allows, loops by the hundred) are refused or imported without recursion.

use cetratus_program::{Program, Value};
use cetratus_sfc::{import_pou, ImportedPou};

/// A PLCopen project of one PROGRAM `P` (see [`project_named`]).
fn project(locals: &str, body: &str) -> String {
    project_named("P", locals, body)
}

/// A PLCopen project of one PROGRAM `name` with BOOL inputs `a`, `b`, `c`, BOOL outputs `x`, `y`,
/// `z`, the locals `locals` (declarations as XML) and the body `body` (an `<LD>` or `<FBD>`).
fn project_named(name: &str, locals: &str, body: &str) -> String {
    let vars = |names: &[&str]| -> String {
        names
            .iter()
            .map(|n| format!(r#"<variable name="{n}"><type><BOOL/></type></variable>"#))
            .collect()
    };
    format!(
        r#"<?xml version="1.0" encoding="utf-8"?>
<project xmlns="http://www.plcopen.org/xml/tc6_0201">
<types><dataTypes/><pous>
<pou name="{name}" pouType="program">
<interface>
<inputVars>{}</inputVars>
<outputVars>{}</outputVars>
<localVars>{locals}</localVars>
</interface>
<body>
{body}
</body>
</pou>
</pous></types>
</project>
"#,
        vars(&["a", "b", "c"]),
        vars(&["x", "y", "z"])
    )
}

/// An element with one input connected to `from` (`ID` or `ID:FORMAL`).
fn input(from: &[&str]) -> String {
    let conns: String = from
        .iter()
        .map(|f| match f.split_once(':') {
            Some((id, formal)) => {
                format!(r#"<connection refLocalId="{id}" formalParameter="{formal}"/>"#)
            }
            None => format!(r#"<connection refLocalId="{f}"/>"#),
        })
        .collect();
    format!("<connectionPointIn>{conns}</connectionPointIn>")
}

fn position(y: u32) -> String {
    format!(r#"<position x="0" y="{y}"/>"#)
}

fn rail(id: u32) -> String {
    format!(
        r#"<leftPowerRail localId="{id}">{}<connectionPointOut/></leftPowerRail>"#,
        position(0)
    )
}

fn contact(id: u32, y: u32, var: &str, attrs: &str, from: &[&str]) -> String {
    format!(
        r#"<contact localId="{id}" {attrs}>{}{}<connectionPointOut/><variable>{var}</variable></contact>"#,
        position(y),
        input(from)
    )
}

fn coil(id: u32, y: u32, var: &str, attrs: &str, from: &[&str]) -> String {
    format!(
        r#"<coil localId="{id}" {attrs}>{}{}<connectionPointOut/><variable>{var}</variable></coil>"#,
        position(y),
        input(from)
    )
}

fn in_var(id: u32, y: u32, expr: &str) -> String {
    format!(
        r#"<inVariable localId="{id}">{}<connectionPointOut/><expression>{expr}</expression></inVariable>"#,
        position(y)
    )
}

fn out_var(id: u32, y: u32, expr: &str, from: &[&str]) -> String {
    format!(
        r#"<outVariable localId="{id}">{}{}<expression>{expr}</expression></outVariable>"#,
        position(y),
        input(from)
    )
}

/// A block: `inputs` are `(formal, attributes, from)`, `outputs` are `(formal, attributes)`.
fn block(
    id: u32,
    y: u32,
    head: &str,
    inputs: &[(&str, &str, &[&str])],
    outputs: &[(&str, &str)],
) -> String {
    let ins: String = inputs
        .iter()
        .map(|(f, a, from)| {
            format!(
                r#"<variable formalParameter="{f}" {a}>{}</variable>"#,
                input(from)
            )
        })
        .collect();
    let outs: String = outputs
        .iter()
        .map(|(f, a)| {
            format!(r#"<variable formalParameter="{f}" {a}><connectionPointOut/></variable>"#)
        })
        .collect();
    format!(
        r#"<block localId="{id}" {head}>{}<inputVariables>{ins}</inputVariables><inOutVariables/><outputVariables>{outs}</outputVariables></block>"#,
        position(y)
    )
}

/// Imports `xml` and runs it: each row of `inputs` (a, b, c) is one scan, 10 ms apart; the
/// outputs (x, y, z) after each.
fn scans(xml: &str, inputs: &[[bool; 3]]) -> Vec<[bool; 3]> {
    let imported = match import_pou(xml, "net.xml", Some("P")) {
        Ok(ImportedPou::Text(t)) => t,
        Ok(ImportedPou::Chart(_)) => panic!("imported as a chart"),
        Err(e) => panic!("{e}"),
    };
    let program: &Program = &imported.program;
    let st = program.st().expect("an ST program");
    let mut state = st.unit().new_state();
    let mut outputs = vec![Value::Bool(false); 3];
    let mut out = Vec::new();
    for (k, row) in inputs.iter().enumerate() {
        let ins: Vec<Value> = row.iter().map(|&b| Value::Bool(b)).collect();
        let mut work = cetratus_st::Work::unlimited();
        st.run(&ins, &mut outputs, &mut state, k as u64 * 10_000, &mut work)
            .expect("a scan");
        let bit = |v: &Value| matches!(v, Value::Bool(true));
        out.push([bit(&outputs[0]), bit(&outputs[1]), bit(&outputs[2])]);
    }
    out
}

fn refusal(xml: &str) -> String {
    match import_pou(xml, "net.xml", Some("P")) {
        Ok(_) => panic!("imported"),
        Err(e) => e.to_string(),
    }
}

const T: bool = true;
const F: bool = false;

/// A network to run: its locals (XML), its body, and the inputs of each scan.
struct Net {
    locals: &'static str,
    body: String,
    inputs: Vec<[bool; 3]>,
}

impl Net {
    fn run(&self) -> Vec<[bool; 3]> {
        scans(&project(self.locals, &self.body), &self.inputs)
    }
}

/// Rung 1: x := a AND NOT b, wired OR with c; y := NOT x. Rungs 2 and 3: z set by a, reset by b.
fn rungs() -> Net {
    let body = format!(
        "<LD>{}{}{}{}{}{}{}{}{}</LD>",
        rail(1),
        contact(2, 10, "a", "", &["1"]),
        contact(3, 10, "b", r#"negated="true""#, &["2"]),
        contact(4, 20, "c", "", &["1"]),
        coil(5, 10, "x", "", &["3", "4"]),
        coil(6, 10, "y", r#"negated="true""#, &["3", "4"]),
        contact(7, 30, "a", "", &["1"]),
        coil(8, 30, "z", r#"storage="set""#, &["7"]),
        coil(9, 40, "z", r#"storage="reset""#, &["10"]) + &contact(10, 40, "b", "", &["1"]),
    );
    let inputs = vec![
        [F, F, F],
        [T, F, F],
        [F, F, F],
        [T, T, F],
        [F, F, T],
        [F, T, F],
    ];
    Net {
        locals: "",
        body,
        inputs,
    }
}

/// x := a rising-edge contact; y := a falling-edge coil on b.
fn edges() -> Net {
    let body = format!(
        "<LD>{}{}{}{}{}</LD>",
        rail(1),
        contact(2, 10, "a", r#"edge="rising""#, &["1"]),
        coil(3, 10, "x", "", &["2"]),
        contact(4, 20, "b", "", &["1"]),
        coil(5, 20, "y", r#"edge="falling""#, &["4"]),
    );
    let inputs = vec![[F, T, F], [T, T, F], [T, F, F], [F, F, F], [T, F, F]];
    Net {
        locals: "",
        body,
        inputs,
    }
}

/// y := NOT (a AND b) through a negated output; a counter counts rising edges of c while a (EN)
/// holds, x := its Q at PV 2, and z reads x back through a connector and continuation.
fn blocks() -> Net {
    let body = format!(
        "<FBD>{}{}{}{}{}{}{}{}{}{}{}</FBD>",
        in_var(1, 0, "a"),
        in_var(2, 0, "b"),
        block(
            3,
            10,
            r#"typeName="AND""#,
            &[("IN1", "", &["1"]), ("IN2", "", &["2"])],
            &[("OUT", r#"negated="true""#)]
        ),
        out_var(4, 10, "y", &["3:OUT"]),
        in_var(5, 0, "c"),
        in_var(6, 0, "2"),
        block(
            7,
            20,
            r#"typeName="CTU" instanceName="ctr""#,
            &[
                ("EN", "", &["1"]),
                ("CU", r#"edge="rising""#, &["5"]),
                ("R", "", &["2"]),
                ("PV", "", &["6"])
            ],
            &[("ENO", ""), ("Q", ""), ("CV", "")]
        ),
        r#"<connector name="done" localId="8"><position x="0" y="30"/><connectionPointIn><connection refLocalId="7" formalParameter="Q"/></connectionPointIn></connector>"#,
        r#"<continuation name="done" localId="9"><position x="0" y="40"/><connectionPointOut/></continuation>"#,
        out_var(10, 40, "z", &["9"]),
        out_var(11, 30, "x", &["7:Q"]),
    );
    let inputs = vec![
        [T, F, F],
        [T, F, T],
        [T, F, F],
        [F, F, T],
        [T, F, F],
        [T, F, T],
        [T, T, F],
    ];
    Net {
        locals: r#"<variable name="ctr"><type><derived name="CTU"/></type></variable>"#,
        body,
        inputs,
    }
}

/// n := n + 1 drawn as a loop through an in-out variable; x := n > 2.
fn feedback() -> Net {
    let body = format!(
        "<FBD>{}{}{}{}{}{}</FBD>",
        in_var(1, 0, "1"),
        block(
            2,
            10,
            r#"typeName="ADD""#,
            &[("IN1", "", &["3"]), ("IN2", "", &["1"])],
            &[("OUT", "")]
        ),
        r#"<inOutVariable localId="3"><position x="0" y="20"/><connectionPointIn><connection refLocalId="2" formalParameter="OUT"/></connectionPointIn><connectionPointOut/><expression>n</expression></inOutVariable>"#,
        in_var(4, 30, "2"),
        block(
            5,
            30,
            r#"typeName="GT""#,
            &[("IN1", "", &["3"]), ("IN2", "", &["4"])],
            &[("OUT", "")]
        ),
        out_var(6, 30, "x", &["5:OUT"]),
    );
    Net {
        locals: r#"<variable name="n"><type><INT/></type></variable>"#,
        body,
        inputs: vec![[F, F, F]; 4],
    }
}

fn column(rows: &[[bool; 3]], k: usize) -> Vec<bool> {
    rows.iter().map(|r| r[k]).collect()
}

#[test]
fn contacts_in_series_and_parallel_drive_plain_negated_set_and_reset_coils() {
    assert_eq!(
        rungs().run(),
        [
            [F, T, F],
            [T, F, T],
            [F, T, T],
            [F, T, F],
            [T, F, F],
            [F, T, F]
        ]
    );
}

#[test]
fn edge_contacts_and_coils_see_one_scan_of_each_change() {
    let got = edges().run();
    assert_eq!(column(&got, 0), [F, T, F, F, T]);
    assert_eq!(column(&got, 1), [F, F, T, F, F]);
}

#[test]
fn blocks_with_en_eno_negated_and_edge_inputs_and_connectors_compute_in_data_flow_order() {
    let got = blocks().run();
    assert_eq!(column(&got, 1), [T, T, T, T, T, T, F]);
    // Counted edges: scan 1 (EN on) and scan 5; scan 3's edge falls while EN is off, and the
    // block's edge detector, outside the EN, still sees it go.
    assert_eq!(column(&got, 0), [F, F, F, F, F, T, F]);
    assert_eq!(column(&got, 2), column(&got, 0));
}

#[test]
fn a_feedback_loop_through_an_in_out_variable_reads_the_scan_before() {
    assert_eq!(column(&feedback().run(), 0), [F, F, T, T]);
}

#[test]
fn the_structured_text_written_for_each_network_runs_the_same_on_matiec() {
    use cetratus_testkit::matiec::{Case, IecType, Matiec};
    let nets = [rungs(), edges(), blocks(), feedback()];
    let mut source = String::new();
    let mut cases = Vec::new();
    for (k, net) in nets.iter().enumerate() {
        let name = format!("Net{k}");
        let xml = project_named(&name, net.locals, &net.body);
        let Ok(ImportedPou::Text(imported)) = import_pou(&xml, "net.xml", Some(&name)) else {
            panic!("{name} imports");
        };
        // The harness brings its own configuration.
        let text = &imported.source;
        source.push_str(&text[..text.find("CONFIGURATION").unwrap_or(text.len())]);
        let bools = |names: &[&str]| {
            names
                .iter()
                .map(|n| (n.to_string(), IecType::Bool))
                .collect()
        };
        let text_of = |b: bool| if b { "TRUE" } else { "FALSE" }.to_string();
        cases.push(Case {
            program: name,
            inputs: bools(&["a", "b", "c"]),
            outputs: bools(&["x", "y", "z"]),
            scans: net
                .inputs
                .iter()
                .map(|r| r.iter().map(|&b| text_of(b)).collect())
                .collect(),
        });
    }
    let matiec = Matiec::get().expect("MATIEC builds with the shared build.sh");
    let theirs = matiec
        .run(&source, &cases, std::time::Duration::from_millis(10))
        .unwrap_or_else(|e| panic!("{e}\n{source}"));
    for ((net, case), theirs) in nets.iter().zip(&cases).zip(theirs) {
        let ours: Vec<Vec<String>> = net
            .run()
            .iter()
            .map(|r| {
                r.iter()
                    .map(|&b| if b { "TRUE" } else { "FALSE" }.to_string())
                    .collect()
            })
            .collect();
        assert_eq!(ours, theirs, "{}", case.program);
    }
}

#[test]
fn what_structured_text_cannot_say_is_refused_with_the_element_and_its_place() {
    let jump = format!(
        r#"<LD>{}<jump localId="2" label="end">{}{}</jump></LD>"#,
        rail(1),
        position(10),
        input(&["1"])
    );
    let err = refusal(&project("", &jump));
    assert!(err.contains("net.xml:"), "{err}");
    assert!(err.contains("<jump>"), "{err}");
    assert!(err.contains("no jumps or labels"), "{err}");

    // A loop through functions only has no value from the scan before.
    let looped = format!(
        "<FBD>{}{}</FBD>",
        block(
            1,
            0,
            r#"typeName="AND""#,
            &[("IN1", "", &["2:OUT"]), ("IN2", "", &["2:OUT"])],
            &[("OUT", "")]
        ),
        block(
            2,
            10,
            r#"typeName="OR""#,
            &[("IN1", "", &["1:OUT"]), ("IN2", "", &["1:OUT"])],
            &[("OUT", "")]
        ),
    );
    let err = refusal(&project("", &looped));
    assert!(err.contains("a loop in the network"), "{err}");

    let dangling = format!("<LD>{}{}</LD>", rail(1), coil(2, 0, "x", "", &["9"]));
    let err = refusal(&project("", &dangling));
    assert!(err.contains("a connection to element 9"), "{err}");

    // An ST error in a generated statement names the element's place and quotes the statement.
    let unknown = format!("<LD>{}{}</LD>", rail(1), coil(2, 0, "nowhere", "", &["1"]));
    let err = refusal(&project("", &unknown));
    assert!(err.contains("net.xml:"), "{err}");
    assert!(err.contains("nowhere := TRUE;"), "{err}");
}

#[test]
fn a_chain_of_twenty_thousand_contacts_imports_without_recursion() {
    let n = 20_000;
    let mut body = rail(1);
    for i in 0..n {
        let from = if i == 0 {
            "1".to_string()
        } else {
            (i + 1).to_string()
        };
        let var = ["a", "b", "c"][i as usize % 3];
        body.push_str(&contact(i + 2, 10, var, "", &[&from]));
    }
    body.push_str(&coil(n + 2, 10, "x", "", &[&(n + 1).to_string()]));
    let got = scans(
        &project("", &format!("<LD>{body}</LD>")),
        &[[T, T, T], [T, F, T]],
    );
    assert_eq!(got, [[T, F, F], [F, F, F]]);
}

#[test]
fn hundreds_of_feedback_loops_import_and_a_hostile_number_is_refused_at_a_bound() {
    // Pairs of an AND, drawn first, and an R_TRIG: the AND reads the trigger's Q, the trigger
    // reads the AND. Each loop is entered at the function and cut at the instance.
    let pairs = |n: u32| {
        let mut locals = String::new();
        let mut body = in_var(1, 0, "a");
        for i in 0..n {
            let (f, t) = (2 * i + 2, 2 * i + 3);
            locals.push_str(&format!(
                r#"<variable name="t{i}"><type><derived name="R_TRIG"/></type></variable>"#
            ));
            body.push_str(&block(
                f,
                i * 20 + 10,
                r#"typeName="AND""#,
                &[("IN1", "", &[&format!("{t}:Q")]), ("IN2", "", &["1"])],
                &[("OUT", "")],
            ));
            body.push_str(&block(
                t,
                i * 20 + 20,
                &format!(r#"typeName="R_TRIG" instanceName="t{i}""#),
                &[("CLK", "", &[&format!("{f}:OUT")])],
                &[("Q", "")],
            ));
        }
        project(&locals, &format!("<FBD>{body}</FBD>"))
    };
    // Never set: the AND reads a trigger that has never fired.
    assert_eq!(scans(&pairs(300), &[[T, F, F]; 2]), [[F, F, F]; 2]);
    let err = refusal(&pairs(4_000));
    assert!(
        err.contains("feedback loops that pass through functions first"),
        "{err}"
    );
}
