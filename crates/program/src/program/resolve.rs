//! Resolving a program document against its net, table by table: every name looked up, every
//! guard and body compiled, every setting checked, each error at the file:line:column to fix.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::time::Duration;

use cetratus_vocab::UnknownName;

use cetratus_net::{Net, Policy};
use toml::Spanned;

use super::{Watchdog, DEFAULT_SCAN_PERIOD};
use crate::action::{Action, Qualifier, Target};
use crate::body::Body;
use crate::guard::{Guard, Scope, SyntaxError};
use crate::invariant::Invariant;
use crate::source::{Doc, Origin, ProgramSection, SignalDecl};
use crate::st::StProgram;
use crate::value::{Signal, Type, Value};
use crate::ProgramError;
use std::sync::Arc;

#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    Input,
    Output,
    Variable,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Input => "input",
            Kind::Output => "output",
            Kind::Variable => "variable",
        }
    }
}

/// What `[program]` sets besides its name: how the net fires, whether it is a chart, how often
/// it scans.
pub(super) struct Settings {
    pub policy: Policy,
    pub sfc: bool,
    pub scan_period: Duration,
}

/// `[program]` checked: a name and a version a reader can tell apart, known settings.
pub(super) fn settings(o: &Origin, p: &ProgramSection) -> Result<Settings, ProgramError> {
    if p.name.get_ref().trim().is_empty() {
        return Err(o.err(
            p.name.span().start,
            "the program name is empty; give it a name such as \"vernadat-cell\"",
        ));
    }
    if p.version.get_ref().trim().is_empty() {
        return Err(o.err(
            p.version.span().start,
            "the version is empty; give one such as \"1.0.0\"",
        ));
    }
    let policy = match &p.policy {
        None => Policy::default(),
        Some(s) => s
            .get_ref()
            .parse::<Policy>()
            .map_err(|m| o.err(s.span().start, m.to_string()))?,
    };
    let sfc = match &p.chart {
        None => false,
        Some(c) if c.get_ref() == "sfc" => true,
        Some(c) => {
            return Err(o.err(
                c.span().start,
                format!("unknown chart kind `{}`; the one kind is \"sfc\" (an IEC 61131-3 chart imported from PLCopen XML)", c.get_ref()),
            ))
        }
    };
    let scan_period = match &p.scan_period {
        None => DEFAULT_SCAN_PERIOD,
        Some(s) => Duration::from_micros(positive_duration(o, s, "the scan period", "10ms")?),
    };
    Ok(Settings {
        policy,
        sfc,
        scan_period,
    })
}

/// A duration setting in µs; 0 is refused, since it would make the scan loop or a watchdog
/// spin.
fn positive_duration(
    o: &Origin,
    s: &Spanned<String>,
    what: &str,
    example: &str,
) -> Result<u64, ProgramError> {
    let us = crate::guard::parse_duration(s.get_ref())
        .map_err(|e| o.err(o.in_string(s, e.offset), e.message))?;
    if us == 0 {
        return Err(o.err(
            s.span().start,
            format!("{what} must be longer than 0; e.g. \"{example}\""),
        ));
    }
    Ok(us)
}

/// The entries of a `[guards]` or `[bodies]` table in document order, so that errors come in
/// the order a reader fixes them.
pub(super) fn in_document_order(
    table: &BTreeMap<Spanned<String>, Spanned<String>>,
) -> Vec<(&Spanned<String>, &Spanned<String>)> {
    let mut entries: Vec<_> = table.iter().collect();
    entries.sort_by_key(|(k, _)| k.span().start);
    entries
}

/// `[guards]` compiled, one slot per transition of the net.
pub(super) fn guards(
    o: &Origin,
    doc: &Doc,
    scope: &Scope,
) -> Result<Vec<Option<Guard>>, ProgramError> {
    let net = scope.net;
    let mut guards: Vec<Option<Guard>> = vec![None; net.num_transitions()];
    for (key, text) in in_document_order(&doc.guards) {
        let Some(t) = net.transition_by_id(key.get_ref()) else {
            let known: Vec<&str> = net
                .transitions()
                .iter()
                .map(|t| t.id.as_str())
                .take(12)
                .collect();
            return Err(o.err(
                key.span().start,
                format!(
                    "guard for unknown transition `{}`; expected a transition id of the net ({}{})",
                    key.get_ref(),
                    known.join(", "),
                    if net.num_transitions() > 12 {
                        ", …"
                    } else {
                        ""
                    }
                ),
            ));
        };
        let g = Guard::compile(text.get_ref(), scope).map_err(|e: SyntaxError| {
            o.err(
                o.in_string(text, e.offset),
                format!("in the guard of {}: {}", key.get_ref(), e.message),
            )
        })?;
        guards[t.index()] = Some(g);
    }
    Ok(guards)
}

/// `[bodies]` compiled, in document order, the order actions name them by index.
pub(super) fn bodies(
    o: &Origin,
    doc: &Doc,
    scope: &Scope,
    st: Option<&Arc<StProgram>>,
) -> Result<Vec<Body>, ProgramError> {
    let entries = in_document_order(&doc.bodies);
    let mut bodies: Vec<Body> = Vec::with_capacity(entries.len() + 1);
    if let (Some(st), Some(decl)) = (st, &doc.st) {
        bodies.extend(super::structured::st_bodies(
            o,
            decl.get_ref(),
            st,
            &doc.bodies,
        )?);
    }
    for (key, text) in entries {
        let b = Body::compile(key.get_ref(), text.get_ref(), scope).map_err(|e| {
            o.err(
                o.in_string(text, e.offset),
                format!("in the body {}: {}", key.get_ref(), e.message),
            )
        })?;
        bodies.push(b);
    }
    Ok(bodies)
}

/// `[[action]]`s resolved; a body that no action runs is refused, since it would never run.
pub(super) fn actions(
    o: &Origin,
    doc: &Doc,
    scope: &Scope,
    bodies: &[Body],
    st: Option<&StProgram>,
) -> Result<Vec<Action>, ProgramError> {
    let mut actions = Vec::with_capacity(doc.action.len());
    let mut named = HashMap::with_capacity(bodies.len());
    for (i, b) in bodies.iter().enumerate() {
        named.entry(b.name()).or_insert(i);
    }
    for a in &doc.action {
        actions.push(action(o, (scope, st), &named, a.get_ref())?);
    }
    let run: HashSet<Target> = actions.iter().map(|a| a.target).collect();
    for (i, b) in bodies.iter().enumerate() {
        if !run.contains(&Target::Body(i as u32)) {
            let key = doc.bodies.keys().find(|k| k.get_ref() == b.name());
            return Err(o.err(
                key.map_or(0, |k| k.span().start),
                format!("the body {} is run by no action; add an [[action]] with `body = \"{}\"`, or remove it", b.name(), b.name()),
            ));
        }
    }
    Ok(actions)
}

/// The distinct targets, in order of first appearance, and each action's slot among them:
/// actions that drive one target combine in one slot.
pub(super) fn action_slots(actions: &[Action]) -> (Vec<Target>, Vec<u32>) {
    let mut action_targets: Vec<Target> = Vec::new();
    let mut action_slot = Vec::with_capacity(actions.len());
    let mut slots = HashMap::new();
    for a in actions {
        let slot = *slots.entry(a.target).or_insert_with(|| {
            action_targets.push(a.target);
            action_targets.len() - 1
        });
        action_slot.push(slot as u32);
    }
    (action_targets, action_slot)
}

/// Actions grouped by place in one flat list with a start per place, so that a scan finds a
/// place's actions without allocating.
pub(super) fn actions_by_place(np: usize, actions: &[Action]) -> (Vec<u32>, Vec<u32>) {
    let mut place_action_start = vec![0u32; np + 1];
    for a in actions {
        place_action_start[a.place.index() + 1] += 1;
    }
    for i in 0..np {
        place_action_start[i + 1] += place_action_start[i];
    }
    let mut fill = place_action_start.clone();
    let mut place_actions = vec![0u32; actions.len()];
    for (i, a) in actions.iter().enumerate() {
        let f = &mut fill[a.place.index()];
        place_actions[*f as usize] = i as u32;
        *f += 1;
    }
    (place_action_start, place_actions)
}

/// `[[invariant]]`s, each checked at M0: one that does not hold there is a typo, not a fault.
pub(super) fn invariants(o: &Origin, doc: &Doc, net: &Net) -> Result<Vec<Invariant>, ProgramError> {
    let m0 = net.initial_marking();
    let mut invariants = Vec::with_capacity(doc.invariant.len());
    for decl in &doc.invariant {
        let e = &decl.get_ref().expr;
        let inv = Invariant::parse(e.get_ref(), net)
            .map_err(|err| o.err(o.in_string(e, err.offset), err.message))?;
        let actual = inv.weighted_sum(m0.as_slice());
        if actual != i128::from(inv.constant()) {
            return Err(o.err(
                e.span().start,
                format!(
                    "invariant `{}` does not hold at the initial marking: the left side is {actual}, expected {}; fix the initial marking or the invariant",
                    inv.expr(),
                    inv.constant()
                ),
            ));
        }
        invariants.push(inv);
    }
    Ok(invariants)
}

fn is_identifier(s: &str) -> bool {
    let mut c = s.chars();
    c.next()
        .is_some_and(|f| f.is_ascii_alphabetic() || f == '_')
        && c.all(|ch| ch.is_ascii_alphanumeric() || ch == '_')
        && !matches!(s, "true" | "false")
}

fn literal(
    o: &Origin,
    v: &Spanned<toml::Value>,
    ty: Type,
    what: &str,
) -> Result<Value, ProgramError> {
    match (v.get_ref(), ty) {
        (toml::Value::Boolean(b), Type::Bool) => Ok(Value::Bool(*b)),
        (toml::Value::Integer(i), Type::Int) => Ok(Value::Int(*i)),
        (toml::Value::Float(f), Type::Real) if f.is_finite() => Ok(Value::Real(*f)),
        // An integer literal is a fine real; the conversion is exact up to 2^53.
        (toml::Value::Integer(i), Type::Real) => Ok(Value::Real(*i as f64)),
        (other, _) => Err(o.err(
            v.span().start,
            format!(
                "`{what}` must be a {ty} ({}), found {}",
                match ty {
                    Type::Bool => "true or false",
                    Type::Int => "an integer such as 0",
                    Type::Real => "a finite number such as 0.0",
                },
                other.type_str()
            ),
        )),
    }
}

pub(super) fn signal(
    o: &Origin,
    net: &Net,
    d: &SignalDecl,
    kind: Kind,
    seen: &mut HashMap<String, &'static str>,
) -> Result<Signal, ProgramError> {
    let name = d.name.get_ref();
    let at = d.name.span().start;
    if !is_identifier(name) {
        return Err(o.err(at, format!("`{name}` is not a valid signal name; use letters, digits and `_`, starting with a letter or `_` (guards must be able to name it)")));
    }
    if let Some(prev) = seen.get(name) {
        return Err(o.err(at, format!("`{name}` is already declared as an {prev}; every input, output and variable needs its own name")));
    }
    if net.place_by_id(name).is_some() {
        return Err(o.err(at, format!("signal `{name}` has the same name as a place of the net; a guard could not tell them apart, so rename the signal")));
    }
    seen.insert(name.clone(), kind.name());
    let ty: Type =
        d.ty.get_ref()
            .parse()
            .map_err(|m: UnknownName| o.err(d.ty.span().start, m.to_string()))?;
    let misplaced = |field: &str, span: std::ops::Range<usize>, only: &str| {
        o.err(
            span.start,
            format!(
                "`{field}` is only for {only}; remove it from this {}",
                kind.name()
            ),
        )
    };
    if let (Some(a), Kind::Variable) = (&d.address, kind) {
        return Err(misplaced("address", a.span(), "inputs and outputs"));
    }
    let safe = match (&d.safe, kind) {
        (None, _) => None,
        (Some(v), Kind::Output | Kind::Input) => Some(literal(o, v, ty, "safe")?),
        (Some(v), _) => return Err(misplaced("safe", v.span(), "inputs and outputs")),
    };
    let initial = match (&d.initial, kind) {
        (None, _) => ty.zero(),
        (Some(v), Kind::Variable) => literal(o, v, ty, "initial")?,
        (Some(v), _) => return Err(misplaced("initial", v.span(), "variables")),
    };
    let retain = match (&d.retain, kind) {
        (None, _) => false,
        (Some(r), Kind::Variable) => *r.get_ref(),
        (Some(r), _) => return Err(misplaced("retain", r.span(), "variables")),
    };
    Ok(Signal {
        name: name.clone(),
        ty,
        address: d.address.as_ref().map(|a| a.get_ref().clone()),
        description: d.description.clone(),
        safe,
        initial,
        retain,
    })
}

/// One `[[action]]` resolved: its place, and what it drives, a signal, a BOOL variable of the
/// chart's POU, or a body (`bodies` by name).
fn action(
    o: &Origin,
    (scope, st): (&Scope, Option<&StProgram>),
    bodies: &HashMap<&str, usize>,
    d: &crate::source::ActionDecl,
) -> Result<Action, ProgramError> {
    let place = scope.net.place_by_id(d.place.get_ref()).ok_or_else(|| {
        o.err(
            d.place.span().start,
            format!(
                "action on unknown place `{}`; expected a place id of the net",
                d.place.get_ref()
            ),
        )
    })?;
    let target = match (&d.target, &d.body) {
        (Some(t), None) => match st.filter(|s| s.is_chart()) {
            Some(st) => st.bool_var(t.get_ref()).map(Target::St).ok_or_else(|| {
                o.err(t.span().start, format!("action target `{}` is not a BOOL variable of the chart's POU `{}`; declare it there", t.get_ref(), st.unit().name))
            })?,
            None => signal_target(o, t, scope)?,
        },
        (None, Some(b)) => {
            let i = (bodies.get(b.get_ref().as_str()).copied()).ok_or_else(|| {
                    o.err(
                        b.span().start,
                        format!(
                            "no body `{}` in [bodies]; declare it there, or name a body that is",
                            b.get_ref()
                        ),
                    )
                })?;
            Target::Body(i as u32)
        }
        (Some(_), Some(b)) => {
            return Err(o.err(
                b.span().start,
                "an action has a `target` or a `body`, not both; split it into two actions",
            ))
        }
        (None, None) => {
            return Err(o.err(
                d.place.span().start,
                "the action has neither `target` (a bool signal) nor `body` (a body of [bodies]); add one",
            ))
        }
    };
    let duration = match &d.duration {
        None => None,
        Some(s) => Some(
            crate::guard::parse_duration(s.get_ref())
                .map_err(|e| o.err(o.in_string(s, e.offset), e.message))?,
        ),
    };
    let q = d.qualifier.get_ref().as_str();
    let qat = d.qualifier.span().start;
    let qualifier = match (q, duration) {
        ("N", None) => Qualifier::N,
        ("S", None) => Qualifier::S,
        ("R", None) => Qualifier::R,
        ("P1", None) => Qualifier::P1,
        ("P0", None) => Qualifier::P0,
        ("L", Some(t)) => Qualifier::L(t),
        ("D", Some(t)) => Qualifier::D(t),
        ("SD", Some(t)) => Qualifier::SD(t),
        ("DS", Some(t)) => Qualifier::DS(t),
        ("SL", Some(t)) => Qualifier::SL(t),
        ("L" | "D" | "SD" | "DS" | "SL", None) => {
            return Err(o.err(
                qat,
                format!("qualifier {q} needs a duration; add `duration = \"2s\"`"),
            ))
        }
        ("N" | "S" | "R" | "P1" | "P0", Some(_)) => {
            let at = d.duration.as_ref().map_or(qat, |s| s.span().start);
            return Err(o.err(
                at,
                format!("qualifier {q} takes no duration; remove it, or use L, D, SD, DS or SL"),
            ));
        }
        _ => {
            return Err(o.err(
                qat,
                format!("unknown qualifier `{q}`; expected N, S, R, P1, P0, L, D, SD, DS or SL"),
            ))
        }
    };
    Ok(Action {
        place,
        qualifier,
        target,
    })
}

/// The bool output or variable an action drives.
fn signal_target(o: &Origin, t: &Spanned<String>, scope: &Scope) -> Result<Target, ProgramError> {
    let tname = t.get_ref();
    let tat = t.span().start;
    let (target, sig) = if let Some(i) = scope.output(tname) {
        (Target::Output(i as u32), &scope.outputs[i])
    } else if let Some(i) = scope.var(tname) {
        (Target::Variable(i as u32), &scope.vars[i])
    } else if scope.input(tname).is_some() {
        return Err(o.err(tat, format!("`{tname}` is an input, which the program cannot drive; an action targets a bool output or a bool variable")));
    } else {
        return Err(o.err(tat, format!("action target `{tname}` is not declared; expected a bool output or a bool variable")));
    };
    if sig.ty != Type::Bool {
        return Err(o.err(tat, format!("action target `{tname}` is {} {}; an action drives a bool output or a bool variable (a body assigns other types)", if sig.ty == Type::Int { "an" } else { "a" }, sig.ty)));
    }
    Ok(target)
}

/// The `[[watchdog]]` places and `[stall] no_firing`, resolved against the net.
pub(super) fn watchdogs(
    o: &Origin,
    doc: &Doc,
    net: &Net,
) -> Result<(Vec<Watchdog>, Option<u64>), ProgramError> {
    let duration = |s: &Spanned<String>, what: &str| positive_duration(o, s, what, "10s");
    let mut out: Vec<Watchdog> = Vec::with_capacity(doc.watchdog.len());
    for decl in &doc.watchdog {
        let d = decl.get_ref();
        let id = d.place.get_ref();
        let place = net.place_by_id(id).ok_or_else(|| {
            o.err(
                d.place.span().start,
                format!("[[watchdog]] place `{id}` is not a place of the net; give a place id"),
            )
        })?;
        if out.iter().any(|w| w.place == place) {
            return Err(o.err(
                d.place.span().start,
                format!("place `{id}` has a [[watchdog]] already; give each place one maximum"),
            ));
        }
        out.push(Watchdog {
            place,
            max_us: duration(&d.max, "a [[watchdog]] max")?,
        });
    }
    let no_firing = match &doc.stall {
        None => None,
        Some(s) => {
            let nf = &s.get_ref().no_firing;
            if out.is_empty() {
                return Err(o.err(
                    nf.span().start,
                    "[stall] no_firing watches the [[watchdog]] places, and there are none; add a [[watchdog]] for each place that must not wait, or remove [stall]",
                ));
            }
            Some(duration(nf, "[stall] no_firing")?)
        }
    };
    Ok((out, no_firing))
}
