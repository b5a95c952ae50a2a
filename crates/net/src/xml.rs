//! A small read-only XML tree, built from quick-xml's event stream: the one hardened XML reader
//! of the workspace (the PNML reader here, the PLCopen importer in `cetratus-sfc`).
//!
//! It bounds what a document can cost: internal entities expand to at most
//! [`MAX_ENTITY_EXPANSION`] bytes in all, external entities are never fetched, duplicate
//! attributes and namespace prefixes are found in time linear in their number, and the tree is
//! built with an explicit stack, so nesting depth costs memory, never call stack.
//!
//! PNML files are small and the reader looks at each element a few times, so a tree is the
//! simplest thing to read from; building our own keeps it to what the reader needs (elements,
//! their attributes, the text right after the start tag and their byte range) and borrows
//! everything that needs no decoding straight from the input. Line and column are computed only
//! when an error is reported.

use std::borrow::Cow;
use std::cell::Cell;
use std::ops::Range;

use quick_xml::escape::resolve_predefined_entity;
use quick_xml::events::attributes::Attribute;
use quick_xml::events::{BytesRef, Event};
use quick_xml::name::QName;
use quick_xml::XmlVersion;
use rustc_hash::{FxHashMap, FxHashSet};

/// Marks a missing link (no parent, child, sibling or namespace).
const NONE: u32 = u32::MAX;

/// The namespace the `xml` prefix is bound to without a declaration.
const XML_NS: &str = "http://www.w3.org/XML/1998/namespace";

/// Most bytes the internal entities of a document (`<!ENTITY name "text">`) may expand to, all
/// references together. An entity cannot refer to another, so nothing grows exponentially, but
/// one 100 KB entity used 20,000 times is 2 GB: the count keeps the expanded text within this.
pub const MAX_ENTITY_EXPANSION: usize = 1 << 20;

/// Up to this many attributes, an element's duplicates are found by a scan; beyond it, by a
/// set, so that one element with a million attributes costs a million steps and not 10¹².
const SCANNED_ATTRIBUTES: usize = 16;

/// A parse failure: a byte offset into the input and what was wrong there.
#[derive(Debug)]
pub struct Error {
    /// Byte offset into the input where the problem was found.
    pub offset: usize,
    /// What was wrong, for people.
    pub message: String,
    /// Malformed or too large.
    pub kind: ErrorKind,
}

/// Why a document was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorKind {
    /// It is not well-formed XML, or uses XML this reader does not support.
    Malformed,
    /// It is well-formed but goes over a limit of the reader.
    TooLarge,
}

struct Element<'i> {
    /// The local name, without prefix.
    name: &'i str,
    /// Index into [`Document::namespaces`], or [`NONE`].
    namespace: u32,
    parent: u32,
    first_child: u32,
    next_sibling: u32,
    /// The last element of this element's subtree (itself when it has no children): elements
    /// are stored in document order, so the descendants are the indices in between.
    last_descendant: u32,
    attributes: Range<u32>,
    /// The text and CDATA right after the start tag, up to the first child element, comment or
    /// processing instruction, entities decoded; `None` when there is none.
    text: Option<Cow<'i, str>>,
    range: Range<usize>,
}

/// A parsed XML document.
pub struct Document<'i> {
    input: &'i str,
    elements: Vec<Element<'i>>,
    /// (qualified name, value); namespace declarations are not attributes.
    attributes: Vec<(&'i str, Cow<'i, str>)>,
    namespaces: Vec<Cow<'i, str>>,
}

/// An element of a [`Document`].
#[derive(Clone, Copy)]
pub struct Node<'a, 'i> {
    doc: &'a Document<'i>,
    id: u32,
}

/// An open element while building, with the state of its text run.
struct Open<'i> {
    id: u32,
    qname: &'i str,
    last_child: u32,
    /// Whether text still belongs to the element's text (no child seen yet).
    in_text: bool,
    /// How many namespace bindings this element pushed onto the scope.
    bindings: usize,
}

impl<'i> Document<'i> {
    /// Parses a whole document; the first error ends parsing.
    pub fn parse(input: &'i str) -> Result<Self, Error> {
        Builder::new(input).run()
    }

    /// The root element.
    pub fn root_element(&self) -> Node<'_, 'i> {
        Node { doc: self, id: 0 }
    }

    /// The input text the document was parsed from.
    pub fn input_text(&self) -> &'i str {
        self.input
    }

    /// The 1-based line and column (in characters) of a byte offset, as editors count them.
    pub fn text_pos_at(&self, offset: usize) -> (u32, u32) {
        Self::text_pos_at_in(self.input, offset)
    }

    /// [`Document::text_pos_at`] for a text that did not parse.
    pub fn text_pos_at_in(input: &str, offset: usize) -> (u32, u32) {
        let mut end = offset.min(input.len());
        while !input.is_char_boundary(end) {
            end -= 1;
        }
        let before = &input[..end];
        let line = 1 + before.bytes().filter(|&b| b == b'\n').count();
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = 1 + before[line_start..].chars().count();
        (
            u32::try_from(line).unwrap_or(u32::MAX),
            u32::try_from(column).unwrap_or(u32::MAX),
        )
    }
}

impl<'a, 'i> Node<'a, 'i> {
    fn element(&self) -> &'a Element<'i> {
        &self.doc.elements[self.id as usize]
    }

    fn at(&self, id: u32) -> Option<Node<'a, 'i>> {
        (id != NONE).then_some(Node { doc: self.doc, id })
    }

    /// A number unique to this element within its document.
    pub fn id(&self) -> u32 {
        self.id
    }

    /// The local name of the element.
    pub fn name(&self) -> &'a str {
        self.element().name
    }

    /// The namespace URI of the element, if it is in one.
    pub fn namespace(&self) -> Option<&'a str> {
        let ns = self.element().namespace;
        (ns != NONE).then(|| self.doc.namespaces[ns as usize].as_ref())
    }

    /// The value of an attribute without prefix, entities decoded and whitespace normalised.
    pub fn attribute(&self, name: &str) -> Option<&'a str> {
        let r = &self.element().attributes;
        self.doc.attributes[r.start as usize..r.end as usize]
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| v.as_ref())
    }

    /// The parent element, `None` for the root.
    pub fn parent(&self) -> Option<Node<'a, 'i>> {
        self.at(self.element().parent)
    }

    /// The child elements in document order.
    pub fn children(&self) -> impl Iterator<Item = Node<'a, 'i>> {
        let mut next = self.at(self.element().first_child);
        std::iter::from_fn(move || {
            let cur = next?;
            next = cur.at(cur.element().next_sibling);
            Some(cur)
        })
    }

    /// The element and all elements inside it, in document order.
    pub fn descendants(&self) -> impl Iterator<Item = Node<'a, 'i>> {
        let doc = self.doc;
        (self.id..=self.element().last_descendant).map(move |id| Node { doc, id })
    }

    /// The text right after the start tag (see [`Element::text`]).
    pub fn text(&self) -> Option<&'a str> {
        self.element().text.as_deref()
    }

    /// The bytes of the input from the start tag's `<` to the end tag's `>`.
    pub fn range(&self) -> Range<usize> {
        self.element().range.clone()
    }
}

struct Builder<'i> {
    input: &'i str,
    doc: Document<'i>,
    stack: Vec<Open<'i>>,
    /// The prefixes bound by the open elements, innermost last, so that closing an element
    /// can undo its bindings.
    scope: Vec<&'i str>,
    /// For each prefix, the namespaces it is bound to by the open elements, innermost last: an
    /// index into namespaces, or NONE when `xmlns=""` undeclares the default namespace. A map
    /// rather than a search of `scope`, whose length the input controls.
    bound: FxHashMap<&'i str, Vec<u32>>,
    /// The same for the default namespace (no prefix), which most elements use: kept apart so
    /// that they cost no hashing.
    default_ns: Vec<u32>,
    /// The attribute names of the element being opened, once it has more than
    /// [`SCANNED_ATTRIBUTES`] of them.
    seen: FxHashSet<&'i str>,
    /// Entities declared in the internal DTD subset, with their replacement text.
    entities: FxHashMap<&'i str, &'i str>,
    /// Bytes the declared entities have expanded to so far, against [`MAX_ENTITY_EXPANSION`].
    expanded: Cell<usize>,
}

impl<'i> Builder<'i> {
    fn new(input: &'i str) -> Self {
        // PNML elements carry about 80 bytes of markup each; reserving avoids regrowth.
        let guess = input.len() / 80 + 4;
        Builder {
            input,
            doc: Document {
                input,
                elements: Vec::with_capacity(guess),
                attributes: Vec::with_capacity(guess),
                namespaces: Vec::new(),
            },
            stack: Vec::with_capacity(16),
            scope: Vec::new(),
            bound: FxHashMap::default(),
            default_ns: Vec::new(),
            seen: FxHashSet::default(),
            entities: FxHashMap::default(),
            expanded: Cell::new(0),
        }
    }

    fn fail<T>(offset: usize, message: impl Into<String>) -> Result<T, Error> {
        Err(Error {
            offset,
            message: message.into(),
            kind: ErrorKind::Malformed,
        })
    }

    /// The error for entities that expanded past [`MAX_ENTITY_EXPANSION`].
    fn too_much_expansion<T>(offset: usize) -> Result<T, Error> {
        Err(Error {
            offset,
            message: format!(
                "the internal entities of this file expand to more than {MAX_ENTITY_EXPANSION} bytes in all, the limit, by this point; write the text out rather than through entities"
            ),
            kind: ErrorKind::TooLarge,
        })
    }

    /// Whether the expansion has gone past [`MAX_ENTITY_EXPANSION`].
    fn over_expansion_limit(&self) -> bool {
        self.expanded.get() > MAX_ENTITY_EXPANSION
    }

    fn run(mut self) -> Result<Document<'i>, Error> {
        let mut reader = quick_xml::Reader::from_str(self.input);
        let config = reader.config_mut();
        // Mismatched end tags are checked here so that the error points at the end tag.
        config.check_end_names = false;
        config.allow_unmatched_ends = true;
        config.check_comments = true;
        loop {
            let start = pos(reader.buffer_position());
            let event = match reader.read_event() {
                Ok(e) => e,
                Err(e) => return Self::fail(pos(reader.error_position()), e.to_string()),
            };
            let end = pos(reader.buffer_position());
            match event {
                Event::Start(e) => self.open(start, end, e.name().as_ref().len(), false)?,
                Event::Empty(e) => self.open(start, end, e.name().as_ref().len(), true)?,
                Event::End(e) => self.close(start, end, e.name().as_ref().len())?,
                Event::Text(_) => {
                    // The text is a slice of the input without references (those come as
                    // separate events), so only line ends may need normalising.
                    if !self.stack.last().is_some_and(|open| open.in_text) {
                        self.text(start, Cow::Borrowed(&self.input[start..end]))?;
                        continue;
                    }
                    let raw = &self.input[start..end];
                    let text = if raw.as_bytes().contains(&b'\r') {
                        Cow::Owned(raw.replace("\r\n", "\n").replace('\r', "\n"))
                    } else {
                        Cow::Borrowed(raw)
                    };
                    self.text(start, text)?;
                }
                Event::CData(t) => {
                    let text = t
                        .xml10_content()
                        .or_else(|e| Self::fail(start, e.to_string()))?;
                    self.text(start, text)?;
                }
                Event::GeneralRef(r) => {
                    let text = self.reference(start, &r)?;
                    self.text(start, text)?;
                }
                Event::Comment(_) | Event::PI(_) => self.end_text(),
                Event::Decl(_) => {
                    if start != 0 {
                        return Self::fail(
                            start,
                            "the XML declaration <?xml ...?> must be at the very start of the file",
                        );
                    }
                }
                Event::DocType(_) => {
                    if !self.doc.elements.is_empty() {
                        return Self::fail(start, "<!DOCTYPE> must come before the root element");
                    }
                    self.doctype(start, end)?;
                }
                Event::Eof => break,
            }
        }
        if let Some(open) = self.stack.last() {
            let at = self.doc.elements[open.id as usize].range.start;
            return Self::fail(at, format!("the element <{}> is never closed", open.qname));
        }
        if self.doc.elements.is_empty() {
            return Self::fail(self.input.len(), "the file holds no root element");
        }
        Ok(self.doc)
    }

    /// Starts an element; `start..end` is its start tag, `name_len` the length of its name.
    fn open(
        &mut self,
        start: usize,
        end: usize,
        name_len: usize,
        empty: bool,
    ) -> Result<(), Error> {
        let parent = match self.stack.last() {
            Some(open) => open.id,
            None if self.doc.elements.is_empty() => NONE,
            None => return Self::fail(start, "a second root element; an XML file has one root"),
        };
        self.end_text();
        let id = u32::try_from(self.doc.elements.len())
            .or_else(|_| Self::fail(start, "too many elements"))?;
        // The tag without `<` and `>` (or `/>`), sliced from the input so it borrows from it.
        let tag_end = if empty { end - 2 } else { end - 1 };
        let tag = &self.input[start + 1..tag_end];
        let qname = &tag[..name_len];
        let attr_start = self.doc.attributes.len();
        let mut bindings = 0;
        let mut rest = &tag[name_len..];
        while let Some((key, value, after)) = next_attribute(rest)
            .or_else(|message| Self::fail(start, format!("<{qname}>: {message}")))?
        {
            rest = after;
            let value = self.attribute_value(start, key, value)?;
            if key == "xmlns" || key.starts_with("xmlns:") {
                let prefix = key.strip_prefix("xmlns:").unwrap_or("");
                let ns = if value.is_empty() {
                    NONE
                } else {
                    self.doc.namespaces.push(value);
                    (self.doc.namespaces.len() - 1) as u32
                };
                self.scope.push(prefix);
                self.bindings(prefix).push(ns);
                bindings += 1;
                continue;
            }
            if self.is_duplicate(attr_start, key) {
                return Self::fail(start, format!("the attribute `{key}` appears twice"));
            }
            self.doc.attributes.push((key, value));
        }
        let (prefix, name) = match qname.split_once(':') {
            Some((p, n)) => (p, n),
            None => ("", qname),
        };
        let bound = match prefix {
            "" => self.default_ns.last(),
            _ => self.bound.get(prefix).and_then(|stack| stack.last()),
        };
        let namespace = match bound {
            Some(&ns) => ns,
            None if prefix.is_empty() => NONE,
            None if prefix == "xml" => {
                self.doc.namespaces.push(Cow::Borrowed(XML_NS));
                (self.doc.namespaces.len() - 1) as u32
            }
            None => {
                return Self::fail(
                    start,
                    format!("the namespace prefix `{prefix}` of <{qname}> is not declared"),
                )
            }
        };
        self.doc.elements.push(Element {
            name,
            namespace,
            parent,
            first_child: NONE,
            next_sibling: NONE,
            last_descendant: id,
            attributes: attr_start as u32..self.doc.attributes.len() as u32,
            text: None,
            range: start..end,
        });
        if let Some(open) = self.stack.last_mut() {
            if open.last_child == NONE {
                self.doc.elements[open.id as usize].first_child = id;
            } else {
                self.doc.elements[open.last_child as usize].next_sibling = id;
            }
            open.last_child = id;
        }
        let open = Open {
            id,
            qname,
            last_child: NONE,
            in_text: true,
            bindings,
        };
        if empty {
            self.finish(open, end);
        } else {
            self.stack.push(open);
        }
        Ok(())
    }

    /// Whether `key` is already among the attributes of the element being opened, which start
    /// at `attr_start`.
    fn is_duplicate(&mut self, attr_start: usize, key: &'i str) -> bool {
        let so_far = &self.doc.attributes[attr_start..];
        if so_far.len() < SCANNED_ATTRIBUTES {
            // Only when needed: clearing costs the set's capacity, which a big element grew.
            if !self.seen.is_empty() {
                self.seen.clear();
            }
            return so_far.iter().any(|(n, _)| *n == key);
        }
        if self.seen.is_empty() {
            self.seen.extend(so_far.iter().map(|(n, _)| *n));
        }
        !self.seen.insert(key)
    }

    /// Decodes an attribute value: entities, character references and the whitespace that XML
    /// turns into spaces. Most values have none of these and are borrowed as they are.
    fn attribute_value(
        &self,
        start: usize,
        key: &'i str,
        raw: &'i str,
    ) -> Result<Cow<'i, str>, Error> {
        if !raw.bytes().any(|b| b == b'&' || (is_space(b) && b != b' ')) {
            return Ok(Cow::Borrowed(raw));
        }
        let attr = Attribute {
            key: QName(key.as_bytes()),
            value: Cow::Borrowed(raw.as_bytes()),
        };
        let value = attr.normalized_value_with(XmlVersion::Implicit1_0, 1, |name| {
            // Past the limit the value is not built any further: the reference is refused, and
            // the error below says why.
            self.entity(name).filter(|_| !self.over_expansion_limit())
        });
        if self.over_expansion_limit() {
            return Self::too_much_expansion(start);
        }
        value.or_else(|e| Self::fail(start, format!("bad value of attribute `{key}`: {e}")))
    }

    /// Ends the open element at an end tag spanning `start..end`.
    fn close(&mut self, start: usize, end: usize, name_len: usize) -> Result<(), Error> {
        let found = &self.input[start + 2..start + 2 + name_len];
        let Some(open) = self.stack.pop() else {
            return Self::fail(start, format!("the end tag </{found}> closes no element"));
        };
        if open.qname != found {
            return Self::fail(
                start,
                format!("expected </{}>, found </{found}>", open.qname),
            );
        }
        self.finish(open, end);
        Ok(())
    }

    fn finish(&mut self, open: Open<'i>, end: usize) {
        let last = self.doc.elements.len() as u32 - 1;
        let el = &mut self.doc.elements[open.id as usize];
        el.range.end = end;
        el.last_descendant = last;
        for k in self.scope.len() - open.bindings..self.scope.len() {
            let prefix = self.scope[k];
            self.bindings(prefix).pop();
        }
        self.scope.truncate(self.scope.len() - open.bindings);
    }

    /// The namespaces `prefix` is bound to by the open elements, innermost last.
    fn bindings(&mut self, prefix: &'i str) -> &mut Vec<u32> {
        match prefix {
            "" => &mut self.default_ns,
            _ => self.bound.entry(prefix).or_default(),
        }
    }

    /// Ends the text run of the innermost open element: a child came.
    fn end_text(&mut self) {
        if let Some(open) = self.stack.last_mut() {
            open.in_text = false;
        }
    }

    fn text(&mut self, start: usize, piece: Cow<'i, str>) -> Result<(), Error> {
        let Some(open) = self.stack.last() else {
            if piece.bytes().all(is_space) {
                return Ok(());
            }
            return Self::fail(start, "text outside the root element");
        };
        if !open.in_text || piece.is_empty() {
            return Ok(());
        }
        let slot = &mut self.doc.elements[open.id as usize].text;
        match slot {
            None => *slot = Some(piece),
            Some(text) => text.to_mut().push_str(&piece),
        }
        Ok(())
    }

    fn reference(&self, start: usize, r: &BytesRef<'i>) -> Result<Cow<'i, str>, Error> {
        match r.resolve_char_ref() {
            Ok(Some(c)) => return Ok(Cow::Owned(c.to_string())),
            Ok(None) => {}
            Err(e) => return Self::fail(start, format!("bad character reference: {e}")),
        }
        let name = r.decode().or_else(|e| Self::fail(start, e.to_string()))?;
        match self.entity(&name) {
            Some(_) if self.over_expansion_limit() => Self::too_much_expansion(start),
            Some(text) => Ok(Cow::Borrowed(text)),
            None => Self::fail(
                start,
                format!("the entity `&{name};` is not defined; write `&amp;` for a literal `&`"),
            ),
        }
    }

    /// The replacement text of a predefined or internally declared entity; a declared one
    /// counts towards [`MAX_ENTITY_EXPANSION`].
    fn entity(&self, name: &str) -> Option<&'i str> {
        resolve_predefined_entity(name).or_else(|| {
            let text = *self.entities.get(name)?;
            self.expanded
                .set(self.expanded.get().saturating_add(text.len()));
            Some(text)
        })
    }

    /// Collects the internal general entities of `<!DOCTYPE ... [ ... ]>` whose replacement
    /// text is plain text; markup inside an entity is refused rather than silently misread.
    fn doctype(&mut self, start: usize, end: usize) -> Result<(), Error> {
        let mut rest = &self.input[start..end];
        while let Some(i) = rest.find("<!ENTITY") {
            rest = rest[i + "<!ENTITY".len()..].trim_start();
            if rest.starts_with('%') {
                continue;
            }
            let name_end = rest.find(|c: char| c.is_whitespace()).unwrap_or(rest.len());
            let name = &rest[..name_end];
            rest = rest[name_end..].trim_start();
            let Some(quote) = rest.chars().next().filter(|c| matches!(c, '"' | '\'')) else {
                // External entities (SYSTEM/PUBLIC) are never fetched.
                continue;
            };
            let Some(len) = rest[1..].find(quote) else {
                return Self::fail(start, format!("the entity `{name}` is not closed"));
            };
            let value = &rest[1..1 + len];
            if value.contains(['<', '&', '%']) {
                return Self::fail(
                    start,
                    format!("the entity `{name}` holds markup or references, which Cetratus does not expand"),
                );
            }
            // The first declaration of an entity binds it (XML 1.0 §4.2).
            self.entities.entry(name).or_insert(value);
            rest = &rest[1 + len..];
        }
        Ok(())
    }
}

/// Splits the first attribute off the inside of a start tag after its name: `(name, raw value,
/// rest)`, or `None` when only whitespace is left.
fn next_attribute(tag: &str) -> Result<Option<(&str, &str, &str)>, &'static str> {
    // Scans bytes, not chars: every delimiter is ASCII, so each index is a char boundary.
    let bytes = tag.as_bytes();
    let skip_space = |mut i: usize| {
        while bytes.get(i).is_some_and(|&b| is_space(b)) {
            i += 1;
        }
        i
    };
    let name_start = skip_space(0);
    if name_start == bytes.len() {
        return Ok(None);
    }
    if name_start == 0 {
        return Err("attributes must be separated by whitespace");
    }
    let mut name_end = name_start;
    while bytes
        .get(name_end)
        .is_some_and(|&b| !is_space(b) && !matches!(b, b'=' | b'"' | b'\'' | b'<' | b'>' | b'/'))
    {
        name_end += 1;
    }
    if name_end == name_start {
        return Err("expected an attribute name");
    }
    let eq = skip_space(name_end);
    if bytes.get(eq) != Some(&b'=') {
        return Err("an attribute name must be followed by `=` and a quoted value");
    }
    let open = skip_space(eq + 1);
    let Some(&quote) = bytes.get(open).filter(|&&b| b == b'"' || b == b'\'') else {
        return Err("an attribute value must be in quotes");
    };
    let Some(len) = bytes[open + 1..].iter().position(|&b| b == quote) else {
        return Err("an attribute value is not closed");
    };
    let value = &tag[open + 1..open + 1 + len];
    if value.as_bytes().contains(&b'<') {
        return Err("an attribute value must not hold `<`; write `&lt;`");
    }
    Ok(Some((
        &tag[name_start..name_end],
        value,
        &tag[open + 2 + len..],
    )))
}

/// XML's whitespace.
fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\r' | b'\n')
}

/// A reader position as an index; the input is a `&str`, so it always fits.
fn pos(p: u64) -> usize {
    usize::try_from(p).unwrap_or(usize::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tree_keeps_names_namespaces_attributes_text_and_ranges() {
        let input = "<?xml version=\"1.0\"?>\n<r xmlns=\"urn:x\"><a k=\"1&amp;2\">t&lt;<![CDATA[<c>]]>x\r\ny<b/>z</a><p:c xmlns:p=\"urn:p\"/></r>";
        let doc = Document::parse(input).expect("well-formed");
        let root = doc.root_element();
        assert_eq!((root.name(), root.namespace()), ("r", Some("urn:x")));
        let kids: Vec<_> = root.children().collect();
        assert_eq!(kids.len(), 2);
        assert_eq!(kids[0].attribute("k"), Some("1&2"));
        assert_eq!(kids[0].text(), Some("t<<c>x\ny"));
        assert_eq!(kids[1].namespace(), Some("urn:p"));
        assert_eq!(
            &input[kids[0].range()],
            "<a k=\"1&amp;2\">t&lt;<![CDATA[<c>]]>x\r\ny<b/>z</a>"
        );
        assert_eq!(root.descendants().count(), 4);
        assert_eq!(doc.text_pos_at(kids[0].range().start), (2, 18));
    }

    #[test]
    fn a_rebound_prefix_holds_inside_its_element_and_reverts_after_it() {
        let input = "<r xmlns:p=\"urn:1\" xmlns=\"urn:d\"><p:a xmlns:p=\"urn:2\" xmlns=\"\"><p:b/><c/></p:a><p:d/><e/></r>";
        let doc = Document::parse(input).expect("well-formed");
        let namespaces: Vec<_> = doc
            .root_element()
            .descendants()
            .map(|n| (n.name(), n.namespace()))
            .collect();
        assert_eq!(
            namespaces,
            [
                ("r", Some("urn:d")),
                ("a", Some("urn:2")),
                ("b", Some("urn:2")),
                ("c", None),
                ("d", Some("urn:1")),
                ("e", Some("urn:d")),
            ]
        );
        let err = Document::parse("<r><a xmlns:p=\"urn:1\"/><p:b/></r>").err();
        assert!(err.expect("out of scope").message.contains("`p`"));
    }

    #[test]
    fn duplicate_attributes_are_found_on_small_and_large_elements_alike() {
        let many: String = (0..40).map(|i| format!(" a{i}=\"v\"")).collect();
        let ok = format!("<r><x{many}/><y a1=\"1\" a2=\"2\"/><z{many}/></r>");
        assert!(Document::parse(&ok).is_ok());
        for bad in [
            format!("<r><x{many} a20=\"again\"/></r>"),
            format!("<r><x{many}/><y a1=\"1\" a1=\"2\"/></r>"),
            "<r a=\"1\" a=\"2\"/>".to_owned(),
        ] {
            let err = Document::parse(&bad).err().expect("a duplicate");
            assert!(err.message.contains("appears twice"), "{}", err.message);
        }
    }

    #[test]
    fn declared_entities_expand_up_to_the_limit_in_text_and_attributes() {
        let kb = "x".repeat(1000);
        let doc = |uses: usize, in_text: bool| {
            let refs = "&e;".repeat(uses);
            let body = if in_text {
                format!("<r>{refs}</r>")
            } else {
                format!("<r a=\"{refs}\"/>")
            };
            format!("<!DOCTYPE r [<!ENTITY e \"{kb}\">]>{body}")
        };
        let fits = MAX_ENTITY_EXPANSION / kb.len();
        for in_text in [true, false] {
            let input = doc(fits, in_text);
            let parsed = Document::parse(&input).expect("within the limit");
            let root = parsed.root_element();
            let value = if in_text {
                root.text()
            } else {
                root.attribute("a")
            };
            assert_eq!(value.map(str::len), Some(fits * kb.len()));
            let input = doc(fits + 1, in_text);
            let err = Document::parse(&input).err().expect("over the limit");
            assert_eq!(err.kind, ErrorKind::TooLarge);
            assert!(err.message.contains(&MAX_ENTITY_EXPANSION.to_string()));
        }
    }

    #[test]
    fn the_first_declaration_of_an_entity_binds_it() {
        let input = "<!DOCTYPE r [<!ENTITY e \"one\"><!ENTITY e \"two\">]><r>&e;</r>";
        let doc = Document::parse(input).expect("well-formed");
        assert_eq!(doc.root_element().text(), Some("one"));
    }

    #[test]
    fn malformed_documents_are_errors_with_an_offset() {
        for bad in [
            "",
            "<",
            "<a>",
            "<a></b>",
            "<a/><b/>",
            "x<a/>",
            "<a>&nope;</a>",
            "<p:a/>",
            "<a x='1' x='2'/>",
            "</a>",
        ] {
            let err = Document::parse(bad)
                .err()
                .unwrap_or_else(|| panic!("{bad} parsed"));
            assert!(err.offset <= bad.len(), "{bad}");
        }
    }
}
