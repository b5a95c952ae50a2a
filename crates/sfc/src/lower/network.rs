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

use std::collections::HashMap;

use cetratus_net::xml::{Document, Node};

use super::Written;
use crate::pou::{Pou, Variable};
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
    /// Writes the variables the network needs, then its statements.
    pub fn write(&self, at: usize, out: &mut Written) {
        if !self.instances.is_empty() {
            out.line(at, "VAR");
            for (name, ty) in &self.instances {
                out.line(at, &format!("  {name} : {ty};"));
            }
            out.line(at, "END_VAR");
        }
        if !self.temps.is_empty() {
            out.line(at, "VAR_TEMP");
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

/// Where a connection comes from: an element and, for a block, the output's formal name.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct From {
    id: u64,
    formal: String,
}

/// An input of an element: its formal name (empty for a one-input element), whether it is
/// negated or edge-sensing, and the connections into it (several into one LD input are an OR).
struct Pin {
    formal: String,
    negated: bool,
    edge: Edge,
    from: Vec<From>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Edge {
    None,
    Rising,
    Falling,
}

impl Edge {
    fn of(node: Node) -> Edge {
        match node.attribute("edge") {
            Some("rising") => Edge::Rising,
            Some("falling") => Edge::Falling,
            _ => Edge::None,
        }
    }

    /// The standard function block that senses this edge.
    fn trigger(self) -> Option<&'static str> {
        match self {
            Edge::None => None,
            Edge::Rising => Some("R_TRIG"),
            Edge::Falling => Some("F_TRIG"),
        }
    }
}

/// What an element of the network is.
enum Kind {
    LeftRail,
    Contact {
        var: String,
        negated: bool,
        edge: Edge,
    },
    Coil {
        var: String,
        negated: bool,
        storage: Option<bool>,
        edge: Edge,
    },
    In {
        expr: String,
        negated: bool,
    },
    Out {
        expr: String,
        negated: bool,
    },
    InOut {
        expr: String,
        negated_in: bool,
        negated_out: bool,
    },
    Block {
        ty: String,
        instance: Option<String>,
        outputs: Vec<(String, bool)>,
    },
    Connector {
        name: String,
    },
    Continuation {
        name: String,
    },
    Return,
    /// Drawn but meaning nothing to the program: comments and the right rail.
    Drawing,
}

/// An element with its inputs, position and execution order.
struct Element {
    id: u64,
    at: usize,
    kind: Kind,
    inputs: Vec<Pin>,
    order: u64,
    position: (i64, i64),
}

/// Lowers the LD or FBD body `body` of `pou`.
pub(super) fn lower(
    source: &Source,
    pou: &Pou,
    body: Node,
    names: &Names,
) -> Result<Lowered, SfcError> {
    let fail = |at: usize, construct: String, message: &str| SfcError::Unsupported {
        pos: source.pos(at),
        pou: pou.name.clone(),
        construct,
        message: message.to_string(),
    };
    let mut elements = Vec::new();
    for node in body.children() {
        elements.push(read_element(node).map_err(|(at, c, m)| fail(at, c, &m))?);
    }
    name_block_outputs(&mut elements);
    let order = execution_order(&elements).map_err(|(at, c, m)| fail(at, c, &m))?;
    let mut w = Writer::new(&pou.variables, names, &elements);
    let mut notes = Vec::new();
    for e in &elements {
        let Kind::Block {
            ty,
            instance: Some(instance),
            ..
        } = &e.kind
        else {
            continue;
        };
        let declared = pou
            .variables
            .iter()
            .any(|v| v.name.eq_ignore_ascii_case(instance));
        if !declared
            && !w
                .instances
                .iter()
                .any(|(n, _)| n.eq_ignore_ascii_case(instance))
        {
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
        w.element(&elements[index])
            .map_err(|(at, c, m)| fail(at, c, &m))?;
    }
    let mut lowered = w.finish();
    lowered.notes = notes;
    Ok(lowered)
}

/// Why an element cannot be written: where, the construct, and what to do.
type Refused = (usize, String, String);

/// Reads one element of an LD or FBD body.
fn read_element(node: Node) -> Result<Element, Refused> {
    let at = node.range().start;
    let id = node
        .attribute("localId")
        .and_then(|i| i.parse().ok())
        .unwrap_or(u64::MAX);
    let flag = |name: &str| node.attribute(name) == Some("true");
    let text_of = |name: &str| {
        child(node, name)
            .and_then(|e| {
                e.text()
                    .or_else(|| e.children().next().and_then(|c| c.text()))
            })
            .unwrap_or_default()
            .trim()
            .to_string()
    };
    let single = || connections(child(node, "connectionPointIn"));
    let one_input = |negated| {
        vec![Pin {
            formal: String::new(),
            negated,
            edge: Edge::None,
            from: single(),
        }]
    };
    let (kind, inputs) = match node.name() {
        "leftPowerRail" => (Kind::LeftRail, Vec::new()),
        "rightPowerRail" | "comment" => (Kind::Drawing, Vec::new()),
        "contact" => (
            Kind::Contact { var: text_of("variable"), negated: flag("negated"), edge: Edge::of(node) },
            one_input(false),
        ),
        "coil" => {
            let storage = match node.attribute("storage") {
                Some("set") => Some(true),
                Some("reset") => Some(false),
                _ => None,
            };
            let kind = Kind::Coil { var: text_of("variable"), negated: flag("negated"), storage, edge: Edge::of(node) };
            (kind, one_input(false))
        }
        "inVariable" => (Kind::In { expr: text_of("expression"), negated: flag("negated") }, Vec::new()),
        "outVariable" => (Kind::Out { expr: text_of("expression"), negated: flag("negated") }, one_input(false)),
        "inOutVariable" => (
            Kind::InOut { expr: text_of("expression"), negated_in: flag("negatedIn"), negated_out: flag("negatedOut") },
            one_input(false),
        ),
        "block" => read_block(node)?,
        "connector" => (Kind::Connector { name: node.attribute("name").unwrap_or_default().to_string() }, one_input(false)),
        "continuation" => (Kind::Continuation { name: node.attribute("name").unwrap_or_default().to_string() }, Vec::new()),
        "return" => (Kind::Return, one_input(false)),
        other => {
            return Err((
                at,
                format!("the network element <{other}>"),
                "Structured Text has no jumps or labels: draw the network without them, or write the POU in ST".into(),
            ))
        }
    };
    let position = child(node, "position")
        .map(|p| {
            let c = |a| {
                p.attribute(a)
                    .and_then(|v| v.parse::<f64>().ok())
                    .unwrap_or(0.0) as i64
            };
            (c("y"), c("x"))
        })
        .unwrap_or_default();
    let order = node
        .attribute("executionOrderId")
        .and_then(|o| o.parse().ok())
        .unwrap_or(0);
    Ok(Element {
        id,
        at,
        kind,
        inputs,
        order,
        position,
    })
}

/// A block: its type, instance, inputs (with their negation and edges) and outputs.
fn read_block(node: Node) -> Result<(Kind, Vec<Pin>), Refused> {
    let pins = |section: &str| -> Vec<Node> {
        child(node, section)
            .into_iter()
            .flat_map(|s| children(s, "variable"))
            .collect()
    };
    if pins("inOutVariables")
        .iter()
        .any(|v| !connections(child(*v, "connectionPointIn")).is_empty())
    {
        return Err((
            node.range().start,
            "a block with a connected VAR_IN_OUT".into(),
            "call it from an ST body, where the in-out variable is named".into(),
        ));
    }
    let inputs = pins("inputVariables")
        .into_iter()
        .map(|v| Pin {
            formal: v
                .attribute("formalParameter")
                .unwrap_or_default()
                .to_string(),
            negated: v.attribute("negated") == Some("true"),
            edge: Edge::of(v),
            from: connections(child(v, "connectionPointIn")),
        })
        .collect();
    let outputs = pins("outputVariables")
        .into_iter()
        .map(|v| {
            let formal = v
                .attribute("formalParameter")
                .unwrap_or_default()
                .to_string();
            (formal, v.attribute("negated") == Some("true"))
        })
        .collect();
    let kind = Kind::Block {
        ty: node.attribute("typeName").unwrap_or_default().to_string(),
        instance: node
            .attribute("instanceName")
            .filter(|i| !i.is_empty())
            .map(str::to_string),
        outputs,
    };
    Ok((kind, inputs))
}

/// A connection from a block that names no output reads the block's first output other than ENO
/// (some editors leave the name out when a block has one output).
fn name_block_outputs(elements: &mut [Element]) {
    let first: HashMap<u64, String> = elements
        .iter()
        .filter_map(|e| match &e.kind {
            Kind::Block { outputs, .. } => {
                let o = outputs
                    .iter()
                    .find(|(f, _)| !f.eq_ignore_ascii_case("ENO"))?;
                Some((e.id, o.0.clone()))
            }
            _ => None,
        })
        .collect();
    for from in elements
        .iter_mut()
        .flat_map(|e| e.inputs.iter_mut().flat_map(|p| p.from.iter_mut()))
    {
        if from.formal.is_empty() {
            if let Some(f) = first.get(&from.id) {
                from.formal = f.clone();
            }
        }
    }
}

/// The connections into a `connectionPointIn`.
fn connections(point: Option<Node>) -> Vec<From> {
    point
        .into_iter()
        .flat_map(|p| children(p, "connection"))
        .filter_map(|c| {
            Some(From {
                id: c.attribute("refLocalId")?.parse().ok()?,
                formal: c
                    .attribute("formalParameter")
                    .unwrap_or_default()
                    .to_string(),
            })
        })
        .collect()
}

/// The elements' indices in execution order (see the module's documentation).
fn execution_order(elements: &[Element]) -> Result<Vec<usize>, Refused> {
    let by_id: HashMap<u64, usize> = elements
        .iter()
        .enumerate()
        .map(|(i, e)| (e.id, i))
        .collect();
    let connectors: HashMap<&str, usize> = elements
        .iter()
        .enumerate()
        .filter_map(|(i, e)| match &e.kind {
            Kind::Connector { name } => Some((name.as_str(), i)),
            _ => None,
        })
        .collect();
    let mut deps: Vec<Vec<usize>> = Vec::with_capacity(elements.len());
    for e in elements {
        let mut d = Vec::new();
        for from in e.inputs.iter().flat_map(|p| &p.from) {
            let i = by_id.get(&from.id).ok_or_else(|| {
                (
                    e.at,
                    format!("a connection to element {}", from.id),
                    "the network names an element it does not have; export it again".to_string(),
                )
            })?;
            d.push(*i);
        }
        if let Kind::Continuation { name } = &e.kind {
            let i = connectors.get(name.as_str()).ok_or_else(|| {
                (
                    e.at,
                    format!("the continuation `{name}`"),
                    "it has no connector of that name".to_string(),
                )
            })?;
            d.push(*i);
        }
        deps.push(d);
    }
    let mut roots: Vec<usize> = (0..elements.len()).collect();
    roots.sort_by_key(|&i| {
        let e = &elements[i];
        (e.order == 0, e.order, e.position)
    });
    // Each loop found is cut at an element that holds its value from the scan before, and the
    // walk starts again; a network has few loops, and a bound keeps a hostile one cheap.
    let mut cut = std::collections::HashSet::new();
    for _ in 0..=MAX_LOOPS {
        match walk(elements, &deps, &roots, &cut)? {
            Walk::Order(order) => return Ok(order),
            Walk::Cut(reader, held) => {
                cut.insert((reader, held));
            }
        }
    }
    Err((
        elements.first().map_or(0, |e| e.at),
        format!("a network with more than {MAX_LOOPS} feedback loops"),
        "split it into several networks or POUs".into(),
    ))
}

/// Most feedback loops one network may have.
const MAX_LOOPS: usize = 256;

/// What a walk of [`execution_order`] found.
enum Walk {
    /// Every element after what it reads.
    Order(Vec<usize>),
    /// A loop, to cut where `reader` reads `held`, which holds the scan before's value.
    Cut(usize, usize),
}

/// The depth-first walk of [`execution_order`]: each element after what it reads (less the cut
/// reads), from the roots in their order; a loop found is returned to be cut, or refused when no
/// element on it holds the scan before's value.
fn walk(
    elements: &[Element],
    deps: &[Vec<usize>],
    roots: &[usize],
    cut: &std::collections::HashSet<(usize, usize)>,
) -> Result<Walk, Refused> {
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        New,
        Open,
        Done,
    }
    let mut mark = vec![Mark::New; elements.len()];
    let mut order = Vec::with_capacity(elements.len());
    let mut stack: Vec<(usize, usize)> = Vec::new();
    for &root in roots {
        if mark[root] != Mark::New {
            continue;
        }
        mark[root] = Mark::Open;
        stack.push((root, 0));
        while let Some(top) = stack.last_mut() {
            let (i, next) = *top;
            let Some(&d) = deps[i].get(next) else {
                stack.pop();
                mark[i] = Mark::Done;
                order.push(i);
                continue;
            };
            top.1 += 1;
            if cut.contains(&(i, d)) {
                continue;
            }
            match mark[d] {
                Mark::New => {
                    mark[d] = Mark::Open;
                    stack.push((d, 0));
                }
                Mark::Open => return loop_cut(elements, &stack, d),
                Mark::Done => {}
            }
        }
    }
    Ok(Walk::Order(order))
}

/// Where to cut the loop that the walk's `stack` closes at `d`: the read of an element on it
/// that holds the scan before's value.
fn loop_cut(elements: &[Element], stack: &[(usize, usize)], d: usize) -> Result<Walk, Refused> {
    let from = stack.iter().rposition(|&(i, _)| i == d).unwrap_or(0);
    let on_loop: Vec<usize> = stack[from..].iter().map(|&(i, _)| i).collect();
    for (k, &held) in on_loop.iter().enumerate() {
        if holds_last_value(&elements[held]) {
            // Each element on the stack reads the one above it; the last reads `d`.
            let reader = if k == 0 {
                on_loop[on_loop.len() - 1]
            } else {
                on_loop[k - 1]
            };
            return Ok(Walk::Cut(reader, held));
        }
    }
    Err((
        elements[d].at,
        format!("a loop in the network through element {}", elements[d].id),
        "a feedback loop must pass through a function block instance or an in-out variable, which holds the value of the scan before".into(),
    ))
}

/// Whether a loop may pass through an element: its output keeps the scan before's value.
fn holds_last_value(e: &Element) -> bool {
    matches!(
        e.kind,
        Kind::InOut { .. }
            | Kind::Block {
                instance: Some(_),
                ..
            }
    )
}

/// A value computed by an element, as the elements that read it see it.
#[derive(Clone)]
struct Value {
    /// The expression (an atom, or parenthesized).
    expr: String,
    /// Its type, when the network can tell.
    ty: Option<String>,
    /// How deeply its expression nests.
    depth: usize,
    /// The statement slot where it could be kept in a temporary, and whether it is already.
    slot: Option<usize>,
}

/// How deeply an expression may nest before it is kept in a temporary.
const MAX_DEPTH: usize = 8;

/// Writes the elements of one network, in order.
struct Writer<'n> {
    /// The POU's interface.
    variables: &'n [Variable],
    names: &'n Names,
    by_id: HashMap<u64, &'n Element>,
    /// How many inputs read each output.
    readers: HashMap<From, usize>,
    values: HashMap<From, Value>,
    connectors: HashMap<String, Value>,
    /// Statements; `None` is a place kept for a temporary that no reader asked for.
    stmts: Vec<(usize, Option<String>)>,
    temps: Vec<(String, String)>,
    instances: Vec<(String, String)>,
}

impl<'n> Writer<'n> {
    fn new(variables: &'n [Variable], names: &'n Names, elements: &'n [Element]) -> Self {
        let mut readers = HashMap::new();
        for from in elements
            .iter()
            .flat_map(|e| e.inputs.iter().flat_map(|p| &p.from))
        {
            *readers.entry(from.clone()).or_insert(0) += 1;
        }
        Writer {
            variables,
            names,
            by_id: elements.iter().map(|e| (e.id, e)).collect(),
            readers,
            values: HashMap::new(),
            connectors: HashMap::new(),
            stmts: Vec::new(),
            temps: Vec::new(),
            instances: Vec::new(),
        }
    }

    fn finish(self) -> Lowered {
        Lowered {
            stmts: self
                .stmts
                .into_iter()
                .filter_map(|(at, s)| Some((at, s?)))
                .collect(),
            temps: self.temps,
            instances: self.instances,
            notes: Vec::new(),
        }
    }

    fn push(&mut self, at: usize, stmt: String) {
        self.stmts.push((at, Some(stmt)));
    }

    /// Writes one element.
    fn element(&mut self, e: &Element) -> Result<(), Refused> {
        let out = |formal: &str| From {
            id: e.id,
            formal: formal.to_string(),
        };
        match &e.kind {
            Kind::LeftRail => {
                let on = Value {
                    expr: "TRUE".into(),
                    ty: Some("BOOL".into()),
                    depth: 0,
                    slot: None,
                };
                for f in self
                    .readers
                    .keys()
                    .filter(|f| f.id == e.id)
                    .cloned()
                    .collect::<Vec<_>>()
                {
                    self.values.insert(f, on.clone());
                }
            }
            Kind::Contact { var, negated, edge } => {
                let power = self.input(e, 0)?;
                let term = match edge.trigger() {
                    Some(fb) => format!("{}.Q", self.trigger(e, "", fb, var)),
                    None if *negated => format!("NOT {var}"),
                    None => var.clone(),
                };
                let expr = if power.expr == "TRUE" {
                    term
                } else {
                    format!("{} AND {term}", power.expr)
                };
                self.keep(e, out(""), expr, Some("BOOL".into()), power.depth + 1);
            }
            Kind::Coil {
                var,
                negated,
                storage,
                edge,
            } => {
                let power = self.input(e, 0)?;
                self.coil(e, var, &power, *negated, *storage, *edge);
                self.values.insert(out(""), power);
            }
            Kind::In { expr, negated } => {
                let ty = self.type_of_expression(expr);
                let expr = if *negated {
                    format!("NOT {expr}")
                } else {
                    expr.clone()
                };
                self.keep(e, out(""), expr, ty, 1);
            }
            Kind::Out { expr, negated }
            | Kind::InOut {
                expr,
                negated_in: negated,
                ..
            } => {
                let value = self.input(e, 0)?;
                let v = if *negated {
                    format!("NOT {}", value.expr)
                } else {
                    value.expr
                };
                self.push(e.at, format!("{expr} := {v};"));
                if let Kind::InOut { negated_out, .. } = &e.kind {
                    let read = if *negated_out {
                        format!("NOT {expr}")
                    } else {
                        expr.clone()
                    };
                    let ty = self.type_of_expression(expr);
                    self.values.insert(
                        out(""),
                        Value {
                            expr: read,
                            ty,
                            depth: 1,
                            slot: None,
                        },
                    );
                }
            }
            Kind::Block {
                ty,
                instance,
                outputs,
            } => self.block(e, ty, instance.as_deref(), outputs)?,
            Kind::Connector { name } => {
                let value = self.input(e, 0)?;
                self.connectors.insert(name.to_ascii_uppercase(), value);
            }
            Kind::Continuation { name } => {
                let value = self
                    .connectors
                    .get(&name.to_ascii_uppercase())
                    .cloned()
                    .ok_or_else(|| {
                        (
                            e.at,
                            format!("the continuation `{name}`"),
                            "its connector is not written before it".to_string(),
                        )
                    })?;
                self.values.insert(out(""), value);
            }
            Kind::Return => {
                let power = self.input(e, 0)?;
                self.push(e.at, format!("IF {} THEN RETURN; END_IF;", power.expr));
            }
            Kind::Drawing => {}
        }
        Ok(())
    }

    /// An LD coil: the variable follows the power, or its negation, its rising or falling edge,
    /// or is set or reset by it.
    fn coil(
        &mut self,
        e: &Element,
        var: &str,
        power: &Value,
        negated: bool,
        storage: Option<bool>,
        edge: Edge,
    ) {
        let p = &power.expr;
        let stmt = match (storage, edge.trigger()) {
            (Some(set), _) => {
                let v = if set { "TRUE" } else { "FALSE" };
                format!("IF {p} THEN {var} := {v}; END_IF;")
            }
            (None, Some(fb)) => {
                let t = self.trigger(e, "", fb, p);
                format!("{var} := {t}.Q;")
            }
            (None, None) if negated => format!("{var} := NOT {p};"),
            (None, None) => format!("{var} := {p};"),
        };
        self.push(e.at, stmt);
    }

    /// Calls an edge detector of element `e` (input `formal`) on `clk`; its instance name.
    fn trigger(&mut self, e: &Element, formal: &str, fb: &'static str, clk: &str) -> String {
        let name = if formal.is_empty() {
            format!("_t{}", e.id)
        } else {
            format!("_t{}_{formal}", e.id)
        };
        self.instances.push((name.clone(), fb.to_string()));
        self.push(e.at, format!("{name}(CLK := {clk});"));
        name
    }

    /// The value of the `index`th input of `e`: its connections ORed, negated or
    /// edge-sensed as drawn.
    fn input(&mut self, e: &Element, index: usize) -> Result<Value, Refused> {
        let pin = &e.inputs[index];
        let mut parts = Vec::new();
        for from in &pin.from {
            parts.push(self.read(e, from)?);
        }
        let mut value = match parts.len() {
            0 => {
                return Err((
                    e.at,
                    format!("element {} with an input connected to nothing", e.id),
                    "connect it, or delete the element".into(),
                ))
            }
            1 => parts.remove(0),
            _ => Value {
                expr: format!(
                    "({})",
                    parts
                        .iter()
                        .map(|p| p.expr.as_str())
                        .collect::<Vec<_>>()
                        .join(" OR ")
                ),
                ty: Some("BOOL".into()),
                depth: parts.iter().map(|p| p.depth).max().unwrap_or(0) + 1,
                slot: None,
            },
        };
        if let Some(fb) = pin.edge.trigger() {
            let t = self.trigger(e, &pin.formal, fb, &value.expr);
            value = Value {
                expr: format!("{t}.Q"),
                ty: Some("BOOL".into()),
                depth: 1,
                slot: None,
            };
        }
        if pin.negated {
            value = Value {
                expr: format!("(NOT {})", value.expr),
                depth: value.depth + 1,
                ..value
            };
        }
        Ok(value)
    }

    /// What reader `e` reads from `from`: the value written, kept in a temporary if others read it
    /// too or a statement came between; or, across a loop, the output as the scan before left it.
    fn read(&mut self, e: &Element, from: &From) -> Result<Value, Refused> {
        let Some(value) = self.values.get(from).cloned() else {
            return self.last_value(e, from);
        };
        let Some(slot) = value.slot else {
            return Ok(value);
        };
        let shared = self.readers.get(from).copied().unwrap_or(0) > 1;
        let moved = slot + 1 != self.stmts.len();
        if !shared && !moved && value.depth <= MAX_DEPTH {
            return Ok(value);
        }
        let Some(ty) = value.ty.clone() else {
            if shared {
                return Err((e.at, format!("the output of element {} read by several elements", from.id), "the importer cannot tell its type; wire it to a variable and read the variable".into()));
            }
            return Ok(value);
        };
        let name = format!(
            "_v{}{}",
            from.id,
            if from.formal.is_empty() {
                String::new()
            } else {
                format!("_{}", from.formal)
            }
        );
        self.temps.push((name.clone(), ty.clone()));
        self.stmts[slot].1 = Some(format!("{name} := {};", value.expr));
        let kept = Value {
            expr: name,
            ty: Some(ty),
            depth: 0,
            slot: None,
        };
        self.values.insert(from.clone(), kept.clone());
        Ok(kept)
    }

    /// An output read before its element runs (a loop): an instance's output or an in-out
    /// variable, as the scan before left it.
    fn last_value(&self, e: &Element, from: &From) -> Result<Value, Refused> {
        let source = self.by_id.get(&from.id).ok_or_else(|| {
            (
                e.at,
                format!("a connection to element {}", from.id),
                "export the network again".to_string(),
            )
        })?;
        let expr = match &source.kind {
            Kind::Block {
                instance: Some(i), ..
            } => format!("{i}.{}", from.formal),
            Kind::InOut { expr, .. } => expr.clone(),
            _ => {
                return Err((
                    e.at,
                    format!("element {} read before it runs", from.id),
                    "draw the network without the loop".into(),
                ))
            }
        };
        let ty = self.type_of_expression(&expr);
        Ok(Value {
            expr,
            ty,
            depth: 0,
            slot: None,
        })
    }

    /// Records the value of an output, with a place kept for a temporary before what follows.
    fn keep(&mut self, e: &Element, out: From, expr: String, ty: Option<String>, depth: usize) {
        let atom = is_atom(&expr);
        let expr = if atom { expr } else { format!("({expr})") };
        let slot = if atom {
            None
        } else {
            self.stmts.push((e.at, None));
            Some(self.stmts.len() - 1)
        };
        self.values.insert(
            out,
            Value {
                expr,
                ty,
                depth,
                slot,
            },
        );
    }

    /// A function block call, or a function's value.
    fn block(
        &mut self,
        e: &Element,
        ty: &str,
        instance: Option<&str>,
        outputs: &[(String, bool)],
    ) -> Result<(), Refused> {
        let mut en = None;
        let mut args = Vec::new();
        for (index, pin) in e.inputs.iter().enumerate() {
            if pin.from.is_empty() {
                continue;
            }
            let value = self.input(e, index)?;
            if pin.formal.eq_ignore_ascii_case("EN") {
                en = Some(value);
            } else {
                args.push((pin.formal.clone(), value));
            }
        }
        let en = match en {
            Some(v) if v.expr != "TRUE" => {
                let name = format!("_en{}", e.id);
                self.temps.push((name.clone(), "BOOL".into()));
                self.push(e.at, format!("{name} := {};", v.expr));
                Some(name)
            }
            _ => None,
        };
        let guarded = |s: String| match &en {
            Some(en) => format!("IF {en} THEN {s} END_IF;"),
            None => s,
        };
        let eno = Value {
            expr: en.clone().unwrap_or_else(|| "TRUE".into()),
            ty: Some("BOOL".into()),
            depth: 0,
            slot: None,
        };
        let out = |formal: &str| From {
            id: e.id,
            formal: formal.to_string(),
        };
        if let Some(instance) = instance {
            let call = args
                .iter()
                .map(|(f, v)| format!("{f} := {}", v.expr))
                .collect::<Vec<_>>()
                .join(", ");
            self.push(e.at, guarded(format!("{instance}({call});")));
            for (formal, negated) in outputs {
                if formal.eq_ignore_ascii_case("ENO") {
                    self.values.insert(out(formal), eno.clone());
                    continue;
                }
                let o = format!("{instance}.{formal}");
                let ty = self.output_type(ty, formal);
                let expr = if *negated { format!("(NOT {o})") } else { o };
                self.values.insert(
                    out(formal),
                    Value {
                        expr,
                        ty,
                        depth: 1,
                        slot: None,
                    },
                );
            }
            return Ok(());
        }
        let result_ty = self.result_type(ty, &args);
        let expr = function_expr(
            ty,
            &args,
            self.names.functions.contains_key(&ty.to_ascii_uppercase()),
        );
        let depth = args.iter().map(|(_, v)| v.depth).max().unwrap_or(0) + 1;
        for (formal, negated) in outputs {
            if formal.eq_ignore_ascii_case("ENO") {
                self.values.insert(out(formal), eno.clone());
                continue;
            }
            let expr = if *negated {
                format!("NOT {expr}")
            } else {
                expr.clone()
            };
            match &en {
                Some(_) => {
                    let t = result_ty.clone().ok_or_else(|| {
                        (
                            e.at,
                            format!("the {ty} block with EN"),
                            "the importer cannot tell its type; wire its output to a variable"
                                .to_string(),
                        )
                    })?;
                    let name = format!("_v{}_{formal}", e.id);
                    self.temps.push((name.clone(), t.clone()));
                    self.push(e.at, guarded(format!("{name} := {expr};")));
                    self.values.insert(
                        out(formal),
                        Value {
                            expr: name,
                            ty: Some(t),
                            depth: 0,
                            slot: None,
                        },
                    );
                }
                None => self.keep(e, out(formal), expr, result_ty.clone(), depth),
            }
        }
        Ok(())
    }

    /// The type of output `formal` of a function block type, when known.
    fn output_type(&self, fb: &str, formal: &str) -> Option<String> {
        let outs = self.names.fb_outputs.get(&fb.to_ascii_uppercase())?;
        outs.iter()
            .find(|(o, _)| o.eq_ignore_ascii_case(formal))
            .map(|(_, t)| t.clone())
    }

    /// The type of what the function `f` returns, for the arguments given, when known.
    fn result_type(&self, f: &str, args: &[(String, Value)]) -> Option<String> {
        let upper = f.to_ascii_uppercase();
        if let Some(ret) = self.names.functions.get(&upper) {
            return Some(ret.clone());
        }
        if let Some((_, to)) = upper.split_once("_TO_") {
            return Some(to.to_string());
        }
        let known = |skip: usize| args.iter().skip(skip).find_map(|(_, v)| v.ty.clone());
        match upper.as_str() {
            "GT" | "GE" | "EQ" | "LE" | "LT" | "NE" => Some("BOOL".into()),
            "LEN" | "FIND" => Some("INT".into()),
            "TRUNC" => Some("DINT".into()),
            "LEFT" | "RIGHT" | "MID" | "CONCAT" | "INSERT" | "DELETE" | "REPLACE" => {
                Some("STRING".into())
            }
            "SEL" | "MUX" | "LIMIT" => known(1),
            _ => known(0),
        }
    }

    /// The type of a variable's expression in this POU, when it is a name the POU or the
    /// configuration declares, a member of an instance, or a typed literal.
    fn type_of_expression(&self, expr: &str) -> Option<String> {
        let e = expr.trim();
        let upper = e.to_ascii_uppercase();
        if upper == "TRUE" || upper == "FALSE" {
            return Some("BOOL".into());
        }
        if let Some((prefix, _)) = upper.split_once('#') {
            return match prefix {
                "T" | "TIME" => Some("TIME".into()),
                p if p.chars().all(|c| c.is_ascii_alphabetic()) => Some(p.to_string()),
                _ => None,
            };
        }
        let declared = |name: &str| {
            let key = name.to_ascii_uppercase();
            self.variables
                .iter()
                .find(|v| v.name.eq_ignore_ascii_case(name))
                .map(|v| v.ty.clone())
                .or_else(|| self.names.globals.get(&key).cloned())
        };
        match e.split_once('.') {
            Some((instance, member)) => self.output_type(&declared(instance)?, member),
            None if is_name(e) => declared(e).filter(|t| t != "array" && t != "struct"),
            None => None,
        }
    }
}

/// The expression of a function block of type `f` on `args`: the ST operator where there is
/// one, else a call (formal for the file's own functions, informal for the standard ones).
fn function_expr(f: &str, args: &[(String, Value)], own: bool) -> String {
    let values: Vec<&str> = args.iter().map(|(_, v)| v.expr.as_str()).collect();
    let infix = match f.to_ascii_uppercase().as_str() {
        "ADD" => Some("+"),
        "SUB" => Some("-"),
        "MUL" => Some("*"),
        "DIV" => Some("/"),
        "MOD" => Some("MOD"),
        "EXPT" => Some("**"),
        "AND" => Some("AND"),
        "OR" => Some("OR"),
        "XOR" => Some("XOR"),
        "GT" => Some(">"),
        "GE" => Some(">="),
        "EQ" => Some("="),
        "LE" => Some("<="),
        "LT" => Some("<"),
        "NE" => Some("<>"),
        _ => None,
    };
    let compare = matches!(infix, Some(">" | ">=" | "=" | "<=" | "<" | "<>"));
    match (f.to_ascii_uppercase().as_str(), infix) {
        ("NOT", _) if values.len() == 1 => format!("NOT {}", values[0]),
        ("MOVE", _) if values.len() == 1 => values[0].to_string(),
        (_, Some(op)) if compare && values.len() > 2 => {
            // An extensible comparison holds when each pair in turn does.
            let pairs: Vec<String> = values
                .windows(2)
                .map(|w| format!("({} {op} {})", w[0], w[1]))
                .collect();
            pairs.join(" AND ")
        }
        (_, Some(op)) if values.len() >= 2 => values.join(&format!(" {op} ")),
        _ if own => {
            let formal: Vec<String> = args
                .iter()
                .map(|(f, v)| format!("{f} := {}", v.expr))
                .collect();
            format!("{f}({})", formal.join(", "))
        }
        _ => format!("{f}({})", values.join(", ")),
    }
}

/// Whether an expression needs no parentheses where it is used: a name, a member, a literal.
fn is_atom(expr: &str) -> bool {
    !expr.is_empty()
        && expr
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '#' | '%'))
}

/// Whether a text is a plain IEC identifier.
fn is_name(text: &str) -> bool {
    text.chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && text.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}
