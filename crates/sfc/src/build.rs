//! A chart and its POU become a Cetratus net and program TOML (the mapping of docs/sfc.md).

use std::collections::HashSet;
use std::fmt::Write as _;

use cetratus_net::{ArcKind, Net, NetBuilder, Place, Transition as NetTransition};
use cetratus_program::guard::{Expr, ExprKind};

use crate::chart::{ActionRef, Association, Chart, Condition, Qualifier, Transition};
use crate::nest::{Nest, SEP};
use crate::pou::{Body, Named, Pou, VarKind};
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
    // Each step's leaving transitions, in transition order: one pass over the arcs, so that a
    // chart of many steps costs what its size costs.
    let mut leaving_of: Vec<Vec<usize>> = vec![Vec::new(); chart.steps.len()];
    for (t, tr) in chart.transitions.iter().enumerate() {
        for &s in &tr.from {
            if leaving_of[s].last() != Some(&t) {
                leaving_of[s].push(t);
            }
        }
    }
    let mut priority = vec![0i32; chart.transitions.len()];
    for mut leaving in leaving_of {
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

/// A variable left out of the program, and why: a name that reads it is refused with that reason.
type Unusable = (String, String);

/// A body of `[bodies]`: its name, and its statements in the program format.
type NamedBody = (String, String);

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
    unusable: &'c [Unusable],
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

/// The program TOML of a chart of the project `project` with its nested charts merged in
/// (`nests`), whose net has the transition ids `ids` and the hold and resume transitions `extra`
/// (id, guard); `notes` gathers what was read but not imported.
#[allow(clippy::too_many_arguments)]
pub(crate) fn program_toml(
    source: &Source,
    project: &str,
    pou: &Pou,
    chart: &Chart,
    nests: &[Nest],
    ids: &[String],
    extra: &[ExtraGuard],
    net_file: &str,
    notes: &mut Vec<String>,
) -> Result<String, SfcError> {
    let mapping = Mapping {
        source,
        project,
        pou,
        chart,
        nests,
    };
    let (signals, unusable) = mapping.signals(notes)?;
    let mut out = mapping.header(net_file);
    write_signals(&mut out, &signals);
    let cond_scope = Scope {
        signals: &signals,
        unusable: &unusable,
        chart,
        in_condition: true,
        prefix: None,
    };
    let guards = mapping.guards(&cond_scope, ids, extra)?;
    if !guards.is_empty() {
        let _ = write!(out, "\n[guards]\n{guards}");
    }
    let body_scope = Scope {
        in_condition: false,
        ..cond_scope
    };
    let (actions, bodies) = mapping.actions(&body_scope, notes)?;
    write_actions(&mut out, &bodies, &actions);
    for (name, count) in &chart.ignored_vendor_data {
        notes.push(format!(
            "{}: vendor data `{name}` ({count}×) is not read; it holds editor settings the mapping does not use",
            source.label
        ));
    }
    Ok(out)
}

/// What a program is mapped from: the file (for positions in messages), the POU, and its chart
/// with the nested charts merged in.
struct Mapping<'m> {
    source: &'m Source<'m>,
    project: &'m str,
    pou: &'m Pou<'m, 'm>,
    chart: &'m Chart,
    nests: &'m [Nest],
}

impl Mapping<'_> {
    /// A refusal that the POU's author fixes in the chart or its declarations.
    fn chart_err(&self, at: usize, message: String) -> SfcError {
        SfcError::Chart {
            pos: self.source.pos(at),
            pou: self.pou.name.clone(),
            message,
        }
    }

    /// A refusal of what the mapping does not import, named as `construct`.
    fn unsupported(&self, at: usize, construct: String, message: &str) -> SfcError {
        SfcError::Unsupported {
            pos: self.source.pos(at),
            pou: self.pou.name.clone(),
            construct,
            message: message.to_string(),
        }
    }

    /// An ST error placed in the file: its offset counts from `base`, where the text starts.
    fn st_err(&self, base: usize, e: StError) -> SfcError {
        match e.construct {
            Some(construct) => SfcError::Unsupported {
                pos: self.source.pos(base + e.offset),
                pou: self.pou.name.clone(),
                construct,
                message: e.message,
            },
            None => SfcError::St {
                pos: self.source.pos(base + e.offset),
                pou: self.pou.name.clone(),
                message: e.message,
            },
        }
    }

    /// The program's signals: the POU's variables of the subset's types, then the `Q` of each
    /// action with a nested chart; and the variables left out, with why, so that a name that
    /// reads one is refused with that reason.
    fn signals(&self, notes: &mut Vec<String>) -> Result<(Vec<Signal>, Vec<Unusable>), SfcError> {
        let mut signals: Vec<Signal> = Vec::new();
        let mut unusable: Vec<Unusable> = Vec::new();
        for v in &self.pou.variables {
            let clash = signals.iter().any(|s| s.name.eq_ignore_ascii_case(&v.name))
                || self.chart.step_index(&v.name).is_some();
            if clash {
                return Err(self.chart_err(
                    v.at,
                    format!(
                        "the name `{}` is declared twice among the POU's variables and steps (IEC names are case-insensitive); rename one",
                        v.name
                    ),
                ));
            }
            let iec = v.ty.to_ascii_uppercase();
            let Some(ty) = signal_type(&iec) else {
                let why = format!(
                    "`{}` has the type {iec}, outside the subset (BOOL, integer types, REAL, LREAL)",
                    v.name
                );
                notes.push(format!(
                    "{}: variable not imported: {why}",
                    self.source.pos(v.at)
                ));
                unusable.push((v.name.clone(), why));
                continue;
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
        for n in self.nests {
            if let Some(v) = self.pou.variable(&n.action) {
                return Err(self.chart_err(
                    v.at,
                    format!(
                        "the action `{}` has a nested chart, whose state is the BOOL variable `{0}`, and a variable of the POU has that name; rename one",
                        n.action
                    ),
                ));
            }
            signals.push(Signal {
                name: n.action.clone(),
                kind: VarKind::Local,
                ty: Ty::Bool,
                address: None,
                initial: None,
            });
        }
        Ok((signals, unusable))
    }

    /// The `[program]` table, which names the project and the POU the program came from: what
    /// the file holds, not where it is or what it is called, so that the same chart is the same
    /// program (and hash) under any file name, and a chart that `cetratus export` writes back
    /// imports as the program it came from.
    fn header(&self, net_file: &str) -> String {
        header(self.project, &self.pou.name, net_file)
    }

    /// The lines of `[guards]`: a transition whose guard is always true has none, and the hold
    /// and resume transitions of nested steps come last.
    fn guards(
        &self,
        scope: &Scope,
        ids: &[String],
        extra: &[ExtraGuard],
    ) -> Result<String, SfcError> {
        let mut guards = String::new();
        for (i, (t, id)) in self.chart.transitions.iter().zip(ids).enumerate() {
            let e = self.guard(i, t, id, scope)?;
            if e.kind == ExprKind::Bool(true) {
                continue;
            }
            let _ = writeln!(guards, "{id} = {}", q(&e.to_string()));
        }
        for (id, guard) in extra {
            let _ = writeln!(guards, "{id} = {}", q(guard));
        }
        Ok(guards)
    }

    /// The guard of transition `i` (net id `id`): its ST condition, negated as its box says,
    /// and for a nested chart's transition only while the chart's action is on.
    fn guard(&self, i: usize, t: &Transition, id: &str, scope: &Scope) -> Result<Expr, SfcError> {
        let nest = Nest::of_transition(self.nests, i);
        let scope = Scope {
            prefix: nest.map(|n| n.action.as_str()),
            ..*scope
        };
        let (text, at, negated) = match &t.condition {
            Condition::St { text, at, negated } => (text, *at, *negated),
            Condition::Unsupported { form, at } => {
                return Err(self.unsupported(
                    *at,
                    form.clone(),
                    &format!(
                        "the condition of transition {id} must be Structured Text (inline, in an inVariable box, or a named transition's ST body)"
                    ),
                ))
            }
            // The ST compiler reads a network (`chart_st`).
            Condition::Network { name, language, at } => {
                return Err(self.unsupported(
                    *at,
                    format!("the {language} body of transition {name}"),
                    "the guard subset reads Structured Text only",
                ))
            }
            Condition::Drawn { language, at } => {
                return Err(self.unsupported(
                    *at,
                    format!("an {language} network drawn in the chart as the condition of {id}"),
                    "the guard subset reads Structured Text only",
                ))
            }
        };
        let mut e = st::condition(text, &scope).map_err(|e| self.st_err(at, e))?;
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
        Ok(e)
    }

    /// The `[[action]]`s and the `[bodies]` they run: each association drives a BOOL variable
    /// under its qualifier, or a body that the runtime's statement executor runs under it.
    fn actions(
        &self,
        scope: &Scope,
        notes: &mut Vec<String>,
    ) -> Result<(Vec<Action>, Vec<NamedBody>), SfcError> {
        let mut actions = Vec::new();
        let mut bodies: Vec<NamedBody> = Vec::new();
        for (k, a) in self.chart.associations.iter().enumerate() {
            let step = self.chart.steps[a.step].name.clone();
            let scope = Scope {
                prefix: Nest::of_step(self.nests, a.step).map(|n| n.action.as_str()),
                ..*scope
            };
            if let Some(ind) = &a.indicator {
                notes.push(format!("{}: the indicator variable `{ind}` is not imported (it has no effect on execution)", self.source.pos(a.at)));
            }
            let duration = self.duration(a)?;
            let qualifier = qualifier_name(a.qualifier);
            let drive = match self.runs(k, a, &step, &scope)? {
                Runs::Target(target) => Drive::Target(target),
                Runs::St { name, text, at } => {
                    // A named action associated with several steps is one body, with one
                    // action control.
                    match bodies.iter().find(|(n, _)| n.eq_ignore_ascii_case(&name)) {
                        Some((n, _)) => Drive::Body(n.clone()),
                        None => {
                            let stmts = st::body(&text, &scope).map_err(|e| self.st_err(at, e))?;
                            bodies.push((name.clone(), print_body(&stmts)));
                            Drive::Body(name)
                        }
                    }
                }
            };
            actions.push(Action {
                place: step,
                qualifier,
                drive,
                duration,
            });
        }
        Ok((actions, bodies))
    }

    /// The duration of a timed qualifier, in microseconds; a timed qualifier needs one.
    fn duration(&self, a: &Association) -> Result<Option<u64>, SfcError> {
        if !a.qualifier.is_timed() {
            return Ok(None);
        }
        let Some(d) = &a.duration else {
            return Err(self.chart_err(
                a.at,
                format!(
                    "the qualifier {} needs a duration; add duration=\"T#…\"",
                    a.qualifier
                ),
            ));
        };
        Ok(Some(st::duration(d).map_err(|e| self.st_err(a.at, e))?))
    }

    /// What association `k` (of step `step`) runs: a BOOL variable, or Structured Text to
    /// compile; a body in another language is refused.
    fn runs(&self, k: usize, a: &Association, step: &str, scope: &Scope) -> Result<Runs, SfcError> {
        match &a.action {
            ActionRef::Reference(name) => match self
                .pou
                .actions
                .iter()
                .find(|n| n.name.eq_ignore_ascii_case(name))
            {
                Some(named) => self.named_action(named, name, a.at),
                None => self.variable_action(name, a.at, scope),
            },
            ActionRef::Inline(Body::St { text, at }) => Ok(Runs::St {
                name: format!("{step}_inline{}", k + 1),
                text: text.clone(),
                at: *at,
            }),
            ActionRef::Inline(Body::Other { language, .. }) => Err(self.unsupported(
                a.at,
                format!("an inline {language} action"),
                "action bodies must be Structured Text",
            )),
        }
    }

    /// What a named action of the POU runs, associated as `name` at byte `assoc_at`.
    fn named_action(&self, named: &Named, name: &str, assoc_at: usize) -> Result<Runs, SfcError> {
        match &named.body {
            Body::St { text, at } => Ok(Runs::St {
                name: named.name.clone(),
                text: text.clone(),
                at: *at,
            }),
            // An action with a nested chart: its Q drives the chart's variable.
            Body::Other { .. } if self.nests.iter().any(|n| n.action == named.name) => {
                Ok(Runs::Target(named.name.clone()))
            }
            Body::Other { language, .. } => Err(self.unsupported(
                assoc_at,
                format!("the action `{name}` with a {language} body"),
                "action bodies must be Structured Text or a chart (an FBD, LD or IL body is not imported)",
            )),
        }
    }

    /// A variable named as an action, which the association sets: it must be a BOOL.
    fn variable_action(&self, name: &str, at: usize, scope: &Scope) -> Result<Runs, SfcError> {
        match scope.resolve(name) {
            Some(Resolved::Var(v, Ty::Bool)) => Ok(Runs::Target(v)),
            Some(Resolved::Var(v, ty)) => Err(self.unsupported(
                at,
                format!("the {} variable `{v}` as an action", ty.iec()),
                "a variable named as an action must be BOOL",
            )),
            _ => Err(self.chart_err(
                at,
                format!("the action `{name}` is neither an action of the POU nor a BOOL variable; declare it"),
            )),
        }
    }
}

/// The `[program]` table of a chart of `project`'s POU `pou` whose net is `net_file`: what the
/// file holds, not where it is or what it is called, so that the same chart is the same program
/// (and hash) under any file name, and a chart that `cetratus export` writes back imports as the
/// program it came from.
pub(crate) fn header(file: &str, pou: &str, net_file: &str) -> String {
    let mut out = String::new();
    // A comment is one line: a project named across lines (`&#10;`) stays in it.
    let one_line = |s: &str| s.replace(char::is_control, " ");
    let _ = writeln!(
        out,
        "# Imported from the PLCopen TC6 XML project {}, POU {}.",
        one_line(file),
        one_line(pou)
    );
    let _ = writeln!(out, "[program]");
    let _ = writeln!(out, "name = {}", q(pou));
    let _ = writeln!(out, "version = \"1\"");
    let _ = writeln!(out, "description = {}", q(&format!("SFC {pou} of {file}")));
    let _ = writeln!(out, "net = {}", q(net_file));
    let _ = writeln!(out, "chart = \"sfc\"");
    out
}

/// The type of a signal declared with the IEC type `iec` (upper case), when the subset has it.
fn signal_type(iec: &str) -> Option<Ty> {
    match iec {
        "BOOL" => Some(Ty::Bool),
        "SINT" | "INT" | "DINT" | "LINT" | "USINT" | "UINT" | "UDINT" | "ULINT" | "BYTE"
        | "WORD" | "DWORD" | "LWORD" => Some(Ty::Int),
        "REAL" | "LREAL" => Some(Ty::Real),
        _ => None,
    }
}

/// The `[[input]]`, `[[output]]` and `[[variable]]` tables, in that order.
fn write_signals(out: &mut String, signals: &[Signal]) {
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
}

/// The qualifier as the program format names it.
pub(crate) fn qualifier_name(qualifier: Qualifier) -> &'static str {
    match qualifier {
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
    }
}

/// The `[bodies]` table, then the `[[action]]` tables.
pub(crate) fn write_actions(out: &mut String, bodies: &[NamedBody], actions: &[Action]) {
    if !bodies.is_empty() {
        let _ = writeln!(out, "\n[bodies]");
        for (name, text) in bodies {
            // A literal string: the body has no quotes to escape, and positions map one to one.
            let _ = writeln!(out, "{} = '''\n{text}'''", q(name));
        }
    }
    for a in actions {
        let _ = writeln!(out, "\n[[action]]");
        let _ = writeln!(out, "place = {}", q(&a.place));
        let _ = writeln!(out, "qualifier = \"{}\"", a.qualifier);
        match &a.drive {
            Drive::Target(t) => {
                let _ = writeln!(out, "target = {}", q(t));
            }
            Drive::Body(b) => {
                let _ = writeln!(out, "body = {}", q(b));
            }
        }
        if let Some(d) = a.duration {
            let _ = writeln!(out, "duration = \"{d}us\"");
        }
    }
}

/// An `[[action]]` of the program: one action association of the chart.
pub(crate) struct Action {
    /// The step's place.
    pub place: String,
    /// The qualifier, as the program format names it.
    pub qualifier: &'static str,
    /// What it drives.
    pub drive: Drive,
    /// The duration of a timed qualifier, in microseconds.
    pub duration: Option<u64>,
}

/// What an association runs, before its body is compiled.
enum Runs {
    /// A BOOL variable, by its Cetratus name.
    Target(String),
    /// Structured Text: the body's name, its text, and where the text starts.
    St {
        name: String,
        text: String,
        at: usize,
    },
}

/// What an action association drives in the program.
pub(crate) enum Drive {
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

/// The name of the project a file holds (its `contentHeader`), or, in a file without one, the
/// file's name without the directory (so the program does not depend on where the file was).
pub(crate) fn project_name<'d>(doc: &'d cetratus_net::xml::Document, label: &'d str) -> &'d str {
    crate::source::child(doc.root_element(), "contentHeader")
        .and_then(|h| h.attribute("name"))
        .map(str::trim)
        .filter(|n| !n.is_empty())
        .unwrap_or_else(|| label.rsplit(['/', '\\']).next().unwrap_or(label))
}

/// A TOML basic string.
pub(crate) fn q(s: &str) -> String {
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
