//! Place actions with the IEC 61131-3 SFC qualifiers, and their per-scan state.

use std::fmt;

use cetratus_net::{PlaceIdx, Tokens};

use crate::body::BodyError;
use crate::guard::EvalCtx;
use crate::value::Value;
use crate::{Program, Work};

/// Why the actions of a scan stopped: a body failed, or running the next body would have passed
/// the scan's work budget (it did not run).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ActError {
    /// A body failed; its assignments before the failing statement have taken effect.
    Body(BodyError),
    /// The body `body` was not run: it costs more work than the scan had left.
    OutOfWork {
        /// The body's name.
        body: String,
    },
}

impl From<BodyError> for ActError {
    fn from(e: BodyError) -> Self {
        ActError::Body(e)
    }
}

/// An SFC action qualifier.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Qualifier {
    /// Non-stored: on while the place is marked.
    N,
    /// Set (stored): latches on when the place is entered.
    S,
    /// Reset: clears the latch when the place is entered.
    R,
    /// Pulse on entry: on for the one scan in which the place is entered.
    P1,
    /// Pulse on exit: on for the one scan in which the place is left.
    P0,
    /// Time limited: on while marked, at most `duration` after entry.
    L(u64),
    /// Time delayed: on while marked, once `duration` has passed since entry.
    D(u64),
    /// Stored and delayed: on `duration` after entry, whether or not the place is still
    /// marked, until an R.
    SD(u64),
    /// Delayed and stored: on once the place has been marked for `duration`, until an R.
    DS(u64),
    /// Stored and time limited: on from entry for `duration`, whether or not the place is
    /// still marked; an R ends it early.
    SL(u64),
}

impl Qualifier {
    /// The duration of a timed qualifier.
    pub fn duration_us(self) -> Option<u64> {
        match self {
            Qualifier::L(d)
            | Qualifier::D(d)
            | Qualifier::SD(d)
            | Qualifier::DS(d)
            | Qualifier::SL(d) => Some(d),
            _ => None,
        }
    }
}

impl fmt::Display for Qualifier {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Qualifier::N => f.write_str("N"),
            Qualifier::S => f.write_str("S"),
            Qualifier::R => f.write_str("R"),
            Qualifier::P1 => f.write_str("P1"),
            Qualifier::P0 => f.write_str("P0"),
            Qualifier::L(d) => {
                f.write_str("L ")?;
                crate::guard::write_duration(f, *d)
            }
            Qualifier::D(d) | Qualifier::SD(d) | Qualifier::DS(d) | Qualifier::SL(d) => {
                f.write_str(match self {
                    Qualifier::D(_) => "D ",
                    Qualifier::SD(_) => "SD ",
                    Qualifier::DS(_) => "DS ",
                    _ => "SL ",
                })?;
                crate::guard::write_duration(f, *d)
            }
        }
    }
}

/// What an action drives: a bool output or a bool variable, or a body it runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// An output, by index.
    Output(u32),
    /// A variable, by index.
    Variable(u32),
    /// An action body, by index into [`Program::bodies`].
    Body(u32),
    /// A BOOL variable of a chart's Structured Text, by its slot in the ST state
    /// ([`crate::st::StProgram::bool_var`]).
    St(u32),
}

/// An action attached to a place.
#[derive(Clone, Debug, PartialEq)]
pub struct Action {
    /// The place.
    pub place: PlaceIdx,
    /// The qualifier.
    pub qualifier: Qualifier,
    /// The bool signal it drives.
    pub target: Target,
}

/// The state actions carry from scan to scan (the S/R latches, the stored timers of SD and SL,
/// the last Q of each body for its final run), with scratch sized once.
#[derive(Clone, Debug)]
pub struct ActionState {
    /// Latch per driven target (index into `targets`).
    latch: Vec<bool>,
    /// Scratch per driven target, cleared every scan: non-stored Q, pulses, resets.
    on: Vec<bool>,
    pulse: Vec<bool>,
    reset: Vec<bool>,
    /// Per target: its Q in the last scan, pulses left out for a body (whose final run follows
    /// its fall) and counted for a variable of a chart's ST (written once more as it falls).
    was_on: Vec<bool>,
    /// Per action: when its SD or SL timer started; `None` when it runs no such timer.
    stored_since: Vec<Option<u64>>,
    deadline: Option<u64>,
    // The outputs of the last scan hold until a place changes, a pulse ends, a timer is due or a
    // body runs: a scan with none of these leaves them as they are, at no cost.
    settled: bool,
    pulsed: bool,
    quiet: bool,
    // Tests compare against a state that always recomputes.
    never_quiet: bool,
    /// The state of the program's Structured Text, if it has some (`[st]`).
    st: Option<cetratus_st::State>,
}

/// The one action of a program that is a Structured Text POU run every scan and nothing else
/// (what `cetratus import st` makes): no transition, one N action whose body is the POU, every
/// output held by that body. While its place stays marked, a scan of such a program is one run
/// of the body, which [`ActionState::run_sole`] runs without the machinery of qualifiers,
/// latches and timers around it, which has nothing to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SoleBody {
    place: PlaceIdx,
    body: u32,
    /// [`Body::cost`](crate::Body::cost) of the body, read once.
    cost: u64,
}

impl SoleBody {
    /// The sole body of `program`, if it is such a program.
    pub fn of(program: &Program) -> Option<SoleBody> {
        let [action] = program.actions.as_slice() else {
            return None;
        };
        let [Target::Body(body)] = *program.action_targets.as_slice() else {
            return None;
        };
        let pou = program.bodies.get(body as usize)?;
        let sole = program.net().num_transitions() == 0
            && action.qualifier == Qualifier::N
            && pou.st().is_some()
            && pou.st_entry().is_none()
            && program.output_held.iter().all(|&held| held);
        sole.then_some(SoleBody {
            place: action.place,
            body,
            cost: pou.cost(),
        })
    }
}

impl ActionState {
    /// Whether the next scan of a [`SoleBody`] program is one run of its body, as
    /// [`ActionState::apply`] would run it: its place is marked and was in the last scan, whose
    /// actions ran in full (so that no first or final run is due).
    pub fn runs_sole(&self, sole: SoleBody, marking: &[Tokens]) -> bool {
        matches!(self.was_on.as_slice(), [true])
            && !self.quiet
            && !self.never_quiet
            && marking.get(sole.place.index()).is_some_and(|&m| m > 0)
    }

    /// One run of the sole body, after [`ActionState::runs_sole`] said yes: what
    /// [`ActionState::apply`] does in that scan, charged to `work` the same way. Never allocates,
    /// unless the body fails or is not run (the error names it).
    #[inline]
    pub fn run_sole(
        &mut self,
        program: &Program,
        sole: SoleBody,
        inputs: &[Value],
        outputs: &mut [Value],
        now_us: u64,
        work: &mut Work,
    ) -> Result<(), ActError> {
        let (Some(body), Some(state)) = (program.bodies.get(sole.body as usize), self.st.as_mut())
        else {
            return Ok(());
        };
        if !work.charge(sole.cost) {
            return Err(ActError::OutOfWork {
                body: body.name().to_string(),
            });
        }
        match body.st() {
            Some(st) => st
                .run(inputs, outputs, state, now_us, work)
                .map_err(|f| st_fault(body, f)),
            None => Ok(()),
        }
    }

    /// Fresh state for `program`, every latch off; use it only with that program.
    pub fn new(program: &Program) -> Self {
        let n = program.action_targets.len();
        ActionState {
            latch: vec![false; n],
            on: vec![false; n],
            pulse: vec![false; n],
            reset: vec![false; n],
            was_on: vec![false; n],
            stored_since: vec![None; program.actions.len()],
            deadline: None,
            settled: false,
            pulsed: false,
            quiet: false,
            never_quiet: false,
            st: program.st().map(|s| s.unit().new_state()),
        }
    }

    /// Becomes a copy of `other`, a state of the same program, without allocating (a rehearsal of
    /// what the program would drive from another marking). Of a state made for another program,
    /// only what fits is copied.
    pub fn copy_from(&mut self, other: &ActionState) {
        fn copy<T: Copy>(to: &mut [T], from: &[T]) {
            for (t, f) in to.iter_mut().zip(from) {
                *t = *f;
            }
        }
        copy(&mut self.latch, &other.latch);
        copy(&mut self.on, &other.on);
        copy(&mut self.pulse, &other.pulse);
        copy(&mut self.reset, &other.reset);
        copy(&mut self.was_on, &other.was_on);
        copy(&mut self.stored_since, &other.stored_since);
        self.deadline = other.deadline;
        self.settled = other.settled;
        self.pulsed = other.pulsed;
        self.quiet = other.quiet;
        self.never_quiet = other.never_quiet;
        if let (Some(to), Some(from)) = (self.st.as_mut(), other.st.as_ref()) {
            if to.slots.len() == from.slots.len() && to.text.len() == from.text.len() {
                to.slots.copy_from_slice(&from.slots);
                to.text.copy_from_slice(&from.text);
            }
        }
    }

    /// The state of the program's Structured Text, if it has some.
    pub fn st_state(&self) -> Option<&cetratus_st::State> {
        self.st.as_ref()
    }

    /// The state of the program's Structured Text, to carry values into it.
    pub fn st_state_mut(&mut self) -> Option<&mut cetratus_st::State> {
        self.st.as_mut()
    }

    /// Makes every `apply` recompute in full, for comparing against the settled shortcut in
    /// tests.
    pub fn set_never_quiet(&mut self, on: bool) {
        self.never_quiet = on;
    }

    /// The first scan (startup): every place marked in `ctx.marking` counts as entered, then as
    /// [`ActionState::apply`].
    pub fn start(
        &mut self,
        program: &Program,
        ctx: &EvalCtx,
        outputs: &mut [Value],
        vars: &mut [Value],
        work: &mut Work,
    ) -> Result<(), ActError> {
        // A first scan always recomputes, whatever the state did before it.
        let marked = ctx.marking.iter().enumerate().filter(|&(_, &m)| m > 0);
        let entered = marked.map(|(p, _)| (PlaceIdx(p as u32), true));
        self.recompute(program, ctx, entered, (outputs, vars), work)
    }

    /// Computes the driven outputs and variables after this scan's marking update, and runs the
    /// bodies whose actions are on (or that take their final run).
    ///
    /// `ctx` is the scan's view: the marking after the update, `place_since_us` already updated
    /// for this scan, the inputs; its `vars` are not read (bodies read `vars`). `changes` lists
    /// the places whose count changed in this scan with their old count
    /// (`cetratus_net::Engine::changes()`). Outputs that neither an action nor a body drives are
    /// set to their type's zero; outputs a body assigns keep their value; variables are left
    /// alone unless driven. `outputs` and `vars` must be the buffers of the previous scan: a scan
    /// in which no place changed, no pulse ends, no timer is due and no body runs leaves them as
    /// they are. Each body that runs is charged to `work` first ([`Body::cost`](crate::Body::cost));
    /// one that would pass its budget does not run. Never allocates, unless a body fails or
    /// is not run (the error names it).
    pub fn apply(
        &mut self,
        program: &Program,
        ctx: &EvalCtx,
        changes: &[(PlaceIdx, Tokens)],
        outputs: &mut [Value],
        vars: &mut [Value],
        work: &mut Work,
    ) -> Result<(), ActError> {
        if self.settled
            && !self.never_quiet
            && changes.is_empty()
            && self.deadline.is_none_or(|d| ctx.now_us < d)
        {
            self.quiet = true;
            return Ok(());
        }
        let edges = changes.iter().filter_map(|&(p, old)| {
            let new = ctx.marking.get(p.index()).copied().unwrap_or(0);
            // Entered (true) or left (false); a count that stays above zero is neither.
            ((old == 0) != (new == 0)).then_some((p, new > 0))
        });
        self.recompute(program, ctx, edges, (outputs, vars), work)
    }

    /// True when the last `apply` changed nothing: no place changed, no pulse ended, no timer was
    /// due, no body ran, so outputs and variables are as before.
    pub fn last_was_quiet(&self) -> bool {
        self.quiet
    }

    /// The earliest future time at which a timed action (L, D, SD, DS, SL) changes its Q, as
    /// computed by the last `apply`/`start`; `None` when no such timer runs.
    pub fn next_deadline_us(&self) -> Option<u64> {
        self.deadline
    }

    /// The S/R latches, one per driven target in [`Program::action_targets`] order (for saving
    /// state across a restart).
    pub fn latches(&self) -> &[bool] {
        &self.latch
    }

    /// Sets one latch (an update carrying the primary's latches over); out of range is ignored.
    pub fn set_latch(&mut self, slot: usize, on: bool) {
        if let Some(l) = self.latch.get_mut(slot) {
            *l = on;
            self.settled = false;
            self.quiet = false;
        }
    }

    /// Restores latches saved with [`ActionState::latches`]; extra or missing entries are ignored.
    pub fn set_latches(&mut self, latches: &[bool]) {
        for (l, &v) in self.latch.iter_mut().zip(latches) {
            *l = v;
        }
        self.settled = false;
        self.quiet = false;
    }

    fn begin(&mut self) {
        self.pulsed = false;
        for v in [&mut self.on, &mut self.pulse, &mut self.reset] {
            v.iter_mut().for_each(|b| *b = false);
        }
        self.deadline = None;
    }

    fn due(&mut self, at: u64) {
        self.deadline = Some(self.deadline.map_or(at, |x| x.min(at)));
    }

    /// A place was entered (`entered`) or left: run its edge-triggered actions.
    fn edge(&mut self, program: &Program, p: PlaceIdx, entered: bool, now_us: u64) {
        for &a in program.actions_of(p) {
            let (q, slot) = (
                program.actions[a as usize].qualifier,
                program.action_slot[a as usize] as usize,
            );
            // `get_mut`: a state made for another program must not be able to panic the scan.
            let cell = match (q, entered) {
                (Qualifier::S, true) => self.latch.get_mut(slot),
                (Qualifier::R, true) => self.reset.get_mut(slot),
                (Qualifier::P1, true) | (Qualifier::P0, false) => {
                    self.pulsed = true;
                    self.pulse.get_mut(slot)
                }
                (Qualifier::SD(_), true) => {
                    // Stored: a second entry while the delay runs does not restart it.
                    if let Some(s) = self.stored_since.get_mut(a as usize) {
                        s.get_or_insert(now_us);
                    }
                    None
                }
                (Qualifier::SL(_), true) => {
                    if let Some(s) = self.stored_since.get_mut(a as usize) {
                        *s = Some(now_us);
                    }
                    None
                }
                _ => None,
            };
            if let Some(c) = cell {
                *c = true;
            }
        }
    }

    /// Reset dominates set, as in the IEC action control's RS flip-flop; it also stops the SD
    /// and SL timers on the same target. SD and SL run whether or not their place is still
    /// marked.
    fn stored_timers(&mut self, program: &Program, now_us: u64) {
        for (l, &r) in self.latch.iter_mut().zip(&self.reset) {
            if r {
                *l = false;
            }
        }
        for (a, (&slot, since)) in program
            .actions
            .iter()
            .zip(program.action_slot.iter().zip(self.stored_since.iter_mut()))
        {
            if self.reset.get(slot as usize).copied().unwrap_or(false) {
                *since = None;
            }
            let Some(s) = *since else { continue };
            let (on, due) = match a.qualifier {
                Qualifier::SD(d) => {
                    let due = s.saturating_add(d);
                    (now_us >= due, (now_us < due).then_some(due))
                }
                Qualifier::SL(d) => {
                    let due = s.saturating_add(d);
                    if now_us >= due {
                        *since = None;
                    }
                    (now_us < due, (now_us < due).then_some(due))
                }
                _ => (false, None),
            };
            if let Some(due) = due {
                self.deadline = Some(self.deadline.map_or(due, |x| x.min(due)));
            }
            if let (true, Some(c)) = (on, self.on.get_mut(slot as usize)) {
                *c = true;
            }
        }
    }

    /// The non-stored and timed qualifiers of the marked places: N on, L before its time, D
    /// after it, DS latched after it unless reset in this scan; a time still to come is due.
    fn qualifiers(&mut self, program: &Program, ctx: &EvalCtx) {
        for (a, &slot) in program.actions.iter().zip(&program.action_slot) {
            let marked = ctx.marking.get(a.place.index()).is_some_and(|&m| m > 0);
            if !marked {
                continue;
            }
            let since = ctx
                .place_since_us
                .get(a.place.index())
                .copied()
                .flatten()
                .unwrap_or(ctx.now_us);
            let elapsed = ctx.now_us.saturating_sub(since);
            let on = match a.qualifier {
                Qualifier::N => true,
                Qualifier::L(d) | Qualifier::D(d) => {
                    if elapsed < d {
                        self.due(since.saturating_add(d));
                    }
                    matches!(a.qualifier, Qualifier::L(_)) == (elapsed < d)
                }
                Qualifier::DS(d) => {
                    let reset = self.reset.get(slot as usize).copied().unwrap_or(false);
                    if elapsed < d {
                        self.due(since.saturating_add(d));
                    } else if let (false, Some(l)) = (reset, self.latch.get_mut(slot as usize)) {
                        *l = true;
                    }
                    false
                }
                _ => false,
            };
            if let (true, Some(c)) = (on, self.on.get_mut(slot as usize)) {
                *c = true;
            }
        }
    }

    /// A scan that is not quiet: the places entered (true) and left (false) in `edges`, then the
    /// timers, the actions and the bodies, into `outputs` and `vars`.
    fn recompute(
        &mut self,
        program: &Program,
        ctx: &EvalCtx,
        edges: impl Iterator<Item = (PlaceIdx, bool)>,
        (outputs, vars): (&mut [Value], &mut [Value]),
        work: &mut Work,
    ) -> Result<(), ActError> {
        self.quiet = false;
        self.begin();
        for (p, entered) in edges {
            self.edge(program, p, entered, ctx.now_us);
        }
        let now_us = ctx.now_us;
        self.stored_timers(program, now_us);
        // A chart's ST reads this scan's inputs, once: a VAR_INPUT one body assigns, the next sees.
        let chart = program.st().filter(|s| s.is_chart());
        if let (Some(st), Some(state)) = (chart, self.st.as_mut()) {
            st.copy_in(ctx.inputs, state);
        }
        self.qualifiers(program, ctx);
        for ((o, s), &held) in outputs
            .iter_mut()
            .zip(&program.outputs)
            .zip(&program.output_held)
        {
            if !held {
                *o = s.ty.zero();
            }
        }
        let mut running = false;
        for (slot, target) in program.action_targets.iter().enumerate() {
            let stored = self.on.get(slot).copied().unwrap_or(false)
                || self.latch.get(slot).copied().unwrap_or(false);
            let q = stored || self.pulse.get(slot).copied().unwrap_or(false);
            let last = if matches!(target, Target::St(_)) {
                q
            } else {
                stored
            };
            let was = self
                .was_on
                .get_mut(slot)
                .is_some_and(|w| std::mem::replace(w, last));
            let cell = match *target {
                Target::Output(i) => outputs.get_mut(i as usize),
                Target::Variable(i) => vars.get_mut(i as usize),
                Target::Body(_) => None,
                // While Q is on, and once more as it falls; else the chart's code has it.
                Target::St(at) if q || was => {
                    let st = self.st.as_mut().and_then(|s| s.slots.get_mut(at as usize));
                    if let Some(c) = st {
                        *c = u64::from(q);
                    }
                    None
                }
                Target::St(_) => None,
            };
            if let Some(c) = cell {
                *c = Value::Bool(q);
            }
            if let Target::Body(b) = *target {
                // Q, or the IEC final run in the scan in which a non-pulse Q falls.
                if q || was {
                    if let Some(body) = program.bodies.get(b as usize) {
                        if !work.charge(body.cost()) {
                            return Err(ActError::OutOfWork {
                                body: body.name().to_string(),
                            });
                        }
                        match (body.st(), self.st.as_mut(), body.st_entry()) {
                            (Some(st), Some(state), Some(k)) => st
                                .run_entry(k, ctx, outputs, state, work)
                                .map_err(|f| st_fault(body, f))?,
                            (Some(st), Some(state), None) => st
                                .run(ctx.inputs, outputs, state, now_us, work)
                                .map_err(|f| st_fault(body, f))?,
                            _ => body.run(ctx, vars, outputs)?,
                        }
                    }
                }
                running |= stored;
            }
        }
        // A chart's ST holds its outputs: the ones its actions set go out even when no body ran.
        if let (Some(st), Some(state)) = (chart, self.st.as_ref()) {
            st.copy_out(outputs, state);
        }
        // A pulse lasts one scan, and a body whose Q holds runs again: the next scan must run.
        self.settled = !self.pulsed && !running;
        Ok(())
    }
}

/// A fault of a Structured Text body in the words of the action machinery.
#[cold]
fn st_fault(body: &crate::Body, f: cetratus_st::Fault) -> ActError {
    use cetratus_st::code::FaultKind;
    let kind = match f.kind {
        FaultKind::Budget => {
            return ActError::OutOfWork {
                body: body.name().to_string(),
            }
        }
        FaultKind::DivisionByZero => crate::EvalErrorKind::DivisionByZero,
        FaultKind::IndexOutOfRange { .. } => crate::EvalErrorKind::IndexOutOfRange,
    };
    ActError::Body(body.st_error(kind, f.pos))
}
