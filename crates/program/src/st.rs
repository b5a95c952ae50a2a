//! A program's Structured Text (`[st]`, docs/program-format.md): the IEC 61131-3 source it
//! carries, compiled at load by `cetratus-st`, and the wiring of its POU's VAR_INPUTs and
//! VAR_OUTPUTs to the program's input and output signals.
//!
//! The POU runs as an action body (an `[[action]]` whose `body` names it). Each run copies the
//! input image into its VAR_INPUTs, runs one pass of its code, and copies its VAR_OUTPUTs to the
//! output image. How a value crosses between a signal and an IEC variable:
//!
//! | IEC type | signal | crossing |
//! |---|---|---|
//! | BOOL | `bool` | as is |
//! | SINT … LINT, USINT … ULINT, BYTE … LWORD | `int` | the low bits of the i64 in, the value out (a ULINT above 2⁶³ reads negative) |
//! | TIME | `int` | milliseconds |
//! | REAL, LREAL | `real` | rounded to the nearest `f32` in, exact out |
//!
//! Other types (STRING, arrays, structures, instances) are not signals: they stay in the ST
//! state, which the container keeps with its program's other state.

use std::collections::BTreeMap;
use std::sync::Arc;

use cetratus_st::ast::Section;
use cetratus_st::types::{wrap, Elem, Size, Ty};
use cetratus_st::{Fault, State, Unit, Var, Work};

use crate::value::{Signal, Type, Value};

mod chart;

use chart::{ns, StepFlags};
pub use chart::{ChartTexts, ConditionFault};

/// Nanoseconds in a millisecond, the unit a TIME signal counts.
const NS_PER_MS: i64 = 1_000_000;

/// The compiled ST of a program and its wiring to the I/O images.
#[derive(Clone, Debug)]
pub struct StProgram {
    unit: Arc<Unit>,
    /// Per VAR_INPUT wired to a signal: the input's index and the variable.
    inputs: Vec<(u32, Elem, u32)>,
    /// Per VAR_OUTPUT wired to a signal: the output's index and the variable.
    outputs: Vec<(u32, Elem, u32)>,
    /// The step flags of a chart's places (`[st.steps]`).
    steps: Vec<StepFlags>,
}

/// A RETAIN variable of a POU as persisted: its name and its part of the state.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RetainedSt {
    /// The variable's name as declared.
    pub name: String,
    /// Its slots (one `u64` per elementary value, instances and arrays flattened).
    pub slots: Vec<u64>,
    /// Its bytes of string text.
    #[serde(default)]
    pub text: Vec<u8>,
}

/// Why a POU's variables do not fit the program's signals.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Wiring {
    /// The variable or signal.
    pub name: String,
    /// What is wrong and what to do.
    pub message: String,
}

/// The signal type an IEC elementary type crosses as.
pub fn signal_type(e: Elem) -> Type {
    match e {
        Elem::Bool => Type::Bool,
        Elem::Real | Elem::Lreal => Type::Real,
        _ => Type::Int,
    }
}

impl StProgram {
    /// Wires `unit`'s VAR_INPUTs and VAR_OUTPUTs of elementary types to the signals of the same
    /// names (case-insensitive), which must have the matching type; a variable of another type
    /// stays unwired, and a signal with no variable is refused.
    pub fn wire(unit: Unit, inputs: &[Signal], outputs: &[Signal]) -> Result<StProgram, Wiring> {
        let wire_one = |signals: &[Signal],
                        section: Section|
         -> Result<Vec<(u32, Elem, u32)>, Wiring> {
            let mut out = Vec::new();
            for (i, s) in signals.iter().enumerate() {
                let v = unit
                    .vars
                    .iter()
                    .find(|v| v.name.eq_ignore_ascii_case(&s.name) && crosses(v) == Some(section));
                let Some(Var {
                    ty: Ty::Elem(e),
                    at,
                    ..
                }) = v
                else {
                    return Err(Wiring {
                        name: s.name.clone(),
                        message: format!("the signal `{}` is not a {} of an elementary type in the POU `{}`; declare it there, or remove the signal", s.name, section.keyword(), unit.name),
                    });
                };
                if signal_type(*e) != s.ty {
                    return Err(Wiring {
                        name: s.name.clone(),
                        message: format!("the signal `{}` is declared `{}`, but the POU's variable is {e}, which crosses as `{}`", s.name, s.ty, signal_type(*e)),
                    });
                }
                out.push((i as u32, *e, at.slots));
            }
            Ok(out)
        };
        Ok(StProgram {
            inputs: wire_one(inputs, Section::Input)?,
            outputs: wire_one(outputs, Section::Output)?,
            unit: Arc::new(unit),
            steps: Vec::new(),
        })
    }

    /// The compiled POU.
    pub fn unit(&self) -> &Unit {
        &self.unit
    }

    /// Copies the RETAIN variables of `state` into `out`, in declaration order, reusing its
    /// buffers (no allocation once they have their sizes): what a warm restart keeps.
    pub fn retained_into(&self, state: &State, out: &mut Vec<RetainedSt>) {
        let retained = self.unit.vars.iter().filter(|v| v.retain);
        out.resize_with(retained.clone().count(), RetainedSt::default);
        for (v, saved) in retained.zip(out.iter_mut()) {
            if saved.name != v.name {
                saved.name.clone_from(&v.name);
            }
            let (slots, text) = self.unit.image(state, v);
            saved.slots.clear();
            saved.slots.extend_from_slice(slots);
            saved.text.clear();
            saved.text.extend_from_slice(text);
        }
    }

    /// A warm restart (docs/st.md, *Restarts*): the RETAIN variables of `saved` are written back
    /// into `state` by name (case-insensitive); every other variable keeps the initial value
    /// `state` holds, as IEC 61131-3 initializes non-RETAIN variables on a warm restart. A saved
    /// variable this POU does not declare RETAIN, whose size has changed, or whose STRING is
    /// longer than its capacity (a damaged or edited state file) is not restored: it keeps its
    /// initial value, and its name (cut to 64 characters) is returned, for the warm start to say.
    pub fn restore_retained(&self, state: &mut State, saved: &[RetainedSt]) -> Vec<String> {
        let mut not_restored = Vec::new();
        for r in saved {
            let restored = match self.unit.var(&r.name).filter(|v| v.retain) {
                Some(v) => self.unit.restore(state, v, &r.slots, &r.text),
                None => false,
            };
            if !restored {
                not_restored.push(r.name.chars().take(64).collect());
            }
        }
        not_restored
    }

    /// The indices of the output signals the POU drives.
    pub fn driven_outputs(&self) -> impl Iterator<Item = usize> + '_ {
        self.outputs.iter().map(|&(i, _, _)| i as usize)
    }

    /// The value in `state` of the variable `path` of an elementary type: a name, or a member
    /// of an instance or structure (`TON0.ET`), for traces (`cetratus run --watch`).
    pub fn watch(&self, state: &State, path: &str) -> Option<Value> {
        let (e, slot) = self.locate(path)?;
        state.slots.get(slot).map(|&s| from_slot(e, s))
    }

    /// The elementary type and slot of the variable `path` (see [`StProgram::watch`]).
    pub fn locate(&self, path: &str) -> Option<(Elem, usize)> {
        let mut parts = path.split('.');
        let v = self.unit.var(parts.next()?.trim())?;
        let (mut ty, mut at) = (v.ty, v.at.slots);
        for member in parts {
            let fields = match ty {
                Ty::Fb(id) => self.unit.fb_fields.get(id as usize)?,
                Ty::Struct(id) => &self.unit.types.structs.get(id as usize)?.fields,
                _ => return None,
            };
            let f = fields
                .iter()
                .find(|f| f.key.eq_ignore_ascii_case(member.trim()))?;
            ty = f.ty;
            at += f.at.slots;
        }
        match ty {
            Ty::Elem(e) => Some((e, at as usize)),
            _ => None,
        }
    }

    /// Translates the POU's code into machine code, once (`cetratus_st::Unit::
    /// prepare_machine_code`): called where the program is made ready to run, off the scan
    /// thread. Until then the interpreter runs it.
    pub fn prepare_machine_code(&self) -> bool {
        self.unit.prepare_machine_code()
    }

    /// One run of the POU on `state` at `now_us`: the inputs copied in, its code run within
    /// `work`, its outputs copied out. Never allocates.
    #[inline]
    pub fn run(
        &self,
        inputs: &[Value],
        outputs: &mut [Value],
        state: &mut State,
        now_us: u64,
        work: &mut Work,
    ) -> Result<(), Fault> {
        self.run_with(inputs, outputs, state, |unit, state| {
            unit.run(state, ns(now_us), work)
        })
    }

    /// `run` of the unit on `state`, the inputs copied in before and the outputs out after: what
    /// [`StProgram::run`] does with [`Unit::run`], open to another way of running the unit (the
    /// bench's [`Unit::run_interpreted`]).
    #[inline]
    pub fn run_with(
        &self,
        inputs: &[Value],
        outputs: &mut [Value],
        state: &mut State,
        run: impl FnOnce(&Unit, &mut State) -> Result<(), Fault>,
    ) -> Result<(), Fault> {
        self.copy_in(inputs, state);
        let ran = run(&self.unit, state);
        self.copy_out(outputs, state);
        ran
    }

    /// The input image copied into the wired VAR_INPUTs.
    #[inline]
    pub(crate) fn copy_in(&self, inputs: &[Value], state: &mut State) {
        for &(i, e, slot) in &self.inputs {
            if let (Some(&v), Some(s)) =
                (inputs.get(i as usize), state.slots.get_mut(slot as usize))
            {
                *s = to_slot(e, v);
            }
        }
    }

    /// The wired VAR_OUTPUTs copied to the output image.
    #[inline]
    pub(crate) fn copy_out(&self, outputs: &mut [Value], state: &State) {
        for &(i, e, slot) in &self.outputs {
            if let (Some(o), Some(&s)) =
                (outputs.get_mut(i as usize), state.slots.get(slot as usize))
            {
                *o = from_slot(e, s);
            }
        }
    }
}

/// The section a variable crosses the I/O image as: its own when it is VAR_INPUT or VAR_OUTPUT,
/// else [`Section::Input`] when it is located at `%I…` and [`Section::Output`] at `%Q…`.
pub fn crosses(v: &Var) -> Option<Section> {
    let located = |prefix: &str| {
        v.address
            .as_deref()
            .is_some_and(|a| a.get(..2).is_some_and(|p| p.eq_ignore_ascii_case(prefix)))
    };
    match v.section {
        Section::Input | Section::Output => Some(v.section),
        _ if located("%I") => Some(Section::Input),
        _ if located("%Q") => Some(Section::Output),
        _ => None,
    }
}

/// A signal's value as the slot of an IEC variable of type `e`.
fn to_slot(e: Elem, v: Value) -> u64 {
    match (e, v) {
        (Elem::Real, Value::Real(x)) => u64::from((x as f32).to_bits()),
        (Elem::Lreal, Value::Real(x)) => x.to_bits(),
        (Elem::Time, Value::Int(ms)) => ms.saturating_mul(NS_PER_MS) as u64,
        (_, Value::Int(i)) => wrap(e, i as u64),
        (_, Value::Bool(b)) => u64::from(b),
        (_, Value::Real(_)) => 0,
    }
}

/// An IEC variable's slot as a signal's value.
fn from_slot(e: Elem, s: u64) -> Value {
    match e {
        Elem::Bool => Value::Bool(s != 0),
        Elem::Real => Value::Real(f64::from(f32::from_bits(s as u32))),
        Elem::Lreal => Value::Real(f64::from_bits(s)),
        Elem::Time => Value::Int((s as i64) / NS_PER_MS),
        _ => Value::Int(s as i64),
    }
}

/// How the state of one program's Structured Text carries into another's at an online change:
/// the parts of the old state copied into the new, worked out once, away from the scan thread.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct StCarry {
    /// Per variable carried: where it is in the old state, where in the new, and its size.
    ranges: Vec<(Size, Size, Size)>,
}

impl StCarry {
    /// Copies the carried variables of `from` into `to`. Never allocates.
    pub fn apply(&self, to: &mut State, from: &State) {
        for &(src, dst, len) in &self.ranges {
            let copy = |to: &mut [u64], from: &[u64], s: u32, d: u32, n: u32| {
                let (s, d, n) = (s as usize, d as usize, n as usize);
                if let (Some(t), Some(f)) = (to.get_mut(d..d + n), from.get(s..s + n)) {
                    t.copy_from_slice(f);
                }
            };
            copy(&mut to.slots, &from.slots, src.slots, dst.slots, len.slots);
            let (s, d, n) = (src.text as usize, dst.text as usize, len.text as usize);
            if let (Some(t), Some(f)) = (to.text.get_mut(d..d + n), from.text.get(s..s + n)) {
                t.copy_from_slice(f);
            }
        }
    }
}

/// How the Structured Text of `old` carries into that of `new` (docs/st.md, *Online change*):
/// every variable of `new` (constants aside) takes the value of the variable of `old` of the
/// same name (case-insensitive) and the same layout, function block instances with their inner
/// state, so a running TON keeps its elapsed time; a new variable starts from its initial
/// value. `map` ([`crate::Changes::variables`]) renames (`old → new`) or lets go (`old → ""`).
///
/// Refused, naming the variable: a variable whose type changed, and a RETAIN variable of `old`
/// that nothing carries, unless `map` names them; and a `map` entry that names a variable
/// neither program has.
pub fn carry_plan(
    old: Option<&StProgram>,
    new: Option<&StProgram>,
    map: &BTreeMap<String, String>,
) -> Result<StCarry, Wiring> {
    let (plan, problems) = plan_with_problems(old, new, map);
    match problems.into_iter().next() {
        Some(p) => Err(p),
        None => Ok(plan),
    }
}

/// What [`carry_plan`] carries when nothing is refused: every variable of the same name and
/// layout, the rest given up (the way back of a revert, to a program built without them).
pub fn carry_what_fits(old: Option<&StProgram>, new: Option<&StProgram>) -> StCarry {
    plan_with_problems(old, new, &BTreeMap::new()).0
}

/// The carry of [`carry_plan`], and what it would refuse.
fn plan_with_problems(
    old: Option<&StProgram>,
    new: Option<&StProgram>,
    map: &BTreeMap<String, String>,
) -> (StCarry, Vec<Wiring>) {
    let none = Vec::new();
    let old_vars = old.map_or(&none, |o| &o.unit.vars);
    let new_vars = new.map_or(&none, |n| &n.unit.vars);
    let mut problems = map_problems(old_vars, new_vars, map);
    let mut plan = StCarry::default();
    let mut carried = vec![false; old_vars.len()];
    if let (Some(old), Some(new)) = (old, new) {
        for v in new.unit.vars.iter().filter(|v| !v.constant) {
            let renamed = map.iter().find(|(_, to)| to.eq_ignore_ascii_case(&v.name));
            let source = match renamed {
                Some((from, _)) => Some(from.as_str()),
                None if map.keys().any(|k| k.eq_ignore_ascii_case(&v.name)) => None,
                None => Some(v.name.as_str()),
            };
            let Some(j) = source.and_then(|name| position(&old.unit.vars, name)) else {
                continue;
            };
            let w = &old.unit.vars[j];
            if old.unit.layout(w.ty) != new.unit.layout(v.ty) || w.size != v.size {
                problems.push(Wiring {
                    name: v.name.clone(),
                    message: format!("`{}` was {} and is {}: its value cannot carry over; say in the manifest's `[changes] variables` what becomes of it (`{} = \"\"` starts it from its initial value)", v.name, old.unit.describe(w.ty), new.unit.describe(v.ty), w.name),
                });
                continue;
            }
            carried[j] = true;
            plan.ranges.push((w.at, v.at, v.size));
        }
    }
    let gone: Vec<&Var> = old_vars
        .iter()
        .zip(&carried)
        .filter(|(_, c)| !**c)
        .map(|(v, _)| v)
        .collect();
    problems.extend(unmapped_retain(&gone, map).err());
    (plan, problems)
}

/// The position of the variable `name` (case-insensitive) among `vars`.
fn position(vars: &[Var], name: &str) -> Option<usize> {
    vars.iter().position(|v| v.name.eq_ignore_ascii_case(name))
}

/// The entries of `map` that name a variable neither program declares.
fn map_problems(old: &[Var], new: &[Var], map: &BTreeMap<String, String>) -> Vec<Wiring> {
    let mut out = Vec::new();
    for (from, to) in map {
        if position(old, from).is_none() {
            out.push(Wiring {
                name: from.clone(),
                message: format!("the manifest's `[changes] variables` names `{from}`, which the running program's Structured Text does not declare; name variables of the running program on the left"),
            });
        } else if !to.is_empty() && position(new, to).is_none() {
            out.push(Wiring {
                name: to.clone(),
                message: format!("the manifest's `[changes] variables` carries `{from}` into `{to}`, which the new program's Structured Text does not declare"),
            });
        }
    }
    out
}

/// The first RETAIN variable among `gone` (not carried) that `map` does not name, as a refusal.
fn unmapped_retain(gone: &[&Var], map: &BTreeMap<String, String>) -> Result<(), Wiring> {
    match gone.iter().find(|v| v.retain && !map.keys().any(|k| k.eq_ignore_ascii_case(&v.name))) {
        None => Ok(()),
        Some(v) => Err(Wiring {
            name: v.name.clone(),
            message: format!("the RETAIN variable `{}` of the running program has nothing to carry into in the new one, so its value would be lost; keep it, or give it up on purpose in the manifest's `[changes] variables` (`{} = \"\"`)", v.name, v.name),
        }),
    }
}
