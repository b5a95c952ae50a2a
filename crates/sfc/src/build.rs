//! A chart and its POU become a Cetratus net and program TOML (the mapping of docs/sfc.md).

use std::collections::HashSet;
use std::fmt::Write as _;

use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition as NetTransition};
use cetratus_program::guard::{Expr, ExprKind};

use crate::chart::{ActionRef, Chart, Qualifier};
use crate::nest::{Nest, SEP};
use crate::pou::{Body, Pou, VarKind};
use crate::source::Source;
use crate::st::{self, Names, Resolved, StError, Stmt, Ty};
use crate::SfcError;

/// A transition the mapping adds (a nested step's hold or resume), with its guard.
pub(crate) type ExtraGuard = (String, String);

/// The structural net of a chart: steps as places (initial steps marked), transitions as
/// transitions with their left-to-right priorities, jumps as arcs to their target. Refuses a
/// network (a connected part of the chart) with no initial step or with two. The steps of a
/// nested chart (`nests`) start unmarked, each with a held place and its hold and resume
/// transitions (module `nest`), whose ids and guards are returned after the transitions' ids.
pub(crate) fn net(
    source: &Source,
    chart: &Chart,
    nests: &[Nest],
) -> Result<(Net, Vec<String>, Vec<ExtraGuard>), SfcError> {
    check_networks(source, chart)?;
    let mut used: HashSet<String> = chart
        .steps
        .iter()
        .map(|s| s.name.to_ascii_lowercase())
        .collect();
    let mut fresh = |base: String| {
        let mut id = base;
        while !used.insert(id.to_ascii_lowercase()) {
            id.push('_');
        }
        id
    };
    let mut b = NetBuilder::new(chart.pou.clone());
    b.name(chart.pou.clone());
    for (i, s) in chart.steps.iter().enumerate() {
        let nested = Nest::of_step(nests, i);
        let mut p = Place::new(s.name.clone(), u32::from(s.initial && nested.is_none()));
        p.name = Some(match nested {
            Some(n) => display(&n.action, &s.name),
            None => s.name.clone(),
        });
        b.add_place(p).map_err(|e| net_err(source, e))?;
    }
    // A nested step's held place, where its token waits while the action is off.
    let mut held = Vec::new();
    for n in nests {
        for i in n.steps.clone() {
            let s = &chart.steps[i];
            let id = fresh(format!("{}{SEP}held", s.name));
            let mut p = Place::new(id.clone(), u32::from(s.initial));
            p.name = Some(format!("{} (held)", display(&n.action, &s.name)));
            b.add_place(p).map_err(|e| net_err(source, e))?;
            held.push((i, id, n.action.clone()));
        }
    }
    // Left to right: among the transitions that leave a step, the leftmost has the highest
    // priority (IEC 61131-3: the first true branch from the left wins).
    let mut priority = vec![0i32; chart.transitions.len()];
    for s in 0..chart.steps.len() {
        let mut leaving: Vec<usize> = (0..chart.transitions.len())
            .filter(|&t| chart.transitions[t].from.contains(&s))
            .collect();
        leaving.sort_by(|&a, &b| {
            chart.transitions[a]
                .x
                .total_cmp(&chart.transitions[b].x)
                .then(a.cmp(&b))
        });
        let n = leaving.len() as i32;
        for (rank, &t) in leaving.iter().enumerate() {
            priority[t] = priority[t].max(n - rank as i32);
        }
    }
    let mut ids = Vec::with_capacity(chart.transitions.len());
    for (i, t) in chart.transitions.iter().enumerate() {
        let base = match &t.name {
            Some(n) if !n.trim().is_empty() => n.trim().to_string(),
            _ => format!("T{}", t.local_id),
        };
        let id = fresh(base);
        let mut nt = NetTransition::new(id.clone());
        nt.priority = priority[i];
        b.add_transition(nt).map_err(|e| net_err(source, e))?;
        for &s in &t.from {
            let arc = fresh(format!("{id}_from_{}", chart.steps[s].name));
            b.add_arc(&arc, &chart.steps[s].name, &id, 1, ArcKind::Normal)
                .map_err(|e| net_err(source, e))?;
        }
        for &s in &t.to {
            let arc = fresh(format!("{id}_to_{}", chart.steps[s].name));
            b.add_arc(&arc, &id, &chart.steps[s].name, 1, ArcKind::Normal)
                .map_err(|e| net_err(source, e))?;
        }
        ids.push(id);
    }
    let mut extra = Vec::new();
    for (i, place, action) in held {
        let step = &chart.steps[i].name;
        for (suffix, from, to, guard) in [
            ("hold", step.as_str(), place.as_str(), format!("!{action}")),
            ("resume", place.as_str(), step.as_str(), action.clone()),
        ] {
            let id = fresh(format!("{step}{SEP}{suffix}"));
            b.add_transition(NetTransition::new(id.clone()))
                .map_err(|e| net_err(source, e))?;
            let arc = fresh(format!("{id}_from_{from}"));
            b.add_arc(&arc, from, &id, 1, ArcKind::Normal)
                .map_err(|e| net_err(source, e))?;
            let arc = fresh(format!("{id}_to_{to}"));
            b.add_arc(&arc, &id, to, 1, ArcKind::Normal)
                .map_err(|e| net_err(source, e))?;
            extra.push((id, guard));
        }
    }
    Ok((b.build().map_err(|e| net_err(source, e))?, ids, extra))
}

/// `A.S` for the place `A__S` of step `S` of action `A`'s chart.
fn display(action: &str, id: &str) -> String {
    format!("{action}.{}", &id[action.len() + SEP.len()..])
}

fn net_err(source: &Source, e: cetratus_net::NetError) -> SfcError {
    SfcError::Net {
        file: source.label.to_string(),
        source: e,
    }
}

/// Every network (steps connected through transitions) has exactly one initial step.
fn check_networks(source: &Source, chart: &Chart) -> Result<(), SfcError> {
    let n = chart.steps.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for t in &chart.transitions {
        let all: Vec<usize> = t.from.iter().chain(&t.to).copied().collect();
        for w in all.windows(2) {
            let (a, b) = (find(&mut parent, w[0]), find(&mut parent, w[1]));
            parent[a] = b;
        }
    }
    let mut initial: Vec<Option<usize>> = vec![None; n];
    for (i, s) in chart.steps.iter().enumerate() {
        if !s.initial {
            continue;
        }
        let root = find(&mut parent, i);
        if let Some(first) = initial[root] {
            return Err(SfcError::Chart {
                pos: source.pos(s.at),
                pou: chart.pou.clone(),
                message: format!(
                    "steps `{}` and `{}` are both initial steps of one network; a network has one initial step (IEC 61131-3), make one of them a plain step",
                    chart.steps[first].name, s.name
                ),
            });
        }
        initial[root] = Some(i);
    }
    for i in 0..n {
        let root = find(&mut parent, i);
        if initial[root].is_none() {
            return Err(SfcError::Chart {
                pos: source.pos(chart.steps[i].at),
                pou: chart.pou.clone(),
                message: format!(
                    "step `{}` is in a network with no initial step; mark the network's first step initial",
                    chart.steps[i].name
                ),
            });
        }
        initial[root] = initial[root].or(Some(i));
    }
    Ok(())
}

/// A signal of the generated program.
struct Signal {
    name: String,
    kind: VarKind,
    ty: Ty,
    address: Option<String>,
    initial: Option<String>,
}

/// Resolves names in a condition or an action body.
struct Scope<'c> {
    signals: &'c [Signal],
    unusable: &'c [(String, String)],
    chart: &'c Chart,
    in_condition: bool,
    /// The action whose nested chart the text belongs to: its own steps are found first.
    prefix: Option<&'c str>,
}

impl Names for Scope<'_> {
    fn resolve(&self, name: &str) -> Option<Resolved> {
        let own = self
            .prefix
            .and_then(|a| self.chart.step_index(&format!("{a}{SEP}{name}")));
        if let Some(s) = own.or_else(|| self.chart.step_index(name)) {
            return Some(Resolved::Step(self.chart.steps[s].name.clone()));
        }
        if let Some(s) = self
            .signals
            .iter()
            .find(|s| s.name.eq_ignore_ascii_case(name))
        {
            if self.in_condition && s.kind == VarKind::Output {
                return Some(Resolved::Unusable(format!(
                    "`{}` is a VAR_OUTPUT, and Cetratus conditions read inputs and variables only; declare it in VAR and copy it to an output",
                    s.name
                )));
            }
            return Some(Resolved::Var(s.name.clone(), s.ty));
        }
        self.unusable
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))
            .map(|(_, why)| Resolved::Unusable(why.clone()))
    }
}

/// The program TOML of a chart with its nested charts merged in (`nests`), whose net has the
/// transition ids `ids` and the hold and resume transitions `extra` (id, guard); `notes` gathers
/// what was read but not imported.
#[allow(clippy::too_many_arguments)]
pub(crate) fn program_toml(
    source: &Source,
    pou: &Pou,
    chart: &Chart,
    nests: &[Nest],
    ids: &[String],
    extra: &[ExtraGuard],
    net_file: &str,
    notes: &mut Vec<String>,
) -> Result<String, SfcError> {
    let st_err = |base: usize, e: StError| match e.construct {
        Some(construct) => SfcError::Unsupported {
            pos: source.pos(base + e.offset),
            pou: pou.name.clone(),
            construct,
            message: e.message,
        },
        None => SfcError::St {
            pos: source.pos(base + e.offset),
            pou: pou.name.clone(),
            message: e.message,
        },
    };
    // Signals.
    let mut signals: Vec<Signal> = Vec::new();
    let mut unusable: Vec<(String, String)> = Vec::new();
    for v in &pou.variables {
        let clash = signals.iter().any(|s| s.name.eq_ignore_ascii_case(&v.name))
            || chart.step_index(&v.name).is_some();
        if clash {
            return Err(SfcError::Chart {
                pos: source.pos(v.at),
                pou: pou.name.clone(),
                message: format!(
                    "the name `{}` is declared twice among the POU's variables and steps (IEC names are case-insensitive); rename one",
                    v.name
                ),
            });
        }
        let ty = match v.ty.to_ascii_uppercase().as_str() {
            "BOOL" => Ty::Bool,
            "SINT" | "INT" | "DINT" | "LINT" | "USINT" | "UINT" | "UDINT" | "ULINT" | "BYTE"
            | "WORD" | "DWORD" | "LWORD" => Ty::Int,
            "REAL" | "LREAL" => Ty::Real,
            other => {
                let why = format!(
                    "`{}` has the type {other}, outside the subset (BOOL, integer types, REAL, LREAL)",
                    v.name
                );
                notes.push(format!(
                    "{}: variable not imported: {why}",
                    source.pos(v.at)
                ));
                unusable.push((v.name.clone(), why));
                continue;
            }
        };
        signals.push(Signal {
            name: v.name.clone(),
            kind: v.kind,
            ty,
            address: v.address.clone(),
            initial: v.initial.clone(),
        });
    }
    // The `Q` of each action with a nested chart, as a BOOL variable named after the action.
    for n in nests {
        if let Some(v) = pou
            .variables
            .iter()
            .find(|v| v.name.eq_ignore_ascii_case(&n.action))
        {
            return Err(SfcError::Chart {
                pos: source.pos(v.at),
                pou: pou.name.clone(),
                message: format!(
                    "the action `{}` has a nested chart, whose state is the BOOL variable `{0}`, and a variable of the POU has that name; rename one",
                    n.action
                ),
            });
        }
        signals.push(Signal {
            name: n.action.clone(),
            kind: VarKind::Local,
            ty: Ty::Bool,
            address: None,
            initial: None,
        });
    }

    let mut out = String::new();
    let _ = writeln!(
        out,
        "# Imported from {} (PLCopen TC6 XML), POU {}.",
        file_name(source.label),
        pou.name
    );
    let _ = writeln!(out, "[program]");
    let _ = writeln!(out, "name = {}", q(&pou.name));
    let _ = writeln!(out, "version = \"1\"");
    let _ = writeln!(
        out,
        "description = {}",
        q(&format!("SFC {} of {}", pou.name, file_name(source.label)))
    );
    let _ = writeln!(out, "net = {}", q(net_file));
    let _ = writeln!(out, "chart = \"sfc\"");
    for (kind, section) in [
        (VarKind::Input, "input"),
        (VarKind::Output, "output"),
        (VarKind::Local, "variable"),
    ] {
        for s in signals.iter().filter(|s| s.kind == kind) {
            let _ = writeln!(out, "\n[[{section}]]");
            let _ = writeln!(out, "name = {}", q(&s.name));
            let ty = match s.ty {
                Ty::Bool => "bool",
                Ty::Int => "int",
                _ => "real",
            };
            let _ = writeln!(out, "type = \"{ty}\"");
            if let Some(a) = &s.address {
                let _ = writeln!(out, "address = {}", q(a));
            }
            if let (VarKind::Local, Some(init)) = (kind, &s.initial) {
                if let Some(v) = initial_value(s.ty, init) {
                    let _ = writeln!(out, "initial = {v}");
                }
            }
        }
    }

    // Guards.
    let cond_scope = Scope {
        signals: &signals,
        unusable: &unusable,
        chart,
        in_condition: true,
        prefix: None,
    };
    let mut guards = String::new();
    for (i, (t, id)) in chart.transitions.iter().zip(ids).enumerate() {
        let nest = Nest::of_transition(nests, i);
        let cond_scope = Scope {
            prefix: nest.map(|n| n.action.as_str()),
            ..cond_scope
        };
        let (text, at, negated) = match &t.condition {
            crate::chart::Condition::St { text, at, negated } => (text, *at, *negated),
            crate::chart::Condition::Unsupported { form, at } => {
                return Err(SfcError::Unsupported {
                    pos: source.pos(*at),
                    pou: pou.name.clone(),
                    construct: form.clone(),
                    message: format!(
                        "the condition of transition {id} must be Structured Text (inline, in an inVariable box, or a named transition's ST body)"
                    ),
                })
            }
        };
        let mut e = st::condition(text, &cond_scope).map_err(|e| st_err(at, e))?;
        if negated {
            e = Expr::new(ExprKind::Unary(
                cetratus_program::guard::UnOp::Not,
                Box::new(e),
            ));
        }
        if let Some(n) = nest {
            // A nested chart evolves only while its action is on.
            let on = Expr::new(ExprKind::Name(n.action.clone()));
            e = match e.kind {
                ExprKind::Bool(true) => on,
                _ => Expr::new(ExprKind::Binary(
                    cetratus_program::guard::BinOp::And,
                    Box::new(on),
                    Box::new(e),
                )),
            };
        }
        if e.kind == ExprKind::Bool(true) {
            continue;
        }
        let _ = writeln!(guards, "{id} = {}", q(&e.to_string()));
    }
    for (id, guard) in extra {
        let _ = writeln!(guards, "{id} = {}", q(guard));
    }
    if !guards.is_empty() {
        let _ = write!(out, "\n[guards]\n{guards}");
    }

    // Actions: a BOOL variable under its qualifier, or a body that the runtime's statement
    // executor runs under it.
    let body_scope = Scope {
        signals: &signals,
        unusable: &unusable,
        chart,
        in_condition: false,
        prefix: None,
    };
    let mut actions: Vec<(String, &'static str, Drive, Option<u64>)> = Vec::new();
    let mut bodies: Vec<(String, String)> = Vec::new();
    for (k, a) in chart.associations.iter().enumerate() {
        let step = chart.steps[a.step].name.clone();
        let body_scope = Scope {
            prefix: Nest::of_step(nests, a.step).map(|n| n.action.as_str()),
            ..body_scope
        };
        if let Some(ind) = &a.indicator {
            notes.push(format!("{}: the indicator variable `{ind}` is not imported (it has no effect on execution)", source.pos(a.at)));
        }
        let unsupported = |construct: String, message: &str| SfcError::Unsupported {
            pos: source.pos(a.at),
            pou: pou.name.clone(),
            construct,
            message: message.to_string(),
        };
        let duration = if a.qualifier.is_timed() {
            let Some(d) = &a.duration else {
                return Err(SfcError::Chart {
                    pos: source.pos(a.at),
                    pou: pou.name.clone(),
                    message: format!(
                        "the qualifier {} needs a duration; add duration=\"T#…\"",
                        a.qualifier
                    ),
                });
            };
            Some(st::duration(d).map_err(|e| st_err(a.at, e))?)
        } else {
            None
        };
        let qualifier = match a.qualifier {
            Qualifier::N => "N",
            Qualifier::S => "S",
            Qualifier::R => "R",
            // P is the IEC pulse: on in the scan the step is entered, as P1.
            Qualifier::P | Qualifier::P1 => "P1",
            Qualifier::P0 => "P0",
            Qualifier::L => "L",
            Qualifier::D => "D",
            Qualifier::SD => "SD",
            Qualifier::DS => "DS",
            Qualifier::SL => "SL",
        };
        // What the association runs: a Boolean variable, or a body.
        let (name, text, at) = match &a.action {
            ActionRef::Reference(name) => {
                if let Some(named) = pou
                    .actions
                    .iter()
                    .find(|n| n.name.eq_ignore_ascii_case(name))
                {
                    match &named.body {
                        Body::St { text, at } => (named.name.clone(), text.clone(), *at),
                        // An action with a nested chart: its Q drives the chart's variable.
                        Body::Other { .. }
                            if nests.iter().any(|n| n.action == named.name) =>
                        {
                            actions.push((
                                step,
                                qualifier,
                                Drive::Target(named.name.clone()),
                                duration,
                            ));
                            continue;
                        }
                        Body::Other { language, .. } => {
                            return Err(unsupported(
                                format!("the action `{name}` with a {language} body"),
                                "action bodies must be Structured Text or a chart (an FBD, LD or IL body is not imported)",
                            ))
                        }
                    }
                } else {
                    match body_scope.resolve(name) {
                        Some(Resolved::Var(v, Ty::Bool)) => {
                            actions.push((step, qualifier, Drive::Target(v), duration));
                            continue;
                        }
                        Some(Resolved::Var(v, ty)) => {
                            return Err(unsupported(
                                format!("the {} variable `{v}` as an action", ty.iec()),
                                "a variable named as an action must be BOOL",
                            ))
                        }
                        _ => {
                            return Err(SfcError::Chart {
                                pos: source.pos(a.at),
                                pou: pou.name.clone(),
                                message: format!("the action `{name}` is neither an action of the POU nor a BOOL variable; declare it"),
                            })
                        }
                    }
                }
            }
            ActionRef::Inline(Body::St { text, at }) => {
                (format!("{step}_inline{}", k + 1), text.clone(), *at)
            }
            ActionRef::Inline(Body::Other { language, .. }) => {
                return Err(unsupported(
                    format!("an inline {language} action"),
                    "action bodies must be Structured Text",
                ))
            }
        };
        // A named action associated with several steps is one body, with one action control.
        let key = match bodies.iter().find(|(n, _)| n.eq_ignore_ascii_case(&name)) {
            Some((n, _)) => n.clone(),
            None => {
                let stmts = st::body(&text, &body_scope).map_err(|e| st_err(at, e))?;
                bodies.push((name.clone(), print_body(&stmts)));
                name
            }
        };
        actions.push((step, qualifier, Drive::Body(key), duration));
    }
    if !bodies.is_empty() {
        let _ = writeln!(out, "\n[bodies]");
        for (name, text) in &bodies {
            // A literal string: the body has no quotes to escape, and positions map one to one.
            let _ = writeln!(out, "{} = '''\n{text}'''", q(name));
        }
    }
    for (step, qualifier, drive, duration) in &actions {
        let _ = writeln!(out, "\n[[action]]");
        let _ = writeln!(out, "place = {}", q(step));
        let _ = writeln!(out, "qualifier = \"{qualifier}\"");
        match drive {
            Drive::Target(t) => {
                let _ = writeln!(out, "target = {}", q(t));
            }
            Drive::Body(b) => {
                let _ = writeln!(out, "body = {}", q(b));
            }
        }
        if let Some(d) = duration {
            let _ = writeln!(out, "duration = \"{d}us\"");
        }
    }
    for (name, count) in &chart.ignored_vendor_data {
        notes.push(format!(
            "{}: vendor data `{name}` ({count}×) is not read; it holds editor settings the mapping does not use",
            source.label
        ));
    }
    Ok(out)
}

/// What an action association drives in the program.
enum Drive {
    /// A BOOL variable, by its Cetratus name.
    Target(String),
    /// A body of `[bodies]`, by name.
    Body(String),
}

/// Statements in the program format's body syntax (docs/program-format.md): one per line,
/// `if`/`elif`/`else`/`end` for IF. Iterative: the nesting is the ST parser's, bounded, and no
/// stack here grows with it.
fn print_body(stmts: &[Stmt]) -> String {
    enum Item<'s> {
        Stmt(&'s Stmt, usize),
        Line(String, usize),
    }
    let mut out = String::new();
    let mut todo: Vec<Item> = stmts.iter().rev().map(|s| Item::Stmt(s, 0)).collect();
    while let Some(item) = todo.pop() {
        match item {
            Item::Line(text, indent) => {
                let _ = writeln!(out, "{:w$}{text}", "", w = indent * 2);
            }
            Item::Stmt(Stmt::Assign { target, value, .. }, indent) => {
                let _ = writeln!(out, "{:w$}{target} := {value}", "", w = indent * 2);
            }
            Item::Stmt(
                Stmt::If {
                    arms, otherwise, ..
                },
                indent,
            ) => {
                // Pushed in reverse: the last line first.
                todo.push(Item::Line("end".into(), indent));
                if !otherwise.is_empty() {
                    todo.extend(otherwise.iter().rev().map(|s| Item::Stmt(s, indent + 1)));
                    todo.push(Item::Line("else".into(), indent));
                }
                for (n, (cond, body)) in arms.iter().enumerate().rev() {
                    todo.extend(body.iter().rev().map(|s| Item::Stmt(s, indent + 1)));
                    let kw = if n == 0 { "if" } else { "elif" };
                    todo.push(Item::Line(format!("{kw} {cond} then"), indent));
                }
            }
        }
    }
    out
}

/// The last path component of a label, so the program does not depend on where the file was.
fn file_name(label: &str) -> &str {
    label.rsplit(['/', '\\']).next().unwrap_or(label)
}

/// A TOML basic string.
fn q(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            c if c.is_control() => {
                let _ = write!(out, "\\u{:04X}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A TOML value for a declared initial value, when it is a plain literal of the type.
fn initial_value(ty: Ty, text: &str) -> Option<String> {
    let t = text.trim();
    match ty {
        Ty::Bool => match t.to_ascii_uppercase().as_str() {
            "TRUE" | "1" => Some("true".into()),
            "FALSE" | "0" => Some("false".into()),
            _ => None,
        },
        Ty::Int => t.parse::<i64>().ok().map(|n| n.to_string()),
        Ty::Real => t
            .parse::<f64>()
            .ok()
            .filter(|r| r.is_finite())
            .map(|r| format!("{r:?}")),
        Ty::Time => None,
    }
}
