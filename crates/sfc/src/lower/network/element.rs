//! The elements of a network as drawn: what each is, its inputs and where they come from.

use std::collections::HashMap;

use cetratus_net::xml::Node;

use super::Refused;
use crate::source::{child, children};

/// Where a connection comes from: an element and, for a block, the output's formal name.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(super) struct From {
    pub(super) id: u64,
    pub(super) formal: String,
}

/// An input of an element: its formal name (empty for a one-input element), whether it is
/// negated or edge-sensing, and the connections into it (several into one LD input are an OR).
#[derive(Clone)]
pub(super) struct Pin {
    pub(super) formal: String,
    pub(super) negated: bool,
    pub(super) edge: Edge,
    pub(super) from: Vec<From>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Edge {
    None,
    Rising,
    Falling,
}

impl Edge {
    pub(super) fn of(node: Node) -> Edge {
        match node.attribute("edge") {
            Some("rising") => Edge::Rising,
            Some("falling") => Edge::Falling,
            _ => Edge::None,
        }
    }

    /// The standard function block that senses this edge.
    pub(super) fn trigger(self) -> Option<&'static str> {
        match self {
            Edge::None => None,
            Edge::Rising => Some("R_TRIG"),
            Edge::Falling => Some("F_TRIG"),
        }
    }
}

/// What an element of the network is.
#[derive(Clone)]
pub(super) enum Kind {
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
#[derive(Clone)]
pub(super) struct Element {
    pub(super) id: u64,
    pub(super) at: usize,
    pub(super) kind: Kind,
    pub(super) inputs: Vec<Pin>,
    pub(super) order: u64,
    pub(super) position: (i64, i64),
}

/// Reads one element of an LD or FBD body.
pub(super) fn read_element(node: Node) -> Result<Element, Refused> {
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
pub(super) fn read_block(node: Node) -> Result<(Kind, Vec<Pin>), Refused> {
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
pub(super) fn name_block_outputs(elements: &mut [Element]) {
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
pub(super) fn connections(point: Option<Node>) -> Vec<From> {
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
