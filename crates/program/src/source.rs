//! The program file (TOML): its schema and the mapping of byte offsets to file:line:column.

use std::collections::BTreeMap;

use cetratus_net::SourcePos;
use serde::Deserialize;
use toml::Spanned;

use crate::ProgramError;

/// A whole program file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Doc {
    pub program: ProgramSection,
    #[serde(default)]
    pub input: Vec<Spanned<SignalDecl>>,
    #[serde(default)]
    pub output: Vec<Spanned<SignalDecl>>,
    #[serde(default)]
    pub variable: Vec<Spanned<SignalDecl>>,
    #[serde(default)]
    pub guards: BTreeMap<Spanned<String>, Spanned<String>>,
    #[serde(default)]
    pub action: Vec<Spanned<ActionDecl>>,
    #[serde(default)]
    pub invariant: Vec<Spanned<InvariantDecl>>,
}

/// `[program]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ProgramSection {
    pub name: Spanned<String>,
    pub version: Spanned<String>,
    #[serde(default)]
    pub description: String,
    /// Read by `Program::load` through [`NetOnly`]; accepted here so the schema stays closed.
    #[allow(dead_code)]
    pub net: Option<Spanned<String>>,
    pub policy: Option<Spanned<String>>,
    pub scan_period: Option<Spanned<String>>,
}

/// `[[input]]`, `[[output]]` or `[[variable]]`; which fields apply depends on the kind.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SignalDecl {
    pub name: Spanned<String>,
    #[serde(rename = "type")]
    pub ty: Spanned<String>,
    pub address: Option<Spanned<String>>,
    #[serde(default)]
    pub description: String,
    pub safe: Option<Spanned<toml::Value>>,
    pub initial: Option<Spanned<toml::Value>>,
    pub retain: Option<Spanned<bool>>,
}

/// `[[action]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ActionDecl {
    pub place: Spanned<String>,
    pub qualifier: Spanned<String>,
    pub target: Spanned<String>,
    pub duration: Option<Spanned<String>>,
}

/// `[[invariant]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct InvariantDecl {
    pub expr: Spanned<String>,
}

/// Just the net file name, read before the rest so the net can be loaded first.
#[derive(Debug, Deserialize)]
pub(crate) struct NetOnly {
    pub program: NetOnlySection,
}

/// `[program]` seen by [`NetOnly`].
#[derive(Debug, Deserialize)]
pub(crate) struct NetOnlySection {
    pub net: Option<Spanned<String>>,
}

/// Where a program text lives: its label and, when it is embedded in another file, the line and
/// column its first character has there.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Origin<'a> {
    pub text: &'a str,
    pub label: &'a str,
    pub line: u32,
    pub column: u32,
}

impl<'a> Origin<'a> {
    /// A stand-alone text: its first character is at 1:1.
    pub fn new(text: &'a str, label: &'a str) -> Self {
        Origin {
            text,
            label,
            line: 1,
            column: 1,
        }
    }

    /// The 1-based line and column (in characters) of a byte offset.
    pub fn pos(&self, offset: usize) -> SourcePos {
        let offset = offset.min(self.text.len());
        // A byte offset inside a multi-byte character moves back to its start.
        let offset = (0..=offset)
            .rev()
            .find(|&o| self.text.is_char_boundary(o))
            .unwrap_or(0);
        let before = &self.text[..offset];
        let line0 = before.matches('\n').count() as u32;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let col0 = before[line_start..].chars().count() as u32;
        SourcePos {
            file: self.label.to_string(),
            line: self.line + line0,
            column: if line0 == 0 {
                self.column + col0
            } else {
                col0 + 1
            },
        }
    }

    /// An error at a byte offset.
    pub fn err(&self, offset: usize, message: impl Into<String>) -> ProgramError {
        ProgramError::At {
            pos: self.pos(offset),
            message: message.into(),
        }
    }

    /// Maps an offset inside a TOML string value (as decoded) to an offset in the text.
    ///
    /// Exact when the string has no escapes; otherwise it points at the string's first character.
    pub fn in_string(&self, value: &Spanned<String>, offset: usize) -> usize {
        let span = value.span();
        let raw = self.text.get(span.clone()).unwrap_or("");
        let (open, close) = if raw.starts_with("\"\"\"") || raw.starts_with("'''") {
            (3, 3)
        } else {
            (1, 1)
        };
        let mut start = span.start + open;
        let inner_end = span.end.saturating_sub(close).max(start);
        let mut inner = self.text.get(start..inner_end).unwrap_or("");
        // TOML drops a newline right after the opening delimiter of a multi-line string.
        if open == 3 {
            if let Some(rest) = inner.strip_prefix("\r\n") {
                start += 2;
                inner = rest;
            } else if let Some(rest) = inner.strip_prefix('\n') {
                start += 1;
                inner = rest;
            }
        }
        if inner == value.get_ref().as_str() {
            start + offset
        } else {
            start
        }
    }
}

/// Extracts the program text from a `<toolspecific>` element: its CDATA section if it has one,
/// else its text with the XML entities decoded. Returns the text and its byte offset in `xml`.
pub(crate) fn toolspecific_text(xml: &str) -> Option<(String, usize)> {
    if let Some(open) = xml.find("<![CDATA[") {
        let start = open + "<![CDATA[".len();
        let len = xml[start..].find("]]>")?;
        return Some((xml[start..start + len].to_string(), start));
    }
    let start = xml.find('>')? + 1;
    let end = xml.rfind("</")?;
    if end < start {
        return Some((String::new(), start));
    }
    let raw = &xml[start..end];
    let mut out = String::with_capacity(raw.len());
    let mut rest = raw;
    while let Some(amp) = rest.find('&') {
        out.push_str(&rest[..amp]);
        let tail = &rest[amp..];
        let semi = tail.find(';')?;
        let ent = &tail[1..semi];
        let ch = match ent {
            "lt" => '<',
            "gt" => '>',
            "amp" => '&',
            "quot" => '"',
            "apos" => '\'',
            _ if ent.starts_with("#x") => char::from_u32(u32::from_str_radix(&ent[2..], 16).ok()?)?,
            _ if ent.starts_with('#') => char::from_u32(ent[1..].parse().ok()?)?,
            _ => return None,
        };
        out.push(ch);
        rest = &tail[semi + 1..];
    }
    out.push_str(rest);
    Some((out, start))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_count_lines_and_columns_from_one() {
        let o = Origin::new("a = 1\nbc = 2\n", "f.toml");
        let p = o.pos(7);
        assert_eq!((p.line, p.column), (2, 2));
    }

    #[test]
    fn an_embedded_text_is_offset_by_its_origin() {
        let o = Origin {
            text: "x\ny",
            label: "f.pnml",
            line: 10,
            column: 5,
        };
        assert_eq!((o.pos(0).line, o.pos(0).column), (10, 5));
        assert_eq!((o.pos(2).line, o.pos(2).column), (11, 1));
    }

    #[test]
    fn cdata_is_taken_verbatim() {
        let xml =
            "<toolspecific tool=\"cetratus\" version=\"1\"><![CDATA[a = \"<b>\"]]></toolspecific>";
        let (text, at) = toolspecific_text(xml).unwrap_or_default();
        assert_eq!(text, "a = \"<b>\"");
        assert_eq!(&xml[at..at + 1], "a");
    }

    #[test]
    fn plain_text_has_its_entities_decoded() {
        let xml = "<toolspecific tool=\"cetratus\" version=\"1\">x = &quot;a &amp;&amp; b&quot;</toolspecific>";
        assert_eq!(
            toolspecific_text(xml).map(|t| t.0).as_deref(),
            Some("x = \"a && b\"")
        );
    }
}
