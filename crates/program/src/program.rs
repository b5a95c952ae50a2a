//! [`Program`]: a net plus its interpretation, resolved and checked at load.

use cetratus_vocab::UnknownName;
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use cetratus_net::{ArcKind, Net, NodeRef, PlaceIdx, Policy, Tokens, TransIdx};
use sha2::{Digest, Sha256};
use toml::Spanned;

use crate::action::{Action, Qualifier, Target};
use crate::body::Body;
use crate::guard::{EvalCtx, EvalError, Guard, Scope, SyntaxError};
use crate::invariant::{self, Invariant, InvariantViolation};
use crate::source::{Doc, Origin, SignalDecl};
use crate::value::{Signal, Type, Value};
use crate::ProgramError;

/// The tool name of the net-level `<toolspecific>` element that carries a program in a PNML file.
pub const TOOL: &str = "cetratus";

/// The scan period when the file does not set one.
pub const DEFAULT_SCAN_PERIOD: Duration = Duration::from_millis(10);

/// A place's maximum dwell time (`[[watchdog]]`): the primary stalls when the place stays marked
/// longer, counted from the scan in which it became marked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Watchdog {
    /// The watched place.
    pub place: PlaceIdx,
    /// Its maximum dwell time, µs.
    pub max_us: u64,
}

/// A PLC program: a net and its interpretation (signals, guards, actions, invariants).
///
/// A `Program` that exists has resolved every name, type-checked and compiled every guard, and
/// checked every declared invariant at M0.
#[derive(Clone, Debug)]
pub struct Program {
    name: String,
    version: String,
    description: String,
    net: Arc<Net>,
    policy: Policy,
    sfc: bool,
    scan_period: Duration,
    pub(crate) inputs: Vec<Signal>,
    pub(crate) outputs: Vec<Signal>,
    pub(crate) variables: Vec<Signal>,
    guards: Vec<Option<Guard>>,
    pub(crate) actions: Vec<Action>,
    /// Action bodies, in declaration order.
    pub(crate) bodies: Vec<Body>,
    /// Per output: a body assigns it, so it keeps its value from scan to scan.
    pub(crate) output_held: Vec<bool>,
    /// Per action, its index in `action_targets`.
    pub(crate) action_slot: Vec<u32>,
    /// The distinct targets actions drive, in order of first appearance.
    pub(crate) action_targets: Vec<Target>,
    /// Actions grouped by place: `place_actions[place_action_start[p]..place_action_start[p+1]]`.
    place_action_start: Vec<u32>,
    place_actions: Vec<u32>,
    invariants: Vec<Invariant>,
    watchdogs: Vec<Watchdog>,
    no_firing_us: Option<u64>,
    source: String,
    // Computed on first use: loading a program does not need its identity, an update does.
    hash: std::sync::OnceLock<([u8; 32], String)>,
}

impl Program {
    /// Loads a program from a `.toml` file (whose `net` names a PNML file next to it) or from a
    /// `.pnml` file that carries the program in a net-level `<toolspecific tool="cetratus">`.
    pub fn load(path: &Path) -> Result<Program, ProgramError> {
        let label = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|source| ProgramError::Io {
            path: label.clone(),
            source,
        })?;
        let is_pnml = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("pnml") || e.eq_ignore_ascii_case("xml"));
        if is_pnml {
            // PIPE writes ISO-8859-1, and says so in the XML declaration.
            let text = cetratus_net::pnml::decode(&bytes, &label)?;
            return Self::from_pnml_text(&text, &label);
        }
        let text = crate::toml_text(bytes, &label)?;
        let origin = Origin::new(&text, &label);
        // Parsed once: the same document names the net and declares the interpretation.
        let doc: Doc = toml::from_str(&text).map_err(|e| toml_error(&origin, &e))?;
        let Some(net_name) = doc.program.net.clone() else {
            return Err(ProgramError::File {
                path: label,
                message: "`[program]` has no `net = \"….pnml\"`; name the PNML file of the net, next to this file".into(),
            });
        };
        let net_path = path
            .parent()
            .unwrap_or_else(|| Path::new(""))
            .join(net_name.get_ref());
        let net = crate::load_net(&net_path).map_err(|e| match e {
            ProgramError::Io { path, source } => origin.err(
                net_name.span().start,
                format!("cannot read the net file `{path}`: {source}"),
            ),
            other => other,
        })?;
        Self::build_doc(origin, doc, net)
    }

    /// Loads a program carried inside PNML text (`label` names it in messages).
    pub fn from_pnml_text(text: &str, label: &str) -> Result<Program, ProgramError> {
        let net = crate::read_net_str(text, label)?;
        let Some(ts) = net.toolspecific().iter().find(|t| t.tool == TOOL) else {
            return Err(ProgramError::File {
                path: label.to_string(),
                message: format!(
                    "no program in this net: add a net-level `<toolspecific tool=\"{TOOL}\" version=\"1\">` holding the program TOML in a CDATA section, or load the program's .toml file"
                ),
            });
        };
        let Some((toml_text, in_xml)) = crate::source::toolspecific_text(&ts.xml) else {
            return Err(ProgramError::File {
                path: label.to_string(),
                message: format!("the `<toolspecific tool=\"{TOOL}\">` element has no readable text; put the program TOML in a CDATA section"),
            });
        };
        // Positions in the embedded TOML are reported in the PNML file when the element can be
        // found there verbatim.
        let mut origin = Origin::new(&toml_text, label);
        if let Some(at) = text.find(&ts.xml) {
            let file = Origin::new(text, label);
            let p = file.pos(at + in_xml);
            origin.line = p.line;
            origin.column = p.column;
        }
        Self::build(origin, net)
    }

    /// Builds a program from its TOML text and a net already read (the update package loader's
    /// entry point). A `net =` entry in the text is ignored: the net given is the net.
    pub fn from_sources(
        toml_text: &str,
        toml_label: &str,
        net: Net,
    ) -> Result<Program, ProgramError> {
        Self::build(Origin::new(toml_text, toml_label), net)
    }

    fn build(o: Origin, net: Net) -> Result<Program, ProgramError> {
        let doc: Doc = toml::from_str(o.text).map_err(|e| toml_error(&o, &e))?;
        Self::build_doc(o, doc, net)
    }

    fn build_doc(o: Origin, doc: Doc, net: Net) -> Result<Program, ProgramError> {
        let p = &doc.program;
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
            Some(s) => {
                let us = crate::guard::parse_duration(s.get_ref())
                    .map_err(|e| o.err(o.in_string(s, e.offset), e.message))?;
                if us == 0 {
                    return Err(o.err(
                        s.span().start,
                        "the scan period must be longer than 0; e.g. \"10ms\"",
                    ));
                }
                Duration::from_micros(us)
            }
        };

        // Signals: one namespace for inputs, outputs and variables, distinct from place ids.
        let mut seen: HashMap<String, &'static str> = HashMap::new();
        let mut signals =
            |decls: &[Spanned<SignalDecl>], kind: Kind| -> Result<Vec<Signal>, ProgramError> {
                decls
                    .iter()
                    .map(|d| signal(&o, &net, d.get_ref(), kind, &mut seen))
                    .collect()
            };
        let inputs = signals(&doc.input, Kind::Input)?;
        let outputs = signals(&doc.output, Kind::Output)?;
        let variables = signals(&doc.variable, Kind::Variable)?;

        // Guards, reported in document order.
        let scope = Scope {
            inputs: &inputs,
            outputs: &outputs,
            vars: &variables,
            net: &net,
        };
        let mut guards: Vec<Option<Guard>> = vec![None; net.num_transitions()];
        let mut entries: Vec<(&Spanned<String>, &Spanned<String>)> = doc.guards.iter().collect();
        entries.sort_by_key(|(k, _)| k.span().start);
        for (key, text) in entries {
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
                        if net.num_transitions() > 12 { ", …" } else { "" }
                    ),
                ));
            };
            let g = Guard::compile(text.get_ref(), &scope).map_err(|e: SyntaxError| {
                o.err(
                    o.in_string(text, e.offset),
                    format!("in the guard of {}: {}", key.get_ref(), e.message),
                )
            })?;
            guards[t.index()] = Some(g);
        }

        // Bodies, in document order, then the actions that run them or drive a signal.
        let mut entries: Vec<(&Spanned<String>, &Spanned<String>)> = doc.bodies.iter().collect();
        entries.sort_by_key(|(k, _)| k.span().start);
        let mut bodies: Vec<Body> = Vec::with_capacity(entries.len());
        for (key, text) in entries {
            let b = Body::compile(key.get_ref(), text.get_ref(), &scope).map_err(|e| {
                o.err(
                    o.in_string(text, e.offset),
                    format!("in the body {}: {}", key.get_ref(), e.message),
                )
            })?;
            bodies.push(b);
        }
        let mut output_held = vec![false; outputs.len()];
        for b in &bodies {
            for &i in b.outputs() {
                output_held[i as usize] = true;
            }
        }
        let mut actions = Vec::with_capacity(doc.action.len());
        for a in &doc.action {
            actions.push(action(
                &o,
                &net,
                (&outputs, &variables, &inputs),
                &bodies,
                a.get_ref(),
            )?);
        }
        for (i, b) in bodies.iter().enumerate() {
            if !actions.iter().any(|a| a.target == Target::Body(i as u32)) {
                let key = doc.bodies.keys().find(|k| k.get_ref() == b.name());
                return Err(o.err(
                    key.map_or(0, |k| k.span().start),
                    format!("the body {} is run by no action; add an [[action]] with `body = \"{}\"`, or remove it", b.name(), b.name()),
                ));
            }
        }
        let mut action_targets: Vec<Target> = Vec::new();
        let mut action_slot = Vec::with_capacity(actions.len());
        for a in &actions {
            let slot = match action_targets.iter().position(|t| *t == a.target) {
                Some(s) => s,
                None => {
                    action_targets.push(a.target);
                    action_targets.len() - 1
                }
            };
            action_slot.push(slot as u32);
        }
        let np = net.num_places();
        let mut place_action_start = vec![0u32; np + 1];
        for a in &actions {
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

        // Invariants, each checked at M0.
        let m0 = net.initial_marking();
        let mut invariants = Vec::with_capacity(doc.invariant.len());
        for decl in &doc.invariant {
            let e = &decl.get_ref().expr;
            let inv = Invariant::parse(e.get_ref(), &net)
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

        let (watchdogs, no_firing_us) = watchdogs(&o, &doc, &net)?;

        Ok(Program {
            watchdogs,
            no_firing_us,
            name: p.name.get_ref().clone(),
            version: p.version.get_ref().clone(),
            description: p.description.clone(),
            net: Arc::new(net),
            policy,
            sfc,
            scan_period,
            inputs,
            outputs,
            variables,
            guards,
            actions,
            bodies,
            output_held,
            action_slot,
            action_targets,
            place_action_start,
            place_actions,
            invariants,
            source: o.text.to_string(),
            hash: std::sync::OnceLock::new(),
        })
    }

    /// The program's name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// The program's version, as written.
    pub fn version(&self) -> &str {
        &self.version
    }
    /// Free text for people.
    pub fn description(&self) -> &str {
        &self.description
    }
    /// The net.
    pub fn net(&self) -> &Arc<Net> {
        &self.net
    }
    /// The firing policy.
    pub fn policy(&self) -> Policy {
        self.policy
    }
    /// True when the net is an IEC 61131-3 chart (`[program] chart = "sfc"`): its places are
    /// steps, and online change starts the steps a new version adds inactive.
    pub fn is_sfc(&self) -> bool {
        self.sfc
    }
    /// The scan period.
    pub fn scan_period(&self) -> Duration {
        self.scan_period
    }
    /// Inputs, in declaration order (the order of the input image).
    pub fn inputs(&self) -> &[Signal] {
        &self.inputs
    }
    /// Outputs, in declaration order (the order of the output image).
    pub fn outputs(&self) -> &[Signal] {
        &self.outputs
    }
    /// Variables, in declaration order.
    pub fn variables(&self) -> &[Signal] {
        &self.variables
    }
    /// The index of an input by name.
    pub fn input_index(&self, name: &str) -> Option<usize> {
        self.inputs.iter().position(|s| s.name == name)
    }
    /// The index of an output by name.
    pub fn output_index(&self, name: &str) -> Option<usize> {
        self.outputs.iter().position(|s| s.name == name)
    }
    /// The index of a variable by name.
    pub fn variable_index(&self, name: &str) -> Option<usize> {
        self.variables.iter().position(|s| s.name == name)
    }
    /// Compiles a condition over this program's inputs, variables, places and place timers (the
    /// guard language), e.g. `P10 == 1 && P20 == 1` for `substitute --when`. The error names the
    /// column in `text`.
    pub fn compile_condition(&self, text: &str) -> Result<Guard, ProgramError> {
        let scope = crate::guard::Scope {
            inputs: &self.inputs,
            outputs: &self.outputs,
            vars: &self.variables,
            net: &self.net,
        };
        Guard::compile(text, &scope).map_err(|e| ProgramError::File {
            path: "<condition>".to_string(),
            message: format!("column {}: {}", e.offset + 1, e.message),
        })
    }
    /// The places' maximum dwell times (`[[watchdog]]`), in declaration order.
    pub fn watchdogs(&self) -> &[Watchdog] {
        &self.watchdogs
    }

    /// `[stall] no_firing`: the primary stalls when nothing fires for this long (µs) while a
    /// watched place is marked.
    pub fn no_firing_us(&self) -> Option<u64> {
        self.no_firing_us
    }

    /// The declared invariants, in declaration order.
    pub fn invariants(&self) -> &[Invariant] {
        &self.invariants
    }
    /// The actions, in declaration order.
    pub fn actions(&self) -> &[Action] {
        &self.actions
    }
    /// The action bodies, in declaration order ([`Target::Body`] indexes them).
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }
    /// The distinct signals actions drive; [`crate::ActionState::latches`] follows this order.
    pub fn action_targets(&self) -> &[Target] {
        &self.action_targets
    }
    /// The program TOML text as loaded (without the net).
    pub fn source(&self) -> &str {
        &self.source
    }
    /// SHA-256 over the program text and a canonical serialization of the net.
    pub fn hash(&self) -> [u8; 32] {
        self.identity().0
    }
    /// [`Program::hash`] in lowercase hex.
    pub fn hash_hex(&self) -> &str {
        &self.identity().1
    }
    fn identity(&self) -> &([u8; 32], String) {
        self.hash.get_or_init(|| {
            let h = hash(&self.source, &self.net);
            (h, hex::encode(h))
        })
    }

    /// The compiled guard of a transition, if it has one.
    pub fn guard(&self, t: TransIdx) -> Option<&Guard> {
        self.guards.get(t.index()).and_then(Option::as_ref)
    }
    /// True when the transition has a guard (one without is always true).
    pub fn has_guard(&self, t: TransIdx) -> bool {
        self.guard(t).is_some()
    }
    /// Evaluates a transition's guard; a transition without one is always true. Never allocates.
    pub fn eval_guard(&self, t: TransIdx, ctx: &EvalCtx) -> Result<bool, EvalError> {
        match self.guard(t) {
            Some(g) => g.eval(ctx),
            None => Ok(true),
        }
    }

    /// Checks every declared invariant on a marking (in place order) and names the first that
    /// fails. Never allocates.
    pub fn check_invariants(&self, marking: &[Tokens]) -> Result<(), InvariantViolation> {
        invariant::check(&self.invariants, marking)
    }

    /// Writes each input's safe value (or its type's zero when it declares none) into `out`: what
    /// the field I/O gives the program for an input whose device is silent.
    pub fn safe_inputs(&self, out: &mut [Value]) {
        for (o, s) in out.iter_mut().zip(self.inputs()) {
            *o = s.safe.unwrap_or(s.ty.zero());
        }
    }

    /// Writes each output's safe value (or its type's zero when it declares none) into `out`.
    pub fn safe_outputs(&self, out: &mut [Value]) {
        for (o, s) in out.iter_mut().zip(&self.outputs) {
            *o = s.safe.unwrap_or(s.ty.zero());
        }
    }

    /// The actions of a place, as indices into [`Program::actions`].
    pub(crate) fn actions_of(&self, p: PlaceIdx) -> &[u32] {
        let (Some(&a), Some(&b)) = (
            self.place_action_start.get(p.index()),
            self.place_action_start.get(p.index() + 1),
        ) else {
            return &[];
        };
        &self.place_actions[a as usize..b as usize]
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
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

fn toml_error(o: &Origin, e: &toml::de::Error) -> ProgramError {
    let at = e.span().map_or(0, |s| s.start);
    o.err(at, e.message().trim_end().to_string())
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

fn signal(
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

fn action(
    o: &Origin,
    net: &Net,
    (outputs, variables, inputs): (&[Signal], &[Signal], &[Signal]),
    bodies: &[Body],
    d: &crate::source::ActionDecl,
) -> Result<Action, ProgramError> {
    let place = net.place_by_id(d.place.get_ref()).ok_or_else(|| {
        o.err(
            d.place.span().start,
            format!(
                "action on unknown place `{}`; expected a place id of the net",
                d.place.get_ref()
            ),
        )
    })?;
    let target = match (&d.target, &d.body) {
        (Some(t), None) => signal_target(o, t, outputs, variables, inputs)?,
        (None, Some(b)) => {
            let i = bodies
                .iter()
                .position(|x| x.name() == b.get_ref())
                .ok_or_else(|| {
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
fn signal_target(
    o: &Origin,
    t: &Spanned<String>,
    outputs: &[Signal],
    variables: &[Signal],
    inputs: &[Signal],
) -> Result<Target, ProgramError> {
    let tname = t.get_ref();
    let tat = t.span().start;
    let (target, sig) = if let Some(i) = outputs.iter().position(|s| &s.name == tname) {
        (Target::Output(i as u32), &outputs[i])
    } else if let Some(i) = variables.iter().position(|s| &s.name == tname) {
        (Target::Variable(i as u32), &variables[i])
    } else if inputs.iter().any(|s| &s.name == tname) {
        return Err(o.err(tat, format!("`{tname}` is an input, which the program cannot drive; an action targets a bool output or a bool variable")));
    } else {
        return Err(o.err(tat, format!("action target `{tname}` is not declared; expected a bool output or a bool variable")));
    };
    if sig.ty != Type::Bool {
        return Err(o.err(tat, format!("action target `{tname}` is {} {}; an action drives a bool output or a bool variable (a body assigns other types)", if sig.ty == Type::Int { "an" } else { "a" }, sig.ty)));
    }
    Ok(target)
}

/// SHA-256 over a domain tag, the program text and the net's behaviour-relevant structure (ids,
/// initial marking, capacities, priorities, arcs by index), every field length-prefixed or
/// fixed-width so that no two different inputs serialize alike. Names and graphics are left out:
/// moving a place on the drawing does not change the program.
fn hash(text: &str, net: &Net) -> [u8; 32] {
    let mut h = Sha256::new();
    let bytes = |h: &mut Sha256, b: &[u8]| {
        h.update((b.len() as u64).to_le_bytes());
        h.update(b);
    };
    bytes(&mut h, b"cetratus-program/1");
    bytes(&mut h, text.as_bytes());
    bytes(&mut h, net.id().as_bytes());
    h.update((net.num_places() as u64).to_le_bytes());
    for p in net.places() {
        bytes(&mut h, p.id.as_bytes());
        h.update(p.initial.to_le_bytes());
        match p.capacity {
            None => h.update([0u8]),
            Some(c) => {
                h.update([1u8]);
                h.update(c.to_le_bytes());
            }
        }
    }
    h.update((net.num_transitions() as u64).to_le_bytes());
    for t in net.transitions() {
        bytes(&mut h, t.id.as_bytes());
        h.update(t.priority.to_le_bytes());
    }
    h.update((net.arcs().len() as u64).to_le_bytes());
    let node = |h: &mut Sha256, n: NodeRef| match n {
        NodeRef::Place(p) => {
            h.update([0u8]);
            h.update(p.0.to_le_bytes());
        }
        NodeRef::Transition(t) => {
            h.update([1u8]);
            h.update(t.0.to_le_bytes());
        }
    };
    for a in net.arcs() {
        node(&mut h, a.source);
        node(&mut h, a.target);
        h.update(a.weight.to_le_bytes());
        h.update([match a.kind {
            ArcKind::Normal => 0u8,
            ArcKind::Inhibitor => 1u8,
        }]);
    }
    h.finalize().into()
}

/// The `[[watchdog]]` places and `[stall] no_firing`, resolved against the net.
fn watchdogs(
    o: &Origin,
    doc: &Doc,
    net: &Net,
) -> Result<(Vec<Watchdog>, Option<u64>), ProgramError> {
    let duration = |s: &Spanned<String>, what: &str| -> Result<u64, ProgramError> {
        let us = crate::guard::parse_duration(s.get_ref())
            .map_err(|e| o.err(o.in_string(s, e.offset), e.message))?;
        if us == 0 {
            return Err(o.err(
                s.span().start,
                format!("{what} must be longer than 0; e.g. \"10s\""),
            ));
        }
        Ok(us)
    };
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
