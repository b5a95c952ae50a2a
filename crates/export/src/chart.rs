//! `--to plcopen` of a program imported from an SFC chart (`chart = "sfc"`): the chart written
//! back as an SFC POU (docs/export.md, *Charts*), which `cetratus import plcopen` reads as the
//! same program, with the same hash.
//!
//! The importer's mapping (docs/sfc.md) is inverted element by element: a place is a step (its
//! initial marking the initial step), a transition `T<n>` is the transition of localId `n`, its
//! condition as `[st.conditions]` holds it (module `texts`), and the left-to-right order of the transitions that leave a step
//! (their x position) gives back their priorities. Steps with several transitions leaving them
//! get a selection divergence, with several entering a selection convergence; a transition with
//! several source steps a simultaneous convergence, with several targets a simultaneous
//! divergence; an arc back to an earlier step is a jump. Each `[[action]]` is an association in
//! an action block of its step: an inline body when the importer named it `<step>_inline<k>`,
//! else a named action of the POU.
//!
//! A nested chart (the importer merged an action's chart into the POU's, its steps `A__S`, its
//! transitions `A__T<n>`, a held place and a hold and a resume transition per step, and a BOOL
//! variable `A` that the action's `Q` drives) is written back as the action `A` with an SFC
//! body: its own steps and transitions under their names in it, its conditions without the
//! `A AND (…)` the importer adds, its initial step the one whose held place is marked.
//!
//! The writer does not trust itself: the chart is imported back in process, and only a chart
//! that gives the program's own hash is returned. A program the chart cannot carry (statements
//! as a nested chart's condition, a chart written by hand in the guard language, a hand edit
//! the importer never writes) is said with the reason, and the caller writes it as Structured
//! Text POUs instead.

use std::collections::HashSet;
use std::fmt::Write as _;

use cetratus_net::{xml_escape, Net};
use cetratus_program::Program;
use cetratus_st::types::{Elem, Ty};

use crate::io::IoRow;

mod sequence;
mod texts;

use sequence::{st_text, Part, Sequence};
use texts::StChart;

/// Between an action's name and the name of one of its nested chart's elements (as the
/// importer writes it).
const SEP: &str = "__";

/// The chart of `program` as a PLCopen project, checked by importing it back; the I/O map lists
/// the signals that declare an address. An error says why the chart cannot carry the program.
pub(crate) fn project(program: &Program, file_name: &str) -> Result<(String, Vec<IoRow>), String> {
    let io: Vec<IoRow> = crate::io::map(program.inputs(), program.outputs(), str::to_string)
        .map_err(|e| e.to_string())?
        .into_iter()
        .filter(|r| !r.assigned)
        .collect();
    let Some(texts) = program.chart_texts() else {
        return Err("its conditions are guards of the program format, and the chart form carries a chart in Structured Text; import the chart's PLCopen file again to get one".into());
    };
    let chart = StChart::new(texts)?;
    let parts = parts(program)?;
    let charts = (parts.iter())
        .map(|p| Sequence::new(program, p))
        .collect::<Result<Vec<_>, _>>()?;
    let mut x = header(program, &chart);
    x.push_str(&chart.interface);
    x.push_str(&actions(program, &charts, &chart)?);
    x.push_str("        <body>\n          <SFC>\n");
    x.push_str(&charts[0].elements(program, &chart)?);
    x.push_str("          </SFC>\n        </body>\n      </pou>\n    </pous>\n  </types>\n");
    // The library says where its POU runs, if anywhere; the chart adds nothing.
    let configs = &chart.configurations;
    let _ = write!(x, "  <instances>\n    <configurations>\n{configs}    </configurations>\n  </instances>\n</project>\n");
    verify(program, &x, file_name)?;
    Ok((x, io))
}

/// The project's opening, named as the program's description names its project, through the
/// chart POU's start tag, with the library's data types and other POUs.
fn header(program: &Program, chart: &StChart) -> String {
    let project = program
        .description()
        .strip_prefix(&format!("SFC {} of ", program.name()))
        .unwrap_or(program.name());
    format!(
        "{}  <types>\n    <dataTypes>\n{}    </dataTypes>\n    <pous>\n{}{}",
        crate::plcopen::opening(project, program.version()),
        chart.data_types,
        chart.pous,
        chart.start
    )
}

/// Imports the chart back and compares: the same program text and net, or the first line that
/// differs.
fn verify(program: &Program, xml: &str, file_name: &str) -> Result<(), String> {
    let net_file = format!("{}.pnml", program.name());
    let back = cetratus_sfc::import_str(xml, file_name, Some(program.name()), &net_file)
        .map_err(|e| format!("the chart written does not import: {e}"))?;
    if back.program.hash() == program.hash() {
        return Ok(());
    }
    let differs = (program.source().lines().zip(back.toml.lines()))
        .find(|(a, b)| a != b)
        .map(|(a, b)| format!("its line `{a}` would read `{b}`"));
    Err(differs.unwrap_or_else(|| net_difference(program.net(), &back.net)))
}

/// The first difference between a net and the one its chart imports as.
fn net_difference(a: &Net, b: &Net) -> String {
    let priorities = (a.transitions().iter().zip(b.transitions()))
        .find(|(x, y)| x.id != y.id || x.priority != y.priority)
        .map(|(x, y)| {
            format!(
                "its transition `{}` of priority {} would be `{}` of priority {}",
                x.id, x.priority, y.id, y.priority
            )
        });
    let arcs = (a.arcs().iter().zip(b.arcs()))
        .find(|(x, y)| (x.source, x.target) != (y.source, y.target))
        .map(|(x, y)| format!("its arc `{}` would be `{}`", x.id, y.id));
    priorities
        .or(arcs)
        .unwrap_or_else(|| "its steps would differ".into())
}

/// The program's charts: the POU's own first, then each nested chart, as the importer merged
/// them; the held places and the hold and resume transitions it added are left out.
fn parts(program: &Program) -> Result<Vec<Part>, String> {
    let net = program.net();
    // An action's name is an IEC name, without `__`: its places' ids start with it and SEP.
    let prefixes: HashSet<&str> = (net.places().iter())
        .filter_map(|p| Some(p.id.split_once(SEP)?.0))
        .collect();
    let actions: Vec<&str> = (program.st().into_iter())
        .flat_map(|s| &s.unit().vars)
        .filter(|v| v.ty == Ty::Elem(Elem::Bool))
        .map(|v| v.name.as_str())
        .filter(|a| prefixes.contains(a))
        .collect();
    let of = |id: &str| {
        (actions.iter())
            .find(|a| id.len() > a.len() + SEP.len() && id.starts_with(&format!("{a}{SEP}")))
    };
    let ids: HashSet<&str> = net.places().iter().map(|p| p.id.as_str()).collect();
    let held = |id: &str| {
        (id.strip_suffix(&format!("{SEP}held")))
            .is_some_and(|step| of(id).is_some() && ids.contains(step))
    };
    let mut parts: Vec<Part> = std::iter::once(None)
        .chain(actions.iter().map(|a| Some(a.to_string())))
        .map(|action| Part {
            action,
            places: Vec::new(),
            transitions: Vec::new(),
            names: Vec::new(),
            initial: Vec::new(),
        })
        .collect();
    for (p, place) in net.places().iter().enumerate() {
        if held(&place.id) {
            continue;
        }
        let k = of(&place.id).map_or(0, |a| 1 + actions.iter().position(|x| x == a).unwrap_or(0));
        let part = &mut parts[k];
        let name = match &part.action {
            Some(a) => place.id[a.len() + SEP.len()..].to_string(),
            None => place.id.clone(),
        };
        let initial = match &part.action {
            Some(_) => (net.place_by_id(&format!("{}{SEP}held", place.id)))
                .is_some_and(|h| net.place(h).initial > 0),
            None => place.initial > 0,
        };
        part.places.push(p);
        part.names.push(name);
        part.initial.push(initial);
        if place.capacity.is_some() || place.initial > 1 {
            return Err(format!(
                "the place `{}` has a capacity or more than one token (a step is active or not)",
                place.id
            ));
        }
    }
    for (t, tr) in net.transitions().iter().enumerate() {
        let added = ["hold", "resume"].iter().any(|s| {
            (tr.id.strip_suffix(&format!("{SEP}{s}"))).is_some_and(|step| ids.contains(step))
        });
        if added && of(&tr.id).is_some() {
            continue;
        }
        let k = of(&tr.id).map_or(0, |a| 1 + actions.iter().position(|x| x == a).unwrap_or(0));
        parts[k].transitions.push(t);
    }
    Ok(parts)
}

/// The POU's named actions: the ST bodies an association refers to by name, and the nested
/// charts.
fn actions(program: &Program, charts: &[Sequence], chart: &StChart) -> Result<String, String> {
    let net = program.net();
    let inline: HashSet<String> = (program.actions().iter().enumerate())
        .map(|(k, a)| format!("{}_inline{}", net.places()[a.place.index()].id, k + 1))
        .collect();
    let mut x = String::new();
    for body in program.bodies() {
        if inline.contains(body.name()) {
            continue;
        }
        let text = chart.body(body.name())?;
        let _ = writeln!(
            x,
            "          <action name=\"{}\">\n            <body>\n              {}\n            </body>\n          </action>",
            xml_escape(body.name()),
            st_text(text)
        );
    }
    for nested in &charts[1..] {
        let _ = writeln!(
            x,
            "          <action name=\"{}\">\n            <body>\n              <SFC>\n{}              </SFC>\n            </body>\n          </action>",
            xml_escape(nested.action().unwrap_or_default()),
            nested.elements(program, chart)?
        );
    }
    Ok(match x.is_empty() {
        true => x,
        false => format!("        <actions>\n{x}        </actions>\n"),
    })
}
