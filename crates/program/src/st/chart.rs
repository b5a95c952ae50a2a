//! The Structured Text of a chart (docs/program-format.md, *Structured Text*): action bodies and
//! transition conditions compiled on the POU's state, and the step flags (`S.X`, `S.T`) the ST
//! reads, written from the marking before each pass.

use cetratus_net::Net;
use cetratus_st::types::{Elem, Ty};
use cetratus_st::{Fault, State, Work};

use super::{StProgram, Wiring};
use crate::guard::{EvalCtx, EvalError, EvalErrorKind};
use crate::value::Value;

/// Nanoseconds in a microsecond, the unit of the place timers.
const NS_PER_US: u64 = 1_000;

/// The flags of one step: its place, and the slots of its `X` (BOOL) and `T` (TIME).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct StepFlags {
    place: u32,
    x: u32,
    t: u32,
}

impl StProgram {
    /// Whether the ST is a chart's (`[st.bodies]`, `[st.conditions]` or `[st.steps]`): its
    /// entries run, and its outputs are held in its state.
    pub fn is_chart(&self) -> bool {
        !(self.unit.entries.is_empty() && self.steps.is_empty())
    }

    /// The slot of the BOOL variable `name` (case-insensitive) of the POU, which a chart's
    /// action drives with its `Q`.
    pub fn bool_var(&self, name: &str) -> Option<u32> {
        let v = self.unit.var(name)?;
        (v.ty == Ty::Elem(Elem::Bool) && !v.constant).then_some(v.at.slots)
    }

    /// The name of the variable at `slot` ([`StProgram::bool_var`]), as declared.
    pub fn slot_name(&self, slot: u32) -> Option<&str> {
        let v = self
            .unit
            .vars
            .iter()
            .find(|v| v.at.slots == slot && v.size.slots == 1)?;
        Some(v.name.as_str())
    }

    /// Wires each `(place id, variable)` of `steps` ([`crate`]'s `[st.steps]`): the variable
    /// is a structure with the members `X : BOOL` and `T : TIME`, which hold, before each pass
    /// of the ST, whether the place is marked and how long it has been (or, once left, how
    /// long it was), as IEC 61131-3's step flags do.
    pub fn wire_steps<'a>(
        &mut self,
        net: &Net,
        steps: impl IntoIterator<Item = (&'a str, &'a str)>,
    ) -> Result<(), Wiring> {
        for (place, var) in steps {
            let refuse = |message: String| Wiring {
                name: place.to_string(),
                message,
            };
            let Some(p) = net.place_by_id(place) else {
                return Err(refuse(format!(
                    "`[st.steps]` names the place `{place}`, which the net does not have"
                )));
            };
            let flags = self.flag_slots(var).ok_or_else(|| {
                refuse(format!("`[st.steps]` gives `{place}` the variable `{var}`; declare it in the POU `{}` as a structure with the members X : BOOL and T : TIME", self.unit.name))
            })?;
            self.steps.push(StepFlags {
                place: p.index() as u32,
                x: flags.0,
                t: flags.1,
            });
        }
        Ok(())
    }

    /// The slots of the members `X : BOOL` and `T : TIME` of the structure variable `var`.
    fn flag_slots(&self, var: &str) -> Option<(u32, u32)> {
        let v = self.unit.var(var)?;
        let Ty::Struct(id) = v.ty else { return None };
        let fields = &self.unit.types.structs.get(id as usize)?.fields;
        let member = |name: &str, e: Elem| {
            (fields.iter())
                .find(|f| f.key.eq_ignore_ascii_case(name) && f.ty == Ty::Elem(e))
                .map(|f| v.at.slots + f.at.slots)
        };
        Some((member("X", Elem::Bool)?, member("T", Elem::Time)?))
    }

    /// Before a pass of conditions: the input image copied into the VAR_INPUTs, and the step
    /// flags written from the marking `ctx` shows. Never allocates.
    pub fn prepare(&self, ctx: &EvalCtx, state: &mut State) {
        self.copy_in(ctx.inputs, state);
        self.write_steps(ctx, state);
    }

    /// The step flags written from the marking `ctx` shows.
    pub(crate) fn write_steps(&self, ctx: &EvalCtx, state: &mut State) {
        for f in &self.steps {
            let p = f.place as usize;
            let marked = ctx.marking.get(p).is_some_and(|&m| m > 0);
            let us = match ctx.place_since_us.get(p).copied().flatten() {
                Some(since) if marked => ctx.now_us.saturating_sub(since),
                _ => ctx.place_dwell_us.get(p).copied().unwrap_or(0),
            };
            if let Some(x) = state.slots.get_mut(f.x as usize) {
                *x = u64::from(marked);
            }
            if let Some(t) = state.slots.get_mut(f.t as usize) {
                *t = us.saturating_mul(NS_PER_US).min(i64::MAX as u64);
            }
        }
    }

    /// The value of the condition entry `k` on `state` (after [`StProgram::prepare`]).
    pub fn condition(
        &self,
        k: u32,
        state: &mut State,
        now_us: u64,
        work: &mut Work,
    ) -> Result<bool, ConditionFault> {
        (self.unit.run_entry(k as usize, state, ns(now_us), work)).map_err(|f| {
            use cetratus_st::code::FaultKind;
            let kind = match f.kind {
                FaultKind::Budget => return ConditionFault::OutOfWork,
                FaultKind::DivisionByZero => EvalErrorKind::DivisionByZero,
                FaultKind::IndexOutOfRange { .. } => EvalErrorKind::IndexOutOfRange,
            };
            ConditionFault::Failed(EvalError {
                kind,
                column: f.pos.saturating_add(1),
            })
        })
    }

    /// One run of the body entry `k`: the step flags written, its code run within `work`, the
    /// outputs copied out (the action control copies the inputs in once a scan, before its
    /// bodies). Never allocates.
    pub fn run_entry(
        &self,
        k: u32,
        ctx: &EvalCtx,
        outputs: &mut [Value],
        state: &mut State,
        work: &mut Work,
    ) -> Result<(), Fault> {
        self.write_steps(ctx, state);
        let ran = self.unit.run_entry(k as usize, state, ns(ctx.now_us), work);
        self.copy_out(outputs, state);
        ran.map(|_| ())
    }
}

/// A chart's Structured Text as the program's text writes it (`[st]`), for writing it out again
/// (`cetratus export`). The entries are in the order they are compiled: the bodies, then the
/// conditions, so that entry `k` of [`cetratus_st::Unit::entries`] is `bodies[k]`, or
/// `conditions[k - bodies.len()]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChartTexts {
    /// `[st] pou`: the POU whose state the entries run on.
    pub pou: String,
    /// `[st] source`: the library that declares it.
    pub library: String,
    /// `[st.bodies]`, in document order: each body's name and statements.
    pub bodies: Vec<(String, String)>,
    /// `[st.conditions]`, in document order: each transition's id and expression.
    pub conditions: Vec<(String, String)>,
    /// `[st.steps]`, in document order: each place's id and the POU's variable of its flags.
    pub steps: Vec<(String, String)>,
}

/// Why an ST condition gave no value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConditionFault {
    /// It would have passed the scan's work budget.
    OutOfWork,
    /// It failed, as a guard fails (its column counts in the condition's text).
    Failed(EvalError),
}

/// Microseconds as the nanoseconds the ST's clock counts.
pub(super) fn ns(now_us: u64) -> i64 {
    i64::try_from(now_us)
        .unwrap_or(i64::MAX / 1000)
        .saturating_mul(1000)
}
