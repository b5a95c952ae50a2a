//! A program whose action body is Structured Text (`[st]`, docs/st.md): its ST library goes into
//! the export as written, but for what IEC asks of a POU that another calls. The body's PROGRAM
//! becomes a FUNCTION_BLOCK (IEC calls no PROGRAM from a POU), its variables located at `%I…`
//! and `%Q…` become its VAR_INPUT and VAR_OUTPUT (the export's PROGRAM wires the addresses),
//! and the library's CONFIGURATION goes (the export has its own). The interpretation calls it
//! as the runtime runs it: the inputs copied in, one pass, the outputs copied out.

use cetratus_program::st::ChartTexts;
use cetratus_st::types::Elem;

use super::*;

/// The ST body of a program, ready to be written and called.
pub(crate) struct StBody {
    /// The POU, now a FUNCTION_BLOCK.
    pub(crate) pou: String,
    /// Its instance in the interpretation.
    pub(crate) instance: String,
    /// The library, rewritten.
    pub(crate) text: String,
    /// The `VAR_GLOBAL` blocks of the library's CONFIGURATION, as written: the export declares
    /// them beside its own, and the library's POUs reach them as they did, by `VAR_EXTERNAL`.
    pub(crate) globals: String,
    /// The wired variables: the POU's variable, its type, the signal, whether an input.
    pub(crate) wires: Vec<(String, Elem, String, bool)>,
    /// For a chart's Structured Text, how the interpretation runs its parts.
    pub(crate) chart: Option<super::st_chart::ChartCalls>,
}

/// The text of the program's ST library and what to name it by in messages: a chart's
/// `[st] source` (`chart`, the program's [`Program::chart_texts`]), or the POU body's own text.
fn library_source(program: &Program, chart: Option<&ChartTexts>) -> Option<(String, String)> {
    if let Some(chart) = chart {
        return Some((chart.library.clone(), "the chart".to_string()));
    }
    let body = program.bodies().iter().find(|b| b.st().is_some())?;
    Some((body.source().to_string(), format!("`{}`", body.name())))
}

/// The names of the POUs and types an ST library declares, which the export's own names must
/// not take.
pub(crate) fn library_names(program: &Program) -> Vec<String> {
    let Some((source, _)) = library_source(program, program.chart_texts().as_ref()) else {
        return Vec::new();
    };
    let Ok(lib) = cetratus_st::parse::parse_library(&source) else {
        return Vec::new();
    };
    let globals = (lib.configs.iter())
        .flat_map(|c| &c.globals)
        .flat_map(|b| &b.decls)
        .flat_map(|d| &d.names);
    (lib.pous.iter().map(|p| p.name.text.clone()))
        .chain(lib.types.iter().map(|t| t.name.text.clone()))
        .chain(globals.map(|n| n.text.clone()))
        .collect()
}

/// The program's ST body, if it has one, with `chart` its [`Program::chart_texts`]; `claim`
/// names its instance.
pub(crate) fn prepare(
    program: &Program,
    chart: Option<&ChartTexts>,
    claim: &mut impl FnMut(&str) -> String,
) -> Result<Option<StBody>, ExportError> {
    let (Some(st), Some((source, what))) = (program.st(), library_source(program, chart)) else {
        return Ok(None);
    };
    let unit = st.unit();
    let refuse = |what: String| ExportError::Unsupported {
        what,
        hint: "keep that part of the program's Structured Text out of what the export writes",
    };
    let lib = cetratus_st::parse::parse_library(&source).map_err(|d| {
        refuse(format!(
            "the ST of {what} does not parse again: {}",
            d.message
        ))
    })?;
    if let Some((f, instance)) = stateful_function(&lib) {
        return Err(ExportError::Unsupported {
            what: format!(
                "the FUNCTION `{f}` declares the function block instance `{instance}`, which IEC 61131-3 allows only in a FUNCTION_BLOCK or a PROGRAM (a function keeps no state from call to call; MATIEC and CODESYS refuse it)"
            ),
            hint: "make it a FUNCTION_BLOCK in the source, called through an instance, and import it again",
        });
    }
    let mut wires = Vec::new();
    for (list, input) in [(program.inputs(), true), (program.outputs(), false)] {
        for s in list {
            let wired = (unit.vars.iter()).find(|v| {
                v.name.eq_ignore_ascii_case(&s.name) && cetratus_program::st::crosses(v).is_some()
            });
            let Some(v) = wired else { continue };
            let cetratus_st::types::Ty::Elem(e) = v.ty else {
                continue;
            };
            if e == Elem::Time {
                return Err(refuse(format!(
                    "the signal `{}` is a TIME of the ST, which crosses as milliseconds",
                    s.name
                )));
            }
            wires.push((v.name.clone(), e, s.name.clone(), input));
        }
    }
    let (mut text, globals) = library_text(&source, &unit.name)?;
    let chart = match chart {
        Some(texts) => Some(super::st_chart::prepare(program, st, texts, &mut text)?),
        None => None,
    };
    Ok(Some(StBody {
        pou: unit.name.clone(),
        instance: claim(&format!("{}_BODY", unit.name)),
        text,
        globals,
        wires,
        chart,
    }))
}

/// A FUNCTION of the library that declares an instance of a function block (standard or its
/// own), which IEC forbids and vendor compilers refuse: its name and the instance's.
fn stateful_function(lib: &cetratus_st::ast::Library) -> Option<(String, String)> {
    use cetratus_st::ast::{PouKind, TypeRef};
    let own_fbs: Vec<String> = (lib.pous.iter())
        .filter(|p| matches!(p.kind, PouKind::FunctionBlock))
        .map(|p| p.name.key())
        .collect();
    let is_fb = |t: &TypeRef| match t {
        TypeRef::Named(n) => {
            cetratus_st::stdfb::StdFb::from_name(&n.key()).is_some() || own_fbs.contains(&n.key())
        }
        _ => false,
    };
    lib.pous
        .iter()
        .filter(|p| matches!(p.kind, PouKind::Function(_)))
        .find_map(|p| {
            let d = (p.vars.iter().flat_map(|b| &b.decls)).find(|d| is_fb(&d.ty))?;
            Some((p.name.text.clone(), d.names.first()?.text.clone()))
        })
}

/// The library with its CONFIGURATIONs taken out and the PROGRAM `pou` made a FUNCTION_BLOCK,
/// and the CONFIGURATIONs' `VAR_GLOBAL` blocks (lines as written, a block per line run).
fn library_text(source: &str, pou: &str) -> Result<(String, String), ExportError> {
    let mut out = String::with_capacity(source.len());
    let mut globals = String::new();
    let (mut config, mut inside, mut global) = (false, false, false);
    let mut blocks: Vec<(String, Vec<String>)> = Vec::new();
    for line in source.lines() {
        let t = line.trim();
        let upper = t.to_ascii_uppercase();
        if upper.starts_with("CONFIGURATION ") {
            config = true;
        }
        if config {
            global |= upper.starts_with("VAR_GLOBAL");
            if global {
                globals.push_str(t);
                globals.push('\n');
                global =
                    !(upper == "END_VAR" || upper == "END_VAR;" || upper.ends_with(" END_VAR"));
            }
            config = !upper.starts_with("END_CONFIGURATION");
            continue;
        }
        let head = upper.strip_prefix("PROGRAM ").map(str::trim);
        if head.is_some_and(|n| n.eq_ignore_ascii_case(pou)) {
            inside = true;
            out.push_str(&format!(
                "FUNCTION_BLOCK {}\n",
                &t["PROGRAM ".len()..].trim()
            ));
            continue;
        }
        if !inside {
            out.push_str(line);
            out.push('\n');
            continue;
        }
        if upper.starts_with("END_PROGRAM") {
            inside = false;
            out.push_str("END_FUNCTION_BLOCK\n");
        } else if upper.starts_with("VAR") && !upper.contains(':') {
            blocks.push((t.to_string(), Vec::new()));
        } else if upper == "END_VAR" || upper == "END_VAR;" {
            let (header, lines) = blocks.pop().expect("a VAR opened it");
            out.push_str(&relocated(&header, &lines)?);
        } else if let Some((_, lines)) = blocks.last_mut() {
            lines.push(line.to_string());
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    Ok((out, globals))
}

/// A declaration block of the body's POU, its `%I…` and `%Q…` variables moved into
/// VAR_INPUT and VAR_OUTPUT blocks without their addresses.
fn relocated(header: &str, lines: &[String]) -> Result<String, ExportError> {
    let mut parts: [(&str, Vec<String>); 3] = [
        ("VAR_INPUT", Vec::new()),
        ("VAR_OUTPUT", Vec::new()),
        (header, Vec::new()),
    ];
    for l in lines {
        let upper = l.to_ascii_uppercase();
        let Some(at) = upper.find(" AT %") else {
            parts[2].1.push(l.clone());
            continue;
        };
        let colon = (upper[at..].find(':')).ok_or_else(|| ExportError::Unsupported {
            what: format!("the located declaration `{}` spans lines", l.trim()),
            hint: "write it on one line",
        })?;
        let slot = match upper.as_bytes().get(at + 5) {
            Some(b'I') => 0,
            Some(b'Q') => 1,
            _ => 2,
        };
        let moved = format!("{}{}", &l[..at], &l[at + colon - 1..]);
        parts[slot]
            .1
            .push(if slot == 2 { l.clone() } else { moved });
    }
    let mut s = String::new();
    for (h, lines) in parts.iter().filter(|(_, l)| !l.is_empty()) {
        s.push_str(h);
        s.push('\n');
        for l in lines {
            s.push_str(l);
            s.push('\n');
        }
        s.push_str("END_VAR\n");
    }
    Ok(s)
}

/// A signal of the interpretation (LINT, LREAL, BOOL) as the POU's variable of type `e`.
pub(crate) fn into_pou(e: Elem, x: &str) -> String {
    match e {
        Elem::Bool | Elem::Lint | Elem::Lreal => x.to_string(),
        Elem::Real => format!("LREAL_TO_REAL({x})"),
        _ => format!("LINT_TO_{}({x})", e.name()),
    }
}

/// The POU's variable of type `e` as a signal of the interpretation.
pub(crate) fn from_pou(e: Elem, x: &str) -> String {
    match e {
        Elem::Bool | Elem::Lint | Elem::Lreal => x.to_string(),
        Elem::Real => format!("REAL_TO_LREAL({x})"),
        _ => format!("{}_TO_LINT({x})", e.name()),
    }
}
