//! A POU of a PLCopen file whose body is ST, LD or FBD, as a Structured Text program (docs/st.md,
//! *PLCopen XML*).
//!
//! The file's data types, its POUs with ST, LD or FBD bodies and its configuration are written
//! out as one Structured Text library ([`decl`]); an LD or FBD body becomes the statements its
//! network means ([`network`]). The library is then imported as `cetratus import st` imports a
//! file, so there is one Structured Text implementation, and the program carries the text it
//! runs. Each line of the text remembers where in the XML it came from, so that an error names
//! the file's line and column and the construct. IL, which the 3rd edition deprecates, is refused
//! by name; SFC bodies take the chart importer.

mod decl;
mod network;

use cetratus_net::xml::Document;
use cetratus_net::SourcePos;

use crate::pou::{self, Pou};
use crate::source::{child, Source};
use crate::structured::{import_st_from, ImportedSt};
use crate::SfcError;

/// The language of a POU's body, as its element names it (`ST`, `LD`, `FBD`, `SFC`, `IL`).
pub(crate) fn body_language<'a>(pou: &Pou<'a, '_>) -> Option<&'a str> {
    child(pou.node, "body")
        .and_then(|b| b.children().next())
        .map(|l| l.name())
}

/// Whether a body in this language is written out as Structured Text.
fn textual(language: &str) -> bool {
    matches!(language, "ST" | "LD" | "FBD")
}

/// Imports the POU `name` (ST, LD or FBD body) of a PLCopen file as a program.
pub(crate) fn import(
    source: &Source,
    doc: &Document,
    name: &str,
    notes: &mut Vec<String>,
) -> Result<ImportedSt, SfcError> {
    let mut noted = decl::Notes::new(*source);
    let pous = pou::pous(source, doc);
    let chosen = pous
        .iter()
        .find(|p| p.name.eq_ignore_ascii_case(name))
        .ok_or_else(|| SfcError::Pou {
            file: source.label.to_string(),
            message: format!("no POU `{name}`; the file's POUs are: {}", listing(&pous)),
        })?;
    let language = body_language(chosen).unwrap_or("no body");
    if !textual(language) {
        return Err(SfcError::Unsupported {
            pos: source.pos(chosen.node.range().start),
            pou: chosen.name.clone(),
            construct: format!("a POU with an {language} body"),
            message: if language == "IL" {
                "Instruction List is deprecated by IEC 61131-3 (3rd edition) and is not imported; rewrite the POU in ST, LD or FBD".into()
            } else {
                "export the POU in ST, LD, FBD or SFC".into()
            },
        });
    }
    let mut out = Written::default();
    let run = decl::library(source, doc, (&pous, chosen), None, &mut out, &mut noted)?;
    notes.append(&mut noted.lines);
    let what = format!("{language} from PLCopen XML");
    import_st_from(
        &out.text,
        source.label,
        Some(&run),
        &what,
        &|line, column| out.locate(source, line, column),
    )
    .map_err(|e| hint_skipped(e, &pous))
}

/// The Structured Text of an SFC POU's chart: the file's data types and the POUs the chart
/// uses, then the chart's POU `chosen` with its interface and the chart's own variables
/// (`chart_vars`), and no body; with where each line came from, and what was noted.
pub(crate) fn chart_library(
    source: &Source,
    doc: &Document,
    chosen: &str,
    chart_vars: &[String],
    notes: &mut Vec<String>,
) -> Result<Written, SfcError> {
    let mut noted = decl::Notes::new(*source);
    let pous = pou::pous(source, doc);
    let Some(pou) = pous.iter().find(|p| p.name == chosen) else {
        return Err(SfcError::Pou {
            file: source.label.to_string(),
            message: format!("no POU `{chosen}`; the file's POUs are: {}", listing(&pous)),
        });
    };
    let mut out = Written::default();
    decl::library(
        source,
        doc,
        (&pous, pou),
        Some(chart_vars),
        &mut out,
        &mut noted,
    )?;
    notes.append(&mut noted.lines);
    Ok(out)
}

/// An LD or FBD network of a chart, the body of one of the named actions or transitions of
/// `pou` (the element at byte `at` of the file), as Structured Text: its statements, the
/// declarations it needs in the chart's POU (`name : type`: the block instances the interface
/// does not declare, and the values the network keeps between its elements), and what the
/// importer added that the file did not say. With `renamed` `(name, id)`, the body of the named
/// transition `name`, assigning its value to the transition `id` that refers to it.
pub(crate) fn chart_network(
    source: &Source,
    doc: &Document,
    pou: &Pou,
    at: usize,
    renamed: Option<(&str, &str)>,
) -> Result<(String, Vec<String>, Vec<String>), SfcError> {
    let pous = pou::pous(source, doc);
    let names = network::Names::of(doc, &pous);
    let Some(body) = pou.node.descendants().find(|n| n.range().start == at) else {
        return Err(SfcError::Pou {
            file: source.label.to_string(),
            message: format!("no network at {} in `{}`", source.pos(at), pou.name),
        });
    };
    let lowered = network::lower(source, pou, body, &names, renamed)?;
    Ok(chart_text(source, lowered))
}

/// A network drawn in a chart of `pou` and wired to a transition's condition, whose
/// `<connectionPointIn>` is at byte `at` of the file, as Structured Text that assigns its value
/// to `result` (the transition's id); the same parts as [`chart_network`]'s.
pub(crate) fn chart_condition(
    source: &Source,
    doc: &Document,
    pou: &Pou,
    at: usize,
    result: &str,
) -> Result<(String, Vec<String>, Vec<String>), SfcError> {
    let pous = pou::pous(source, doc);
    let names = network::Names::of(doc, &pous);
    let within = |n: &cetratus_net::xml::Node| n.range().contains(&at);
    let sfc = (pou.node.descendants())
        .filter(|n| n.name() == "SFC" && within(n))
        .last();
    let point = pou.node.descendants().find(|n| n.range().start == at);
    let (Some(sfc), Some(point)) = (sfc, point) else {
        return Err(SfcError::Pou {
            file: source.label.to_string(),
            message: format!("no condition at {} in `{}`", source.pos(at), pou.name),
        });
    };
    let lowered = network::lower_condition(source, pou, (sfc, point), result, &names)?;
    Ok(chart_text(source, lowered))
}

/// A lowered network as a chart's text: its statements, its declarations and its notes.
fn chart_text(source: &Source, lowered: network::Lowered) -> (String, Vec<String>, Vec<String>) {
    let (stmts, decls, notes) = lowered.into_parts();
    let text: String = stmts.iter().map(|(_, s)| format!("{s}\n")).collect();
    let notes = (notes.into_iter())
        .map(|(at, note)| format!("{}: {note}", source.pos(at)))
        .collect();
    (text, decls, notes)
}

/// `NAME (LANGUAGE)` for every POU of the file.
pub(crate) fn listing(pous: &[Pou]) -> String {
    let all: Vec<String> = pous
        .iter()
        .map(|p| format!("{} ({})", p.name, body_language(p).unwrap_or("no body")))
        .collect();
    if all.is_empty() {
        "none".into()
    } else {
        all.join(", ")
    }
}

/// An error that names a POU which was not written out (IL or SFC) says why it is missing.
fn hint_skipped(e: SfcError, pous: &[Pou]) -> SfcError {
    let SfcError::St { pos, pou, message } = e else {
        return e;
    };
    let lower = message.to_ascii_lowercase();
    let skipped = pous.iter().find(|p| {
        body_language(p).is_some_and(|l| !textual(l))
            && lower.contains(&format!("`{}`", p.name.to_ascii_lowercase()))
    });
    let message = match skipped {
        Some(p) => format!(
            "{message} (`{}` has an {} body, which a Structured Text program cannot call: IL is not imported and an SFC imports as a program of its own)",
            p.name,
            body_language(p).unwrap_or("other")
        ),
        None => message,
    };
    SfcError::St { pos, pou, message }
}

/// Structured Text written from a PLCopen file, each line with where it came from.
#[derive(Default)]
pub(crate) struct Written {
    /// The text.
    pub text: String,
    /// Per line: the byte offset in the file it came from, and whether the line is the file's
    /// own text (an ST body), whose columns are the file's too.
    origins: Vec<(usize, bool)>,
}

impl Written {
    /// Writes one line of generated text that comes from the element at byte offset `at`.
    pub fn line(&mut self, at: usize, line: &str) {
        for part in line.split('\n') {
            self.text.push_str(part);
            self.text.push('\n');
            self.origins.push((at, false));
        }
    }

    /// Writes an ST body as it is in the file, whose text starts at byte offset `at`.
    pub fn verbatim(&mut self, source: &Source, at: usize, body: &str) {
        let mut from = at;
        for part in body.trim_end().split('\n') {
            self.text.push_str(part.trim_end_matches('\r'));
            self.text.push('\n');
            self.origins.push((from, true));
            // The next line starts after the next newline of the file's own text.
            from = source.text[from.min(source.text.len())..]
                .find('\n')
                .map_or(source.text.len(), |i| from + i + 1);
        }
    }

    /// The file position of line `line`, column `column` (1-based) of the text, and the line
    /// itself when the importer wrote it (a message then quotes what it is about).
    pub(crate) fn locate(
        &self,
        source: &Source,
        line: u32,
        column: u32,
    ) -> (SourcePos, Option<String>) {
        let index = line.saturating_sub(1) as usize;
        let Some(&(at, verbatim)) = self.origins.get(index) else {
            return (source.pos(0), None);
        };
        let mut pos = source.pos(at);
        if verbatim {
            pos.column += column.saturating_sub(1);
            return (pos, None);
        }
        let quoted = self.text.lines().nth(index).map(|l| l.trim().to_string());
        (pos, quoted)
    }
}
