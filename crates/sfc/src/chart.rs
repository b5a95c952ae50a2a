//! One SFC body read into a chart: steps, transitions with their source and target steps,
//! divergences, jumps and action associations, as the PLCopen file draws them.
//!
//! PLCopen links elements backwards: each element names, in `connectionPointIn/connection`, the
//! elements it follows. A transition's source steps are found by walking back through
//! divergences and convergences, its target steps by walking forward (through a reverse index)
//! until steps or jumps. Both walks keep a visited set, so each costs at most the chart's size,
//! and neither recurses.

use std::collections::HashMap;

use cetratus_net::xml::Node;

use crate::pou::{Body, Pou};
use crate::source::{body_text, child, children, Source};
use crate::SfcError;

/// A step.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// Its name.
    pub name: String,
    /// Whether it is an initial step.
    pub initial: bool,
    /// Byte offset of its element.
    pub at: usize,
}

/// How a transition's condition is written.
#[derive(Clone, Debug, PartialEq)]
pub enum Condition {
    /// A Structured Text expression: inline, in an `<inVariable>` box (CODESYS, TwinCAT), or the
    /// body of a named transition.
    St {
        /// The expression.
        text: String,
        /// Byte offset of its text.
        at: usize,
        /// Negated by the `<inVariable negated="true">` that holds it.
        negated: bool,
    },
    /// The LD or FBD network of a named transition, which assigns the transition's name: the ST
    /// compiler reads the expression it computes (docs/sfc.md).
    Network {
        /// The transition's name.
        name: String,
        /// The network's language (`LD`, `FBD`).
        language: String,
        /// Byte offset of the network's element.
        at: usize,
    },
    /// An LD or FBD network drawn in the chart and wired to the transition's condition: the
    /// ST compiler reads the statements it means, which assign the condition's value.
    Drawn {
        /// The network's language (`LD`, `FBD`).
        language: String,
        /// Byte offset of the condition's `<connectionPointIn>`.
        at: usize,
    },
    /// A form Cetratus does not import (IL, a function-call body).
    Unsupported {
        /// The form, as the README of the fixtures names it.
        form: String,
        /// Byte offset of the condition.
        at: usize,
    },
}

impl Condition {
    /// The form's name: `inline ST`, `inVariable`, `reference (ST body)`, `FBD network`, …
    pub fn form(&self) -> &str {
        match self {
            Condition::St { .. } => "ST",
            Condition::Network { language, .. } | Condition::Drawn { language, .. } => language,
            Condition::Unsupported { form, .. } => form,
        }
    }
}

/// A transition.
#[derive(Clone, Debug, PartialEq)]
pub struct Transition {
    /// Its `localId`.
    pub local_id: String,
    /// Its `name`, if it has one.
    pub name: Option<String>,
    /// Source steps, by index into [`Chart::steps`], in order of first appearance.
    pub from: Vec<usize>,
    /// Target steps.
    pub to: Vec<usize>,
    /// Its condition.
    pub condition: Condition,
    /// Graphical x position (0 when the file gives none).
    pub x: f64,
    /// Byte offset of its element.
    pub at: usize,
}

/// An action qualifier of IEC 61131-3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Qualifier {
    /// Non-stored.
    N,
    /// Set (stored).
    S,
    /// Reset.
    R,
    /// Pulse.
    P,
    /// Pulse, falling edge.
    P0,
    /// Pulse, rising edge.
    P1,
    /// Time limited.
    L,
    /// Time delayed.
    D,
    /// Stored and time delayed.
    SD,
    /// Delayed and stored.
    DS,
    /// Stored and time limited.
    SL,
}

impl Qualifier {
    /// Parses a qualifier as written in the `qualifier` attribute.
    pub fn parse(s: &str) -> Option<Qualifier> {
        Some(match s {
            "N" => Qualifier::N,
            "S" => Qualifier::S,
            "R" => Qualifier::R,
            "P" => Qualifier::P,
            "P0" => Qualifier::P0,
            "P1" => Qualifier::P1,
            "L" => Qualifier::L,
            "D" => Qualifier::D,
            "SD" => Qualifier::SD,
            "DS" => Qualifier::DS,
            "SL" => Qualifier::SL,
            _ => return None,
        })
    }

    /// Whether the qualifier takes a duration.
    pub fn is_timed(self) -> bool {
        matches!(
            self,
            Qualifier::L | Qualifier::D | Qualifier::SD | Qualifier::DS | Qualifier::SL
        )
    }
}

impl std::fmt::Display for Qualifier {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        std::fmt::Debug::fmt(self, f)
    }
}

/// What an action association runs.
#[derive(Clone, Debug, PartialEq)]
pub enum ActionRef {
    /// A named action of the POU, or a Boolean variable (`<reference name="…"/>`).
    Reference(String),
    /// A body written in the association itself (`<inline>`).
    Inline(Body),
}

/// An action association: a step, a qualifier and what it runs.
#[derive(Clone, Debug, PartialEq)]
pub struct Association {
    /// The step, by index into [`Chart::steps`].
    pub step: usize,
    /// The qualifier (`N` when the attribute is absent, the schema default).
    pub qualifier: Qualifier,
    /// The duration as written, for timed qualifiers.
    pub duration: Option<String>,
    /// The indicator variable, if any.
    pub indicator: Option<String>,
    /// What it runs.
    pub action: ActionRef,
    /// Byte offset of the `<action>` element.
    pub at: usize,
}

/// An SFC chart read from one `<SFC>` element.
#[derive(Clone, Debug, PartialEq)]
pub struct Chart {
    /// The POU.
    pub pou: String,
    /// `body`, or `action NAME` for a chart in a named action.
    pub location: String,
    /// Steps in document order.
    pub steps: Vec<Step>,
    /// Transitions in document order.
    pub transitions: Vec<Transition>,
    /// Number of `<selectionDivergence>` elements.
    pub selection_divergences: usize,
    /// Number of `<selectionConvergence>` elements.
    pub selection_convergences: usize,
    /// Number of `<simultaneousDivergence>` elements.
    pub simultaneous_divergences: usize,
    /// Number of `<simultaneousConvergence>` elements.
    pub simultaneous_convergences: usize,
    /// The targets of the `<jumpStep>` elements, in document order.
    pub jumps: Vec<String>,
    /// Number of `<actionBlock>` elements.
    pub action_blocks: usize,
    /// Action associations in document order.
    pub associations: Vec<Association>,
    /// Vendor data (`addData`) that the importer does not read, by data name, with a count.
    pub ignored_vendor_data: Vec<(String, usize)>,
    /// Each step's index by its name in ASCII lower case (IEC names are case-insensitive), so
    /// that a name is found in constant time however many steps the chart has.
    step_names: HashMap<String, usize>,
}

impl Chart {
    /// The index of a step by name (IEC names are case-insensitive).
    pub fn step_index(&self, name: &str) -> Option<usize> {
        self.step_names.get(&name.to_ascii_lowercase()).copied()
    }

    /// Appends a step; the first of two steps with one name keeps it.
    pub(crate) fn push_step(&mut self, step: Step) {
        let next = self.steps.len();
        self.step_names
            .entry(step.name.to_ascii_lowercase())
            .or_insert(next);
        self.steps.push(step);
    }
}

/// The kinds of SFC element that carry the sequence.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Kind {
    Step,
    Transition,
    Jump,
    /// Divergences and convergences: walked through.
    Branch,
    /// Anything else (action blocks, condition boxes, comments).
    Other,
}

/// The GUID of CODESYS's step attribute naming the step's entry action (run once on activation).
const STEP_ENTRY_ACTION: &str = "a6b08bd8-b696-47e3-9cbf-7408b61c9ff8";
/// The GUID of the step attribute naming its active ("main") action, run while it is active.
const STEP_ACTIVE_ACTION: &str = "700a583f-b4d4-43e4-8c14-629c7cd3bec8";
/// The GUID of the step attribute naming its exit action (run once on deactivation).
const STEP_EXIT_ACTION: &str = "a2621e18-7de3-4ea6-ae6d-89e9e0b7befd";

/// Reads one `<SFC>` element of `pou`.
pub(crate) fn read(
    source: &Source,
    pou: &Pou,
    location: &str,
    sfc: Node,
) -> Result<Chart, SfcError> {
    let mut reader = Reader::new(source, pou, location, sfc)?;
    let links = reader.links()?;
    reader.transitions(&links)?;
    for j in reader.elements.iter().filter(|e| e.name() == "jumpStep") {
        reader.named_step(j.attribute("targetName").unwrap_or(""), j.range().start)?;
    }
    reader.action_blocks()?;
    reader.step_actions();
    reader.chart.ignored_vendor_data = ignored_vendor_data(sfc);
    Ok(reader.chart)
}

/// A chart being read: the `<SFC>` element's children, what each of them is, and the chart so
/// far.
struct Reader<'r, 'a, 'i> {
    source: &'r Source<'r>,
    pou: &'r Pou<'a, 'i>,
    elements: Vec<Node<'a, 'i>>,
    kinds: Vec<Kind>,
    /// Element index by `localId`.
    by_id: HashMap<&'a str, usize>,
    /// Element index -> step index.
    step_of: HashMap<usize, usize>,
    chart: Chart,
}

/// The sequence's links: for each element, the elements it follows (its inputs) and those
/// that follow it (the reverse index).
struct Links {
    inputs: Vec<Vec<usize>>,
    outputs: Vec<Vec<usize>>,
}

impl<'r, 'a, 'i> Reader<'r, 'a, 'i> {
    /// Sorts the chart's elements into kinds, counting the branches and action blocks, and
    /// reads the steps and jumps.
    fn new(
        source: &'r Source<'r>,
        pou: &'r Pou<'a, 'i>,
        location: &str,
        sfc: Node<'a, 'i>,
    ) -> Result<Self, SfcError> {
        let elements: Vec<Node> = sfc.children().collect();
        let mut reader = Reader {
            source,
            pou,
            kinds: Vec::with_capacity(elements.len()),
            by_id: HashMap::with_capacity(elements.len()),
            step_of: HashMap::new(),
            elements,
            chart: Chart {
                pou: pou.name.clone(),
                location: location.to_string(),
                steps: Vec::new(),
                transitions: Vec::new(),
                selection_divergences: 0,
                selection_convergences: 0,
                simultaneous_divergences: 0,
                simultaneous_convergences: 0,
                jumps: Vec::new(),
                action_blocks: 0,
                associations: Vec::new(),
                ignored_vendor_data: Vec::new(),
                step_names: HashMap::new(),
            },
        };
        for i in 0..reader.elements.len() {
            let e = reader.elements[i];
            let kind = reader.kind(e)?;
            if let Some(id) = e.attribute("localId") {
                if reader.by_id.insert(id, i).is_some() && kind != Kind::Other {
                    return Err(reader.err(
                        e.range().start,
                        format!("two elements have localId {id}; every element needs its own id"),
                    ));
                }
            }
            if kind == Kind::Step {
                reader.step(i, e)?;
            }
            if kind == Kind::Jump {
                reader
                    .chart
                    .jumps
                    .push(e.attribute("targetName").unwrap_or("").to_string());
            }
            reader.kinds.push(kind);
        }
        Ok(reader)
    }

    /// A refusal of the chart as drawn, at byte `at`.
    fn err(&self, at: usize, message: String) -> SfcError {
        SfcError::Chart {
            pos: self.source.pos(at),
            pou: self.pou.name.clone(),
            message,
        }
    }

    /// The kind of element `e`, counted in the chart; a macro step is refused.
    fn kind(&mut self, e: Node) -> Result<Kind, SfcError> {
        let chart = &mut self.chart;
        Ok(match e.name() {
            "step" => Kind::Step,
            "transition" => Kind::Transition,
            "jumpStep" => Kind::Jump,
            "selectionDivergence" => {
                chart.selection_divergences += 1;
                Kind::Branch
            }
            "selectionConvergence" => {
                chart.selection_convergences += 1;
                Kind::Branch
            }
            "simultaneousDivergence" => {
                chart.simultaneous_divergences += 1;
                Kind::Branch
            }
            "simultaneousConvergence" => {
                chart.simultaneous_convergences += 1;
                Kind::Branch
            }
            "macroStep" => {
                return Err(SfcError::Unsupported {
                    pos: self.source.pos(e.range().start),
                    pou: self.pou.name.clone(),
                    construct: "a macro step".into(),
                    message: "expand the macro step into its steps in the editor before exporting"
                        .into(),
                })
            }
            "actionBlock" => {
                chart.action_blocks += 1;
                Kind::Other
            }
            _ => Kind::Other,
        })
    }

    /// Adds the step of element `i`: it needs a name of its own.
    fn step(&mut self, i: usize, e: Node) -> Result<(), SfcError> {
        let name = e.attribute("name").unwrap_or("").trim().to_string();
        if name.is_empty() {
            return Err(self.err(
                e.range().start,
                "a step has no name; name every step".into(),
            ));
        }
        if self.chart.step_index(&name).is_some() {
            return Err(self.err(
                e.range().start,
                format!(
                    "two steps are named `{name}` (IEC names are case-insensitive); rename one"
                ),
            ));
        }
        self.step_of.insert(i, self.chart.steps.len());
        self.chart.push_step(Step {
            name,
            initial: e.attribute("initialStep") == Some("true"),
            at: e.range().start,
        });
        Ok(())
    }

    /// The links of the sequence's elements, from their `connectionPointIn`s; a connection to
    /// an id no element has is refused.
    fn links(&self) -> Result<Links, SfcError> {
        let n = self.elements.len();
        let mut links = Links {
            inputs: vec![Vec::new(); n],
            outputs: vec![Vec::new(); n],
        };
        for (i, e) in self.elements.iter().enumerate() {
            if self.kinds[i] == Kind::Other {
                continue;
            }
            for cp in children(*e, "connectionPointIn") {
                for c in children(cp, "connection") {
                    let Some(r) = c.attribute("refLocalId") else {
                        continue;
                    };
                    let Some(&j) = self.by_id.get(r) else {
                        return Err(self.err(
                            c.range().start,
                            format!("a connection refers to localId {r}, which no element of this chart has"),
                        ));
                    };
                    links.inputs[i].push(j);
                    links.outputs[j].push(i);
                }
            }
        }
        Ok(links)
    }

    /// The step that a jump at byte `at` goes to.
    fn named_step(&self, name: &str, at: usize) -> Result<usize, SfcError> {
        self.chart.step_index(name.trim()).ok_or_else(|| {
            self.err(
                at,
                format!("the jump goes to `{name}`, which is no step of this chart; name an existing step"),
            )
        })
    }

    /// Reads every transition with its source and target steps.
    fn transitions(&mut self, links: &Links) -> Result<(), SfcError> {
        // The walks of transition `i` mark what they visit with `2i` and `2i + 1`: no clearing
        // between them.
        let mut seen = vec![u32::MAX; self.elements.len()];
        for i in 0..self.elements.len() {
            if self.kinds[i] != Kind::Transition {
                continue;
            }
            let t = self.transition(i, links, &mut seen)?;
            self.chart.transitions.push(t);
        }
        Ok(())
    }

    /// The transition of element `i`, its walks marking `seen`.
    fn transition(
        &self,
        i: usize,
        links: &Links,
        seen: &mut [u32],
    ) -> Result<Transition, SfcError> {
        let e = self.elements[i];
        let at = e.range().start;
        let mut from = self.sources(i, links, seen)?;
        let mut to = self.targets(i, links, seen)?;
        if from.is_empty() {
            return Err(self.err(
                at,
                "the transition has no source step; connect it below a step".into(),
            ));
        }
        if to.is_empty() {
            return Err(self.err(
                at,
                "the transition has no target; connect a step or a jump below it".into(),
            ));
        }
        // Steps in the order the chart declares them, so the net does not depend on the walk.
        from.sort_unstable();
        to.sort_unstable();
        let x = child(e, "position")
            .and_then(|p| p.attribute("x"))
            .and_then(|x| x.trim().parse::<f64>().ok())
            .filter(|x| x.is_finite())
            .unwrap_or(0.0);
        let condition = condition(self.source, self.pou, &self.elements, &self.by_id, e)?;
        Ok(Transition {
            local_id: e.attribute("localId").unwrap_or("").to_string(),
            name: e.attribute("name").map(str::to_string),
            from,
            to,
            condition,
            x,
            at,
        })
    }

    /// The source steps of transition `i`, walking back through branches.
    fn sources(&self, i: usize, links: &Links, seen: &mut [u32]) -> Result<Vec<usize>, SfcError> {
        // Its own stamp, apart from the targets' walk: a step that is both (a transition back
        // to the step it leaves) is found by both.
        let stamp = 2 * i as u32;
        let mut from = Vec::new();
        let mut stack: Vec<usize> = links.inputs[i].clone();
        while let Some(j) = stack.pop() {
            if seen[j] == stamp {
                continue;
            }
            seen[j] = stamp;
            match self.kinds[j] {
                Kind::Step => push_unique(&mut from, self.step_of[&j]),
                Kind::Branch => stack.extend(links.inputs[j].iter().copied()),
                Kind::Transition | Kind::Jump | Kind::Other => {
                    return Err(self.err(
                        self.elements[i].range().start,
                        format!(
                            "the transition follows a <{}> (localId {}), not a step; a transition must follow steps",
                            self.elements[j].name(),
                            self.elements[j].attribute("localId").unwrap_or("?")
                        ),
                    ))
                }
            }
        }
        Ok(from)
    }

    /// The target steps of transition `i`, walking forward through branches and jumps.
    fn targets(&self, i: usize, links: &Links, seen: &mut [u32]) -> Result<Vec<usize>, SfcError> {
        let stamp = 2 * i as u32 + 1;
        let mut to = Vec::new();
        let mut stack: Vec<usize> = links.outputs[i].clone();
        while let Some(j) = stack.pop() {
            if seen[j] == stamp {
                continue;
            }
            seen[j] = stamp;
            match self.kinds[j] {
                Kind::Step => push_unique(&mut to, self.step_of[&j]),
                Kind::Jump => {
                    let jump = self.elements[j];
                    let target = jump.attribute("targetName").unwrap_or("");
                    push_unique(&mut to, self.named_step(target, jump.range().start)?);
                }
                Kind::Branch => stack.extend(links.outputs[j].iter().copied()),
                Kind::Transition | Kind::Other => {
                    return Err(self.err(
                        self.elements[i].range().start,
                        "the transition is followed by another transition; put a step between them"
                            .into(),
                    ))
                }
            }
        }
        Ok(to)
    }

    /// Reads the action associations of every action block.
    fn action_blocks(&mut self) -> Result<(), SfcError> {
        for e in self.elements.iter().filter(|e| e.name() == "actionBlock") {
            let step = children(*e, "connectionPointIn")
                .flat_map(|cp| children(cp, "connection"))
                .filter_map(|c| self.by_id.get(c.attribute("refLocalId")?).copied())
                .find_map(|j| self.step_of.get(&j).copied());
            let Some(step) = step else {
                return Err(self.err(
                    e.range().start,
                    "the action block is not connected to a step; connect it to one".into(),
                ));
            };
            for a in children(*e, "action") {
                let association = self.association(step, a)?;
                self.chart.associations.push(association);
            }
        }
        Ok(())
    }

    /// One `<action>` of an action block connected to `step`.
    fn association(&self, step: usize, a: Node) -> Result<Association, SfcError> {
        let at = a.range().start;
        let qualifier = match a.attribute("qualifier") {
            None => Qualifier::N,
            Some(q) => Qualifier::parse(q.trim()).ok_or_else(|| {
                self.err(
                    at,
                    format!("unknown action qualifier `{q}`; IEC 61131-3 has N, S, R, P, P0, P1, L, D, SD, DS and SL"),
                )
            })?,
        };
        let action = if let Some(r) = child(a, "reference") {
            ActionRef::Reference(r.attribute("name").unwrap_or("").to_string())
        } else if let Some(lang) = child(a, "inline").and_then(|i| i.children().next()) {
            match (lang.name(), body_text(self.source, lang)) {
                ("ST", Some((text, at))) => ActionRef::Inline(Body::St { text, at }),
                (other, _) => ActionRef::Inline(Body::Other {
                    language: other.to_string(),
                    at: lang.range().start,
                }),
            }
        } else {
            return Err(self.err(
                at,
                "the action names no action and has no inline body; add one".into(),
            ));
        };
        let nonempty = |v: Option<&str>| {
            v.map(str::trim)
                .filter(|s| !s.is_empty())
                .map(str::to_string)
        };
        Ok(Association {
            step,
            qualifier,
            duration: nonempty(a.attribute("duration")),
            indicator: nonempty(a.attribute("indicator")),
            action,
            at,
        })
    }

    /// CODESYS and TwinCAT keep a step's entry, active and exit actions in the step's own
    /// `addData` (`…/plcopenxml/sfc/element`), one attribute each, by GUID, naming an action of
    /// the POU (empty when the step has none). They become P1, N and P0 associations.
    fn step_actions(&mut self) {
        for e in self.elements.iter().filter(|e| e.name() == "step") {
            let Some(&step) = self
                .by_id
                .get(e.attribute("localId").unwrap_or(""))
                .and_then(|i| self.step_of.get(i))
            else {
                continue;
            };
            let attributes = children(*e, "addData")
                .flat_map(|d| children(d, "data"))
                .filter(|d| {
                    d.attribute("name")
                        .is_some_and(|n| n.ends_with("/plcopenxml/sfc/element"))
                })
                .flat_map(|d| children(d, "attributes"))
                .flat_map(|a| children(a, "attribute"));
            for attr in attributes {
                let qualifier = match attr.attribute("guid").map(|g| g.trim_matches(['{', '}'])) {
                    Some(STEP_ENTRY_ACTION) => Qualifier::P1,
                    Some(STEP_ACTIVE_ACTION) => Qualifier::N,
                    Some(STEP_EXIT_ACTION) => Qualifier::P0,
                    _ => continue,
                };
                let name = attr.text().unwrap_or("").trim();
                if name.is_empty() {
                    continue;
                }
                self.chart.associations.push(Association {
                    step,
                    qualifier,
                    duration: None,
                    indicator: None,
                    action: ActionRef::Reference(name.to_string()),
                    at: attr.range().start,
                });
            }
        }
    }
}

/// The vendor data (`addData`) of a chart, by name, with a count: not read, but noted rather
/// than silently dropped.
fn ignored_vendor_data(sfc: Node) -> Vec<(String, usize)> {
    let mut ignored: Vec<(String, usize)> = Vec::new();
    for d in sfc.descendants().filter(|n| n.name() == "data") {
        let name = d.attribute("name").unwrap_or("").to_string();
        match ignored.iter_mut().find(|(n, _)| *n == name) {
            Some((_, c)) => *c += 1,
            None => ignored.push((name, 1)),
        }
    }
    ignored
}

fn push_unique(v: &mut Vec<usize>, x: usize) {
    if !v.contains(&x) {
        v.push(x);
    }
}

/// Reads a transition's condition.
fn condition(
    source: &Source,
    pou: &Pou,
    elements: &[Node],
    by_id: &HashMap<&str, usize>,
    transition: Node,
) -> Result<Condition, SfcError> {
    let at = transition.range().start;
    let unsupported = |form: &str, at: usize| Condition::Unsupported {
        form: form.to_string(),
        at,
    };
    let Some(cond) = child(transition, "condition") else {
        return Err(SfcError::Chart {
            pos: source.pos(at),
            pou: pou.name.clone(),
            message: "the transition has no condition; give it one (TRUE if it should always fire)"
                .into(),
        });
    };
    let Some(form) = cond.children().next() else {
        return Ok(unsupported("an empty condition", cond.range().start));
    };
    let at = form.range().start;
    Ok(match form.name() {
        "inline" => match form.children().next() {
            Some(lang) if lang.name() == "ST" => match body_text(source, lang) {
                Some((text, at)) => Condition::St {
                    text,
                    at,
                    negated: false,
                },
                None => unsupported("an empty inline ST condition", at),
            },
            Some(lang) => unsupported(&format!("an inline {} condition", lang.name()), at),
            None => unsupported("an empty inline condition", at),
        },
        "reference" => {
            let name = form.attribute("name").unwrap_or("");
            match pou.transition(name) {
                Some(t) => match &t.body {
                    // A transition body in ST is `transition_name := expr;` or, as some editors
                    // write it, `:= expr;`: the importer reads the expression (docs/sfc.md).
                    Body::St { text, at } => Condition::St {
                        text: text.clone(),
                        at: *at,
                        negated: false,
                    },
                    Body::Other { language, at } if matches!(language.as_str(), "LD" | "FBD") => {
                        Condition::Network {
                            name: t.name.clone(),
                            language: language.clone(),
                            at: *at,
                        }
                    }
                    Body::Other { language, at } => unsupported(
                        &format!("the {language} body of transition {name}"),
                        *at,
                    ),
                },
                None => {
                    return Err(SfcError::Chart {
                        pos: source.pos(at),
                        pou: pou.name.clone(),
                        message: format!(
                            "the condition refers to transition `{name}`, which the POU does not declare"
                        ),
                    })
                }
            }
        }
        "connectionPointIn" => {
            let target = children(form, "connection")
                .filter_map(|c| by_id.get(c.attribute("refLocalId")?).copied())
                .next();
            match target.map(|j| elements[j]) {
                Some(v) if v.name() == "inVariable" => match child(v, "expression") {
                    Some(e) => Condition::St {
                        text: e.text().unwrap_or("").to_string(),
                        at: e.range().start + "<expression>".len(),
                        negated: v.attribute("negated") == Some("true"),
                    },
                    None => unsupported("an <inVariable> with no expression", v.range().start),
                },
                Some(v) => Condition::Drawn {
                    language: match v.name() {
                        "contact" | "leftPowerRail" | "coil" => "LD",
                        _ => "FBD",
                    }
                    .into(),
                    at,
                },
                None => unsupported("a condition wired to nothing", at),
            }
        }
        other => unsupported(&format!("a <{other}> condition"), at),
    })
}
