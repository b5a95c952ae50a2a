//! The program file (TOML): its schema and the mapping of byte offsets to file:line:column.

use std::collections::BTreeMap;
use std::fmt;

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
    pub bodies: BTreeMap<Spanned<String>, Spanned<String>>,
    #[serde(default)]
    pub action: Vec<Spanned<ActionDecl>>,
    #[serde(default)]
    pub invariant: Vec<Spanned<InvariantDecl>>,
    #[serde(default)]
    pub watchdog: Vec<Spanned<WatchdogDecl>>,
    pub stall: Option<Spanned<StallDecl>>,
    pub st: Option<Spanned<StDecl>>,
}

/// `[st]`: the program's Structured Text and the POU an action runs.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct StDecl {
    pub pou: Spanned<String>,
    pub source: Spanned<String>,
    /// `[st.bodies]`: action bodies in ST, on the POU's state (a chart's actions).
    #[serde(default)]
    pub bodies: BTreeMap<Spanned<String>, Spanned<String>>,
    /// `[st.conditions]`: transition id to an ST BOOL expression, its guard.
    #[serde(default)]
    pub conditions: BTreeMap<Spanned<String>, Spanned<String>>,
    /// `[st.steps]`: place id to the POU's variable that holds its step flags (`X`, `T`).
    #[serde(default)]
    pub steps: BTreeMap<Spanned<String>, Spanned<String>>,
}

impl StDecl {
    /// Whether the ST is a chart's: entries of its own, the POU's body not run.
    pub fn is_chart(&self) -> bool {
        !(self.bodies.is_empty() && self.conditions.is_empty() && self.steps.is_empty())
    }
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
    /// `"sfc"`: the net is an IEC 61131-3 chart (online change starts added steps inactive).
    pub chart: Option<Spanned<String>>,
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
    pub target: Option<Spanned<String>>,
    pub body: Option<Spanned<String>>,
    pub duration: Option<Spanned<String>>,
}

/// `[[invariant]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct InvariantDecl {
    pub expr: Spanned<String>,
}

/// `[[watchdog]]`: a place's maximum dwell time.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct WatchdogDecl {
    pub place: Spanned<String>,
    pub max: Spanned<String>,
}

/// `[stall]`: the program-wide stall condition.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct StallDecl {
    pub no_firing: Spanned<String>,
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

/// A TOML file that is not UTF-8: where its first byte that is not.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NotUtf8 {
    /// The file, line and column of the byte.
    pub pos: SourcePos,
    /// Its offset in the file, from 0.
    pub offset: usize,
    /// The byte.
    pub byte: u8,
}

impl NotUtf8 {
    /// What is wrong and what to do, without the position.
    pub fn message(&self) -> String {
        format!(
            "the file is not UTF-8: the byte 0x{:02X} at byte offset {} is not valid UTF-8 (text in Latin-1 or a Windows code page?); a TOML file must be UTF-8, so save it as UTF-8",
            self.byte, self.offset
        )
    }
}

impl fmt::Display for NotUtf8 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.pos, self.message())
    }
}

impl std::error::Error for NotUtf8 {}

impl From<NotUtf8> for ProgramError {
    fn from(e: NotUtf8) -> Self {
        ProgramError::At {
            message: e.message(),
            pos: e.pos,
        }
    }
}

/// The text of a TOML file (a program, a package manifest, a configuration; `label` names it in
/// the error). TOML is UTF-8 by definition, so any other byte is an error rather than a guess: a
/// PNML file may be ISO-8859-1, as its XML declaration says, but a TOML file has no declaration.
pub fn toml_text(bytes: Vec<u8>, label: &str) -> Result<String, NotUtf8> {
    String::from_utf8(bytes).map_err(|e| {
        let offset = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        // Everything before the offset is valid UTF-8, so it maps to a line and a column.
        let before = std::str::from_utf8(&bytes[..offset]).unwrap_or_default();
        NotUtf8 {
            pos: Origin::new(before, label).pos(offset),
            offset,
            byte: bytes.get(offset).copied().unwrap_or_default(),
        }
    })
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
    fn a_toml_text_that_is_not_utf8_names_the_byte_and_its_position() {
        let e = toml_text(b"a = 1\nb = \"caf\xE9\"\n".to_vec(), "f.toml").err();
        let e = e.expect("Latin-1 is refused");
        assert_eq!((e.offset, e.byte), (14, 0xE9));
        assert_eq!((e.pos.line, e.pos.column), (2, 9));
        assert!(e
            .to_string()
            .starts_with("f.toml:2:9: the file is not UTF-8"));
        assert!(e.to_string().contains("byte offset 14"));
        assert_eq!(
            toml_text("é = 1".into(), "f.toml").ok().as_deref(),
            Some("é = 1")
        );
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
