//! The declarations of a PLCopen file as Structured Text: data types, POUs with their interfaces
//! and bodies, and the configuration's global variables and tasks.

use std::collections::HashSet;

use cetratus_net::xml::{Document, Node};

use super::network::{self, Names};
use super::{body_language, textual, Written};
use crate::pou::Pou;
use crate::source::{body_text, child, children, Source};
use crate::SfcError;

/// Writes the file as one Structured Text library into `out`; the name of the POU to run: the
/// chosen one, or for a FUNCTION the PROGRAM written to call it.
pub(super) fn library(
    source: &Source,
    doc: &Document,
    (pous, chosen): (&[Pou], &Pou),
    names: &Names,
    chart_vars: Option<&[String]>,
    out: &mut Written,
    notes: &mut Notes,
) -> Result<String, SfcError> {
    let root = doc.root_element();
    if chart_vars.is_some() {
        out.line(chosen.node.range().start, STEP_TYPE);
    }
    let fail = |at: usize, construct: &str, message: &str| SfcError::Unsupported {
        pos: source.pos(at),
        pou: chosen.name.clone(),
        construct: construct.to_string(),
        message: message.to_string(),
    };
    let data_types = child(root, "types").and_then(|t| child(t, "dataTypes"));
    for dt in data_types.iter().flat_map(|d| children(*d, "dataType")) {
        data_type(dt, out, notes).map_err(|(at, what, why)| fail(at, &what, &why))?;
    }
    let needed = needed(pous, chosen);
    for pou in pous
        .iter()
        .filter(|p| needed.contains(&p.name.to_ascii_uppercase()))
    {
        match (body_language(pou), chart_vars) {
            (_, Some(vars)) if std::ptr::eq(pou, chosen) => {
                write_chart_pou(pou, vars, out, notes).map_err(|(at, w, y)| fail(at, &w, &y))?;
            }
            (Some(l), _) if textual(l) => {
                write_pou(source, pou, names, out, notes).map_err(|e| match e {
                    Refusal::Here(at, what, why) => fail(at, &what, &why),
                    Refusal::Error(e) => e,
                })?;
            }
            (other, _) => notes.at(
                pou.node.range().start,
                format!(
                    "POU `{}` ({}) is not part of the Structured Text written for `{}`",
                    pou.name,
                    other.unwrap_or("no body"),
                    chosen.name
                ),
            ),
        }
    }
    let run = match pou_kind(chosen) {
        PouKind::Function => {
            call_program(chosen, out, notes).map_err(|(at, w, y)| fail(at, &w, &y))?
        }
        _ => chosen.name.clone(),
    };
    let externals: std::collections::HashSet<String> = pous
        .iter()
        .filter(|p| needed.contains(&p.name.to_ascii_uppercase()))
        .filter_map(|p| child(p.node, "interface"))
        .flat_map(|i| children(i, "externalVars"))
        .flat_map(|e| children(e, "variable"))
        .filter_map(|v| v.attribute("name"))
        .map(str::to_ascii_uppercase)
        .collect();
    let keep = |name: &str| externals.contains(&name.to_ascii_uppercase());
    configurations(root, &run, out, notes, &keep).map_err(|(at, w, y)| fail(at, &w, &y))?;
    Ok(run)
}

/// The names (upper case) of the POUs that `chosen` uses, itself included, followed through the
/// types of their variables, the blocks of their networks and the names in their ST bodies.
fn needed(pous: &[Pou], chosen: &Pou) -> std::collections::HashSet<String> {
    let by_name: std::collections::HashMap<String, &Pou> = pous
        .iter()
        .map(|p| (p.name.to_ascii_uppercase(), p))
        .collect();
    let mut seen = std::collections::HashSet::from([chosen.name.to_ascii_uppercase()]);
    let mut work = vec![chosen];
    while let Some(pou) = work.pop() {
        let types = pou.variables.iter().map(|v| v.ty.to_ascii_uppercase());
        let blocks = pou
            .node
            .descendants()
            .filter(|n| n.name() == "block")
            .filter_map(|n| n.attribute("typeName"))
            .map(str::to_ascii_uppercase);
        let words = pou
            .node
            .descendants()
            .filter(|n| n.name() == "ST")
            .flat_map(|n| n.descendants())
            .filter_map(|n| n.text())
            .flat_map(|t| t.split(|c: char| !c.is_ascii_alphanumeric() && c != '_'))
            .map(str::to_ascii_uppercase);
        for name in types.chain(blocks).chain(words).collect::<Vec<_>>() {
            if let Some(p) = by_name.get(&name) {
                if seen.insert(name) {
                    work.push(p);
                }
            }
        }
    }
    seen
}

/// What the importer noted while writing the text, each line once, with the file position.
pub(super) struct Notes<'s> {
    source: &'s Source<'s>,
    /// The notes, in order.
    pub lines: Vec<String>,
    /// The notes already taken.
    seen: HashSet<String>,
}

impl<'s> Notes<'s> {
    pub fn new(source: &'s Source<'s>) -> Self {
        Notes {
            source,
            lines: Vec::new(),
            seen: HashSet::new(),
        }
    }

    /// Notes `message` about the element at byte offset `at`, unless it is noted already.
    pub fn at(&mut self, at: usize, message: String) {
        let line = format!("{}: {message}", self.source.pos(at));
        if self.seen.insert(line.clone()) {
            self.lines.push(line);
        }
    }
}

/// Why a declaration was not written: where, the construct, and what to do.
type Refused = (usize, String, String);

/// Why a POU was not written.
pub(super) enum Refusal {
    /// A construct the importer does not write (where, what, what to do).
    Here(usize, String, String),
    /// An error of its own.
    Error(SfcError),
}

impl From<Refused> for Refusal {
    fn from((at, what, why): Refused) -> Self {
        Refusal::Here(at, what, why)
    }
}

/// What kind of POU a `<pou>` is.
#[derive(Clone, Copy, PartialEq, Eq)]
enum PouKind {
    Function,
    FunctionBlock,
    Program,
}

fn pou_kind(pou: &Pou) -> PouKind {
    match pou.node.attribute("pouType") {
        Some("function") => PouKind::Function,
        Some("functionBlock") => PouKind::FunctionBlock,
        _ => PouKind::Program,
    }
}

/// One POU: its header, interface, the variables its network needs, its body and its end.
fn write_pou(
    source: &Source,
    pou: &Pou,
    names: &Names,
    out: &mut Written,
    notes: &mut Notes,
) -> Result<(), Refusal> {
    let at = pou.node.range().start;
    let interface = child(pou.node, "interface");
    let (open, close) = match pou_kind(pou) {
        PouKind::Function => {
            let ret = return_type(pou)?;
            (format!("FUNCTION {} : {ret}", pou.name), "END_FUNCTION")
        }
        PouKind::FunctionBlock => (format!("FUNCTION_BLOCK {}", pou.name), "END_FUNCTION_BLOCK"),
        PouKind::Program => (format!("PROGRAM {}", pou.name), "END_PROGRAM"),
    };
    out.line(at, &open);
    for section in interface.iter().flat_map(|i| i.children()) {
        var_block(section, out, notes, &|_| true)?;
    }
    let body = child(pou.node, "body")
        .and_then(|b| b.children().next())
        .ok_or_else(|| {
            (
                at,
                "a POU without a body".to_string(),
                "export it with its body".to_string(),
            )
        })?;
    if body.name() == "ST" {
        if let Some((text, text_at)) = body_text(source, body) {
            out.verbatim(source, text_at, &text);
        }
    } else {
        let mut lowered = network::lower(source, pou, body, names, None).map_err(Refusal::Error)?;
        lowered.write(at, out, matches!(pou_kind(pou), PouKind::Function));
        for (at, note) in lowered.notes.drain(..) {
            notes.at(at, note);
        }
    }
    out.line(at, close);
    Ok(())
}

/// The structure of a chart's step flags (`S.X`, `S.T`), declared before the chart's POU.
pub const STEP_TYPE: &str = "TYPE CETRATUS_STEP : STRUCT X : BOOL; T : TIME; END_STRUCT; END_TYPE";

/// A chart's POU: its header, interface, the chart's own variables (`vars`: its steps' flags,
/// its nested charts' `Q`), and no body, which its actions and conditions take.
fn write_chart_pou(
    pou: &Pou,
    vars: &[String],
    out: &mut Written,
    notes: &mut Notes,
) -> Result<(), Refused> {
    let at = pou.node.range().start;
    let (open, close) = match pou_kind(pou) {
        PouKind::FunctionBlock => (format!("FUNCTION_BLOCK {}", pou.name), "END_FUNCTION_BLOCK"),
        _ => (format!("PROGRAM {}", pou.name), "END_PROGRAM"),
    };
    out.line(at, &open);
    let interface = child(pou.node, "interface");
    for section in interface.iter().flat_map(|i| i.children()) {
        var_block(section, out, notes, &|_| true)?;
    }
    if !vars.is_empty() {
        out.line(at, "VAR");
        for v in vars {
            out.line(at, &format!("  {v};"));
        }
        out.line(at, "END_VAR");
    }
    out.line(at, close);
    Ok(())
}

/// A `VAR…END_VAR` block from an interface section (`inputVars`, `localVars`, …).
fn var_block(
    section: Node,
    out: &mut Written,
    notes: &mut Notes,
    keep: &dyn Fn(&str) -> bool,
) -> Result<(), Refused> {
    let at = section.range().start;
    let keyword = match section.name() {
        "inputVars" => "VAR_INPUT",
        "outputVars" => "VAR_OUTPUT",
        "inOutVars" => "VAR_IN_OUT",
        "localVars" => "VAR",
        "tempVars" => "VAR_TEMP",
        "externalVars" => "VAR_EXTERNAL",
        "globalVars" => "VAR_GLOBAL",
        "returnType" | "documentation" | "addData" => return Ok(()),
        other => {
            return Err((
                at,
                format!("the interface section <{other}>"),
                "declare the variables in VAR, VAR_INPUT, VAR_OUTPUT, VAR_IN_OUT, VAR_TEMP or VAR_EXTERNAL".into(),
            ))
        }
    };
    let mut head = keyword.to_string();
    for (attr, word) in [("constant", " CONSTANT"), ("retain", " RETAIN")] {
        if section.attribute(attr) == Some("true") {
            head.push_str(word);
        }
    }
    let kept: Vec<Node> = children(section, "variable")
        .filter(|v| keep(v.attribute("name").unwrap_or_default()))
        .collect();
    if kept.is_empty() {
        return Ok(());
    }
    out.line(at, &head);
    for v in kept {
        out.line(v.range().start, &format!("  {};", variable(v, notes)?));
    }
    out.line(at, "END_VAR");
    Ok(())
}

/// `NAME [AT address] : TYPE [:= initial]` of a `<variable>`. An array or structure given as
/// the initial value of an elementary variable is left out, with a note: the variable starts at
/// its type's initial value.
fn variable(v: Node, notes: &mut Notes) -> Result<String, Refused> {
    let at = v.range().start;
    let name = v.attribute("name").unwrap_or_default();
    let ty = child(v, "type")
        .ok_or_else(|| {
            (
                at,
                format!("the variable `{name}` without a type"),
                "give it a type".into(),
            )
        })
        .and_then(type_text)?;
    let mut text = name.to_string();
    if let Some(address) = v.attribute("address") {
        text.push_str(&format!(" AT {address}"));
    }
    text.push_str(&format!(" : {ty}"));
    if let Some(init) = child(v, "initialValue") {
        let structured = init
            .children()
            .next()
            .is_some_and(|i| i.name() != "simpleValue");
        if structured && !ty.starts_with("ARRAY") && ty.chars().all(|c| c.is_ascii_uppercase()) {
            notes.at(at, format!(
                "the initial value of `{name}` is an array or a structure, which a {ty} cannot hold: left out, so `{name}` starts at the initial value of {ty}"
            ));
        } else {
            text.push_str(&format!(" := {}", value_text(init)?));
        }
    }
    Ok(text)
}

/// The ST type of a `<type>` or `<baseType>` element: elementary, derived, STRING[n], or an
/// ARRAY of those (arrays of arrays by a loop, not by recursion).
fn type_text(holder: Node) -> Result<String, Refused> {
    let at = holder.range().start;
    let mut prefix = String::new();
    let mut t = holder.children().next();
    loop {
        let Some(node) = t else {
            return Err((
                at,
                "an empty type".into(),
                "give the variable a type".into(),
            ));
        };
        let text = match node.name() {
            "array" => {
                let dims: Vec<String> = children(node, "dimension")
                    .map(|d| {
                        let bound = |a| d.attribute(a).unwrap_or("0");
                        format!("{}..{}", bound("lower"), bound("upper"))
                    })
                    .collect();
                prefix.push_str(&format!("ARRAY [{}] OF ", dims.join(", ")));
                t = child(node, "baseType").and_then(|b| b.children().next());
                continue;
            }
            "derived" => node.attribute("name").unwrap_or_default().to_string(),
            "string" => match node.attribute("length") {
                Some(n) => format!("STRING[{n}]"),
                None => "STRING".into(),
            },
            "subrangeSigned" | "subrangeUnsigned" => {
                t = child(node, "baseType").and_then(|b| b.children().next());
                continue;
            }
            "struct" | "enum" => {
                return Err((
                    node.range().start,
                    format!("a {} declared inside a variable", node.name()),
                    "declare it as a data type and use its name".into(),
                ))
            }
            "pointer" | "wstring" => {
                return Err((
                    node.range().start,
                    format!("the type {}", node.name().to_ascii_uppercase()),
                    "use STRING, and no pointers".into(),
                ))
            }
            elementary => elementary.to_string(),
        };
        return Ok(format!("{prefix}{text}"));
    }
}

/// The ST text of an `<initialValue>` or `<value>`: a simple value, an array (nested arrays
/// flattened in order, as IEC 61131-3 initializes a multi-dimensional array; repetitions kept),
/// or a structure of simple values.
fn value_text(holder: Node) -> Result<String, Refused> {
    let at = holder.range().start;
    let nested = || {
        (
            at,
            "a structure inside an initial value".to_string(),
            "initialize the inner values in the body".to_string(),
        )
    };
    let Some(node) = holder.children().next() else {
        return Err((
            at,
            "an empty initial value".into(),
            "give it a value".into(),
        ));
    };
    match node.name() {
        "simpleValue" => Ok(node.attribute("value").unwrap_or_default().to_string()),
        "arrayValue" => {
            let mut items = Vec::new();
            // The values still to read, last first: a nested array pushes its own.
            let mut todo: Vec<Node> = children(node, "value").collect();
            todo.reverse();
            while let Some(v) = todo.pop() {
                let inner = v.children().next();
                match inner.map(|i| (i.name(), i)) {
                    Some(("simpleValue", s)) => {
                        let item = s.attribute("value").unwrap_or_default();
                        items.push(match v.attribute("repetitionValue") {
                            Some(n) => format!("{n}({item})"),
                            None => item.to_string(),
                        });
                    }
                    Some(("arrayValue", a)) => {
                        let mut more: Vec<Node> = children(a, "value").collect();
                        more.reverse();
                        todo.extend(more);
                    }
                    _ => return Err(nested()),
                }
            }
            Ok(format!("[{}]", items.join(", ")))
        }
        "structValue" => {
            let mut items = Vec::new();
            for v in children(node, "value") {
                let member = v.attribute("member").unwrap_or_default();
                let value = child(v, "simpleValue")
                    .and_then(|s| s.attribute("value"))
                    .ok_or_else(nested)?;
                items.push(format!("{member} := {value}"));
            }
            Ok(format!("({})", items.join(", ")))
        }
        _ => Err(nested()),
    }
}

/// A `<dataType>` as `TYPE … END_TYPE`: a structure, an enumeration, or another type's alias.
fn data_type(dt: Node, out: &mut Written, notes: &mut Notes) -> Result<(), Refused> {
    let at = dt.range().start;
    let name = dt.attribute("name").unwrap_or_default();
    let base = child(dt, "baseType").ok_or_else(|| {
        (
            at,
            format!("the data type `{name}` without a base type"),
            "give it one".into(),
        )
    })?;
    let init = match child(dt, "initialValue") {
        Some(i) => format!(" := {}", value_text(i)?),
        None => String::new(),
    };
    out.line(at, "TYPE");
    match base.children().next().map(|n| (n.name(), n)) {
        Some(("struct", s)) => {
            out.line(at, &format!("  {name} : STRUCT"));
            for v in children(s, "variable") {
                out.line(v.range().start, &format!("    {};", variable(v, notes)?));
            }
            out.line(at, "  END_STRUCT;");
        }
        Some(("enum", e)) => {
            // A value with its integer, where one is given (`Run := 5`).
            let values: Vec<String> = child(e, "values")
                .iter()
                .flat_map(|v| children(*v, "value"))
                .filter_map(|v| {
                    let name = v.attribute("name")?;
                    Some(match v.attribute("value") {
                        Some(n) => format!("{name} := {n}"),
                        None => name.to_string(),
                    })
                })
                .collect();
            out.line(at, &format!("  {name} : ({}){init};", values.join(", ")));
        }
        _ => out.line(at, &format!("  {name} : {}{init};", type_text(base)?)),
    }
    out.line(at, "END_TYPE");
    Ok(())
}

/// The ST type a FUNCTION returns.
fn return_type(f: &Pou) -> Result<String, Refused> {
    child(f.node, "interface")
        .and_then(|i| child(i, "returnType"))
        .ok_or_else(|| {
            let at = f.node.range().start;
            (
                at,
                "a FUNCTION without a return type".into(),
                "give it one".into(),
            )
        })
        .and_then(type_text)
}

/// For a FUNCTION imported as a program: a PROGRAM `NAME_CALL` whose inputs are the function's
/// and whose output `RESULT` is what the function returns, every scan.
fn call_program(f: &Pou, out: &mut Written, notes: &mut Notes) -> Result<String, Refused> {
    let at = f.node.range().start;
    let interface = child(f.node, "interface");
    let ret = return_type(f)?;
    let name = format!("{}_CALL", f.name);
    out.line(at, &format!("PROGRAM {name}"));
    let mut args = Vec::new();
    for section in interface.iter().flat_map(|i| children(*i, "inputVars")) {
        out.line(at, "VAR_INPUT");
        for v in children(section, "variable") {
            out.line(v.range().start, &format!("  {};", variable(v, notes)?));
            let n = v.attribute("name").unwrap_or_default();
            args.push(format!("{n} := {n}"));
        }
        out.line(at, "END_VAR");
    }
    out.line(at, &format!("VAR_OUTPUT\n  RESULT : {ret};\nEND_VAR"));
    out.line(at, &format!("RESULT := {}({});", f.name, args.join(", ")));
    out.line(at, "END_PROGRAM");
    Ok(name)
}

/// The configurations (`instances/configurations`): the global variables that `keep` keeps (those
/// a written POU declares VAR_EXTERNAL), and the task that runs the POU `run`, so that its
/// INTERVAL is the program's scan period.
fn configurations(
    root: Node,
    run: &str,
    out: &mut Written,
    notes: &mut Notes,
    keep: &dyn Fn(&str) -> bool,
) -> Result<(), Refused> {
    let configs = child(root, "instances")
        .and_then(|i| child(i, "configurations"))
        .into_iter()
        .flat_map(|c| children(c, "configuration"));
    for config in configs {
        let at = config.range().start;
        out.line(
            at,
            &format!(
                "CONFIGURATION {}",
                config.attribute("name").unwrap_or("config")
            ),
        );
        for g in children(config, "globalVars") {
            var_block(g, out, notes, keep)?;
        }
        for resource in children(config, "resource") {
            let r_at = resource.range().start;
            let r_name = resource.attribute("name").unwrap_or("resource");
            out.line(r_at, &format!("  RESOURCE {r_name} ON PLC"));
            for g in children(resource, "globalVars") {
                var_block(g, out, notes, keep)?;
            }
            for task in children(resource, "task") {
                let runs: Vec<&str> = children(task, "pouInstance")
                    .filter(|i| {
                        let ty = i.attribute("typeName").or_else(|| i.attribute("type"));
                        ty.is_some_and(|t| t.eq_ignore_ascii_case(run))
                    })
                    .filter_map(|i| i.attribute("name"))
                    .collect();
                if runs.is_empty() {
                    continue;
                }
                let t_name = task.attribute("name").unwrap_or("task");
                let mut params = Vec::new();
                if let Some(i) = task.attribute("interval") {
                    params.push(format!("INTERVAL := {i}"));
                }
                params.push(format!(
                    "PRIORITY := {}",
                    task.attribute("priority").unwrap_or("0")
                ));
                out.line(
                    task.range().start,
                    &format!("    TASK {t_name}({});", params.join(", ")),
                );
                for instance in runs {
                    out.line(
                        task.range().start,
                        &format!("    PROGRAM {instance} WITH {t_name} : {run};"),
                    );
                }
            }
            out.line(r_at, "  END_RESOURCE");
        }
        out.line(at, "END_CONFIGURATION");
    }
    Ok(())
}
