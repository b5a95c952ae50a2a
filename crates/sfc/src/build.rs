//! A chart and its POU become a Cetratus net and program TOML (the mapping of docs/sfc.md).

use std::collections::HashSet;
use std::fmt::Write as _;

use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition as NetTransition};

use crate::chart::{Chart, Qualifier};
use crate::nest::{Nest, SEP};
use crate::source::Source;
use crate::SfcError;

/// A transition the mapping adds (a nested step's hold or resume), with its ST condition.
pub(crate) type ExtraCondition = (String, String);

/// The structural net of a chart: steps as places (initial steps marked), transitions as
/// transitions with their left-to-right priorities, jumps as arcs to their target. Refuses a
/// network (a connected part of the chart) with no initial step or with two. The steps of a
/// nested chart (`nests`) start unmarked, each with a held place and its hold and resume
/// transitions (module `nest`), whose ids and guards are returned after the transitions' ids.
pub(crate) fn net(
    source: &Source,
    chart: &Chart,
    nests: &[Nest],
) -> Result<(Net, Vec<String>, Vec<ExtraCondition>), SfcError> {
    check_networks(source, chart)?;
    let mut used: HashSet<String> = chart
        .steps
        .iter()
        .map(|s| s.name.to_ascii_lowercase())
        .collect();
    let mut fresh = |base: String| {
        let mut id = base;
        while !used.insert(id.to_ascii_lowercase()) {
            id.push('_');
        }
        id
    };
    let mut b = NetBuilder::new(chart.pou.clone());
    b.name(chart.pou.clone());
    for (i, s) in chart.steps.iter().enumerate() {
        let nested = Nest::of_step(nests, i);
        let mut p = Place::new(s.name.clone(), u32::from(s.initial && nested.is_none()));
        p.name = Some(match nested {
            Some(n) => display(&n.action, &s.name),
            None => s.name.clone(),
        });
        b.add_place(p).map_err(|e| net_err(source, e))?;
    }
    // A nested step's held place, where its token waits while the action is off.
    let mut held = Vec::new();
    for n in nests {
        for i in n.steps.clone() {
            let s = &chart.steps[i];
            let id = fresh(format!("{}{SEP}held", s.name));
            let mut p = Place::new(id.clone(), u32::from(s.initial));
            p.name = Some(format!("{} (held)", display(&n.action, &s.name)));
            b.add_place(p).map_err(|e| net_err(source, e))?;
            held.push((i, id, n.action.clone()));
        }
    }
    // Left to right: among the transitions that leave a step, the leftmost has the highest
    // priority (IEC 61131-3: the first true branch from the left wins).
    // Each step's leaving transitions, in transition order: one pass over the arcs, so that a
    // chart of many steps costs what its size costs.
    let mut leaving_of: Vec<Vec<usize>> = vec![Vec::new(); chart.steps.len()];
    for (t, tr) in chart.transitions.iter().enumerate() {
        for &s in &tr.from {
            if leaving_of[s].last() != Some(&t) {
                leaving_of[s].push(t);
            }
        }
    }
    let mut priority = vec![0i32; chart.transitions.len()];
    for mut leaving in leaving_of {
        leaving.sort_by(|&a, &b| {
            chart.transitions[a]
                .x
                .total_cmp(&chart.transitions[b].x)
                .then(a.cmp(&b))
        });
        let n = leaving.len() as i32;
        for (rank, &t) in leaving.iter().enumerate() {
            priority[t] = priority[t].max(n - rank as i32);
        }
    }
    let mut ids = Vec::with_capacity(chart.transitions.len());
    for (i, t) in chart.transitions.iter().enumerate() {
        let base = match &t.name {
            Some(n) if !n.trim().is_empty() => n.trim().to_string(),
            _ => format!("T{}", t.local_id),
        };
        let id = fresh(base);
        let mut nt = NetTransition::new(id.clone());
        nt.priority = priority[i];
        b.add_transition(nt).map_err(|e| net_err(source, e))?;
        for &s in &t.from {
            let arc = fresh(format!("{id}_from_{}", chart.steps[s].name));
            b.add_arc(&arc, &chart.steps[s].name, &id, 1, ArcKind::Normal)
                .map_err(|e| net_err(source, e))?;
        }
        for &s in &t.to {
            let arc = fresh(format!("{id}_to_{}", chart.steps[s].name));
            b.add_arc(&arc, &id, &chart.steps[s].name, 1, ArcKind::Normal)
                .map_err(|e| net_err(source, e))?;
        }
        ids.push(id);
    }
    let mut extra = Vec::new();
    for (i, place, action) in held {
        let step = &chart.steps[i].name;
        for (suffix, from, to, condition) in [
            (
                "hold",
                step.as_str(),
                place.as_str(),
                format!("NOT {action}"),
            ),
            ("resume", place.as_str(), step.as_str(), action.clone()),
        ] {
            let id = fresh(format!("{step}{SEP}{suffix}"));
            b.add_transition(NetTransition::new(id.clone()))
                .map_err(|e| net_err(source, e))?;
            let arc = fresh(format!("{id}_from_{from}"));
            b.add_arc(&arc, from, &id, 1, ArcKind::Normal)
                .map_err(|e| net_err(source, e))?;
            let arc = fresh(format!("{id}_to_{to}"));
            b.add_arc(&arc, &id, to, 1, ArcKind::Normal)
                .map_err(|e| net_err(source, e))?;
            extra.push((id, condition));
        }
    }
    Ok((b.build().map_err(|e| net_err(source, e))?, ids, extra))
}

/// `A.S` for the place `A__S` of step `S` of action `A`'s chart.
fn display(action: &str, id: &str) -> String {
    format!("{action}.{}", &id[action.len() + SEP.len()..])
}

fn net_err(source: &Source, e: cetratus_net::NetError) -> SfcError {
    SfcError::Net {
        file: source.label.to_string(),
        source: e,
    }
}

/// Every network (steps connected through transitions) has exactly one initial step.
fn check_networks(source: &Source, chart: &Chart) -> Result<(), SfcError> {
    let n = chart.steps.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for t in &chart.transitions {
        let all: Vec<usize> = t.from.iter().chain(&t.to).copied().collect();
        for w in all.windows(2) {
            let (a, b) = (find(&mut parent, w[0]), find(&mut parent, w[1]));
            parent[a] = b;
        }
    }
    let mut initial: Vec<Option<usize>> = vec![None; n];
    for (i, s) in chart.steps.iter().enumerate() {
        if !s.initial {
            continue;
        }
        let root = find(&mut parent, i);
        if let Some(first) = initial[root] {
            return Err(SfcError::Chart {
                pos: source.pos(s.at),
                pou: chart.pou.clone(),
                message: format!(
                    "steps `{}` and `{}` are both initial steps of one network; a network has one initial step (IEC 61131-3), make one of them a plain step",
                    chart.steps[first].name, s.name
                ),
            });
        }
        initial[root] = Some(i);
    }
    for i in 0..n {
        let root = find(&mut parent, i);
        if initial[root].is_none() {
            return Err(SfcError::Chart {
                pos: source.pos(chart.steps[i].at),
                pou: chart.pou.clone(),
                message: format!(
                    "step `{}` is in a network with no initial step; mark the network's first step initial",
                    chart.steps[i].name
                ),
            });
        }
        initial[root] = initial[root].or(Some(i));
    }
    Ok(())
}

/// The `[program]` table of a chart of `project`'s POU `pou` whose net is `net_file`: what the
/// file holds, not where it is or what it is called, so that the same chart is the same program
/// (and hash) under any file name, and a chart that `cetratus export` writes back imports as the
/// program it came from.
pub(crate) fn header(file: &str, pou: &str, net_file: &str) -> String {
    let mut out = String::new();
    // A comment is one line: a project named across lines (`&#10;`) stays in it.
    let one_line = |s: &str| s.replace(char::is_control, " ");
    let _ = writeln!(
        out,
        "# Imported from the PLCopen TC6 XML project {}, POU {}.",
        one_line(file),
        one_line(pou)
    );
    let _ = writeln!(out, "[program]");
    let _ = writeln!(out, "name = {}", q(pou));
    let _ = writeln!(out, "version = \"1\"");
    let _ = writeln!(out, "description = {}", q(&format!("SFC {pou} of {file}")));
    let _ = writeln!(out, "net = {}", q(net_file));
    let _ = writeln!(out, "chart = \"sfc\"");
    out
}

/// The qualifier as the program format names it.
pub(crate) fn qualifier_name(qualifier: Qualifier) -> &'static str {
    match qualifier {
        Qualifier::N => "N",
        Qualifier::S => "S",
        Qualifier::R => "R",
        // P is the IEC pulse: on in the scan the step is entered, as P1.
        Qualifier::P | Qualifier::P1 => "P1",
        Qualifier::P0 => "P0",
        Qualifier::L => "L",
        Qualifier::D => "D",
        Qualifier::SD => "SD",
        Qualifier::DS => "DS",
        Qualifier::SL => "SL",
    }
}

/// The `[[action]]` tables.
pub(crate) fn write_actions(out: &mut String, actions: &[Action]) {
    for a in actions {
        let _ = writeln!(out, "\n[[action]]");
        let _ = writeln!(out, "place = {}", q(&a.place));
        let _ = writeln!(out, "qualifier = \"{}\"", a.qualifier);
        match &a.drive {
            Drive::Target(t) => {
                let _ = writeln!(out, "target = {}", q(t));
            }
            Drive::Body(b) => {
                let _ = writeln!(out, "body = {}", q(b));
            }
        }
        if let Some(d) = a.duration {
            let _ = writeln!(out, "duration = \"{d}us\"");
        }
    }
}

/// An `[[action]]` of the program: one action association of the chart.
pub(crate) struct Action {
    /// The step's place.
    pub place: String,
    /// The qualifier, as the program format names it.
    pub qualifier: &'static str,
    /// What it drives.
    pub drive: Drive,
    /// The duration of a timed qualifier, in microseconds.
    pub duration: Option<u64>,
}

/// What an action association drives in the program.
pub(crate) enum Drive {
    /// A BOOL variable, by its Cetratus name.
    Target(String),
    /// A body of `[bodies]`, by name.
    Body(String),
}

/// The name of the project a file holds (its `contentHeader`), or, in a file without one, the
/// file's name without the directory (so the program does not depend on where the file was).
pub(crate) fn project_name<'d>(doc: &'d cetratus_net::xml::Document, label: &'d str) -> &'d str {
    crate::source::child(doc.root_element(), "contentHeader")
        .and_then(|h| h.attribute("name"))
        .map(str::trim)
        .filter(|n| !n.is_empty())
        .unwrap_or_else(|| label.rsplit(['/', '\\']).next().unwrap_or(label))
}

/// A TOML basic string.
pub(crate) fn q(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            c if c.is_control() => {
                let _ = write!(out, "\\u{:04X}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}
