//! `--to plcopen` of a program imported from an SFC chart (`chart = "sfc"`): the chart written
//! back as an SFC POU (docs/export.md, *Charts*), which `cetratus import plcopen` reads as the
//! same program, with the same hash.
//!
//! The importer's mapping (docs/sfc.md) is inverted element by element: a place is a step (its
//! initial marking the initial step), a transition `T<n>` is the transition of localId `n`, its
//! guard the ST condition, and the left-to-right order of the transitions that leave a step
//! (their x position) gives back their priorities. Steps with several transitions leaving them
//! get a selection divergence, with several entering a selection convergence; a transition with
//! several source steps a simultaneous convergence, with several targets a simultaneous
//! divergence; an arc back to an earlier step is a jump. Each `[[action]]` is an association in
//! an action block of its step: an inline body when the importer named it `<step>_inline<k>`,
//! else a named action of the POU.
//!
//! The writer does not trust itself: the chart is imported back in process, and only a chart
//! that gives the program's own hash is returned. A program the chart cannot carry (nested
//! charts, a guard outside the chart's ST subset, a hand edit the importer never writes) is
//! said with the reason, and the caller writes it as Structured Text POUs instead.

use std::collections::HashSet;
use std::fmt::Write as _;

use cetratus_net::{xml_escape, ArcKind, Net, NodeRef, TransIdx};
use cetratus_program::{Program, Qualifier, Target, Type, Value};

use crate::io::IoRow;

mod st;

/// The namespace the project is written in (TC6 2.01).
const TC6: &str = "http://www.plcopen.org/xml/tc6_0201";
/// Vertical distance between two steps of the drawing.
const ROW: u32 = 120;
/// Horizontal distance between two branches of a divergence.
const COLUMN: u32 = 160;

/// The chart of `program` as a PLCopen project, checked by importing it back; the I/O map lists
/// the signals that declare an address. An error says why the chart cannot carry the program.
pub(crate) fn project(program: &Program, file_name: &str) -> Result<(String, Vec<IoRow>), String> {
    let io: Vec<IoRow> = crate::io::map(program.inputs(), program.outputs(), str::to_string)
        .map_err(|e| e.to_string())?
        .into_iter()
        .filter(|r| !r.assigned)
        .collect();
    let sfc = Sequence::new(program)?;
    let mut x = header(program);
    interface(&mut x, program, &io)?;
    x.push_str(&sfc.named_actions(program)?);
    x.push_str("        <body>\n          <SFC>\n");
    x.push_str(&sfc.elements(program)?);
    x.push_str("          </SFC>\n        </body>\n      </pou>\n    </pous>\n  </types>\n");
    configuration(&mut x, program);
    verify(program, &x, file_name)?;
    Ok((x, io))
}

/// The project's opening, named as the program's description names its project.
fn header(program: &Program) -> String {
    let project = program
        .description()
        .strip_prefix(&format!("SFC {} of ", program.name()))
        .unwrap_or(program.name());
    format!(
        "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<project xmlns=\"{TC6}\" xmlns:xhtml=\"http://www.w3.org/1999/xhtml\">\n  \
         <fileHeader companyName=\"Cetratus\" productName=\"cetratus export\" productVersion=\"{}\" creationDateTime=\"1970-01-01T00:00:00\"/>\n  \
         <contentHeader name=\"{}\" version=\"{}\">\n    <coordinateInfo>\n      <fbd><scaling x=\"1\" y=\"1\"/></fbd>\n      <ld><scaling x=\"1\" y=\"1\"/></ld>\n      <sfc><scaling x=\"1\" y=\"1\"/></sfc>\n    </coordinateInfo>\n  </contentHeader>\n  \
         <types>\n    <dataTypes/>\n    <pous>\n      <pou name=\"{}\" pouType=\"program\">\n",
        env!("CARGO_PKG_VERSION"),
        xml_escape(project),
        xml_escape(program.version()),
        xml_escape(program.name()),
    )
}

/// The POU's interface: inputs, outputs and variables, a located one typed by its address.
fn interface(x: &mut String, program: &Program, io: &[IoRow]) -> Result<(), String> {
    let declared = declared_initials(program)?;
    x.push_str("        <interface>\n");
    let blocks = [
        ("inputVars", program.inputs()),
        ("outputVars", program.outputs()),
        ("localVars", program.variables()),
    ];
    for (element, signals) in blocks.into_iter().filter(|(_, s)| !s.is_empty()) {
        let _ = writeln!(x, "          <{element}>");
        for s in signals {
            let row = io.iter().find(|r| r.signal == s.name);
            let ty = match (s.ty, row) {
                (_, Some(r)) => r.iec_type,
                (Type::Bool, None) => "BOOL",
                (Type::Int, None) => "LINT",
                (Type::Real, None) => "LREAL",
            };
            let address = (row.map(|r| format!(" address=\"{}\"", xml_escape(&r.address))))
                .unwrap_or_default();
            let _ = writeln!(
                x,
                "            <variable name=\"{}\"{address}>\n              <type><{ty}/></type>",
                xml_escape(&s.name)
            );
            if declared.contains(s.name.as_str()) {
                let v = match s.initial {
                    Value::Bool(b) => (if b { "TRUE" } else { "FALSE" }).to_string(),
                    Value::Int(i) => i.to_string(),
                    Value::Real(r) => format!("{r:?}"),
                };
                let _ = writeln!(
                    x,
                    "              <initialValue><simpleValue value=\"{v}\"/></initialValue>"
                );
            }
            x.push_str("            </variable>\n");
        }
        let _ = writeln!(x, "          </{element}>");
    }
    x.push_str("        </interface>\n");
    Ok(())
}

/// The variables whose `initial` the program text declares (a zero declared and a zero by
/// default are one value, and two programs).
fn declared_initials(program: &Program) -> Result<HashSet<String>, String> {
    let table: toml::Table = program
        .source()
        .parse()
        .map_err(|e| format!("the program text does not read back as TOML: {e}"))?;
    let variables = table.get("variable").and_then(|v| v.as_array());
    Ok(variables
        .into_iter()
        .flatten()
        .filter(|v| v.get("initial").is_some())
        .filter_map(|v| v.get("name")?.as_str().map(str::to_string))
        .collect())
}

/// The chart's structure: each transition's localId and source and target steps, each step's
/// entering and leaving transitions, and the x rank that gives a transition its priority.
struct Sequence<'n> {
    net: &'n Net,
    local: Vec<u64>,
    from: Vec<Vec<usize>>,
    to: Vec<Vec<usize>>,
    leaving: Vec<Vec<usize>>,
    rank: Vec<u32>,
    /// The next free localId.
    next: u64,
}

impl<'n> Sequence<'n> {
    fn new(program: &'n Program) -> Result<Self, String> {
        let net = program.net().as_ref();
        let (np, nt) = (net.num_places(), net.num_transitions());
        let (mut from, mut to) = (vec![Vec::new(); nt], vec![Vec::new(); nt]);
        let mut leaving = vec![Vec::new(); np];
        for a in net.arcs() {
            if a.kind != ArcKind::Normal || a.weight != 1 {
                return Err(format!(
                    "the arc `{}` is an inhibitor or has a weight (a chart's arcs are plain)",
                    a.id
                ));
            }
            match (a.source, a.target) {
                (NodeRef::Place(p), NodeRef::Transition(t)) => {
                    from[t.index()].push(p.index());
                    leaving[p.index()].push(t.index());
                }
                (NodeRef::Transition(t), NodeRef::Place(p)) => to[t.index()].push(p.index()),
                _ => unreachable!("a net's arcs join a place and a transition"),
            }
        }
        if let Some(p) = net
            .places()
            .iter()
            .find(|p| p.capacity.is_some() || p.initial > 1)
        {
            return Err(format!(
                "the place `{}` has a capacity or more than one token (a step is active or not)",
                p.id
            ));
        }
        let mut local = Vec::with_capacity(nt);
        for t in net.transitions() {
            let n = t.id.trim_end_matches('_').strip_prefix('T');
            match n.and_then(|n| n.parse::<u64>().ok()) {
                Some(n) if !local.contains(&n) => local.push(n),
                _ => {
                    return Err(format!(
                        "the transition `{}` is not named T<localId> as a chart's transitions are",
                        t.id
                    ))
                }
            }
        }
        let rank = ranks(net, &from, &leaving);
        let next = local.iter().max().map_or(1, |m| m + 1);
        Ok(Sequence {
            net,
            local,
            from,
            to,
            leaving,
            rank,
            next,
        })
    }
}

/// Each transition's x rank, from which the importer gives back its priority: among the
/// transitions that leave a step, ranked left to right, the leftmost gets as many as there are
/// and the next one less, and a transition that leaves several steps the most of them.
///
/// When every transition leaves one step, the highest priority leftmost (ties in transition
/// order) is the order. Otherwise the order is built from the left: a step's next slot is worth
/// what is left of it, a transition may be placed when no step it leaves would give it more
/// than its priority and one gives exactly that; of those, one that takes no slot another
/// transition is waiting for goes first, then the one with the fewest steps that give it its
/// priority. The order is checked by importing the chart back (`verify`).
fn ranks(net: &Net, from: &[Vec<usize>], leaving: &[Vec<usize>]) -> Vec<u32> {
    let priority = |t: usize| i64::from(net.transitions()[t].priority);
    let nt = net.num_transitions();
    let mut rank = vec![0u32; nt];
    if from.iter().all(|f| f.len() <= 1) {
        for l in leaving {
            let mut order = l.clone();
            order.sort_by_key(|&t| (-priority(t), t));
            for (r, &t) in order.iter().enumerate() {
                rank[t] = r as u32;
            }
        }
        return rank;
    }
    // What the next slot of each step is worth.
    let mut left: Vec<i64> = leaving.iter().map(|l| l.len() as i64).collect();
    let mut placed = vec![false; nt];
    for r in 0..nt {
        // Placing `t` takes a slot of each step it leaves: one that another transition still
        // needs at its value goes last.
        let score = |t: usize| {
            let p = priority(t);
            let tight = from[t].iter().filter(|&&s| left[s] == p).count();
            let takes = from[t].iter().any(|&s| {
                (leaving[s].iter()).any(|&u| u != t && !placed[u] && priority(u) == left[s])
            });
            (from[t].iter().all(|&s| left[s] <= p) && tight > 0).then_some((takes, tight, t))
        };
        let next = (0..nt)
            .filter(|&t| !placed[t])
            .filter_map(score)
            .min()
            .map(|(_, _, t)| t)
            .or_else(|| (0..nt).find(|&t| !placed[t]));
        let Some(t) = next else { break };
        placed[t] = true;
        rank[t] = r as u32;
        for &s in &from[t] {
            left[s] -= 1;
        }
    }
    rank
}

/// The configuration: one task at the scan period running the chart.
fn configuration(x: &mut String, program: &Program) {
    let period = crate::expr::time_literal(program.scan_period().as_micros() as u64);
    let _ = write!(
        x,
        "  <instances>\n    <configurations>\n      <configuration name=\"CETRATUS_CONFIG\">\n        <resource name=\"CETRATUS_RESOURCE\">\n          \
         <task name=\"CETRATUS_TASK\" interval=\"{period}\" priority=\"1\">\n            <pouInstance name=\"CETRATUS_MAIN\" typeName=\"{}\"/>\n          </task>\n        </resource>\n      </configuration>\n    </configurations>\n  </instances>\n</project>\n",
        xml_escape(program.name())
    );
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

/// Where each kind of element is drawn.
fn position(x: u32, y: u32) -> String {
    format!("<position x=\"{x}\" y=\"{y}\"/>")
}

impl Sequence<'_> {
    /// The SFC elements: steps with their convergences, transitions with their branches and
    /// jumps, then the action blocks, each kind in the program's order.
    fn elements(&self, program: &Program) -> Result<String, String> {
        let mut ids = Ids::new(self);
        let mut x = String::new();
        let entering = self.entering(&mut ids);
        for (p, place) in self.net.places().iter().enumerate() {
            let y = ROW * p as u32 + 40;
            let producers = &entering[p];
            let input = match producers.as_slice() {
                [] => None,
                [one] => Some(*one),
                many => {
                    let c = ids.take();
                    let pins: String = many
                        .iter()
                        .map(|m| format!("              <connectionPointIn><connection refLocalId=\"{m}\"/></connectionPointIn>\n"))
                        .collect();
                    let _ = write!(
                        x,
                        "            <selectionConvergence localId=\"{c}\">\n              {}\n{pins}            </selectionConvergence>\n",
                        position(100, y - 20)
                    );
                    Some(c)
                }
            };
            let _ = writeln!(
                x,
                "            <step localId=\"{}\" name=\"{}\"{}>\n              {}{}\n            </step>",
                ids.step[p],
                xml_escape(&place.id),
                if place.initial > 0 { " initialStep=\"true\"" } else { "" },
                position(100, y),
                connect(input)
            );
            if self.leaving[p].len() > 1 {
                let _ = writeln!(
                    x,
                    "            <selectionDivergence localId=\"{}\">\n              {}{}\n            </selectionDivergence>",
                    ids.out[p],
                    position(100, y + 20),
                    connect(Some(ids.step[p]))
                );
            }
        }
        self.transitions(program, &mut ids, &mut x)?;
        self.action_blocks(program, &ids, &mut x)?;
        Ok(x)
    }

    /// Per step, the elements that feed it (transitions or simultaneous divergences); the arcs
    /// back to an earlier step are left to jumps.
    fn entering(&self, ids: &mut Ids) -> Vec<Vec<u64>> {
        let mut entering = vec![Vec::new(); self.net.num_places()];
        for (t, to) in self.to.iter().enumerate() {
            let producer = match to.len() {
                1 => self.local[t],
                _ => ids.split[t],
            };
            let last_source = self.from[t].iter().max().copied().unwrap_or(0);
            for &p in to.iter().filter(|&&p| p > last_source) {
                entering[p].push(producer);
            }
        }
        entering
    }

    /// The transitions, each with its simultaneous convergence, divergence and jumps.
    fn transitions(&self, program: &Program, ids: &mut Ids, x: &mut String) -> Result<(), String> {
        let steps = st::Steps(self.net.places().iter().map(|p| p.id.as_str()).collect());
        for (t, tr) in self.net.transitions().iter().enumerate() {
            let first = self.from[t].iter().min().copied().unwrap_or(0);
            let (tx, ty) = (100 + COLUMN * self.rank[t], ROW * first as u32 + 100);
            let input = match self.from[t].as_slice() {
                [p] => ids.out[*p],
                sources => {
                    let c = ids.take();
                    let pins: String = sources
                        .iter()
                        .map(|&p| format!("              <connectionPointIn><connection refLocalId=\"{}\"/></connectionPointIn>\n", ids.out[p]))
                        .collect();
                    let _ = write!(
                        x,
                        "            <simultaneousConvergence localId=\"{c}\">\n              {}\n{pins}            </simultaneousConvergence>\n",
                        position(tx, ty - 20)
                    );
                    c
                }
            };
            let condition = match program.guard(TransIdx(t as u32)) {
                Some(g) => steps
                    .expr(g.expr())
                    .map_err(|e| format!("transition `{}`'s guard reads {e}", tr.id))?,
                None => "TRUE".into(),
            };
            let _ = writeln!(
                x,
                "            <transition localId=\"{}\">\n              {}{}\n              <condition><inline name=\"\">{}</inline></condition>\n            </transition>",
                self.local[t],
                position(tx, ty),
                connect(Some(input)),
                st_text(&condition)
            );
            self.after(t, ids, (tx, ty), x);
        }
        Ok(())
    }

    /// What follows transition `t`: a simultaneous divergence when it has several targets, and
    /// a jump for each target that is not below it.
    fn after(&self, t: usize, ids: &mut Ids, (tx, ty): (u32, u32), x: &mut String) {
        let mut from = self.local[t];
        if self.to[t].len() > 1 {
            from = ids.split[t];
            let _ = writeln!(
                x,
                "            <simultaneousDivergence localId=\"{from}\">\n              {}{}\n            </simultaneousDivergence>",
                position(tx, ty + 20),
                connect(Some(self.local[t]))
            );
        }
        let last_source = self.from[t].iter().max().copied().unwrap_or(0);
        for (k, &p) in self.to[t].iter().filter(|&&p| p <= last_source).enumerate() {
            let _ = writeln!(
                x,
                "            <jumpStep localId=\"{}\" targetName=\"{}\">\n              {}{}\n            </jumpStep>",
                ids.take(),
                xml_escape(&self.net.places()[p].id),
                position(tx + COLUMN / 2 * k as u32, ty + 40),
                connect(Some(from))
            );
        }
    }

    /// The action blocks: one per run of `[[action]]`s on the same step, in the program's order.
    fn action_blocks(&self, program: &Program, ids: &Ids, x: &mut String) -> Result<(), String> {
        let actions = program.actions();
        let mut k = 0;
        let mut next = ids.next;
        while k < actions.len() {
            let p = actions[k].place.index();
            let run = actions[k..]
                .iter()
                .take_while(|a| a.place.index() == p)
                .count();
            let _ = writeln!(
                x,
                "            <actionBlock localId=\"{next}\">\n              {}{}",
                position(400, ROW * p as u32 + 40),
                connect(Some(ids.step[p]))
            );
            next += 1;
            for (j, a) in actions[k..k + run].iter().enumerate() {
                let (qualifier, duration) = qualifier(a.qualifier);
                let what = match a.target {
                    Target::Body(b) => {
                        let body = &program.bodies()[b as usize];
                        let place = &self.net.places()[p].id;
                        if body.name() == format!("{place}_inline{}", k + j + 1) {
                            inline(&self.body_text(program, b)?)
                        } else {
                            format!("<reference name=\"{}\"/>", xml_escape(body.name()))
                        }
                    }
                    Target::Output(i) => reference(&program.outputs()[i as usize].name),
                    Target::Variable(i) => reference(&program.variables()[i as usize].name),
                };
                let _ = writeln!(
                    x,
                    "              <action localId=\"{next}\" qualifier=\"{qualifier}\"{duration}>\n                <relPosition x=\"0\" y=\"{}\"/>\n                {what}\n              </action>",
                    20 * j
                );
                next += 1;
            }
            x.push_str("            </actionBlock>\n");
            k += run;
        }
        Ok(())
    }

    /// The named actions of the POU: the bodies an association refers to by name.
    fn named_actions(&self, program: &Program) -> Result<String, String> {
        let mut inline_names = HashSet::new();
        for (k, a) in program.actions().iter().enumerate() {
            inline_names.insert(format!(
                "{}_inline{}",
                self.net.places()[a.place.index()].id,
                k + 1
            ));
        }
        let mut x = String::new();
        for (b, body) in program.bodies().iter().enumerate() {
            if inline_names.contains(body.name()) {
                continue;
            }
            let text = self.body_text(program, b as u32)?;
            let _ = writeln!(
                x,
                "          <action name=\"{}\">\n            <body>\n              {}\n            </body>\n          </action>",
                xml_escape(body.name()),
                st_text(&text)
            );
        }
        Ok(match x.is_empty() {
            true => x,
            false => format!("        <actions>\n{x}        </actions>\n"),
        })
    }

    /// A body's statements in the chart's ST.
    fn body_text(&self, program: &Program, b: u32) -> Result<String, String> {
        let body = &program.bodies()[b as usize];
        let statements = body
            .statements()
            .map_err(|e| format!("the body `{}` does not read: {e}", body.name()))?;
        let steps = st::Steps(self.net.places().iter().map(|p| p.id.as_str()).collect());
        (steps.body(&statements)).map_err(|e| format!("the body `{}` reads {e}", body.name()))
    }
}

/// The localIds of the elements that are not transitions.
struct Ids {
    /// Per step: its own.
    step: Vec<u64>,
    /// Per step: where its leaving transitions connect (the step, or its selection divergence).
    out: Vec<u64>,
    /// Per transition with several targets: its simultaneous divergence.
    split: Vec<u64>,
    next: u64,
}

impl Ids {
    fn new(s: &Sequence) -> Self {
        let mut next = s.next;
        let mut take = || {
            next += 1;
            next - 1
        };
        let step: Vec<u64> = (0..s.net.num_places()).map(|_| take()).collect();
        let out = (s.leaving.iter().zip(&step))
            .map(|(l, &id)| if l.len() > 1 { take() } else { id })
            .collect();
        let split = (s.to.iter())
            .map(|to| if to.len() > 1 { take() } else { 0 })
            .collect();
        Ids {
            step,
            out,
            split,
            next,
        }
    }

    fn take(&mut self) -> u64 {
        self.next += 1;
        self.next - 1
    }
}

/// A `connectionPointIn` to `id`, or nothing.
fn connect(id: Option<u64>) -> String {
    id.map(|id| format!("<connectionPointIn><connection refLocalId=\"{id}\"/></connectionPointIn>"))
        .unwrap_or_default()
}

fn reference(name: &str) -> String {
    format!("<reference name=\"{}\"/>", xml_escape(name))
}

/// An ST body, inline.
fn inline(text: &str) -> String {
    format!("<inline>{}</inline>", st_text(text))
}

/// ST text as a TC6 body's content.
fn st_text(text: &str) -> String {
    format!(
        "<ST><xhtml:p><![CDATA[{}]]></xhtml:p></ST>",
        text.replace("]]>", "]]]]><![CDATA[>")
    )
}

/// The qualifier as TC6 writes it, with the duration of a timed one.
fn qualifier(q: Qualifier) -> (&'static str, String) {
    let name = match q {
        Qualifier::N => "N",
        Qualifier::S => "S",
        Qualifier::R => "R",
        Qualifier::P1 => "P1",
        Qualifier::P0 => "P0",
        Qualifier::L(_) => "L",
        Qualifier::D(_) => "D",
        Qualifier::SD(_) => "SD",
        Qualifier::DS(_) => "DS",
        Qualifier::SL(_) => "SL",
    };
    let duration = q
        .duration_us()
        .map(|d| format!(" duration=\"{}\"", crate::expr::time_literal(d)))
        .unwrap_or_default();
    (name, duration)
}
