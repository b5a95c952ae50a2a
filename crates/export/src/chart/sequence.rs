//! One chart written as TC6 SFC elements: steps with their convergences, transitions with their
//! branches and jumps, and the action blocks, placed so that the importer reads them back as
//! they were (module `chart`).

use std::collections::HashMap;
use std::fmt::Write as _;

use cetratus_net::{xml_escape, ArcKind, Net, NodeRef};
use cetratus_program::{Program, Qualifier, Target};

use super::texts::StChart;
use super::SEP;

/// Vertical distance between two steps of the drawing.
const ROW: u32 = 120;
/// Horizontal distance between two branches of a divergence.
const COLUMN: u32 = 160;

/// One chart of the program: the POU's own, or the nested chart of an action (`action`), as
/// the importer merged it (docs/sfc.md, *Nested charts*): its steps and transitions by their
/// index in the net, each step's name in the chart and whether it is initial.
pub(super) struct Part {
    pub(super) action: Option<String>,
    pub(super) places: Vec<usize>,
    pub(super) transitions: Vec<usize>,
    pub(super) names: Vec<String>,
    pub(super) initial: Vec<bool>,
}

/// A chart's structure: each transition's localId and source and target steps, each step's
/// entering and leaving transitions, and the x rank that gives a transition its priority; all
/// by the step's and the transition's index in the part.
pub(super) struct Sequence<'n> {
    net: &'n Net,
    part: &'n Part,
    local: Vec<u64>,
    from: Vec<Vec<usize>>,
    to: Vec<Vec<usize>>,
    leaving: Vec<Vec<usize>>,
    rank: Vec<u32>,
    /// The next free localId.
    next: u64,
}

impl<'n> Sequence<'n> {
    /// The action whose nested chart this is; `None` for the POU's own.
    pub(super) fn action(&self) -> Option<&str> {
        self.part.action.as_deref()
    }

    pub(super) fn new(program: &'n Program, part: &'n Part) -> Result<Self, String> {
        let net = program.net().as_ref();
        let mut place_of = vec![usize::MAX; net.num_places()];
        for (i, &p) in part.places.iter().enumerate() {
            place_of[p] = i;
        }
        let mut trans_of = vec![usize::MAX; net.num_transitions()];
        for (i, &t) in part.transitions.iter().enumerate() {
            trans_of[t] = i;
        }
        let (np, nt) = (part.places.len(), part.transitions.len());
        let (mut from, mut to) = (vec![Vec::new(); nt], vec![Vec::new(); nt]);
        let mut leaving = vec![Vec::new(); np];
        for a in net.arcs() {
            if a.kind != ArcKind::Normal || a.weight != 1 {
                return Err(format!(
                    "the arc `{}` is an inhibitor or has a weight (a chart's arcs are plain)",
                    a.id
                ));
            }
            let (p, t, out) = match (a.source, a.target) {
                (NodeRef::Place(p), NodeRef::Transition(t)) => (p.index(), t.index(), false),
                (NodeRef::Transition(t), NodeRef::Place(p)) => (p.index(), t.index(), true),
                _ => unreachable!("a net's arcs join a place and a transition"),
            };
            let (pl, tl) = (place_of[p], trans_of[t]);
            match (pl == usize::MAX, tl == usize::MAX) {
                (_, true) => continue,
                (true, false) => {
                    return Err(format!(
                        "the arc `{}` joins a transition of one chart to a step of another",
                        a.id
                    ))
                }
                (false, false) if out => to[tl].push(pl),
                (false, false) => {
                    from[tl].push(pl);
                    leaving[pl].push(tl);
                }
            }
        }
        let local = local_ids(net, part)?;
        let priority: Vec<i64> = (part.transitions.iter())
            .map(|&t| i64::from(net.transitions()[t].priority))
            .collect();
        let rank = ranks(&priority, &from, &leaving);
        let next = local.iter().max().map_or(1, |m| m + 1);
        Ok(Sequence {
            net,
            part,
            local,
            from,
            to,
            leaving,
            rank,
            next,
        })
    }
}

/// Each transition's localId, from its id `T<n>` (after its action's prefix, and any `_` the
/// importer added to keep it apart from a step's name).
fn local_ids(net: &Net, part: &Part) -> Result<Vec<u64>, String> {
    let prefix = part
        .action
        .as_ref()
        .map(|a| format!("{a}{SEP}"))
        .unwrap_or_default();
    let mut local = Vec::with_capacity(part.transitions.len());
    for &t in &part.transitions {
        let id = &net.transitions()[t].id;
        let n = (id.strip_prefix(&prefix))
            .and_then(|n| n.trim_end_matches('_').strip_prefix('T'))
            .and_then(|n| n.parse::<u64>().ok());
        match n {
            Some(n) if !local.contains(&n) => local.push(n),
            _ => {
                return Err(format!(
                    "the transition `{id}` is not named T<localId> as a chart's transitions are"
                ))
            }
        }
    }
    Ok(local)
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
fn ranks(priorities: &[i64], from: &[Vec<usize>], leaving: &[Vec<usize>]) -> Vec<u32> {
    let priority = |t: usize| priorities[t];
    let nt = priorities.len();
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

/// Where each kind of element is drawn.
fn position(x: u32, y: u32) -> String {
    format!("<position x=\"{x}\" y=\"{y}\"/>")
}

impl Sequence<'_> {
    /// The SFC elements: steps with their convergences, transitions with their branches and
    /// jumps, then the action blocks, each kind in the program's order.
    pub(super) fn elements(&self, program: &Program, chart: &StChart) -> Result<String, String> {
        let mut ids = Ids::new(self);
        let mut x = String::new();
        let entering = self.entering(&mut ids);
        for (p, producers) in entering.iter().enumerate() {
            let y = ROW * p as u32 + 40;
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
                xml_escape(&self.part.names[p]),
                if self.part.initial[p] { " initialStep=\"true\"" } else { "" },
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
        self.transitions(chart, &mut ids, &mut x)?;
        self.action_blocks(program, chart, &ids, &mut x)?;
        Ok(x)
    }

    /// Per step, the elements that feed it (transitions or simultaneous divergences); the arcs
    /// back to an earlier step are left to jumps.
    fn entering(&self, ids: &mut Ids) -> Vec<Vec<u64>> {
        let mut entering = vec![Vec::new(); self.part.places.len()];
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
    fn transitions(&self, chart: &StChart, ids: &mut Ids, x: &mut String) -> Result<(), String> {
        for (t, &global) in self.part.transitions.iter().enumerate() {
            let tr = &self.net.transitions()[global];
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
            let condition = chart.condition(&tr.id, self.action())?;
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
                xml_escape(&self.part.names[p]),
                position(tx + COLUMN / 2 * k as u32, ty + 40),
                connect(Some(from))
            );
        }
    }

    /// The action blocks: one per run of `[[action]]`s on the same step, in the program's order.
    fn action_blocks(
        &self,
        program: &Program,
        chart: &StChart,
        ids: &Ids,
        x: &mut String,
    ) -> Result<(), String> {
        let actions = program.actions();
        let mut place_of = HashMap::new();
        for (i, &p) in self.part.places.iter().enumerate() {
            place_of.insert(p, i);
        }
        let mut k = 0;
        let mut next = ids.next;
        while k < actions.len() {
            let global = actions[k].place.index();
            let run = (actions[k..].iter())
                .take_while(|a| a.place.index() == global)
                .count();
            let Some(&p) = place_of.get(&global) else {
                k += run;
                continue;
            };
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
                        let place = &self.net.places()[global].id;
                        if body.name() == format!("{place}_inline{}", k + j + 1) {
                            inline(chart.body(body.name())?)
                        } else {
                            format!("<reference name=\"{}\"/>", xml_escape(body.name()))
                        }
                    }
                    Target::Output(i) => reference(&program.outputs()[i as usize].name),
                    Target::Variable(i) => reference(&program.variables()[i as usize].name),
                    // A BOOL variable of a chart in ST.
                    Target::St(at) => {
                        reference(program.st().and_then(|s| s.slot_name(at)).unwrap_or("?"))
                    }
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
        let step: Vec<u64> = (0..s.part.places.len()).map(|_| take()).collect();
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
pub(super) fn st_text(text: &str) -> String {
    format!(
        "<ST><xhtml:p>{}</xhtml:p></ST>",
        crate::plcopen::cdata(text)
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
