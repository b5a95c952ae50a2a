//! The PLCopen file as text: its label, the limits on it, and positions for messages.

use cetratus_net::xml::{Document, ErrorKind, Node};
use cetratus_net::SourcePos;

use crate::SfcError;

/// The namespaces of PLCopen TC6 XML 2.00 and 2.01, by which a file is recognised.
pub const NAMESPACES: [&str; 2] = [
    "http://www.plcopen.org/xml/tc6_0200",
    "http://www.plcopen.org/xml/tc6_0201",
];

/// Most bytes a PLCopen file may have. The largest editor exports of whole projects seen are a
/// few megabytes; a chart is kilobytes.
pub const MAX_FILE_BYTES: usize = 32 << 20;

/// Most XML elements a PLCopen file may have (about one per 30 bytes at the size limit).
pub const MAX_ELEMENTS: usize = 1 << 20;

/// A PLCopen file's text and the label that names it in messages.
#[derive(Clone, Copy)]
pub(crate) struct Source<'t> {
    pub label: &'t str,
    pub text: &'t str,
}

impl<'t> Source<'t> {
    /// The file:line:column of a byte offset.
    pub fn pos(&self, offset: usize) -> SourcePos {
        let (line, column) = Document::text_pos_at_in(self.text, offset);
        SourcePos {
            file: self.label.to_string(),
            line,
            column,
        }
    }

    /// Parses the text as XML, within the limits.
    pub fn parse(&self) -> Result<Document<'t>, SfcError> {
        if self.text.len() > MAX_FILE_BYTES {
            return Err(SfcError::TooLarge {
                pos: self.pos(0),
                message: format!(
                    "the file has {} bytes, more than the {MAX_FILE_BYTES} a PLCopen file may have; export only the POU to import",
                    self.text.len()
                ),
            });
        }
        let doc = Document::parse(self.text).map_err(|e| match e.kind {
            ErrorKind::Malformed => SfcError::Malformed {
                pos: self.pos(e.offset),
                message: format!(
                    "not well-formed XML: {}; fix the XML or export it again",
                    e.message
                ),
            },
            ErrorKind::TooLarge => SfcError::TooLarge {
                pos: self.pos(e.offset),
                message: e.message,
            },
        })?;
        let root = doc.root_element();
        let elements = root.descendants().count();
        if elements > MAX_ELEMENTS {
            return Err(SfcError::TooLarge {
                pos: self.pos(0),
                message: format!(
                    "the file has {elements} XML elements, more than the {MAX_ELEMENTS} a PLCopen file may have; export only the POU to import"
                ),
            });
        }
        if root.name() != "project" || !root.namespace().is_some_and(|n| NAMESPACES.contains(&n)) {
            return Err(SfcError::Malformed {
                pos: self.pos(root.range().start),
                message: format!(
                    "not PLCopen TC6 XML: the root element is <{}> in namespace `{}`; expected <project xmlns=\"{}\"> (or tc6_0200)",
                    root.name(),
                    root.namespace().unwrap_or(""),
                    NAMESPACES[1]
                ),
            });
        }
        Ok(doc)
    }
}

/// Whether a text is PLCopen TC6 XML, by the namespace of its root element (read from the start
/// of the text only, so a PNML file named `.xml` is told apart cheaply).
pub fn is_plcopen(text: &str) -> bool {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    // The root start tag is within the first few kilobytes of any export (after the declaration
    // and comments); a bounded look keeps this cheap on a huge file.
    let mut end = text.len().min(16 * 1024);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    let head = &text[..end];
    let Some(at) = head.find("<project") else {
        return false;
    };
    let tag_end = head[at..].find('>').map_or(head.len(), |i| at + i);
    let tag = &head[at..tag_end];
    NAMESPACES.iter().any(|ns| tag.contains(ns))
}

/// The first child element of `node` with the local name `name`.
pub(crate) fn child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|c| c.name() == name)
}

/// The child elements of `node` with the local name `name`.
pub(crate) fn children<'a, 'i: 'a>(
    node: Node<'a, 'i>,
    name: &'a str,
) -> impl Iterator<Item = Node<'a, 'i>> + 'a {
    node.children().filter(move |c| c.name() == name)
}

/// The text of a body written in a textual language (`<ST>`, `<IL>`): in an xhtml element (`<p>`
/// or `<xhtml>`) as the schema wants, or bare as some editors write it; with the byte offset at
/// which the text starts in the file.
pub(crate) fn body_text(source: &Source, node: Node) -> Option<(String, usize)> {
    let holder = node
        .children()
        .next()
        .filter(|c| c.text().is_some())
        .unwrap_or(node);
    let text = holder.text()?;
    Some((text.to_string(), text_start(source, holder)))
}

/// The byte offset where an element's text starts: after its start tag and a CDATA opener.
fn text_start(source: &Source, node: Node) -> usize {
    let r = node.range();
    let tag = &source.text[r.clone()];
    let mut at = tag.find('>').map_or(r.start, |i| r.start + i + 1);
    let rest = &source.text[at..];
    let trimmed = rest.trim_start();
    if trimmed.starts_with("<![CDATA[") {
        at += rest.len() - trimmed.len() + "<![CDATA[".len();
    }
    at
}
