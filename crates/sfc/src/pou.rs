//! The POUs of a PLCopen project: their interface, named actions and transitions, and bodies.

use std::collections::HashMap;

use cetratus_net::xml::{Document, Node};

use crate::source::{body_text, child, children, Source};

/// Where a variable comes from in the POU's interface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VarKind {
    /// `VAR_INPUT`.
    Input,
    /// `VAR_OUTPUT`.
    Output,
    /// `VAR`, `VAR_IN_OUT`, `VAR_EXTERNAL`, `VAR_GLOBAL`, `VAR_TEMP`.
    Local,
}

/// A variable declared in a POU's interface.
#[derive(Clone, Debug, PartialEq)]
pub struct Variable {
    /// The name as declared.
    pub name: String,
    /// Input, output or local.
    pub kind: VarKind,
    /// The IEC type name (`BOOL`, `INT`, …), or the derived type's name.
    pub ty: String,
    /// The located address (`%IX0.0`), if any.
    pub address: Option<String>,
    /// The initial value as written, if any.
    pub initial: Option<String>,
    /// Byte offset of the declaration.
    pub at: usize,
}

/// The body of a named action or transition.
#[derive(Clone, Debug, PartialEq)]
pub enum Body {
    /// Structured Text, with the byte offset where its text starts.
    St {
        /// The text.
        text: String,
        /// Where it starts.
        at: usize,
    },
    /// Another language (FBD, LD, IL, SFC), by name.
    Other {
        /// The language's element name.
        language: String,
        /// Where the body is.
        at: usize,
    },
}

/// A named action or transition of a POU.
#[derive(Clone, Debug, PartialEq)]
pub struct Named {
    /// Its name.
    pub name: String,
    /// Its body.
    pub body: Body,
}

/// A POU of the project.
pub(crate) struct Pou<'a, 'i> {
    pub name: String,
    pub variables: Vec<Variable>,
    pub actions: Vec<Named>,
    pub transitions: Vec<Named>,
    /// The indexes of `variables`, `actions` and `transitions` by name, which the import looks
    /// names up in once per element, reference and association.
    index: [HashMap<String, usize>; 3],
    /// The `<pou>` element.
    pub node: Node<'a, 'i>,
    /// Where it was found: `types/pous`, or (TwinCAT) project-level `addData`.
    pub in_add_data: bool,
}

impl Pou<'_, '_> {
    /// The variable `name` of the interface (IEC names are case-insensitive).
    pub fn variable(&self, name: &str) -> Option<&Variable> {
        self.variables.get(self.find(0, name)?)
    }

    /// The named action `name`.
    pub fn action(&self, name: &str) -> Option<&Named> {
        self.actions.get(self.find(1, name)?)
    }

    /// The named transition `name`.
    pub fn transition(&self, name: &str) -> Option<&Named> {
        self.transitions.get(self.find(2, name)?)
    }

    /// Where `name` is in the list `k` of [`Pou::index`].
    fn find(&self, k: usize, name: &str) -> Option<usize> {
        self.index[k].get(&name.to_ascii_uppercase()).copied()
    }
}

/// Each name's position among `names`, by its upper case (IEC names are case-insensitive): the
/// first, where two are one name.
fn by_name<'n>(names: impl Iterator<Item = &'n str>) -> HashMap<String, usize> {
    let mut index = HashMap::new();
    for (i, name) in names.enumerate() {
        index.entry(name.to_ascii_uppercase()).or_insert(i);
    }
    index
}

/// The data name under which TwinCAT puts a POU in project-level `addData`.
const TWINCAT_POU: &str = "http://www.3s-software.com/plcopenxml/pou";

/// Every POU of the document: those in `types/pous` and those that TwinCAT puts in
/// project-level `addData` (`…/plcopenxml/application` → `resource` → `…/plcopenxml/pou`).
pub(crate) fn pous<'a, 'i>(source: &Source, doc: &'a Document<'i>) -> Vec<Pou<'a, 'i>> {
    doc.root_element()
        .descendants()
        .filter(|n| n.name() == "pou")
        .filter_map(|n| {
            let parent = n.parent()?;
            let in_add_data = match parent.name() {
                "pous" => false,
                "data" if parent.attribute("name") == Some(TWINCAT_POU) => true,
                _ => return None,
            };
            Some(read_pou(source, n, in_add_data))
        })
        .collect()
}

fn read_pou<'a, 'i>(source: &Source, node: Node<'a, 'i>, in_add_data: bool) -> Pou<'a, 'i> {
    let mut variables = Vec::new();
    if let Some(interface) = child(node, "interface") {
        for section in interface.children() {
            let kind = match section.name() {
                "inputVars" => VarKind::Input,
                "outputVars" => VarKind::Output,
                "localVars" | "tempVars" | "inOutVars" | "externalVars" | "globalVars" => {
                    VarKind::Local
                }
                _ => continue,
            };
            for v in children(section, "variable") {
                variables.push(Variable {
                    name: v.attribute("name").unwrap_or("").to_string(),
                    kind,
                    ty: child(v, "type")
                        .and_then(|t| t.children().next())
                        .map(|t| match t.name() {
                            "derived" => t.attribute("name").unwrap_or("derived").to_string(),
                            other => other.to_string(),
                        })
                        .unwrap_or_default(),
                    address: v.attribute("address").map(str::to_string),
                    initial: child(v, "initialValue")
                        .and_then(|i| child(i, "simpleValue"))
                        .and_then(|s| s.attribute("value"))
                        .map(str::to_string)
                        .or_else(|| {
                            let external = section.name() == "externalVars";
                            external.then(|| global_initial(node, v.attribute("name")?))?
                        }),
                    at: v.range().start,
                });
            }
        }
    }
    let named = |section: &str, item: &str| -> Vec<Named> {
        child(node, section)
            .map(|s| {
                children(s, item)
                    .map(|a| Named {
                        name: a.attribute("name").unwrap_or("").to_string(),
                        body: read_body(source, a),
                    })
                    .collect()
            })
            .unwrap_or_default()
    };
    let (actions, transitions) = (
        named("actions", "action"),
        named("transitions", "transition"),
    );
    let index = [
        by_name(variables.iter().map(|v| v.name.as_str())),
        by_name(actions.iter().map(|a| a.name.as_str())),
        by_name(transitions.iter().map(|t| t.name.as_str())),
    ];
    Pou {
        name: node.attribute("name").unwrap_or("").to_string(),
        variables,
        actions,
        transitions,
        index,
        node,
        in_add_data,
    }
}

/// The initial value of the configuration's global variable `name`, which a VAR_EXTERNAL of the
/// POU at `node` names: the global's value is the one the POU sees.
fn global_initial(node: Node, name: &str) -> Option<String> {
    let mut root = node;
    while let Some(up) = root.parent() {
        root = up;
    }
    root.descendants()
        .filter(|n| n.name() == "globalVars")
        .flat_map(|g| children(g, "variable"))
        .find(|g| {
            g.attribute("name")
                .is_some_and(|n| n.eq_ignore_ascii_case(name))
        })
        .and_then(|g| child(g, "initialValue"))
        .and_then(|i| child(i, "simpleValue"))
        .and_then(|s| s.attribute("value"))
        .map(str::to_string)
}

/// The body of a named action or transition.
fn read_body(source: &Source, node: Node) -> Body {
    let at = node.range().start;
    let Some(lang) = child(node, "body").and_then(|b| b.children().next()) else {
        return Body::Other {
            language: "no body".into(),
            at,
        };
    };
    if lang.name() == "ST" {
        if let Some((text, at)) = body_text(source, lang) {
            return Body::St { text, at };
        }
    }
    Body::Other {
        language: lang.name().to_string(),
        at: lang.range().start,
    }
}

/// The SFC bodies of a POU: its own body, then those of its named actions, with a label
/// (`body`, `action NAME`).
pub(crate) fn sfc_bodies<'a, 'i>(pou: &Pou<'a, 'i>) -> Vec<(String, Node<'a, 'i>)> {
    let mut out = Vec::new();
    if let Some(sfc) = child(pou.node, "body").and_then(|b| child(b, "SFC")) {
        out.push(("body".to_string(), sfc));
    }
    if let Some(actions) = child(pou.node, "actions") {
        for a in children(actions, "action") {
            if let Some(sfc) = child(a, "body").and_then(|b| child(b, "SFC")) {
                let name = a.attribute("name").unwrap_or("");
                out.push((format!("action {name}"), sfc));
            }
        }
    }
    out
}
