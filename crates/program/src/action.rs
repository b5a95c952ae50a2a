//! Place actions with the IEC 61131-3 SFC qualifiers, and their per-scan state.

use std::fmt;

use cetratus_net::{PlaceIdx, Tokens};

use crate::value::Value;
use crate::Program;

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
            Qualifier::D(d) => {
                f.write_str("D ")?;
                crate::guard::write_duration(f, *d)
            }
        }
    }
}

/// What an action drives: a bool output or a bool variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// An output, by index.
    Output(u32),
    /// A variable, by index.
    Variable(u32),
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

/// The state actions carry from scan to scan (the S/R latches), with scratch sized once.
#[derive(Clone, Debug)]
pub struct ActionState {
    /// Latch per driven target (index into `targets`).
    latch: Vec<bool>,
    /// Scratch per driven target, cleared every scan.
    on: Vec<bool>,
    reset: Vec<bool>,
    deadline: Option<u64>,
    // The outputs of the last scan hold until a place changes, a pulse ends or a timer is due:
    // a scan with none of these leaves them as they are, at no cost.
    settled: bool,
    pulsed: bool,
    quiet: bool,
}

impl ActionState {
    /// Fresh state for `program`, every latch off; use it only with that program.
    pub fn new(program: &Program) -> Self {
        let n = program.action_targets.len();
        ActionState {
            latch: vec![false; n],
            on: vec![false; n],
            reset: vec![false; n],
            deadline: None,
            settled: false,
            pulsed: false,
            quiet: false,
        }
    }

    /// The first scan (startup): every place marked in `marking` counts as entered, then as
    /// [`ActionState::apply`].
    pub fn start(
        &mut self,
        program: &Program,
        marking: &[Tokens],
        place_since_us: &[Option<u64>],
        now_us: u64,
        outputs: &mut [Value],
        vars: &mut [Value],
    ) {
        // A first scan always recomputes, whatever the state did before it.
        self.quiet = false;
        self.begin();
        for (p, &m) in marking.iter().enumerate() {
            if m > 0 {
                self.edge(program, PlaceIdx(p as u32), true);
            }
        }
        self.finish(program, marking, place_since_us, now_us, outputs, vars);
    }

    /// Computes the driven outputs and variables after this scan's marking update.
    ///
    /// `marking` is the marking after the update; `changes` lists the places whose count changed
    /// in this scan with their old count (`cetratus_net::Engine::changes()`); `place_since_us` is
    /// already updated for this scan. Outputs no action drives are set to their type's zero;
    /// variables no action drives are left alone. `outputs` and `vars` must be the buffers of the
    /// previous scan: a scan in which no place changed, no pulse ends and no timer is due leaves them
    /// as they are. Never allocates.
    #[allow(clippy::too_many_arguments)]
    pub fn apply(
        &mut self,
        program: &Program,
        marking: &[Tokens],
        changes: &[(PlaceIdx, Tokens)],
        place_since_us: &[Option<u64>],
        now_us: u64,
        outputs: &mut [Value],
        vars: &mut [Value],
    ) {
        if self.settled && changes.is_empty() && self.deadline.is_none_or(|d| now_us < d) {
            self.quiet = true;
            return;
        }
        self.quiet = false;
        self.begin();
        for &(p, old) in changes {
            let new = marking.get(p.index()).copied().unwrap_or(0);
            if old == 0 && new > 0 {
                self.edge(program, p, true);
            } else if old > 0 && new == 0 {
                self.edge(program, p, false);
            }
        }
        self.finish(program, marking, place_since_us, now_us, outputs, vars);
    }

    /// True when the last `apply` changed nothing: no place changed, no pulse ended, no timer was
    /// due, so outputs and variables are as before.
    pub fn last_was_quiet(&self) -> bool {
        self.quiet
    }

    /// The earliest future time at which an L or D action of a marked place changes its output,
    /// as computed by the last `apply`/`start`; `None` when no such timer runs.
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
        self.on.iter_mut().for_each(|b| *b = false);
        self.reset.iter_mut().for_each(|b| *b = false);
        self.deadline = None;
    }

    /// A place was entered (`entered`) or left: run its edge-triggered actions.
    fn edge(&mut self, program: &Program, p: PlaceIdx, entered: bool) {
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
                    self.on.get_mut(slot)
                }
                _ => None,
            };
            if let Some(c) = cell {
                *c = true;
            }
        }
    }

    fn finish(
        &mut self,
        program: &Program,
        marking: &[Tokens],
        place_since_us: &[Option<u64>],
        now_us: u64,
        outputs: &mut [Value],
        vars: &mut [Value],
    ) {
        // Reset dominates set, as in the IEC action control's RS flip-flop.
        for (l, &r) in self.latch.iter_mut().zip(&self.reset) {
            if r {
                *l = false;
            }
        }
        for (a, &slot) in program.actions.iter().zip(&program.action_slot) {
            let marked = marking.get(a.place.index()).is_some_and(|&m| m > 0);
            if !marked {
                continue;
            }
            let since = place_since_us
                .get(a.place.index())
                .copied()
                .flatten()
                .unwrap_or(now_us);
            let elapsed = now_us.saturating_sub(since);
            let on = match a.qualifier {
                Qualifier::N => true,
                Qualifier::L(d) | Qualifier::D(d) => {
                    if elapsed < d {
                        let due = since.saturating_add(d);
                        self.deadline = Some(self.deadline.map_or(due, |x| x.min(due)));
                    }
                    matches!(a.qualifier, Qualifier::L(_)) == (elapsed < d)
                }
                _ => false,
            };
            if let (true, Some(c)) = (on, self.on.get_mut(slot as usize)) {
                *c = true;
            }
        }
        for (o, s) in outputs.iter_mut().zip(&program.outputs) {
            *o = s.ty.zero();
        }
        for (slot, target) in program.action_targets.iter().enumerate() {
            let on = self.on.get(slot).copied().unwrap_or(false);
            let v = Value::Bool(on || self.latch.get(slot).copied().unwrap_or(false));
            let cell = match *target {
                Target::Output(i) => outputs.get_mut(i as usize),
                Target::Variable(i) => vars.get_mut(i as usize),
            };
            if let Some(c) = cell {
                *c = v;
            }
        }
        // A pulse lasts one scan: the next scan must take it back.
        self.settled = !self.pulsed;
    }
}
