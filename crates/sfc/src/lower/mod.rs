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

pub use decl::STEP_TYPE;

use std::cell::OnceCell;
use std::collections::HashMap;

use cetratus_net::xml::{Document, Node};
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
    let mut noted = decl::Notes::new(source);
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
    let names = network::Names::of(doc, &pous);
    let run = decl::library(
        source,
        doc,
        (&pous, chosen),
        &names,
        None,
        &mut out,
        &mut noted,
    )?;
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

/// The LD and FBD networks of an SFC POU's chart, lowered from what is read of the file once per
/// chart: the file's names, the POU's elements by where they start, and the network elements
/// drawn in each of its charts. A chart of many networks so costs the sum of their sizes, not
/// their number times the file's.
pub(crate) struct ChartNetworks<'s, 'a, 'i> {
    source: &'s Source<'s>,
    /// The file's POUs, and the chart's among them.
    pous: &'s [Pou<'a, 'i>],
    pou: &'s Pou<'a, 'i>,
    names: network::Names,
    /// The POU's elements by the byte where they start (the outermost, where several do).
    nodes: HashMap<usize, Node<'a, 'i>>,
    /// The POU's SFC bodies in document order, each with its drawn network once read.
    charts: Vec<(
        Node<'a, 'i>,
        OnceCell<Result<network::Drawn, network::Refused>>,
    )>,
}

impl<'s, 'a, 'i> ChartNetworks<'s, 'a, 'i> {
    /// The networks of the chart of `pou`, one of the POUs `pous` of the file `doc`.
    pub(crate) fn new(
        source: &'s Source<'s>,
        doc: &Document,
        (pous, pou): (&'s [Pou<'a, 'i>], &'s Pou<'a, 'i>),
    ) -> Self {
        let names = network::Names::of(doc, pous);
        let mut nodes = HashMap::new();
        let mut charts = Vec::new();
        for n in pou.node.descendants() {
            nodes.entry(n.range().start).or_insert(n);
            if n.name() == "SFC" {
                charts.push((n, OnceCell::new()));
            }
        }
        ChartNetworks {
            source,
            pous,
            pou,
            names,
            nodes,
            charts,
        }
    }

    /// The Structured Text of the chart's POU: the file's data types and the POUs the chart
    /// uses, then the chart's POU with its interface and the chart's own variables
    /// (`chart_vars`), and no body; with where each line came from, and what was noted.
    pub(crate) fn library(
        &self,
        doc: &Document,
        chart_vars: &[String],
        notes: &mut Vec<String>,
    ) -> Result<Written, SfcError> {
        let mut noted = decl::Notes::new(self.source);
        let mut out = Written::default();
        let (pous, chart) = ((self.pous, self.pou), Some(chart_vars));
        decl::library(
            self.source,
            doc,
            pous,
            &self.names,
            chart,
            &mut out,
            &mut noted,
        )?;
        notes.append(&mut noted.lines);
        Ok(out)
    }

    /// The element of the POU at byte `at`, or the error that no `what` is there.
    fn node(&self, at: usize, what: &str) -> Result<Node<'a, 'i>, SfcError> {
        (self.nodes.get(&at).copied()).ok_or_else(|| self.missing(at, what))
    }

    /// The error that the POU has no `what` at byte `at`.
    fn missing(&self, at: usize, what: &str) -> SfcError {
        SfcError::Pou {
            file: self.source.label.to_string(),
            message: format!(
                "no {what} at {} in `{}`",
                self.source.pos(at),
                self.pou.name
            ),
        }
    }

    /// The body of one of the chart's named actions or transitions (the element at byte `at`
    /// of the file) as Structured Text: its statements, the declarations it needs in the
    /// chart's POU (`name : type`: the block instances the interface does not declare, and the
    /// values the network keeps between its elements), and what the importer added that the
    /// file did not say. With `renamed` `(name, id)`, the body of the named transition `name`,
    /// assigning its value to the transition `id` that refers to it.
    pub(crate) fn body(&self, at: usize, renamed: Option<(&str, &str)>) -> Result<Text, SfcError> {
        let body = self.node(at, "network")?;
        let lowered = network::lower(self.source, self.pou, body, &self.names, renamed)?;
        Ok(chart_text(self.source, lowered))
    }

    /// A network drawn in the chart and wired to a transition's condition, whose
    /// `<connectionPointIn>` is at byte `at` of the file, as Structured Text that assigns its
    /// value to `result` (the transition's id); the same parts as [`ChartNetworks::body`]'s.
    pub(crate) fn condition(&self, at: usize, result: &str) -> Result<Text, SfcError> {
        let point = self.node(at, "condition")?;
        let within = (self.charts.iter()).rfind(|(n, _)| n.range().contains(&at));
        let Some((sfc, drawn)) = within else {
            return Err(self.missing(at, "chart around the condition"));
        };
        let drawn = (drawn.get_or_init(|| network::Drawn::read(*sfc)).as_ref())
            .map_err(|r| network::refusal(self.source, self.pou)(r.clone()))?;
        let lowered =
            network::lower_condition(self.source, self.pou, (drawn, point), result, &self.names)?;
        Ok(chart_text(self.source, lowered))
    }
}

/// A network of a chart as Structured Text: its statements, the declarations it needs, and the
/// notes of its lowering.
pub(crate) type Text = (String, Vec<String>, Vec<String>);

/// A lowered network as a chart's text: its statements, its declarations and its notes.
fn chart_text(source: &Source, lowered: network::Lowered) -> Text {
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
