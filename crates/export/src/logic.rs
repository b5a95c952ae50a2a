//! Parts 3 and 4 of the export: the interpretation compiled to Structured Text (a
//! FUNCTION_BLOCK with the program's signals, its guards, place timers and actions, which calls
//! the kernel), and the PROGRAM that wires the signals to their located addresses.

use std::collections::{BTreeSet, HashMap};
use std::fmt::Write as _;

use cetratus_program::guard::{Expr, ExprKind};
use cetratus_program::st::ChartTexts;
use cetratus_program::{Program, Qualifier, Signal, Statement, Target, Type};

use crate::expr::{st, time_literal, Symbols};
use crate::io::IoRow;
use crate::names::Names;
use crate::{comment, ExportError};

/// How long a place timer may count: the largest TIME every dialect holds (32-bit ms).
const TIMER_RANGE: &str = "T#24d";

/// The names of the interpretation's own state, besides the signals: the kernel's instance,
/// the first-scan flag, and the kernel's members the interpretation reads and writes.
struct Locals {
    kernel: String,
    first: String,
    marking: String,
    cond: String,
    candidate: String,
    entered: String,
    left: String,
}

/// What the actions of one driven target (an output, a variable or a body) keep: the IEC
/// action control's flags, only those its qualifiers need.
#[derive(Default)]
struct Slot {
    on: Option<String>,
    latch: Option<String>,
    pulse: Option<String>,
    reset: Option<String>,
    was: Option<String>,
}

impl Slot {
    /// The stored part of Q (pulses left out), as an expression.
    fn stored(&self) -> String {
        or_of(&[&self.on, &self.latch])
    }
    fn q(&self) -> String {
        or_of(&[&self.on, &self.latch, &self.pulse])
    }
}

fn or_of(parts: &[&Option<String>]) -> String {
    let v: Vec<&str> = parts.iter().filter_map(|p| p.as_deref()).collect();
    if v.is_empty() {
        "FALSE".to_string()
    } else {
        v.join(" OR ")
    }
}

/// The interpretation being written.
pub(crate) struct Logic<'p> {
    program: &'p Program,
    names: Names,
    pub(crate) sym: Symbols,
    locals: Locals,
    slots: Vec<Slot>,
    /// Per action: the run flag and the TON of its SD or SL timer.
    stored: Vec<Option<(String, String)>>,
    /// The program's Structured Text body, if it has one.
    st_body: Option<st_body::StBody>,
}

/// The ST type of a signal inside the interpretation.
pub(crate) fn st_type(ty: Type) -> &'static str {
    match ty {
        Type::Bool => "BOOL",
        Type::Int => "LINT",
        Type::Real => "LREAL",
    }
}

fn zero(ty: Type) -> &'static str {
    match ty {
        Type::Bool => "FALSE",
        Type::Int => "LINT#0",
        Type::Real => "LREAL#0.0",
    }
}

/// The places whose time, dwell or input edges the program's guards and bodies read.
#[derive(Default)]
struct Reads {
    timers: BTreeSet<String>,
    dwells: BTreeSet<String>,
    edges: BTreeSet<String>,
}

impl Reads {
    /// Walks `e`; the guard parser bounds its depth.
    fn walk(&mut self, e: &Expr) {
        match &e.kind {
            ExprKind::Timer(p) => {
                self.timers.insert(p.clone());
            }
            ExprKind::Dwell(p) => {
                self.timers.insert(p.clone());
                self.dwells.insert(p.clone());
            }
            ExprKind::Rise(x) | ExprKind::Fall(x) => {
                self.edges.insert(x.clone());
            }
            ExprKind::Call(_, a) | ExprKind::Unary(_, a) => self.walk(a),
            ExprKind::Binary(_, l, r) => {
                self.walk(l);
                self.walk(r);
            }
            _ => {}
        }
    }
}

impl<'p> Logic<'p> {
    /// Names everything in the interpretation's scope: the signals first, so that they keep
    /// their names when they can, then the state the export adds.
    pub(crate) fn new(
        program: &'p Program,
        mut names: Names,
        dialect: crate::Dialect,
    ) -> Result<Self, ExportError> {
        let mut signals = HashMap::new();
        for (kind, list) in [
            ("input", program.inputs()),
            ("output", program.outputs()),
            ("variable", program.variables()),
        ] {
            for s in list {
                signals.insert(s.name.clone(), names.claim(Some(kind), &s.name));
            }
        }
        // A chart's ST texts, read again from the program's text once for the whole export.
        let chart = program.chart_texts();
        let reads = reads(program, chart.as_ref())?;
        let net = program.net();
        let mut claim = |n: &str| names.claim(None, n);
        let kernel = claim("KERNEL");
        let member = |m: &str| format!("{kernel}.{m}");
        let locals = Locals {
            first: claim("FIRST"),
            marking: member("M"),
            cond: member("COND"),
            candidate: member("CANDIDATE"),
            entered: member("ENTERED"),
            left: member("EXITED"),
            kernel,
        };
        let places = (net.places().iter().enumerate())
            .map(|(i, p)| (p.id.clone(), i + 1))
            .collect();
        let mut timed: BTreeSet<String> = reads.timers.clone();
        for a in program.actions() {
            if matches!(
                a.qualifier,
                Qualifier::L(_) | Qualifier::D(_) | Qualifier::DS(_)
            ) {
                timed.insert(net.place(a.place).id.clone());
            }
        }
        let timers = (timed.iter())
            .map(|p| (p.clone(), claim(&format!("{p}_T"))))
            .collect();
        let dwells = (reads.dwells.iter())
            .map(|p| (p.clone(), claim(&format!("{p}_DWELL"))))
            .collect();
        let previous = (reads.edges.iter())
            .map(|x| (x.clone(), claim(&format!("PREV_{x}"))))
            .collect();
        let (slots, stored) = slots(program, &mut claim);
        let st_body = st_body::prepare(program, chart.as_ref(), &mut claim)?;
        let sym = Symbols {
            signals,
            places,
            timers,
            dwells,
            previous,
            marking: locals.marking.clone(),
            and_or: dialect.and_or(),
        };
        Ok(Logic {
            program,
            names,
            sym,
            locals,
            slots,
            stored,
            st_body,
        })
    }

    /// The program's ST library as the export writes it, if it has one.
    pub(crate) fn st_library(&self) -> Option<&str> {
        self.st_body.as_ref().map(|b| b.text.as_str())
    }

    /// The `VAR_GLOBAL` blocks of the program's ST CONFIGURATION, as written (empty without).
    pub(crate) fn st_globals(&self) -> &str {
        self.st_body.as_ref().map_or("", |b| b.globals.as_str())
    }

    /// The renames of the program's own names.
    pub(crate) fn names(&self) -> &Names {
        &self.names
    }

    /// The signal's name in the export.
    pub(crate) fn signal(&self, name: &str) -> String {
        self.sym.signals.get(name).cloned().unwrap_or_default()
    }
}

/// What the guards and the guard-language bodies read (a Structured Text body keeps its own
/// timers and edges).
fn reads(program: &Program, chart: Option<&ChartTexts>) -> Result<Reads, ExportError> {
    let mut r = Reads::default();
    for t in 0..program.net().num_transitions() {
        if let Some(g) = program.guard(cetratus_net::TransIdx(t as u32)) {
            r.walk(g.expr());
        }
    }
    // A chart's ST reads the step flags, `X` and `T`: a timer and a dwell per step.
    for (place, _) in chart.iter().flat_map(|c| &c.steps) {
        r.timers.insert(place.clone());
        r.dwells.insert(place.clone());
    }
    for b in program.bodies().iter().filter(|b| b.st().is_none()) {
        for s in statements(b)? {
            match s {
                Statement::Assign { expr: e, .. } | Statement::If(e) | Statement::Elif(e) => {
                    r.walk(&e)
                }
                Statement::Else | Statement::End => {}
            }
        }
    }
    Ok(r)
}

/// A guard-language body's statements (a Structured Text body has none: it is called, see
/// `st_body`). The body compiled at load, so its text parses again.
pub(crate) fn statements(b: &cetratus_program::Body) -> Result<Vec<Statement>, ExportError> {
    b.statements().map_err(|e| ExportError::Unsupported {
        what: format!(
            "action body `{}` does not parse again: {}",
            b.name(),
            e.message
        ),
        hint: "this is a fault of the exporter; report it with the program",
    })
}

/// The flags of each driven target, and the SD/SL timers of each action.
fn slots(
    program: &Program,
    claim: &mut impl FnMut(&str) -> String,
) -> (Vec<Slot>, Vec<Option<(String, String)>>) {
    let targets = program.action_targets();
    let mut slots: Vec<Slot> = targets.iter().map(|_| Slot::default()).collect();
    let mut stored = Vec::new();
    for (k, a) in program.actions().iter().enumerate() {
        let s = program.action_slots()[k] as usize;
        let q = s + 1;
        let slot = &mut slots[s];
        let mut flag = |f: &mut Option<String>, what: &str| {
            if f.is_none() {
                *f = Some(claim(&format!("Q{q}_{what}")));
            }
        };
        match a.qualifier {
            Qualifier::S | Qualifier::DS(_) => flag(&mut slot.latch, "LATCH"),
            Qualifier::R => flag(&mut slot.reset, "RESET"),
            Qualifier::P1 | Qualifier::P0 => flag(&mut slot.pulse, "PULSE"),
            _ => flag(&mut slot.on, "ON"),
        }
        let holds = !matches!(a.qualifier, Qualifier::P1 | Qualifier::P0 | Qualifier::R);
        // A body's Q in the last scan, for its final run; a chart variable's, for its last write.
        if matches!(
            (a.target, holds),
            (Target::Body(_), true) | (Target::St(_), _)
        ) {
            flag(&mut slot.was, "WAS");
        }
        stored.push(match a.qualifier {
            Qualifier::SD(_) | Qualifier::SL(_) => {
                let n = k + 1;
                Some((claim(&format!("A{n}_RUN")), claim(&format!("A{n}_TIMER"))))
            }
            _ => None,
        });
    }
    (slots, stored)
}

/// The 1-based line of each key of the section `section` of a TOML source (bare or quoted; the
/// first line of a key that stands twice), read in one pass, so that a program with many guards
/// costs its length once and not once a guard.
pub(crate) fn section_key_lines(source: &str, section: &str) -> HashMap<String, usize> {
    let mut inside = false;
    let mut lines = HashMap::new();
    for (i, line) in source.lines().enumerate() {
        let t = line.trim();
        if t.starts_with('[') {
            inside = t == section;
        } else if inside {
            if let Some((key, _)) = t.split_once('=') {
                let key = key.trim();
                let key = key
                    .strip_prefix('"')
                    .and_then(|k| k.strip_suffix('"'))
                    .unwrap_or(key);
                lines.entry(key.to_string()).or_insert(i + 1);
            }
        }
    }
    lines
}

/// Declares a signal in a VAR block.
fn declare(s: &mut String, name: &str, sig: &Signal, init: bool) {
    let _ = write!(s, "  {name} : {}", st_type(sig.ty));
    if init {
        let _ = write!(s, " := {}", value(sig.initial));
    }
    s.push(';');
    if !sig.description.is_empty() {
        let _ = write!(s, "  (* {} *)", comment(&sig.description));
    }
    s.push('\n');
}

fn value(v: cetratus_program::Value) -> String {
    match v {
        cetratus_program::Value::Bool(b) => (if b { "TRUE" } else { "FALSE" }).to_string(),
        cetratus_program::Value::Int(i) => format!("LINT#{i}"),
        cetratus_program::Value::Real(r) => format!("LREAL#{}", crate::expr::real_literal(r)),
    }
}

mod actions;
mod st_body;
mod st_chart;
mod write;

pub(crate) use self::st_body::library_names;

pub(crate) use self::write::{configuration, program_pou};
