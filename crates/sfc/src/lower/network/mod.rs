//! An LD or FBD body as the Structured Text statements its network means (docs/st.md, *LD and
//! FBD*).
//!
//! Every element is read with the elements it reads from. They run in execution order: by
//! `executionOrderId` where the editor wrote one, else top to bottom and left to right, and
//! always after the elements whose outputs they read (data-flow order, found by a depth-first
//! walk with a stack of its own, so no recursion follows the input's depth). A loop in the
//! network must pass through a function block instance or an in-out variable, whose output then
//! holds the value of the scan before, as IEC 61131-3 says of feedback; another loop is refused.
//!
//! A value that one element reads is written into the reader's expression; a value that several
//! read, or that is read after a statement could have changed what it depends on, is kept in a
//! VAR_TEMP of the POU at the place its element runs, so that every element reads what the
//! network computed at its own place in the order.

mod element;
mod order;
mod writer;

use element::{name_block_outputs, read_element, Element, Kind};
use order::execution_order;
use writer::Writer;

use std::collections::{HashMap, HashSet};

use cetratus_net::xml::{Document, Node};

use super::Written;
use crate::pou::Pou;
use crate::source::{child, children, Source};
use crate::SfcError;

/// The types that a network needs to know for the values it keeps: the outputs of function
/// blocks, the return types of functions, and the global variables.
pub(crate) struct Names {
    /// Per function block type (upper case), its outputs (upper case) with their types.
    fb_outputs: HashMap<String, Vec<(String, String)>>,
    /// Per function (upper case), its return type.
    functions: HashMap<String, String>,
    /// The global variables of the configurations (upper case), with their types.
    globals: HashMap<String, String>,
}

/// The outputs of the standard function blocks, with their types.
const STANDARD_FB_OUTPUTS: &[(&str, &[(&str, &str)])] = &[
    ("TON", &[("Q", "BOOL"), ("ET", "TIME")]),
    ("TOF", &[("Q", "BOOL"), ("ET", "TIME")]),
    ("TP", &[("Q", "BOOL"), ("ET", "TIME")]),
    ("CTU", &[("Q", "BOOL"), ("CV", "INT")]),
    ("CTD", &[("Q", "BOOL"), ("CV", "INT")]),
    ("CTUD", &[("QU", "BOOL"), ("QD", "BOOL"), ("CV", "INT")]),
    ("R_TRIG", &[("Q", "BOOL")]),
    ("F_TRIG", &[("Q", "BOOL")]),
    ("SR", &[("Q1", "BOOL")]),
    ("RS", &[("Q1", "BOOL")]),
];

impl Names {
    /// The names of a file's POUs and configurations.
    pub fn of(doc: &Document, pous: &[Pou]) -> Names {
        let mut fb_outputs: HashMap<String, Vec<(String, String)>> = STANDARD_FB_OUTPUTS
            .iter()
            .map(|(fb, outs)| {
                let outs = outs.iter().map(|(o, t)| (o.to_string(), t.to_string()));
                (fb.to_string(), outs.collect())
            })
            .collect();
        let mut functions = HashMap::new();
        for p in pous {
            let key = p.name.to_ascii_uppercase();
            match p.node.attribute("pouType") {
                Some("function") => {
                    let ret = child(p.node, "interface")
                        .and_then(|i| child(i, "returnType"))
                        .and_then(|r| r.children().next())
                        .map(elementary_or_derived);
                    if let Some(ret) = ret {
                        functions.insert(key, ret);
                    }
                }
                _ => {
                    let outs = p
                        .variables
                        .iter()
                        .filter(|v| v.kind == crate::VarKind::Output);
                    let outs = outs.map(|v| (v.name.to_ascii_uppercase(), v.ty.clone()));
                    fb_outputs.insert(key, outs.collect());
                }
            }
        }
        let globals = doc
            .root_element()
            .descendants()
            .filter(|n| n.name() == "globalVars")
            .flat_map(|g| children(g, "variable"))
            .filter_map(|v| {
                let ty = child(v, "type")?
                    .children()
                    .next()
                    .map(elementary_or_derived)?;
                Some((v.attribute("name")?.to_ascii_uppercase(), ty))
            })
            .collect();
        Names {
            fb_outputs,
            functions,
            globals,
        }
    }
}

/// The name of an elementary (`<INT/>`) or derived (`<derived name="T"/>`) type element.
fn elementary_or_derived(t: Node) -> String {
    match t.name() {
        "derived" => t.attribute("name").unwrap_or_default().to_string(),
        "string" => "STRING".into(),
        other => other.to_string(),
    }
}

/// Lines each at the byte offset of the file they come from: statements, or notes.
pub(crate) type Placed = Vec<(usize, String)>;

/// A network written as Structured Text.
pub(super) struct Lowered {
    /// The statements, in order, each with the byte offset of the element it comes from.
    stmts: Vec<(usize, String)>,
    /// The values kept between elements (VAR_TEMP): name and type.
    temps: Vec<(String, String)>,
    /// The function block instances the network adds (VAR): the edge detectors of edge
    /// contacts, coils and block inputs, and the blocks' instances that the interface does not
    /// declare. Name and type.
    instances: Vec<(String, String)>,
    /// What the importer added that the file did not say: where, and what.
    pub notes: Vec<(usize, String)>,
}

impl Lowered {
    /// The statements, and the declarations the network needs (`name : type`): the instances
    /// it adds, then the values it keeps.
    pub fn into_parts(self) -> (Placed, Vec<String>, Placed) {
        let decls = (self.instances.iter().chain(&self.temps))
            .map(|(name, ty)| format!("{name} : {ty}"))
            .collect();
        (self.stmts, decls, self.notes)
    }

    /// Writes the variables the network needs, then its statements. In a FUNCTION the values
    /// kept between elements are its VAR, which a function starts afresh at every call: IEC has
    /// no VAR_TEMP in a FUNCTION, and MATIEC refuses one.
    pub fn write(&self, at: usize, out: &mut Written, function: bool) {
        if !self.instances.is_empty() {
            out.line(at, "VAR");
            for (name, ty) in &self.instances {
                out.line(at, &format!("  {name} : {ty};"));
            }
            out.line(at, "END_VAR");
        }
        if !self.temps.is_empty() {
            out.line(at, if function { "VAR" } else { "VAR_TEMP" });
            for (name, ty) in &self.temps {
                out.line(at, &format!("  {name} : {ty};"));
            }
            out.line(at, "END_VAR");
        }
        for (at, s) in &self.stmts {
            out.line(*at, s);
        }
    }
}

/// Lowers the LD or FBD body `body` of `pou`. With `renamed` `(name, id)`, the body of the
/// named transition `name`, whose network assigns its value to `name`, assigns it to the
/// transition `id` that refers to it instead: the form a condition written as statements takes
/// (`id := …;`).
pub(super) fn lower(
    source: &Source,
    pou: &Pou,
    body: Node,
    names: &Names,
    renamed: Option<(&str, &str)>,
) -> Result<Lowered, SfcError> {
    let mut elements = Vec::new();
    for node in body.children() {
        let mut e = read_element(node).map_err(refusal(source, pou))?;
        if let (Kind::Out { expr, .. }, Some((name, id))) = (&mut e.kind, renamed) {
            if expr.eq_ignore_ascii_case(name) {
                *expr = id.to_string();
            }
        }
        elements.push(e);
    }
    lower_elements(source, pou, elements, names)
}

/// The elements of an SFC body that are the chart's own, not a network's.
const SFC_ELEMENTS: &[&str] = &[
    "step",
    "macroStep",
    "transition",
    "selectionDivergence",
    "selectionConvergence",
    "simultaneousDivergence",
    "simultaneousConvergence",
    "jumpStep",
    "actionBlock",
];

/// The network elements drawn in a chart (the elements of its body that are not the chart's
/// own), read once for all the conditions they feed, with the indexes that find what an element
/// reads from: an element by its id, and the connectors by their names (upper case).
pub(super) struct Drawn {
    elements: Vec<Element>,
    by_id: HashMap<u64, Vec<usize>>,
    connectors: HashMap<String, Vec<u64>>,
}

impl Drawn {
    /// The network elements of the chart `sfc`, or the first that cannot be written.
    pub(super) fn read(sfc: Node) -> Result<Drawn, Refused> {
        let mut drawn = Drawn {
            elements: Vec::new(),
            by_id: HashMap::new(),
            connectors: HashMap::new(),
        };
        let nodes = sfc.children().filter(|n| !SFC_ELEMENTS.contains(&n.name()));
        for (index, node) in nodes.enumerate() {
            let e = read_element(node)?;
            drawn.by_id.entry(e.id).or_default().push(index);
            if let Kind::Connector { name } = &e.kind {
                let key = name.to_ascii_uppercase();
                drawn.connectors.entry(key).or_default().push(e.id);
            }
            drawn.elements.push(e);
        }
        Ok(drawn)
    }

    /// The elements that `from` reads, directly or through others, in the order drawn.
    fn feeding(&self, from: &[element::From]) -> Vec<Element> {
        let mut wanted: Vec<u64> = from.iter().map(|f| f.id).collect();
        let (mut seen, mut kept) = (std::collections::HashSet::new(), Vec::new());
        while let Some(id) = wanted.pop() {
            if !seen.insert(id) {
                continue;
            }
            for &index in self.by_id.get(&id).into_iter().flatten() {
                let e = &self.elements[index];
                kept.push(index);
                wanted.extend(e.inputs.iter().flat_map(|p| p.from.iter().map(|f| f.id)));
                if let Kind::Continuation { name } = &e.kind {
                    let key = name.to_ascii_uppercase();
                    wanted.extend(self.connectors.get(&key).into_iter().flatten());
                }
            }
        }
        kept.sort_unstable();
        kept.into_iter().map(|i| self.elements[i].clone()).collect()
    }
}

/// The network drawn in a chart (`drawn`) that feeds a transition's condition through
/// `condition` (its `<connectionPointIn>`): the network elements that the condition reads,
/// directly or through others, ending in `result := …;`.
pub(super) fn lower_condition(
    source: &Source,
    pou: &Pou,
    (drawn, condition): (&Drawn, Node),
    result: &str,
    names: &Names,
) -> Result<Lowered, SfcError> {
    let from = element::connections(Some(condition));
    let mut elements = drawn.feeding(&from);
    elements.push(Element {
        id: u64::MAX - 1,
        at: condition.range().start,
        kind: Kind::Out {
            expr: result.to_string(),
            negated: false,
        },
        inputs: vec![element::Pin {
            formal: String::new(),
            negated: false,
            edge: element::Edge::None,
            from,
        }],
        order: 0,
        // Last in the order of the drawing: below and right of every element.
        position: (i64::MAX, i64::MAX),
    });
    lower_elements(source, pou, elements, names)
}

/// Lowers the elements of one network.
fn lower_elements(
    source: &Source,
    pou: &Pou,
    mut elements: Vec<Element>,
    names: &Names,
) -> Result<Lowered, SfcError> {
    name_block_outputs(&mut elements);
    let order = execution_order(&elements).map_err(refusal(source, pou))?;
    let mut w = Writer::new(pou, names, &elements);
    let (mut notes, mut added) = (Vec::new(), HashSet::new());
    for e in &elements {
        let Kind::Block {
            ty,
            instance: Some(instance),
            ..
        } = &e.kind
        else {
            continue;
        };
        if pou.variable(instance).is_none() && added.insert(instance.to_ascii_uppercase()) {
            w.instances.push((instance.clone(), ty.clone()));
            notes.push((
                e.at,
                format!(
                    "the block instance `{instance}` ({ty}) is not declared in `{}`'s interface: declared as a VAR",
                    pou.name
                ),
            ));
        }
    }
    for index in order {
        w.element(&elements[index]).map_err(refusal(source, pou))?;
    }
    let mut lowered = w.finish();
    lowered.notes = notes;
    Ok(lowered)
}

/// Why an element cannot be written: where, the construct, and what to do.
pub(super) type Refused = (usize, String, String);

/// A [`Refused`] element of `pou`'s network as the importer's error, at its place in the file.
pub(super) fn refusal<'a>(source: &'a Source, pou: &'a Pou) -> impl Fn(Refused) -> SfcError + 'a {
    move |(at, construct, message)| SfcError::Unsupported {
        pos: source.pos(at),
        pou: pou.name.clone(),
        construct,
        message,
    }
}
