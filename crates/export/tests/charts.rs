//! A program imported from an SFC chart is exported as that chart, and `import plcopen` of the
//! export gives the same program with the same hash: on charts drawn at random from a seed,
//! with every construct the importer maps (selection and simultaneous branches, jumps, the
//! left-to-right priorities, conditions on `Step.X` and `Step.T`, every qualifier, inline and
//! named action bodies with IF), and on what a chart cannot carry, which falls back to the
//! Structured Text POUs with the reason.

use cetratus_export::to_plcopen;

/// A small deterministic generator (xorshift64*), so that a failure names its seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn pick<'a>(&mut self, items: &[&'a str]) -> &'a str {
        items[self.below(items.len())]
    }
}

/// A BOOL condition over the POU's inputs, variables and the steps named `steps`.
fn condition(r: &mut Rng, steps: &[String], depth: u32) -> String {
    let step = steps[r.below(steps.len())].clone();
    match (depth, r.below(9)) {
        (0, _) | (_, 0) => r.pick(&["I0", "I1", "NOT I2", "TRUE"]).to_string(),
        (_, 1) => format!("{step}.X"),
        (_, 2) => format!("{step}.T >= T#{}ms", 10 * r.below(50)),
        (_, 3) => format!("N {} {}", r.pick(&["<", ">=", "=", "<>"]), r.below(9)),
        (_, 4) => format!("N * 2 - {} > -{}", r.below(5), r.below(3)),
        (_, 5) => format!("R / 2.5 < {}.5", r.below(4)),
        (d, 6) => format!("NOT ({})", condition(r, steps, d - 1)),
        (d, k) => format!(
            "({}) {} {}",
            condition(r, steps, d - 1),
            ["AND", "OR", "XOR"][k % 3],
            condition(r, steps, d - 1)
        ),
    }
}

/// An action body: assignments and an IF with ELSIF and ELSE.
fn body(r: &mut Rng, steps: &[String]) -> String {
    format!(
        "N := N + {};\nIF {} THEN\n  R := R * 0.5;\nELSIF {} THEN\n  B := NOT B;\nELSE\n  N := -{};\nEND_IF;\n",
        r.below(3),
        condition(r, steps, 1),
        condition(r, steps, 1),
        r.below(4)
    )
}

/// A connection point to each element.
fn pins(from: &[usize]) -> String {
    if from.is_empty() {
        return String::new();
    }
    let c: String = (from.iter())
        .map(|f| format!("<connection refLocalId=\"{f}\"/>"))
        .collect();
    format!("<connectionPointIn>{c}</connectionPointIn>")
}

/// The elements of a chart of 2 to 8 steps `{prefix}0…` in one network: a tree of
/// transitions that reaches every step from the initial one, and as many more with one or two
/// sources and one or two targets; conditions and bodies read `names` (its own steps and the
/// POU's). LocalIds start at `base`; `sub` is associated from a step when given.
fn network(r: &mut Rng, prefix: &str, names: &mut Vec<String>, base: usize, sub: bool) -> String {
    let steps = 2 + r.below(7);
    names.extend((0..steps).map(|s| format!("{prefix}{s}")));
    let mut trans: Vec<(Vec<usize>, Vec<usize>)> =
        (1..steps).map(|s| (vec![r.below(s)], vec![s])).collect();
    for _ in 0..steps {
        let mut from = vec![r.below(steps)];
        let mut to = vec![r.below(steps)];
        if r.below(3) == 0 {
            from.push(r.below(steps));
        }
        if r.below(3) == 0 {
            to.push(r.below(steps));
        }
        from.dedup();
        to.dedup();
        trans.insert(r.below(trans.len() + 1), (from, to));
    }
    // Steps are localIds base+1…, transitions base+100…, blocks base+500…, actions base+600….
    let mut x = String::new();
    for s in 0..steps {
        let entering: Vec<usize> = (trans.iter().enumerate())
            .filter(|(_, (_, to))| to.contains(&s))
            .map(|(t, _)| base + 100 + t)
            .collect();
        x += &format!(
            "<step localId=\"{}\" name=\"{prefix}{s}\" initialStep=\"{}\"><position x=\"0\" y=\"{}\"/>{}</step>\n",
            base + s + 1,
            s == 0,
            100 * s,
            pins(&entering)
        );
    }
    for (t, (from, _)) in trans.iter().enumerate() {
        let sources: Vec<usize> = from.iter().map(|s| base + s + 1).collect();
        x += &format!(
            "<transition localId=\"{}\"><position x=\"{}\" y=\"0\"/>{}<condition><inline name=\"\"><ST><xhtml:p><![CDATA[{}]]></xhtml:p></ST></inline></condition></transition>\n",
            base + 100 + t,
            r.below(4) * 50,
            pins(&sources),
            condition(r, names, 3)
        );
    }
    let qualifiers = ["N", "S", "R", "P", "P1", "P0", "L", "D", "SD", "DS", "SL"];
    for b in 0..r.below(5) + usize::from(sub) {
        let s = r.below(steps);
        x += &format!(
            "<actionBlock localId=\"{}\"><position x=\"300\" y=\"0\"/>{}\n",
            base + 500 + b,
            pins(&[base + s + 1])
        );
        for a in 0..1 + r.below(3) {
            let q = r.pick(&qualifiers);
            let timed = ["L", "D", "SD", "DS", "SL"].contains(&q);
            let duration = match timed {
                true => format!(" duration=\"T#{}ms\"", 10 + 10 * r.below(30)),
                false => String::new(),
            };
            let what = match (sub && a == 0 && b == 0, r.below(3)) {
                (true, _) => "<reference name=\"Sub\"/>".to_string(),
                (_, 0) => format!("<reference name=\"{}\"/>", r.pick(&["Q0", "Q1", "B"])),
                (_, 1) => "<reference name=\"Count\"/>".to_string(),
                _ => format!(
                    "<inline><ST><xhtml:p><![CDATA[{}]]></xhtml:p></ST></inline>",
                    body(r, names)
                ),
            };
            x += &format!(
                "<action localId=\"{}\" qualifier=\"{q}\"{duration}><relPosition x=\"0\" y=\"0\"/>{what}</action>\n",
                base + 600 + 10 * b + a
            );
        }
        x += "</actionBlock>\n";
    }
    x
}

/// A POU whose chart is drawn from `seed`: every other one with the action `Sub`, whose body
/// is a nested chart of its own.
fn chart(seed: u64) -> String {
    let mut r = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let nested = seed % 2 == 1;
    let mut names = Vec::new();
    let main = network(&mut r, "S", &mut names, 0, nested);
    let mut actions = format!(
        "<action name=\"Count\"><body><ST><xhtml:p><![CDATA[{}]]></xhtml:p></ST></body></action>",
        body(&mut r, &names)
    );
    if nested {
        let sub = network(&mut r, "N", &mut names, 1000, false);
        actions += &format!("<action name=\"Sub\"><body><SFC>\n{sub}</SFC></body></action>");
    }
    project(&format!("<actions>{actions}</actions>"), &main)
}

fn project(actions: &str, sfc: &str) -> String {
    let var = |n: &str, t: &str, extra: &str| {
        format!("<variable name=\"{n}\"{extra}><type><{t}/></type></variable>")
    };
    format!(
        "<?xml version=\"1.0\"?>\n<project xmlns=\"http://www.plcopen.org/xml/tc6_0201\" xmlns:xhtml=\"http://www.w3.org/1999/xhtml\">\
         <fileHeader companyName=\"t\" creationDateTime=\"2026-01-01T00:00:00\"/><contentHeader name=\"random charts\"><coordinateInfo><fbd><scaling x=\"1\" y=\"1\"/></fbd><ld><scaling x=\"1\" y=\"1\"/></ld><sfc><scaling x=\"1\" y=\"1\"/></sfc></coordinateInfo></contentHeader>\
         <types><dataTypes/><pous><pou name=\"Random\" pouType=\"program\"><interface>\
         <inputVars>{}{}{}</inputVars><outputVars>{}{}</outputVars>\
         <localVars>{}<variable name=\"R\"><type><LREAL/></type><initialValue><simpleValue value=\"1.5\"/></initialValue></variable>{}</localVars>\
         </interface>{actions}<body><SFC>\n{sfc}</SFC></body></pou></pous></types></project>\n",
        var("I0", "BOOL", " address=\"%IX0.0\""),
        var("I1", "BOOL", ""),
        var("I2", "BOOL", " address=\"%IX0.2\""),
        var("Q0", "BOOL", " address=\"%QX0.0\""),
        var("Q1", "BOOL", ""),
        var("N", "INT", ""),
        var("B", "BOOL", ""),
    )
}

#[test]
fn random_charts_export_as_charts_that_import_to_the_same_hash() {
    let (mut branches, mut nested) = ([0usize; 4], 0);
    for seed in 0..300u64 {
        let xml = chart(seed);
        let imported = cetratus_sfc::import_str(&xml, "random.xml", None, "Random.pnml")
            .unwrap_or_else(|e| panic!("seed {seed}: the drawn chart does not import: {e}"));
        let export = to_plcopen(&imported.program).expect("a chart exports");
        assert!(
            export.chart,
            "seed {seed}: written as ST, not as a chart: {:?}\n{xml}",
            export.notes
        );
        let back = cetratus_sfc::import_str(&export.text, "Random.xml", None, "Random.pnml")
            .unwrap_or_else(|e| panic!("seed {seed}: the export does not import: {e}"));
        assert_eq!(back.toml, imported.toml, "seed {seed}");
        assert_eq!(back.program.hash(), imported.program.hash(), "seed {seed}");
        nested += usize::from(
            export.text.contains("<action name=\"Sub\"><body><SFC>")
                || export
                    .text
                    .contains("<action name=\"Sub\">\n            <body>\n              <SFC>"),
        );
        for (k, element) in [
            "<selectionDivergence",
            "<selectionConvergence",
            "<simultaneousDivergence",
            "<simultaneousConvergence",
        ]
        .iter()
        .enumerate()
        {
            branches[k] += usize::from(export.text.contains(element));
        }
    }
    // Every kind of branch is written by many of the charts, and half have a nested chart.
    assert!(branches.iter().all(|&n| n >= 30), "{branches:?}");
    assert_eq!(nested, 150);
}

fn vernadat_sfc() -> cetratus_sfc::Imported {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/vernadat-sfc/vernadat-sfc.xml");
    let text = std::fs::read_to_string(path).expect("the example reads");
    cetratus_sfc::import_str(&text, "vernadat-sfc.xml", None, "Cell.pnml").expect("it imports")
}

#[test]
fn the_same_chart_is_the_same_program_under_any_file_name() {
    let a = vernadat_sfc();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/vernadat-sfc/vernadat-sfc.xml");
    let text = std::fs::read_to_string(path).expect("the example reads");
    let b = cetratus_sfc::import_str(&text, "elsewhere/copy.xml", None, "Cell.pnml").unwrap();
    assert_eq!(a.program.hash(), b.program.hash());
    assert!(a
        .toml
        .starts_with("# Imported from the PLCopen TC6 XML project vernadat-sfc, POU Cell.\n"));
}

/// A program that says it is a chart but holds what no chart imports as (here a variable
/// edited by hand into the block of the chart's own variables, which the importer writes) is
/// written as Structured Text POUs, and the note says why.
#[test]
fn what_a_chart_cannot_carry_is_written_as_st_pous_with_the_reason() {
    let cell = vernadat_sfc();
    let edited = cell.toml.replacen(
        " : CETRATUS_STEP;\n",
        " : CETRATUS_STEP;\n  Extra : INT;\n",
        1,
    );
    assert_ne!(edited, cell.toml);
    let program =
        cetratus_program::Program::from_sources(&edited, "Cell.toml", cell.net.clone()).unwrap();
    let export = to_plcopen(&program).expect("it exports");
    assert!(!export.chart);
    assert!(
        export.notes[0].contains("rather than as a chart: its line `  Extra : INT;`"),
        "{:?}",
        export.notes
    );
    assert!(export.text.contains("FUNCTION_BLOCK") || export.text.contains("functionBlock"));
}

/// A chart written by hand in the guard language (`chart = "sfc"` with `[guards]`, no `[st]`)
/// is written as Structured Text POUs: its file would import as a chart in Structured Text, a
/// different program, and the note says so.
#[test]
fn a_chart_in_the_guard_language_is_written_as_st_pous_saying_why() {
    let cell = vernadat_sfc();
    let toml = "[program]\nname = \"Cell\"\nversion = \"1\"\nnet = \"Cell.pnml\"\nchart = \"sfc\"\n\n[[input]]\nname = \"FCM1\"\ntype = \"bool\"\n\n[guards]\nT5 = \"FCM1\"\n";
    let program =
        cetratus_program::Program::from_sources(toml, "Cell.toml", cell.net.clone()).unwrap();
    let export = to_plcopen(&program).expect("it exports");
    assert!(!export.chart);
    assert!(
        export.notes[0].contains("its conditions are guards of the program format"),
        "{:?}",
        export.notes
    );
}
