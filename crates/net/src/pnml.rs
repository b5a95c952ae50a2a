//! PNML in and out: ISO/IEC 15909-2 place/transition nets and the PIPE dialect.
//!
//! Reading accepts both dialects and flattens nested pages in document order, so the order of
//! places and transitions in the file is the order of the [`Net`] (docs/design.md §3). Writing always
//! produces ISO PNML on a single page, in declaration order.
//!
//! The ISO P/T grammar has no capacities, priorities or inhibitor arcs. The writer stores them in a
//! Cetratus tool-specific element on the place, transition or arc concerned:
//!
//! ```xml
//! <toolspecific tool="cetratus" version="1"><capacity>7</capacity></toolspecific>
//! <toolspecific tool="cetratus" version="1"><priority>2</priority></toolspecific>
//! <toolspecific tool="cetratus" version="1"><arcType>inhibitor</arcType></toolspecific>
//! ```
//!
//! The reader interprets an element with tool `cetratus`, version `1` and only those children
//! instead of keeping it; every other `<toolspecific>` element of the net, a page, a place or a
//! transition is kept as text and written back unchanged (page-level ones move to the net).
//! Tool-specific data on arcs is dropped, because [`crate::Arc`] has nowhere to keep it.

use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};
use std::borrow::Cow;
use std::fmt::Write as _;
use std::path::Path;

use crate::xml::{Document, ErrorKind, Node};

pub use crate::xml::MAX_ENTITY_EXPANSION;

use crate::{
    ArcKind, Net, NetBuilder, NetError, NodeRef, Place, Position, SourcePos, Tokens, ToolSpecific,
    Transition,
};

/// The ISO/IEC 15909-2 PNML namespace.
pub const PNML_NS: &str = "http://www.pnml.org/version-2009/grammar/pnml";
/// The ISO net type of place/transition nets, written on every net.
pub const PTNET_TYPE: &str = "http://www.pnml.org/version-2009/grammar/ptnet";
/// The `tool` attribute of the tool-specific elements Cetratus writes and interprets.
pub const TOOL: &str = "cetratus";
/// The `version` attribute of the tool-specific elements Cetratus writes and interprets.
pub const TOOL_VERSION: &str = "1";

/// The PNML flavour a document is written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dialect {
    /// ISO/IEC 15909-2: namespaced, labels hold `<text>`.
    Iso,
    /// PIPE 2/4/5: no namespace, labels hold `<value>`, capacities, priorities and inhibitor arcs.
    Pipe,
}

/// Reads a PNML file of either dialect; the file may be UTF-8 or ISO-8859-1.
pub fn read_file(path: &Path) -> Result<Net, NetError> {
    let label = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| NetError::Io {
        path: label.clone(),
        source,
    })?;
    read_bytes(&bytes, &label)
}

/// Reads PNML from raw bytes (UTF-8, or ISO-8859-1 as PIPE writes); `file_label` names it in errors.
pub fn read_bytes(bytes: &[u8], file_label: &str) -> Result<Net, NetError> {
    read_str(&decode(bytes, file_label)?, file_label)
}

/// The text of a PNML file: UTF-8, or else ISO-8859-1 (which PIPE writes and declares); UTF-16
/// is refused. `file_label` names it in errors.
pub fn decode<'b>(bytes: &'b [u8], file_label: &str) -> Result<Cow<'b, str>, NetError> {
    if bytes.starts_with(&[0xFE, 0xFF]) || bytes.starts_with(&[0xFF, 0xFE]) {
        return Err(NetError::Syntax {
            pos: SourcePos {
                file: file_label.to_string(),
                line: 1,
                column: 1,
            },
            message: "the file is encoded in UTF-16; save it as UTF-8 or ISO-8859-1".to_string(),
        });
    }
    Ok(match std::str::from_utf8(bytes) {
        Ok(s) => Cow::Borrowed(s),
        // PIPE declares and writes ISO-8859-1, whose every byte is the code point of the same value.
        Err(_) => Cow::Owned(bytes.iter().map(|&b| char::from(b)).collect()),
    })
}

/// Reads PNML text of either dialect; `file_label` names the source in error positions.
pub fn read_str(text: &str, file_label: &str) -> Result<Net, NetError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let doc = Document::parse(text).map_err(|e| {
        let (line, column) = Document::text_pos_at_in(text, e.offset);
        NetError::Syntax {
            pos: SourcePos {
                file: file_label.to_string(),
                line,
                column,
            },
            message: match e.kind {
                ErrorKind::Malformed => format!(
                    "not well-formed XML: {}; fix the XML (an editor that checks XML helps)",
                    e.message
                ),
                ErrorKind::TooLarge => e.message,
            },
        }
    })?;
    let root = doc.root_element();
    let dialect = if root.namespace() == Some(PNML_NS) {
        Dialect::Iso
    } else {
        Dialect::Pipe
    };
    Reader {
        doc: &doc,
        file: file_label,
        dialect,
    }
    .read(root)
}

/// Detects the dialect of a PNML text, or `None` when it is not well-formed XML.
pub fn detect_dialect(text: &str) -> Option<Dialect> {
    let doc = Document::parse(text.strip_prefix('\u{feff}').unwrap_or(text)).ok()?;
    Some(if doc.root_element().namespace() == Some(PNML_NS) {
        Dialect::Iso
    } else {
        Dialect::Pipe
    })
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum RefKind {
    Place,
    Transition,
}

impl RefKind {
    fn element(self) -> &'static str {
        match self {
            RefKind::Place => "referencePlace",
            RefKind::Transition => "referenceTransition",
        }
    }
}

/// The structural elements of a net in document order, pages flattened.
#[derive(Default)]
struct Items<'a, 'i> {
    places: Vec<Node<'a, 'i>>,
    transitions: Vec<Node<'a, 'i>>,
    refs: Vec<(Node<'a, 'i>, RefKind)>,
    arcs: Vec<Node<'a, 'i>>,
    toolspecific: Vec<Node<'a, 'i>>,
    name: Option<Node<'a, 'i>>,
}

/// What a Cetratus tool-specific element says.
#[derive(Default)]
struct Extra {
    capacity: Option<Tokens>,
    priority: Option<i32>,
    kind: Option<ArcKind>,
}

enum CountError {
    Negative,
    NotNumber,
    TooLarge,
    BadList,
}

struct Reader<'a, 'i> {
    doc: &'a Document<'i>,
    file: &'a str,
    dialect: Dialect,
}

impl<'a, 'i: 'a> Reader<'a, 'i> {
    fn pos(&self, node: Node) -> SourcePos {
        let (line, column) = self.doc.text_pos_at(node.range().start);
        SourcePos {
            file: self.file.to_string(),
            line,
            column,
        }
    }

    fn err(&self, node: Node, message: impl Into<String>) -> NetError {
        NetError::Syntax {
            pos: self.pos(node),
            message: message.into(),
        }
    }

    fn read(&self, root: Node<'a, 'i>) -> Result<Net, NetError> {
        if root.name() != "pnml" {
            return Err(self.err(
                root,
                format!(
                    "the root element is <{}>, not <pnml>; a PNML file starts with <pnml> and holds one <net>",
                    root.name()
                ),
            ));
        }
        let nets: Vec<Node> = root.children().filter(|n| is(n, "net")).collect();
        let net = match nets.as_slice() {
            [] => {
                return Err(self.err(
                    root,
                    "missing <net>: <pnml> holds no <net> element; put the places, transitions and arcs in a <net id=\"...\">",
                ))
            }
            [net] => *net,
            [_, second, ..] => {
                return Err(self.err(
                    *second,
                    format!(
                        "the file holds {} <net> elements; Cetratus reads one net per file, so split it into one file per net",
                        nets.len()
                    ),
                ))
            }
        };
        if let Some(ty) = net.attribute("type") {
            if ["symmetricnet", "hlpn", "pt-hlpng"]
                .iter()
                .any(|hl| ty.contains(hl))
            {
                return Err(self.err(
                    net,
                    format!("net type `{ty}` is a high-level net; Cetratus reads place/transition nets (`{PTNET_TYPE}`), so unfold it first"),
                ));
            }
        }

        let items = self.collect(net)?;
        let mut b = NetBuilder::new(net.attribute("id").unwrap_or(""));
        if let Some(name) = items.name {
            if let Some(text) = self.label(name) {
                b.name(text.text().unwrap_or(""));
            }
        }
        for ts in &items.toolspecific {
            b.toolspecific(self.verbatim(*ts));
        }
        for &node in &items.places {
            let place = self.place(node)?;
            b.add_place(place)
                .map_err(|e| NetError::at(self.pos(node), e))?;
        }
        for &node in &items.transitions {
            let transition = self.transition(node)?;
            b.add_transition(transition)
                .map_err(|e| NetError::at(self.pos(node), e))?;
        }
        let refs = self.resolve_refs(&items.refs, &b)?;
        for &node in &items.arcs {
            self.arc(node, &refs, &mut b)?;
        }
        b.build().map_err(|e| NetError::at(self.pos(net), e))
    }

    /// Walks the net and its pages in document order; checks that ids are present and unique.
    fn collect(&self, net: Node<'a, 'i>) -> Result<Items<'a, 'i>, NetError> {
        let mut items = Items::default();
        // Pages are containers only if their parent is one, so a <place> inside a tool's own data
        // is not mistaken for a place of the net.
        let mut containers: HashSet<u32> = HashSet::default();
        containers.insert(net.id());
        let mut ids: HashMap<&'a str, Node<'a, 'i>> = HashMap::default();
        for node in net.descendants().skip(1) {
            match node.parent() {
                Some(parent) if containers.contains(&parent.id()) => {}
                _ => continue,
            }
            let tag = node.name();
            match tag {
                "page" => {
                    containers.insert(node.id());
                    continue;
                }
                "toolspecific" => {
                    items.toolspecific.push(node);
                    continue;
                }
                "name" => {
                    if node.parent().map(|p| p.id()) == Some(net.id()) {
                        items.name = Some(node);
                    }
                    continue;
                }
                "place" => items.places.push(node),
                "transition" => items.transitions.push(node),
                "referencePlace" => items.refs.push((node, RefKind::Place)),
                "referenceTransition" => items.refs.push((node, RefKind::Transition)),
                "arc" => items.arcs.push(node),
                _ => continue,
            }
            let id = self.id_of(node)?;
            if let Some(first) = ids.insert(id, node) {
                return Err(self.err(
                    node,
                    format!(
                        "duplicate id `{id}`, first declared at {}; every place, transition, reference and arc needs its own id, so rename one of them",
                        self.pos(first)
                    ),
                ));
            }
        }
        Ok(items)
    }

    fn id_of(&self, node: Node<'a, 'i>) -> Result<&'a str, NetError> {
        match node.attribute("id") {
            Some(id) if !id.is_empty() => Ok(id),
            _ => Err(self.err(
                node,
                format!(
                    "<{}> has no id; give it an attribute id=\"...\" that no other element uses",
                    node.name()
                ),
            )),
        }
    }

    fn required_attr(&self, node: Node<'a, 'i>, attr: &str) -> Result<&'a str, NetError> {
        node.attribute(attr).ok_or_else(|| {
            self.err(
                node,
                format!(
                    "<{}> has no `{attr}` attribute; add {attr}=\"...\"",
                    node.name()
                ),
            )
        })
    }

    /// The `<text>` (ISO) or `<value>` (PIPE) child of a label, trying the file's dialect first.
    fn label(&self, node: Node<'a, 'i>) -> Option<Node<'a, 'i>> {
        let (first, second) = match self.dialect {
            Dialect::Iso => ("text", "value"),
            Dialect::Pipe => ("value", "text"),
        };
        child(node, first).or_else(|| child(node, second))
    }

    /// A token count from a label; `default` when the label or its text is missing or empty.
    fn count(&self, node: Node<'a, 'i>, default: Tokens, what: &str) -> Result<Tokens, NetError> {
        let Some(text_node) = self.label(node) else {
            return Ok(default);
        };
        let text = text_node.text().unwrap_or("");
        match parse_count(text) {
            Ok(Some(n)) => Ok(n),
            Ok(None) => Ok(default),
            Err(e) => Err(self.err(text_node, count_message(what, text.trim(), e))),
        }
    }

    fn place(&self, node: Node<'a, 'i>) -> Result<Place, NetError> {
        let mut place = Place::new(self.id_of(node)?, 0);
        let mut pipe_capacity = None;
        let mut own_capacity = None;
        for c in node.children() {
            match c.name() {
                "name" => place.name = self.name(c),
                "initialMarking" => place.initial = self.count(c, 0, "initial marking")?,
                // PIPE writes 0 for an unbounded place.
                "capacity" => pipe_capacity = Some(self.count(c, 0, "capacity")?),
                "graphics" => place.position = self.position(c)?,
                "toolspecific" => match self.extra(c)? {
                    Some(extra) => own_capacity = extra.capacity.or(own_capacity),
                    None => place.toolspecific.push(self.verbatim(c)),
                },
                _ => {}
            }
        }
        place.capacity = own_capacity.or(pipe_capacity.filter(|&c| c != 0));
        Ok(place)
    }

    fn transition(&self, node: Node<'a, 'i>) -> Result<Transition, NetError> {
        let mut t = Transition::new(self.id_of(node)?);
        let mut own_priority = None;
        for c in node.children() {
            match c.name() {
                "name" => t.name = self.name(c),
                "graphics" => t.position = self.position(c)?,
                "priority" => {
                    if let Some(v) = self.label(c) {
                        let text = v.text().unwrap_or("").trim();
                        if !text.is_empty() {
                            t.priority = self.priority(v, text)?;
                        }
                    }
                }
                "toolspecific" => match self.extra(c)? {
                    Some(extra) => own_priority = extra.priority.or(own_priority),
                    None => t.toolspecific.push(self.verbatim(c)),
                },
                _ => {}
            }
        }
        if let Some(p) = own_priority {
            t.priority = p;
        }
        Ok(t)
    }

    fn priority(&self, node: Node<'a, 'i>, text: &str) -> Result<i32, NetError> {
        text.parse::<i32>().map_err(|_| {
            self.err(
                node,
                format!("priority `{text}` is not a whole number; write an integer such as 0 or 2 (higher fires first)"),
            )
        })
    }

    fn name(&self, node: Node<'a, 'i>) -> Option<String> {
        self.label(node).map(|t| t.text().unwrap_or("").to_string())
    }

    fn position(&self, graphics: Node<'a, 'i>) -> Result<Option<Position>, NetError> {
        match child(graphics, "position") {
            Some(p) => Ok(Some(self.point(p)?)),
            None => Ok(None),
        }
    }

    fn point(&self, node: Node<'a, 'i>) -> Result<Position, NetError> {
        Ok(Position {
            x: self.coordinate(node, "x")?,
            y: self.coordinate(node, "y")?,
        })
    }

    fn coordinate(&self, node: Node<'a, 'i>, attr: &str) -> Result<f64, NetError> {
        let text = self.required_attr(node, attr)?;
        match text.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.err(
                node,
                format!("coordinate {attr}=\"{text}\" is not a number; write a decimal such as 120 or 45.5"),
            )),
        }
    }

    fn verbatim(&self, node: Node<'a, 'i>) -> ToolSpecific {
        ToolSpecific {
            tool: node.attribute("tool").unwrap_or("").to_string(),
            version: node.attribute("version").unwrap_or("").to_string(),
            xml: self.doc.input_text()[node.range()].to_string(),
        }
    }

    /// Interprets a Cetratus tool-specific element; `None` for anything else, which is kept verbatim.
    fn extra(&self, node: Node<'a, 'i>) -> Result<Option<Extra>, NetError> {
        if node.attribute("tool") != Some(TOOL) || node.attribute("version") != Some(TOOL_VERSION) {
            return Ok(None);
        }
        let kids: Vec<Node> = node.children().collect();
        let known = |n: &Node| matches!(n.name(), "capacity" | "priority" | "arcType");
        if kids.is_empty() || !kids.iter().all(known) {
            return Ok(None);
        }
        let mut extra = Extra::default();
        for k in kids {
            let raw = k.text().unwrap_or("");
            let text = raw.trim();
            match k.name() {
                "capacity" => {
                    let cap = parse_number(text)
                        .map_err(|e| self.err(k, count_message("capacity", text, e)))?;
                    extra.capacity = Some(cap);
                }
                "priority" => extra.priority = Some(self.priority(k, text)?),
                _ => {
                    extra.kind = Some(match text {
                        "normal" => ArcKind::Normal,
                        "inhibitor" => ArcKind::Inhibitor,
                        other => return Err(self.err(k, format!(
                            "arc type `{other}` is not supported; Cetratus knows `normal` and `inhibitor` arcs"
                        ))),
                    })
                }
            }
        }
        Ok(Some(extra))
    }

    /// Resolves every reference node, following chains, to the place or transition it ends at.
    fn resolve_refs(
        &self,
        refs: &[(Node<'a, 'i>, RefKind)],
        b: &NetBuilder,
    ) -> Result<HashMap<&'a str, NodeRef>, NetError> {
        let mut decl: HashMap<&'a str, (Node<'a, 'i>, RefKind, &'a str)> = HashMap::default();
        for &(node, kind) in refs {
            let id = self.id_of(node)?;
            let target = self.required_attr(node, "ref")?;
            decl.insert(id, (node, kind, target));
        }
        let mut resolved: HashMap<&'a str, NodeRef> = HashMap::default();
        for &(node, _) in refs {
            let start = self.id_of(node)?;
            let mut chain: Vec<&'a str> = vec![start];
            let mut seen: HashSet<&'a str> = std::iter::once(start).collect();
            let mut cur = start;
            let end = loop {
                if let Some(&r) = resolved.get(cur) {
                    break r;
                }
                // `cur` is always a declared reference: the walk only moves to ids found in `decl`.
                let Some(&(cur_node, kind, target)) = decl.get(cur) else {
                    return Err(self.err(node, format!("reference `{cur}` is not declared")));
                };
                if let Some(found) = b.node(target) {
                    match (kind, found) {
                        (RefKind::Place, NodeRef::Place(_))
                        | (RefKind::Transition, NodeRef::Transition(_)) => break found,
                        _ => {
                            return Err(self.err(
                                cur_node,
                                format!(
                                    "{} `{cur}` refers to `{target}`, which is a {}; a referencePlace must refer to a place and a referenceTransition to a transition",
                                    kind.element(),
                                    if kind == RefKind::Place { "transition" } else { "place" }
                                ),
                            ))
                        }
                    }
                }
                match decl.get(target) {
                    Some(&(_, next_kind, _)) if next_kind != kind => {
                        return Err(self.err(
                            cur_node,
                            format!(
                                "{} `{cur}` refers to {} `{target}`; a reference must refer to a node of its own kind",
                                kind.element(),
                                next_kind.element()
                            ),
                        ))
                    }
                    Some(_) => {
                        if !seen.insert(target) {
                            chain.push(target);
                            return Err(self.err(
                                node,
                                format!(
                                    "reference cycle {}; a chain of references must end at a place or a transition",
                                    chain
                                        .iter()
                                        .map(|id| format!("`{id}`"))
                                        .collect::<Vec<_>>()
                                        .join(" -> ")
                                ),
                            ));
                        }
                        chain.push(target);
                        cur = target;
                    }
                    None => {
                        return Err(self.err(
                            cur_node,
                            format!(
                                "{} `{cur}` refers to `{target}`, which is not declared; declare it or fix the ref attribute",
                                kind.element()
                            ),
                        ))
                    }
                }
            };
            for id in chain {
                resolved.insert(id, end);
            }
        }
        Ok(resolved)
    }

    fn arc(
        &self,
        node: Node<'a, 'i>,
        refs: &HashMap<&'a str, NodeRef>,
        b: &mut NetBuilder,
    ) -> Result<(), NetError> {
        let id = self.id_of(node)?;
        let ends = [
            self.required_attr(node, "source")?,
            self.required_attr(node, "target")?,
        ];
        let mut resolved = [NodeRef::Place(crate::PlaceIdx(0)); 2];
        for (slot, end) in resolved.iter_mut().zip(ends) {
            *slot = b
                .node(end)
                .or_else(|| refs.get(end).copied())
                .ok_or_else(|| {
                    NetError::at(
                        self.pos(node),
                        NetError::UnknownNode {
                            arc: id.to_string(),
                            node: end.to_string(),
                        },
                    )
                })?;
        }
        let mut weight = 1;
        let mut kind = ArcKind::Normal;
        let mut path = Vec::new();
        let mut pipe_path = Vec::new();
        for c in node.children() {
            match c.name() {
                "inscription" => weight = self.count(c, 1, "arc weight")?,
                "graphics" => {
                    for p in c.children().filter(|n| is(n, "position")) {
                        path.push(self.point(p)?);
                    }
                }
                "arcpath" => pipe_path.push(self.point(c)?),
                "type" => {
                    kind = match c.attribute("value").unwrap_or("normal") {
                        "normal" => ArcKind::Normal,
                        "inhibitor" => ArcKind::Inhibitor,
                        other => return Err(self.err(c, format!(
                            "arc type `{other}` is not supported; Cetratus knows `normal` and `inhibitor` arcs"
                        ))),
                    }
                }
                "toolspecific" => {
                    if let Some(extra) = self.extra(c)? {
                        kind = extra.kind.unwrap_or(kind);
                    }
                }
                _ => {}
            }
        }
        // PIPE's arc path starts and ends at the nodes; only the points between are bends.
        if path.is_empty() && pipe_path.len() > 2 {
            path = pipe_path[1..pipe_path.len() - 1].to_vec();
        }
        let idx = b
            .add_arc_resolved(id, resolved[0], resolved[1], weight, kind)
            .map_err(|e| NetError::at(self.pos(node), e))?;
        if !path.is_empty() {
            b.set_arc_path(idx, path);
        }
        Ok(())
    }
}

fn is(node: &Node, name: &str) -> bool {
    node.name() == name
}

fn child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|n| is(n, name))
}

/// Parses a token count: `N`, or PIPE's `Class,N[,Class,N...]` (summed); `None` when empty.
fn parse_count(text: &str) -> Result<Option<Tokens>, CountError> {
    let text = text.trim();
    if text.is_empty() {
        return Ok(None);
    }
    if !text.contains(',') {
        return parse_number(text).map(Some);
    }
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if !parts.len().is_multiple_of(2) {
        return Err(CountError::BadList);
    }
    let mut total: Tokens = 0;
    for pair in parts.chunks(2) {
        if pair[0].is_empty() {
            return Err(CountError::BadList);
        }
        total = total
            .checked_add(parse_number(pair[1])?)
            .ok_or(CountError::TooLarge)?;
    }
    Ok(Some(total))
}

fn parse_number(text: &str) -> Result<Tokens, CountError> {
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    if let Some(rest) = text.strip_prefix('-') {
        if digits(rest) && rest.bytes().any(|b| b != b'0') {
            return Err(CountError::Negative);
        }
    }
    if !digits(text) {
        return Err(CountError::NotNumber);
    }
    text.parse::<Tokens>().map_err(|_| CountError::TooLarge)
}

fn count_message(what: &str, text: &str, e: CountError) -> String {
    match e {
        CountError::Negative => format!(
            "{what} `{text}` is negative; a token count is a whole number of 0 or more"
        ),
        CountError::NotNumber => format!(
            "{what} `{text}` is not a number; write a whole number such as 0 or 3 (PIPE files may also write `Default,3`)"
        ),
        CountError::TooLarge => format!(
            "{what} `{text}` is too large; a token count is at most {}",
            Tokens::MAX
        ),
        CountError::BadList => format!(
            "{what} `{text}` is not a PIPE token list; write pairs of token class and count such as `Default,3`"
        ),
    }
}

/// Writes the net as ISO PNML on one page; capacities, priorities and inhibitor arcs go in
/// Cetratus tool-specific elements (see the module documentation).
pub fn write_string(net: &Net) -> String {
    let mut out = String::with_capacity(256 + 160 * (net.num_places() + net.arcs().len()));
    write_net(net, &mut out).expect("writing to a String cannot fail");
    out
}

/// Writes the net as ISO PNML to a file.
pub fn write_file(net: &Net, path: &Path) -> Result<(), NetError> {
    std::fs::write(path, write_string(net)).map_err(|source| NetError::Io {
        path: path.display().to_string(),
        source,
    })
}

fn write_net(net: &Net, w: &mut String) -> std::fmt::Result {
    writeln!(w, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>")?;
    writeln!(w, "<pnml xmlns=\"{PNML_NS}\">")?;
    writeln!(w, "  <net id=\"{}\" type=\"{PTNET_TYPE}\">", attr(net.id()))?;
    if let Some(name) = net.name() {
        writeln!(w, "    <name><text>{}</text></name>", text(name))?;
    }
    for ts in net.toolspecific() {
        writeln!(w, "    {}", ts.xml)?;
    }
    writeln!(w, "    <page id=\"{}\">", attr(&page_id(net)))?;
    for p in net.places() {
        writeln!(w, "      <place id=\"{}\">", attr(&p.id))?;
        write_name(w, p.name.as_deref())?;
        write_position(w, p.position)?;
        if p.initial != 0 {
            writeln!(
                w,
                "        <initialMarking><text>{}</text></initialMarking>",
                p.initial
            )?;
        }
        if let Some(cap) = p.capacity {
            write_extra(w, "capacity", &cap.to_string())?;
        }
        write_toolspecific(w, &p.toolspecific)?;
        writeln!(w, "      </place>")?;
    }
    for t in net.transitions() {
        writeln!(w, "      <transition id=\"{}\">", attr(&t.id))?;
        write_name(w, t.name.as_deref())?;
        write_position(w, t.position)?;
        if t.priority != 0 {
            write_extra(w, "priority", &t.priority.to_string())?;
        }
        write_toolspecific(w, &t.toolspecific)?;
        writeln!(w, "      </transition>")?;
    }
    for a in net.arcs() {
        writeln!(
            w,
            "      <arc id=\"{}\" source=\"{}\" target=\"{}\">",
            attr(&a.id),
            attr(node_id(net, a.source)),
            attr(node_id(net, a.target))
        )?;
        if a.weight != 1 {
            writeln!(
                w,
                "        <inscription><text>{}</text></inscription>",
                a.weight
            )?;
        }
        if !a.path.is_empty() {
            writeln!(w, "        <graphics>")?;
            for p in &a.path {
                writeln!(w, "          <position x=\"{}\" y=\"{}\"/>", p.x, p.y)?;
            }
            writeln!(w, "        </graphics>")?;
        }
        if a.kind == ArcKind::Inhibitor {
            write_extra(w, "arcType", "inhibitor")?;
        }
        writeln!(w, "      </arc>")?;
    }
    writeln!(w, "    </page>")?;
    writeln!(w, "  </net>")?;
    writeln!(w, "</pnml>")
}

fn write_name(w: &mut String, name: Option<&str>) -> std::fmt::Result {
    match name {
        Some(name) => writeln!(w, "        <name><text>{}</text></name>", text(name)),
        None => Ok(()),
    }
}

fn write_position(w: &mut String, pos: Option<Position>) -> std::fmt::Result {
    match pos {
        // `{}` prints the shortest decimal that parses back to the same f64.
        Some(p) => writeln!(
            w,
            "        <graphics><position x=\"{}\" y=\"{}\"/></graphics>",
            p.x, p.y
        ),
        None => Ok(()),
    }
}

fn write_extra(w: &mut String, key: &str, value: &str) -> std::fmt::Result {
    writeln!(
        w,
        "        <toolspecific tool=\"{TOOL}\" version=\"{TOOL_VERSION}\"><{key}>{value}</{key}></toolspecific>"
    )
}

fn write_toolspecific(w: &mut String, list: &[ToolSpecific]) -> std::fmt::Result {
    for ts in list {
        writeln!(w, "        {}", ts.xml)?;
    }
    Ok(())
}

fn node_id(net: &Net, node: NodeRef) -> &str {
    match node {
        NodeRef::Place(p) => &net.place(p).id,
        NodeRef::Transition(t) => &net.transition(t).id,
    }
}

/// A page id that no node or arc of the net uses.
fn page_id(net: &Net) -> String {
    let taken: HashSet<&str> = net
        .places()
        .iter()
        .map(|p| p.id.as_str())
        .chain(net.transitions().iter().map(|t| t.id.as_str()))
        .chain(net.arcs().iter().map(|a| a.id.as_str()))
        .chain(std::iter::once(net.id()))
        .collect();
    let mut id = "page0".to_string();
    let mut n = 0;
    while taken.contains(id.as_str()) {
        n += 1;
        id = format!("page0_{n}");
    }
    id
}

/// Escapes text content; `\r` too, because XML parsers turn a raw one into `\n`.
fn text(s: &str) -> Cow<'_, str> {
    // Quotes may stay raw in text, and leaving them keeps the files as earlier versions wrote them.
    char_refs(quick_xml::escape::partial_escape(s), &['\r'])
}

/// Escapes an attribute value; whitespace too, because parsers turn raw tabs and newlines into spaces.
fn attr(s: &str) -> Cow<'_, str> {
    char_refs(crate::xml_escape(s), &['\t', '\n', '\r'])
}

/// Writes each of `chars` in `s` as a numeric character reference (`&#13;`), which a parser
/// gives back as that character instead of normalising it.
fn char_refs<'a>(s: Cow<'a, str>, chars: &[char]) -> Cow<'a, str> {
    if !s.contains(chars) {
        return s;
    }
    let mut out = String::with_capacity(s.len() + 8);
    for c in s.chars() {
        if chars.contains(&c) {
            let _ = write!(out, "&#{};", u32::from(c));
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
}

#[cfg(test)]
mod tests;
