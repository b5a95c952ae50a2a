//! A chart on the one Structured Text compiler (docs/sfc.md, *Charts in Structured Text*): the
//! POU's declarations, with a step-flags variable per step and a `Q` per nested chart, become
//! the program's `[st]`; each action body its `[st.bodies]` entry and each condition its
//! `[st.conditions]` entry, as the file writes them. Everything is compiled here first, so that
//! an error names the file's line and column; the program then compiles the same text.

use std::collections::HashSet;
use std::fmt::Write as _;

use cetratus_st::ast::{Expr, ExprKind, Literal};
use cetratus_st::parse::parse_library;
use cetratus_st::types::{Elem, Ty};
use cetratus_st::{compile_entry_texts, Unit};

use crate::build::{header, q, qualifier_name, write_actions, Action, Drive, ExtraCondition};
use crate::chart::{ActionRef, Chart, Condition};
use crate::lower::{ChartNetworks, Text};
use crate::nest::{Nest, SEP};
use crate::pou::{Body, Named, Pou};
use crate::source::Source;
use crate::structured::{st_error, toml_text, write_signals};
use crate::SfcError;

/// What a chart is imported from.
pub(crate) struct Parts<'p> {
    pub source: &'p Source<'p>,
    pub doc: &'p cetratus_net::xml::Document<'p>,
    pub project: &'p str,
    /// The file's POUs, and the chart's among them.
    pub pous: &'p [Pou<'p, 'p>],
    pub pou: &'p Pou<'p, 'p>,
    pub chart: &'p Chart,
    pub nests: &'p [Nest],
    /// The net's transition ids, one per transition of the chart.
    pub ids: &'p [String],
    /// The hold and resume transitions of nested steps, with their guards.
    pub extra: &'p [ExtraCondition],
    pub net_file: &'p str,
}

/// An entry of the chart's ST: its name, its text, where the file's text starts in it (after
/// what the importer put before it), and where that is in the file.
struct Entry {
    name: String,
    text: String,
    lead: usize,
    at: Option<usize>,
    body: bool,
}

/// The program TOML of the chart on the ST compiler.
pub(crate) fn program_toml(p: &Parts, notes: &mut Vec<String>) -> Result<String, SfcError> {
    // Conditions first, then the actions: the first refusal is the first as the chart reads.
    let mut networks = Networks {
        lower: ChartNetworks::new(p.source, p.doc, (p.pous, p.pou)),
        decls: Vec::new(),
        notes: Vec::new(),
    };
    let conditions = conditions(p, &mut networks)?;
    let (actions, mut entries) = actions(p, &mut networks)?;
    entries.extend(conditions);
    let mut vars = chart_vars(p)?;
    let mut declared: HashSet<String> = vars.iter().cloned().collect();
    for d in networks.decls {
        if declared.insert(d.clone()) {
            vars.push(d);
        }
    }
    let written = networks.lower.library(p.doc, &vars, notes)?;
    notes.extend(networks.notes);
    let unit = compile(p, &written, &entries)?;
    check_targets(p, &unit, &actions)?;
    let mut out = header(p.project, &p.pou.name, p.net_file);
    write_signals(&unit, p.source.label, &mut out, notes);
    write_actions(&mut out, &actions);
    let _ = writeln!(out, "\n[st]\npou = {}", q(&p.pou.name));
    let _ = writeln!(out, "source = {}", toml_text(&written.text));
    for (table, body) in [("bodies", true), ("conditions", false)] {
        let mine: Vec<&Entry> = entries.iter().filter(|e| e.body == body).collect();
        if !mine.is_empty() {
            let _ = writeln!(out, "\n[st.{table}]");
        }
        for e in mine {
            let _ = writeln!(out, "{} = {}", q(&e.name), toml_text(&e.text));
        }
    }
    let _ = writeln!(out, "\n[st.steps]");
    for (i, s) in p.chart.steps.iter().enumerate() {
        let _ = writeln!(out, "{} = {}", q(&s.name), q(local_name(p, i)));
    }
    Ok(out)
}

/// Step `s`'s name as the ST reads it: a nested chart's step without its action's prefix.
fn local_name<'p>(p: &Parts<'p>, s: usize) -> &'p str {
    let step = p.chart.steps[s].name.as_str();
    let nest = Nest::of_step(p.nests, s);
    (nest.and_then(|n| step.strip_prefix(n.action.as_str())))
        .and_then(|rest| rest.strip_prefix(SEP))
        .unwrap_or(step)
}

/// The chart's own variables: each step's flags, and each nested chart's `Q`; a name that is
/// taken already is refused.
fn chart_vars(p: &Parts) -> Result<Vec<String>, SfcError> {
    let mut names: HashSet<String> = (p.pou.variables.iter())
        .map(|v| v.name.to_ascii_uppercase())
        .collect();
    let mut out = Vec::new();
    let steps = p
        .chart
        .steps
        .iter()
        .enumerate()
        .map(|(i, s)| (local_name(p, i), s.at, true));
    let nested = p.nests.iter().map(|n| (n.action.as_str(), 0, false));
    for (name, at, step) in steps.chain(nested) {
        if !names.insert(name.to_ascii_uppercase()) {
            return Err(SfcError::Chart {
                pos: p.source.pos(at),
                pou: p.pou.name.clone(),
                message: format!("the name `{name}` is declared twice among the POU's variables, its steps and its nested charts (IEC names are case-insensitive); rename one"),
            });
        }
        out.push(match step {
            true => format!("{name} : CETRATUS_STEP"),
            false => format!("{name} : BOOL"),
        });
    }
    Ok(out)
}

/// The LD and FBD networks of the chart, and what they add to its POU: the declarations they
/// need (`name : type`), and the notes of their lowering.
struct Networks<'s, 'a, 'i> {
    lower: ChartNetworks<'s, 'a, 'i>,
    decls: Vec<String>,
    notes: Vec<String>,
}

impl Networks<'_, '_, '_> {
    /// The statements of a lowered network, its declarations and notes taken.
    fn take(&mut self, (text, decls, notes): Text) -> String {
        self.decls.extend(decls);
        self.notes.extend(notes);
        text
    }
}

/// The `[[action]]`s, and the bodies they run as entries: a named action associated with
/// several steps is one body, with one action control, as in IEC 61131-3. A body in LD or FBD
/// is the Structured Text its network means (docs/st.md, *LD and FBD*).
fn actions(p: &Parts, networks: &mut Networks) -> Result<(Vec<Action>, Vec<Entry>), SfcError> {
    let mut actions = Vec::new();
    let mut bodies = Bodies::default();
    let nested: HashSet<&str> = p.nests.iter().map(|n| n.action.as_str()).collect();
    for (k, a) in p.chart.associations.iter().enumerate() {
        let step = p.chart.steps[a.step].name.clone();
        let duration = match (a.qualifier.is_timed(), &a.duration) {
            (false, _) => None,
            (true, Some(d)) => Some(duration(d).map_err(|message| st_err(p, a.at, message))?),
            (true, None) => {
                let why = format!(
                    "the qualifier {} needs a duration; add duration=\"T#…\"",
                    a.qualifier
                );
                return Err(chart_err(p, a.at, why));
            }
        };
        let refuse = |construct: String, why: &str| Err(unsupported(p, a.at, construct, why));
        let drive = match &a.action {
            ActionRef::Reference(name) => match p.pou.action(name) {
                Some(n) if nested.contains(n.name.as_str()) => Drive::Target(n.name.clone()),
                Some(n) if bodies.has(&n.name) => Drive::Body(n.name.clone()),
                Some(Named {
                    name,
                    body: Body::St { text, at },
                }) => bodies.add(name, text.clone(), *at, false),
                Some(Named {
                    name,
                    body: Body::Other { language, at },
                }) if matches!(language.as_str(), "LD" | "FBD") => {
                    let text = networks.lower.body(*at, None)?;
                    // The text is the importer's: an error in it is placed at the network.
                    bodies.add(name, networks.take(text), *at, true)
                }
                Some(Named {
                    body: Body::Other { language, .. },
                    ..
                }) => {
                    return refuse(format!("the action `{name}` with a {language} body"), "action bodies are Structured Text, LD, FBD or a chart; Instruction List, which IEC 61131-3 deprecates, is not imported: rewrite the action in ST");
                }
                None => Drive::Target(name.clone()),
            },
            ActionRef::Inline(Body::St { text, at }) => {
                let name = format!("{step}_inline{}", k + 1);
                match bodies.has(&name) {
                    true => Drive::Body(name),
                    false => bodies.add(&name, text.clone(), *at, false),
                }
            }
            ActionRef::Inline(Body::Other { language, .. }) => {
                return refuse(
                    format!("an inline {language} action"),
                    "action bodies must be Structured Text",
                );
            }
        };
        actions.push(Action {
            place: step,
            qualifier: qualifier_name(a.qualifier),
            drive,
            duration,
        });
    }
    Ok((actions, bodies.entries))
}

/// The microseconds of a timed qualifier's duration, an IEC time literal (`T#10s`).
fn duration(text: &str) -> Result<u64, String> {
    let literal = |e: Expr| match e.kind {
        ExprKind::Lit(Literal::Time(ns)) => u64::try_from(ns / 1000).ok(),
        _ => None,
    };
    let not = || {
        format!(
            "the duration `{}` is not an IEC time literal; write it as T#10s",
            text.trim()
        )
    };
    cetratus_st::parse::parse_expression(text)
        .map_err(|_| not())
        .and_then(|e| literal(e).ok_or_else(not))
}

/// The action bodies of the chart, each once.
#[derive(Default)]
struct Bodies {
    entries: Vec<Entry>,
    /// Their names, upper case (IEC names are case-insensitive).
    names: HashSet<String>,
}

impl Bodies {
    /// Whether the body `name` is there.
    fn has(&self, name: &str) -> bool {
        self.names.contains(&name.to_ascii_uppercase())
    }

    /// The body `name` (its `text` at byte `at` of the file) as an entry, and run; an error
    /// in the text is placed at `at` if it is the importer's (`written`), at its own place in
    /// the file if it is the file's.
    fn add(&mut self, name: &str, text: String, at: usize, written: bool) -> Drive {
        self.names.insert(name.to_ascii_uppercase());
        self.entries.push(Entry {
            name: name.to_string(),
            lead: if written { text.len() } else { 0 },
            text,
            at: Some(at),
            body: true,
        });
        Drive::Body(name.to_string())
    }
}

/// The conditions as entries: negated as their box says, and a nested chart's only while its
/// action is on; the hold and resume transitions of nested steps last.
fn conditions(p: &Parts, networks: &mut Networks) -> Result<Vec<Entry>, SfcError> {
    let mut out = Vec::new();
    for (i, (t, id)) in p.chart.transitions.iter().zip(p.ids).enumerate() {
        let nest = Nest::of_transition(p.nests, i);
        // A nested chart's transition `A__T5` is `T5` in its chart: what its statements assign.
        let local = nest.and_then(|n| id.strip_prefix(&n.action)?.strip_prefix(SEP));
        let result = local.unwrap_or(id);
        let (text, at, negated, form) = condition_text(p, &t.condition, (id, result), networks)?;
        if form == Form::Statements {
            // A nested chart's condition holds only while its action is on.
            let text = match nest {
                Some(n) => format!("{text}{result} := {} AND {result};\n", n.action),
                None => text,
            };
            // The importer's text: an error in it is placed at the network.
            let lead = text.len();
            out.push(Entry {
                name: id.clone(),
                text,
                lead,
                at: Some(at),
                body: false,
            });
            continue;
        }
        let lowered = form == Form::Lowered;
        let text = &text;
        let always = text.trim().eq_ignore_ascii_case("TRUE") && !negated;
        let (open, close) = match (negated, nest) {
            (true, Some(n)) => (format!("{} AND NOT (", n.action), ")"),
            (false, Some(n)) if always => (n.action.clone(), ""),
            (false, Some(n)) => (format!("{} AND (", n.action), ")"),
            (true, None) => ("NOT (".to_string(), ")"),
            (false, None) if always => continue,
            (false, None) => (String::new(), ""),
        };
        let (skipped, expr) = expression_of(text);
        let expr = if lowered { expr.trim() } else { expr };
        let body = if close.is_empty() && !open.is_empty() {
            ""
        } else {
            expr
        };
        let text = format!("{open}{body}{close}");
        out.push(Entry {
            name: id.clone(),
            // The importer's text: an error in it is placed at the network.
            lead: if lowered { text.len() } else { open.len() },
            text,
            at: Some(if lowered { at } else { at + skipped }),
            body: false,
        });
    }
    for (id, condition) in p.extra {
        out.push(Entry {
            name: id.clone(),
            text: condition.clone(),
            lead: 0,
            at: None,
            body: false,
        });
    }
    Ok(out)
}

/// Where a condition's text comes from.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Form {
    /// The file's own ST.
    File,
    /// A network that means one statement, `id := expr;`, whose expression is the condition.
    Lowered,
    /// A network that means several statements, the last of which assigns the condition's
    /// value to the transition's id (a condition the ST compiler reads as statements).
    Statements,
}

/// The text of a transition's condition `c` (the transition `id`, whose value a network of
/// statements assigns to `result`), where in the file it is, whether its box negates it, and
/// where it comes from; a network's declarations and notes go into `networks`.
fn condition_text(
    p: &Parts,
    c: &Condition,
    (id, result): (&str, &str),
    networks: &mut Networks,
) -> Result<(String, usize, bool, Form), SfcError> {
    Ok(match c {
        Condition::St { text, at, negated } => (text.clone(), *at, *negated, Form::File),
        Condition::Network { name, at, .. } => network_text(*at, Some(name), result, networks)?,
        Condition::Drawn { at, .. } => network_text(*at, None, result, networks)?,
        Condition::Unsupported { form, at } => {
            return Err(unsupported(p, *at, form.clone(), &format!("the condition of transition {id} must be Structured Text (inline, in an inVariable box, or a named transition's ST, FBD or LD body) or a network drawn in the chart")))
        }
    })
}

/// The condition of transition `id` from a network at byte `at`: the body of the named
/// transition `name`, or one drawn in the chart. A network of one statement gives its
/// expression; a longer one, statements that assign the condition's value to `id`.
fn network_text(
    at: usize,
    name: Option<&str>,
    id: &str,
    networks: &mut Networks,
) -> Result<(String, usize, bool, Form), SfcError> {
    let lowered = match name {
        Some(name) => networks.lower.body(at, Some((name, id)))?,
        None => networks.lower.condition(at, id)?,
    };
    let form = match lowered.0.lines().count() == 1 && lowered.1.is_empty() {
        true => Form::Lowered,
        false => Form::Statements,
    };
    Ok((networks.take(lowered), at, false, form))
}

/// The expression of a condition's text, and how many bytes before it were left out: a named
/// transition's ST body may be written as an assignment, `name := expr;` or `:= expr;` (the
/// forms of IEC 61131-3's textual SFC and of some editors), whose value is the expression. No
/// expression starts with a name and `:=`, so the form is told apart by its first tokens.
fn expression_of(text: &str) -> (usize, &str) {
    let trimmed = text.trim_start();
    let ident = trimmed
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(trimmed.len());
    let after_name = trimmed[ident..].trim_start();
    let assigned = match after_name.strip_prefix(":=") {
        Some(rest) if ident > 0 => Some(rest),
        _ => trimmed.strip_prefix(":="),
    };
    let Some(rest) = assigned else {
        return (0, text);
    };
    let body = rest.trim_end();
    let body = body.strip_suffix(';').unwrap_or(body);
    (text.len() - rest.len(), body)
}

/// The chart's ST compiled: the declarations, then every entry, each error placed in the file.
fn compile(
    p: &Parts,
    written: &crate::lower::Written,
    entries: &[Entry],
) -> Result<Unit, SfcError> {
    let locate = |line, column| written.locate(p.source, line, column);
    let declared = |d| st_error((p.source.label, &written.text), &locate, &p.pou.name, d);
    let lib = parse_library(&written.text).map_err(declared)?;
    let in_entry = |e: &Entry, d: cetratus_st::Diagnostic| {
        let offset = (d.pos as usize).saturating_sub(e.lead);
        st_err(
            p,
            e.at.map_or(0, |at| at + offset),
            format!("in {}: {}", what(e), d.message),
        )
    };
    let texts: Vec<(&str, &str, bool)> = (entries.iter())
        .map(|e| (e.name.as_str(), e.text.as_str(), e.body))
        .collect();
    compile_entry_texts(&lib, Some(&p.pou.name), &texts).map_err(|err| {
        match err.entry.and_then(|k| entries.get(k)) {
            Some(e) => in_entry(e, err.diagnostic),
            None => declared(err.diagnostic),
        }
    })
}

/// What an entry is, for messages.
fn what(e: &Entry) -> String {
    match e.body {
        true => format!("the action `{}`", e.name),
        false => format!("the condition of transition {}", e.name),
    }
}

/// Each variable an association sets is a BOOL of the POU.
fn check_targets(p: &Parts, unit: &Unit, actions: &[Action]) -> Result<(), SfcError> {
    for (a, assoc) in actions.iter().zip(&p.chart.associations) {
        let Drive::Target(name) = &a.drive else {
            continue;
        };
        match unit.var(name) {
            Some(v) if v.ty == Ty::Elem(Elem::Bool) => {}
            Some(v) => return Err(unsupported(p, assoc.at, format!("the {} variable `{name}` as an action", unit.describe(v.ty)), "a variable named as an action must be BOOL")),
            None => return Err(chart_err(p, assoc.at, format!("the action `{name}` is neither an action of the POU nor a BOOL variable; declare it"))),
        }
    }
    Ok(())
}

fn chart_err(p: &Parts, at: usize, message: String) -> SfcError {
    SfcError::Chart {
        pos: p.source.pos(at),
        pou: p.pou.name.clone(),
        message,
    }
}

fn st_err(p: &Parts, at: usize, message: String) -> SfcError {
    SfcError::St {
        pos: p.source.pos(at),
        pou: p.pou.name.clone(),
        message,
    }
}

fn unsupported(p: &Parts, at: usize, construct: String, message: &str) -> SfcError {
    SfcError::Unsupported {
        pos: p.source.pos(at),
        pou: p.pou.name.clone(),
        construct,
        message: message.to_string(),
    }
}
