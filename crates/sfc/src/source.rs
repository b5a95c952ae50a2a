//! The PLCopen file as text: its label, the limits on it, and positions for messages.

use std::cell::OnceCell;

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
pub(crate) struct Source<'t> {
    pub label: &'t str,
    pub text: &'t str,
    /// The line and column at every [`MARK_BYTES`]th byte, found when a position is first
    /// asked for: a position then costs a scan of at most that many bytes, not of the text
    /// before it, however many the import names (a note per element of a large file).
    marks: OnceCell<Vec<(u32, u32)>>,
}

/// How far apart the marks of [`Source`] are.
const MARK_BYTES: usize = 4096;

impl<'t> Source<'t> {
    /// The text `text` of the file named `label` in messages.
    pub fn new(label: &'t str, text: &'t str) -> Self {
        Source {
            label,
            text,
            marks: OnceCell::new(),
        }
    }

    /// The file:line:column of a byte offset.
    pub fn pos(&self, offset: usize) -> SourcePos {
        let bytes = self.text.as_bytes();
        let marks = self.marks.get_or_init(|| {
            let mut at = (1, 1);
            let chunks = bytes.chunks(MARK_BYTES);
            let mark = |c| {
                let before = at;
                at = advance(at, c);
                before
            };
            chunks.map(mark).collect()
        });
        let mut end = offset.min(bytes.len());
        while !self.text.is_char_boundary(end) {
            end -= 1;
        }
        let k = (end / MARK_BYTES).min(marks.len().saturating_sub(1));
        let from = marks.get(k).copied().unwrap_or((1, 1));
        let (line, column) = advance(from, &bytes[k * MARK_BYTES..end]);
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

/// The line and column after `bytes`, from `(line, column)` before them: a column counts
/// characters, which are the bytes that do not continue a UTF-8 sequence.
fn advance((line, column): (u32, u32), bytes: &[u8]) -> (u32, u32) {
    let chars = |b: &[u8]| b.iter().filter(|&&b| b & 0xC0 != 0x80).count();
    let count = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    match bytes.iter().rposition(|&b| b == b'\n') {
        Some(last) => {
            let newlines = bytes.iter().filter(|&&b| b == b'\n').count();
            let after = chars(&bytes[last + 1..]);
            (line.saturating_add(count(newlines)), 1 + count(after))
        }
        None => (line, column.saturating_add(count(chars(bytes)))),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The marks give every offset the position that counting from the start gives: across
    /// marks, in multi-byte characters, on long lines and on empty ones.
    #[test]
    fn a_position_from_the_marks_is_the_position_counted_from_the_start() {
        let line = |i: usize| {
            "é€x".repeat(i * 131 % 400) + if i.is_multiple_of(5) { "\n\n" } else { "\n" }
        };
        let text: String = (0..24).map(line).collect();
        let source = Source::new("f.xml", &text);
        for offset in (0..=text.len() + 3)
            .step_by(11)
            .chain([0, 4096, 8192, text.len()])
        {
            let pos = source.pos(offset);
            let mut end = offset.min(text.len());
            while !text.is_char_boundary(end) {
                end -= 1;
            }
            let counted = Document::text_pos_at_in(&text, end);
            assert_eq!((pos.line, pos.column), counted, "offset {offset}");
        }
        assert_eq!(Source::new("e", "").pos(5).line, 1);
    }
}
