//! A PROGRAM or FUNCTION_BLOCK in Structured Text as a Cetratus program (docs/st.md,
//! *Programs in ST*): a net of one step, always active, whose action runs the POU's body in every
//! scan; the POU's inputs and outputs become the program's signals.
//!
//! A VAR_INPUT, or a variable located at `%I…`, of an elementary type is an input signal; a
//! VAR_OUTPUT, or a variable located at `%Q…`, an output signal, with its address. The scan period
//! is the INTERVAL of the TASK that runs the POU in the file's CONFIGURATION, else 10 ms. The ST
//! text goes into the program whole, so the program's hash covers it.

use std::fmt::Write as _;

use cetratus_net::{Net, NetBuilder, Place, SourcePos};
use cetratus_program::st::{crosses, signal_type};
use cetratus_program::Program;
use cetratus_st::ast::Section;
use cetratus_st::types::Ty;
use cetratus_st::{Source, Unit};

use crate::build::q;
use crate::SfcError;

/// The id of the one step of an imported ST program.
pub const MAIN_STEP: &str = "Main";

/// A POU of an ST file imported as a Cetratus program.
#[derive(Debug)]
pub struct ImportedSt {
    /// The program's net: the step [`MAIN_STEP`], marked.
    pub net: Net,
    /// The program's TOML text (its `net =` names the PNML file to write beside it).
    pub toml: String,
    /// The program, loaded from `net` and `toml`.
    pub program: Program,
    /// The Structured Text the program runs: the file's, or what the importer wrote for a
    /// PLCopen POU.
    pub source: String,
    /// Variables that are not signals (strings, arrays, instances are state, not I/O), one line
    /// each.
    pub notes: Vec<String>,
}

/// Imports the POU `pou` of the ST text `text` (or the file's only PROGRAM), with its net file
/// named after the POU: what `cetratus import st` writes.
pub fn import_st(text: &str, label: &str, pou: Option<&str>) -> Result<ImportedSt, SfcError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let at = |line, column| {
        let file = label.to_string();
        (SourcePos { file, line, column }, None)
    };
    import_st_from(text, label, pou, "Structured Text", &at)
}

/// Where a line and column of Structured Text is in the file it came from, and the line itself
/// when the text was written from the file rather than read from it.
pub(crate) type Locate<'a> = dyn Fn(u32, u32) -> (SourcePos, Option<String>) + 'a;

/// Imports the POU `pou` of the ST text `text`, which came from the file `label` as `what`
/// (`Structured Text`, `FBD from PLCopen XML`, …) and whose positions `locate` maps to it.
pub(crate) fn import_st_from(
    text: &str,
    label: &str,
    pou: Option<&str>,
    what: &str,
    locate: &Locate,
) -> Result<ImportedSt, SfcError> {
    let located = |d, pou: &str| st_error((label, text), locate, pou, d);
    let lib =
        cetratus_st::parse::parse_library(text).map_err(|d| located(d, pou.unwrap_or("-")))?;
    let unit = cetratus_st::compile(&lib, pou).map_err(|d| located(d, pou.unwrap_or("-")))?;
    let mut b = NetBuilder::new(unit.name.clone());
    b.name(unit.name.clone());
    b.add_place(Place::new(MAIN_STEP, 1))
        .map_err(|source| SfcError::Net {
            file: label.to_string(),
            source,
        })?;
    let net = b.build().map_err(|source| SfcError::Net {
        file: label.to_string(),
        source,
    })?;
    let mut notes = Vec::new();
    let toml = program_toml(
        &unit,
        text,
        (label, what),
        &format!("{}.pnml", unit.name),
        &mut notes,
    );
    let program =
        Program::from_sources(&toml, label, net.clone()).map_err(|source| SfcError::Program {
            file: label.to_string(),
            source,
        })?;
    Ok(ImportedSt {
        net,
        toml,
        program,
        source: text.to_string(),
        notes,
    })
}

/// An error in the Structured Text `text` (read from, or written for, the file `label`) placed
/// where `locate` puts its line and column in the file, quoting the line when the text was
/// written rather than read.
pub(crate) fn st_error(
    (label, text): (&str, &str),
    locate: &Locate,
    pou: &str,
    d: cetratus_st::Diagnostic,
) -> SfcError {
    let e = Source {
        origin: label,
        text,
    }
    .error(d);
    let (pos, written) = locate(e.line, e.column);
    let message = match written {
        Some(line) => format!(
            "{} (in the Structured Text written for it: `{line}`)",
            e.message
        ),
        None => e.message,
    };
    SfcError::St {
        pos,
        pou: pou.to_string(),
        message,
    }
}

/// The program TOML of an imported POU.
fn program_toml(
    unit: &Unit,
    text: &str,
    (label, what): (&str, &str),
    net_file: &str,
    notes: &mut Vec<String>,
) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "[program]");
    let _ = writeln!(out, "name = {}", q(&unit.name));
    let _ = writeln!(out, "version = \"1\"");
    let _ = writeln!(
        out,
        "description = {}",
        q(&format!(
            "IEC 61131-3 {what}: POU {} of {}",
            unit.name,
            // The file's name, not the path it was read by: the program hash covers the text.
            std::path::Path::new(label)
                .file_name()
                .map_or(label.into(), |f| f.to_string_lossy())
        ))
    );
    let _ = writeln!(out, "net = {}", q(net_file));
    if let Some(ns) = unit.interval.filter(|&ns| ns > 0) {
        let _ = writeln!(out, "scan_period = \"{}us\"", (ns / 1000).max(1));
    }
    write_signals(unit, label, &mut out, notes);
    let _ = writeln!(
        out,
        "\n[[action]]\nplace = \"{MAIN_STEP}\"\nqualifier = \"N\"\nbody = {}",
        q(&unit.name)
    );
    let _ = writeln!(out, "\n[st]\npou = {}", q(&unit.name));
    let _ = writeln!(out, "source = {}", toml_text(text));
    out
}

/// A TOML string of `text`: a literal string, whose characters are the text's so that error
/// positions map one to one, unless the text holds `'''` or control characters.
pub(crate) fn toml_text(text: &str) -> String {
    let plain = !text.contains("'''")
        && !(text.chars()).any(|c| c.is_control() && !matches!(c, '\n' | '\r' | '\t'));
    match plain {
        true => format!("'''\n{text}'''"),
        false => q(text),
    }
}

/// The `[[input]]` and `[[output]]` tables of a POU's variables that cross the I/O image: its
/// VAR_INPUTs and VAR_OUTPUTs (or variables located at `%I`, `%Q`) of elementary types.
pub(crate) fn write_signals(unit: &Unit, label: &str, out: &mut String, notes: &mut Vec<String>) {
    for (kind, section) in [("input", Section::Input), ("output", Section::Output)] {
        for v in unit.vars.iter().filter(|v| crosses(v) == Some(section)) {
            let Ty::Elem(e) = v.ty else {
                notes.push(format!(
                    "{label}: `{}` ({}) is not a signal: only elementary types cross the I/O image",
                    v.name,
                    unit.describe(v.ty)
                ));
                continue;
            };
            let _ = writeln!(
                out,
                "\n[[{kind}]]\nname = {}\ntype = \"{}\"",
                q(&v.name),
                signal_type(e)
            );
            if let Some(a) = &v.address {
                let _ = writeln!(out, "address = {}", q(a));
            }
            let _ = writeln!(out, "description = \"{} {}\"", v.section.keyword(), e);
        }
    }
}
