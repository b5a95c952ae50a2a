//! IEC 61131-3 Sequential Function Charts from PLCopen TC6 XML, as Cetratus programs.
//!
//! [`charts`] reads every SFC chart of a PLCopen file as drawn ([`Chart`]); [`import_str`] turns
//! the chart of one POU into a net and a program TOML by the mapping of docs/sfc.md: steps become
//! places, transitions transitions, a selection divergence a conflict resolved left to right
//! through priorities, simultaneous branches fork and join transitions, jumps arcs to their
//! target, conditions guards (through the Structured Text subset of [`st`]) and action
//! associations the program's actions. The XML is read with the net crate's hardened reader
//! ([`cetratus_net::xml`]); the file is bounded in bytes and elements, and no walk over it
//! recurses.
//!
//! The same file always gives the same net and TOML text, so the same program hash.

#![warn(missing_docs)]

mod build;
mod chart;
mod chart_st;
mod error;
mod lower;
mod nest;
mod pou;
mod source;
pub mod structured;

use std::collections::HashSet;

use cetratus_net::Net;
use cetratus_program::Program;

pub use chart::{ActionRef, Association, Chart, Condition, Qualifier, Step, Transition};
pub use error::SfcError;
pub use lower::STEP_TYPE;
pub use pou::{Body, Named, VarKind, Variable};
pub use source::{is_plcopen, MAX_ELEMENTS, MAX_FILE_BYTES, NAMESPACES};

use source::Source;

/// A chart imported as a Cetratus program.
#[derive(Debug)]
pub struct Imported {
    /// The chart as drawn.
    pub chart: Chart,
    /// The charts of the actions with an SFC body that the chart associates (nested charts), as
    /// drawn, in order of first association. Their steps and transitions are in `net` as
    /// `ACTION__NAME` (docs/sfc.md, *Nested charts*).
    pub nested: Vec<Chart>,
    /// The program's net.
    pub net: Net,
    /// The program's TOML text (its `net =` names the PNML file to write beside it).
    pub toml: String,
    /// The program, loaded from `net` and `toml`.
    pub program: Program,
    /// What was read but not imported, one line each (vendor data, indicators, variables of
    /// other types): nothing is left out silently.
    pub notes: Vec<String>,
}

/// Every SFC chart of a PLCopen file, as drawn: the body of each SFC POU, then the SFC bodies of
/// its named actions. `label` names the file in messages.
pub fn charts(text: &str, label: &str) -> Result<Vec<Chart>, SfcError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let source = Source::new(label, text);
    let doc = source.parse()?;
    let mut out = Vec::new();
    for pou in pou::pous(&source, &doc) {
        for (location, sfc) in pou::sfc_bodies(&pou) {
            out.push(chart::read(&source, &pou, &location, sfc)?);
        }
    }
    Ok(out)
}

/// The structural net of a chart read from `text` (guards and actions left out): what
/// [`import_str`] builds, for analysis of charts that do not import as programs.
pub fn chart_net(text: &str, label: &str, chart: &Chart) -> Result<Net, SfcError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let source = Source::new(label, text);
    Ok(build::net(&source, chart, &[])?.0)
}

/// Imports the SFC POU `pou` (or the file's only SFC POU) as [`import_str`] does, with the net
/// file named after the POU (`POU.pnml`): what `cetratus import plcopen` writes and what a package
/// manifest naming the file carries, so both give the same program hash.
pub fn import_program(text: &str, label: &str, pou: Option<&str>) -> Result<Imported, SfcError> {
    // The net file's name is in the TOML, and it follows the POU's name as declared.
    let probe = import_str(text, label, pou, "net.pnml")?;
    let net_file = format!("{}.pnml", probe.program.name());
    import_str(text, label, pou, &net_file)
}

/// Imports the SFC POU `pou` (or the file's only SFC POU when `None`) of a PLCopen file as a
/// program whose TOML names `net_file` as its net.
pub fn import_str(
    text: &str,
    label: &str,
    pou: Option<&str>,
    net_file: &str,
) -> Result<Imported, SfcError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let source = Source::new(label, text);
    let doc = source.parse()?;
    let pous = pou::pous(&source, &doc);
    let with_sfc: Vec<&pou::Pou> = pous
        .iter()
        .filter(|p| {
            pou::sfc_bodies(p)
                .first()
                .is_some_and(|(loc, _)| loc == "body")
        })
        .collect();
    let names = || {
        with_sfc
            .iter()
            .map(|p| p.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let chosen = match pou {
        Some(name) => with_sfc
            .iter()
            .find(|p| p.name.eq_ignore_ascii_case(name))
            .ok_or_else(|| SfcError::Pou {
                file: label.to_string(),
                message: format!(
                    "no POU `{name}` with an SFC body; the file's SFC POUs are: {}",
                    if with_sfc.is_empty() {
                        "none".to_string()
                    } else {
                        names()
                    }
                ),
            })?,
        None => match with_sfc.as_slice() {
            [one] => one,
            [] => {
                return Err(SfcError::Pou {
                    file: label.to_string(),
                    message: "the file has no POU with an SFC body; export the SFC POU".into(),
                })
            }
            _ => {
                return Err(SfcError::Pou {
                    file: label.to_string(),
                    message: format!(
                        "the file has several SFC POUs ({}); name one with --pou",
                        names()
                    ),
                })
            }
        },
    };
    let mut notes = Vec::new();
    if chosen.in_add_data {
        notes.push(format!(
            "{label}: POU `{}` read from project-level addData (TwinCAT)",
            chosen.name
        ));
    }
    let (_, sfc) = pou::sfc_bodies(chosen)
        .into_iter()
        .next()
        .ok_or_else(|| SfcError::Pou {
            file: label.to_string(),
            message: format!("POU `{}` has no SFC body", chosen.name),
        })?;
    let chart = chart::read(&source, chosen, "body", sfc)?;
    let (merged, nests, nested) = nest::merge(&source, chosen, &chart)?;
    let associated: HashSet<&str> = nests.iter().map(|n| n.action.as_str()).collect();
    for a in &chosen.actions {
        if nest::sfc_action(chosen, &a.name).is_some() && !associated.contains(&*a.name) {
            notes.push(format!(
                "{label}: the action `{}` has a SFC body and no step of the chart associates it: not imported",
                a.name
            ));
        }
    }
    let (net, ids, extra) = build::net(&source, &merged, &nests)?;
    let project = build::project_name(&doc, label);
    let parts = chart_st::Parts {
        source: &source,
        doc: &doc,
        project,
        pous: &pous,
        pou: chosen,
        chart: &merged,
        nests: &nests,
        ids: &ids,
        extra: &extra,
        net_file,
    };
    let toml = chart_st::program_toml(&parts, &mut notes)?;
    let program =
        Program::from_sources(&toml, label, net.clone()).map_err(|e| SfcError::Program {
            file: label.to_string(),
            source: e,
        })?;
    Ok(Imported {
        chart,
        nested,
        net,
        toml,
        program,
        notes,
    })
}

/// A POU of a PLCopen file imported as a program.
#[derive(Debug)]
pub enum ImportedPou {
    /// An SFC POU: its chart, as [`import_program`] imports it.
    Chart(Box<Imported>),
    /// A POU with an ST, LD or FBD body, written out as Structured Text with the file's other
    /// POUs, data types and configuration (docs/st.md, *PLCopen XML*).
    Text(Box<structured::ImportedSt>),
}

impl ImportedPou {
    /// The program.
    pub fn program(&self) -> &Program {
        match self {
            ImportedPou::Chart(c) => &c.program,
            ImportedPou::Text(t) => &t.program,
        }
    }

    /// The program's net.
    pub fn net(&self) -> &Net {
        match self {
            ImportedPou::Chart(c) => &c.net,
            ImportedPou::Text(t) => &t.net,
        }
    }

    /// The program's TOML text.
    pub fn toml(&self) -> &str {
        match self {
            ImportedPou::Chart(c) => &c.toml,
            ImportedPou::Text(t) => &t.toml,
        }
    }

    /// What was read but not imported, one line each.
    pub fn notes(&self) -> &[String] {
        match self {
            ImportedPou::Chart(c) => &c.notes,
            ImportedPou::Text(t) => &t.notes,
        }
    }
}

/// Imports the POU `pou` of a PLCopen file, whatever its body's language: an SFC as
/// [`import_program`] does, an ST, LD or FBD body as Structured Text. Without a name, the file's
/// only SFC POU, else its only PROGRAM. IL is refused by name.
pub fn import_pou(text: &str, label: &str, pou: Option<&str>) -> Result<ImportedPou, SfcError> {
    let bare = text.strip_prefix('\u{feff}').unwrap_or(text);
    let source = Source::new(label, bare);
    let doc = source.parse()?;
    let pous = pou::pous(&source, &doc);
    let language = |p: &pou::Pou| lower::body_language(p).unwrap_or("no body").to_string();
    let name = match pou {
        Some(name) => {
            let found = pous.iter().find(|p| p.name.eq_ignore_ascii_case(name));
            if found.is_some_and(|p| language(p) == "SFC") {
                return import_program(text, label, Some(name))
                    .map(|c| ImportedPou::Chart(Box::new(c)));
            }
            name.to_string()
        }
        None if pous.iter().any(|p| language(p) == "SFC") => {
            return import_program(text, label, None).map(|c| ImportedPou::Chart(Box::new(c)));
        }
        None => {
            let programs: Vec<&pou::Pou> = pous
                .iter()
                .filter(|p| p.node.attribute("pouType") == Some("program"))
                .collect();
            match programs.as_slice() {
                [one] => one.name.clone(),
                _ => {
                    return Err(SfcError::Pou {
                        file: label.to_string(),
                        message: format!(
                            "name the POU to import with --pou; the file's POUs are: {}",
                            lower::listing(&pous)
                        ),
                    })
                }
            }
        }
    };
    let mut notes = Vec::new();
    let mut imported = lower::import(&source, &doc, &name, &mut notes)?;
    notes.append(&mut imported.notes);
    imported.notes = notes;
    Ok(ImportedPou::Text(Box::new(imported)))
}

/// The IEC 61131-3 importer for package manifests: a `program` or `base` that is PLCopen XML
/// (`.xml`) or Structured Text (`.st`) is imported as `cetratus import plcopen` or `cetratus
/// import st` writes it ([`import_program`], [`structured::import_st`]), so the package binds to
/// the same program hash.
pub struct IecImporter;

use cetratus_program::package::{ImportError, ProgramText};

impl cetratus_program::ProgramImporter for IecImporter {
    fn import(
        &self,
        path: &std::path::Path,
        pou: Option<&str>,
    ) -> Option<Result<ProgramText, ImportError>> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or_default();
        let (is_xml, is_st) = (
            ext.eq_ignore_ascii_case("xml"),
            ext.eq_ignore_ascii_case("st"),
        );
        if !is_xml && !is_st {
            return None;
        }
        let label = path.display().to_string();
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) => return Some(Err(ImportError(format!("cannot read `{label}`: {e}")))),
        };
        if is_st {
            return Some(
                structured::import_st(&text, &label, pou)
                    .map(|i| ProgramText {
                        pnml: cetratus_net::pnml::write_string(&i.net),
                        toml: i.toml,
                    })
                    .map_err(|e| ImportError(e.to_string())),
            );
        }
        if !is_plcopen(text.strip_prefix('\u{feff}').unwrap_or(&text)) {
            return None;
        }
        Some(
            import_pou(&text, &label, pou)
                .map(|i| ProgramText {
                    pnml: cetratus_net::pnml::write_string(i.net()),
                    toml: i.toml().to_string(),
                })
                .map_err(|e| ImportError(e.to_string())),
        )
    }
}
