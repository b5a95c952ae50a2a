//! [`Program`]: a net plus its interpretation, resolved and checked at load.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use cetratus_net::{ArcKind, Net, NodeRef, PlaceIdx, Policy, Tokens, TransIdx};
use sha2::{Digest, Sha256};
use toml::Spanned;

use crate::action::{Action, Target};
use crate::body::Body;
use crate::guard::{EvalCtx, EvalError, Guard, Scope};
use crate::invariant::{self, Invariant, InvariantViolation};
use crate::source::{Doc, Origin, SignalDecl};
use crate::st::StProgram;
use crate::value::{Signal, Value};
use crate::ProgramError;

mod resolve;
mod structured;

use resolve::{
    action_slots, actions, actions_by_place, bodies, guards, invariants, settings, signal,
    watchdogs, Kind, Settings,
};

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
    /// Per transition, the entry of the ST that is its condition (`[st.conditions]`).
    st_conditions: Vec<Option<u32>>,
    pub(crate) actions: Vec<Action>,
    /// Action bodies, in declaration order.
    pub(crate) bodies: Vec<Body>,
    /// The program's Structured Text, compiled and wired to its signals (`[st]`).
    st: Option<Arc<StProgram>>,
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
        let Settings {
            policy,
            sfc,
            scan_period,
        } = settings(&o, &doc.program)?;

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

        let scope = Scope::new(&inputs, &outputs, &variables, &net);
        let guards = guards(&o, &doc, &scope)?;
        let st_conditions = structured::st_conditions(&o, &doc, &net)?;
        // Bodies, then the actions that run them or drive a signal.
        let st = structured::structured_text(&o, &doc, &net, (&inputs, &outputs))?;
        let bodies = bodies(&o, &doc, &scope, st.as_ref())?;
        let mut output_held = vec![false; outputs.len()];
        for b in &bodies {
            for &i in b.outputs() {
                output_held[i as usize] = true;
            }
        }
        let actions = actions(&o, &doc, &scope, &bodies, st.as_deref())?;
        let (action_targets, action_slot) = action_slots(&actions);
        let (place_action_start, place_actions) = actions_by_place(net.num_places(), &actions);
        let invariants = invariants(&o, &doc, &net)?;
        let (watchdogs, no_firing_us) = watchdogs(&o, &doc, &net)?;

        let p = &doc.program;
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
            st_conditions,
            actions,
            bodies,
            st,
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

    /// The program's name as a file name: letters, digits, `-`, `_` and `.` kept, every other
    /// character `_`, and `program` when nothing but dots would be left (a name is free text;
    /// a path built from it must stay in its directory).
    pub fn file_stem(&self) -> String {
        let name: String = (self.name.chars())
            .map(|c| match c.is_ascii_alphanumeric() || "-_.".contains(c) {
                true => c,
                false => '_',
            })
            .collect();
        match name.trim_matches('.').is_empty() {
            true => "program".to_string(),
            false => name,
        }
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
        let scope =
            crate::guard::Scope::new(&self.inputs, &self.outputs, &self.variables, &self.net);
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
    /// The program's Structured Text, if it has some (`[st]`).
    pub fn st(&self) -> Option<&StProgram> {
        self.st.as_deref()
    }
    /// Translates the program's Structured Text into machine code, once, if it has some: what
    /// a container does when it is built, off the scan thread (docs/st.md, *Machine code*).
    pub fn prepare_machine_code(&self) {
        if let Some(st) = &self.st {
            st.prepare_machine_code();
        }
    }
    /// The distinct signals actions drive; [`crate::ActionState::latches`] follows this order.
    pub fn action_targets(&self) -> &[Target] {
        &self.action_targets
    }
    /// Per action (in [`Program::actions`] order), the index of its target in
    /// [`Program::action_targets`].
    pub fn action_slots(&self) -> &[u32] {
        &self.action_slot
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
    /// True when the transition has a guard or an ST condition (one without is always true).
    pub fn has_guard(&self, t: TransIdx) -> bool {
        self.guard(t).is_some() || self.st_condition(t).is_some()
    }
    /// The entry of the program's ST that is the transition's condition (`[st.conditions]`),
    /// which [`crate::st::StProgram::condition`] evaluates in place of a guard.
    #[inline]
    pub fn st_condition(&self, t: TransIdx) -> Option<u32> {
        self.st_conditions.get(t.index()).copied().flatten()
    }
    /// What evaluating a transition's guard costs in units of [`crate::Work`]: its code's
    /// length, or 1 to look at a transition without one (an ST condition charges its own
    /// cost when it runs).
    #[inline]
    pub fn guard_cost(&self, t: TransIdx) -> u64 {
        self.guard(t).map_or(1, Guard::cost)
    }
    /// Evaluates a transition's guard; a transition without one is always true, and so is one
    /// whose condition is ST (see [`Program::st_condition`]). Never allocates.
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

fn toml_error(o: &Origin, e: &toml::de::Error) -> ProgramError {
    let at = e.span().map_or(0, |s| s.start);
    o.err(at, e.message().trim_end().to_string())
}
