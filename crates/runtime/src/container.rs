//! A container: one running program with its marking, timers, action state and I/O images.

use std::sync::Arc;

use cetratus_net::{Engine, FireError, PlaceIdx, Tokens, TransIdx};
use cetratus_program::st::{RetainedSt, StCarry};
use cetratus_program::{ActError, ActionState, EvalCtx, Program, SoleBody, Value, Work};

use crate::RuntimeError;

/// One program running: the paper's program container.
///
/// All buffers are sized at construction; [`Container::scan`] never allocates.
#[derive(Clone, Debug)]
pub struct Container {
    program: Arc<Program>,
    engine: Engine,
    // The marking as it was at the start of the scan: guards read this, not the step in progress.
    marking_at_start: Vec<Tokens>,
    place_since_us: Vec<Option<u64>>,
    // Per place: how long it was marked the last time (`P.dwell`, IEC's Step.T once it is left).
    place_dwell_us: Vec<u64>,
    actions: ActionState,
    inputs: Vec<Value>,
    prev_inputs: Vec<Value>,
    vars: Vec<Value>,
    outputs: Vec<Value>,
    firings: Vec<u64>,
    scans: u64,
    // Transitions whose guard reads a place timer: their guard can change with time alone.
    timed_guard: Vec<bool>,
    // The next scan must run in full (state was replaced from outside).
    force_full: bool,
    // The last full scan saw the same inputs as the one before it (rise/fall were false).
    inputs_steady: bool,
    // The next scan is the first from the present state (a new container, an install, a
    // retransform): it enters every marked place, and is never quiet.
    fresh_state: bool,
    // The first scan resumes (warm start) instead of entering every marked place.
    resume: bool,
    // `inputs` holds an image seen before (by this container, or handed over from the program
    // that ran before it): the next scan's rise/fall compare against it. False only until the
    // first scan of a container that has no past, where no edge is seen.
    edge_memory: bool,
    // Tests compare against a container that never takes the quiet path.
    always_full: bool,
    // The program is one ST POU run every scan: a scan runs it and nothing else.
    sole: Option<SoleBody>,
}

/// Which scan computes the actions: one that fired, or a quiet one that skipped firing.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Scan {
    Full,
    Quiet,
}

/// Why a guard stopped a scan: its evaluation failed, or the scan ran out of its work budget.
enum Stop {
    Guard(cetratus_program::EvalError),
    Budget,
}

/// Whether transition `t`'s guard holds, by `holds`, with its evaluation and its firing charged
/// to `work`.
#[inline(always)]
fn charged(
    program: &Program,
    t: cetratus_net::TransIdx,
    work: &mut Work,
    holds: impl FnOnce(&mut Work) -> Result<bool, Stop>,
) -> Result<bool, Stop> {
    if !work.charge(program.guard_cost(t)) {
        return Err(Stop::Budget);
    }
    let holds = holds(work)?;
    if holds && !work.charge(1) {
        return Err(Stop::Budget);
    }
    Ok(holds)
}

/// A fault of an ST condition, as a failing guard (or a scan out of work).
#[cold]
fn condition_fault(f: cetratus_program::st::ConditionFault) -> Stop {
    match f {
        cetratus_program::st::ConditionFault::OutOfWork => Stop::Budget,
        cetratus_program::st::ConditionFault::Failed(e) => Stop::Guard(e),
    }
}

/// A failed action body in the runtime's words.
#[cold]
fn act_error(e: ActError, budget: u64) -> RuntimeError {
    match e {
        ActError::Body(e) => RuntimeError::Body(e),
        ActError::OutOfWork { body } => RuntimeError::WorkBudget {
            budget,
            at: format!("action body `{body}`"),
        },
    }
}

/// Takes over the S/R latches and the variables of `from` through the maps built by the
/// Updater: `latch_map[i]` is `from`'s latch for latch `i`, `var_map[i]` `from`'s variable for
/// variable `i`.
fn carry(
    actions: &mut ActionState,
    vars: &mut [Value],
    from: &Container,
    latch_map: &[Option<u32>],
    var_map: &[Option<u32>],
    st: &StCarry,
) {
    if let (Some(to), Some(f)) = (actions.st_state_mut(), from.actions.st_state()) {
        st.apply(to, f);
    }
    for (i, m) in latch_map.iter().enumerate() {
        if let Some(&on) = m.and_then(|j| from.latches().get(j as usize)) {
            actions.set_latch(i, on);
        }
    }
    for (v, m) in vars.iter_mut().zip(var_map) {
        if let Some(&x) = m.and_then(|j| from.vars.get(j as usize)) {
            *v = x;
        }
    }
}

/// Copies `from` into `to` element by element, as far as both go.
fn copy_into<T: Copy>(to: &mut [T], from: &[T]) {
    for (t, f) in to.iter_mut().zip(from) {
        *t = *f;
    }
}

/// Where the state to rehearse from comes from: the latches and variables of another
/// container, through the maps of [`Container::carry_from`].
pub(crate) struct Carry<'a> {
    pub from: &'a Container,
    pub latch_map: &'a [Option<u32>],
    pub var_map: &'a [Option<u32>],
    pub st: &'a StCarry,
}

/// Scratch for rehearsing what a program would drive from a marking, sized once for it (away
/// from the scan thread): its action state, outputs and variables.
pub(crate) struct Rehearsal {
    actions: ActionState,
    /// The outputs the rehearsed scan drives, in the program's output order.
    pub outputs: Vec<Value>,
    vars: Vec<Value>,
}

impl Rehearsal {
    /// Scratch for `program`.
    pub fn new(program: &Program) -> Self {
        Rehearsal {
            actions: ActionState::new(program),
            outputs: program.outputs().iter().map(|s| s.initial).collect(),
            vars: program.variables().iter().map(|s| s.initial).collect(),
        }
    }
}

/// A failed firing in the program's words: transition and place ids rather than indices.
#[cold]
fn fire_error(program: &Program, e: FireError<Stop>, work_budget: u64) -> RuntimeError {
    let net = program.net();
    match e {
        FireError::Guard {
            transition,
            error: Stop::Guard(error),
        } => RuntimeError::Guard {
            transition: net.transition(transition).id.clone(),
            message: error.to_string(),
        },
        FireError::Guard {
            transition,
            error: Stop::Budget,
        } => RuntimeError::WorkBudget {
            budget: work_budget,
            at: format!("transition `{}`", net.transition(transition).id),
        },
        FireError::Overflow { transition, place } => RuntimeError::Overflow {
            transition: net.transition(transition).id.clone(),
            place: net.place(place).id.clone(),
        },
    }
}

/// Why a transition did not fire in a container's last scan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blocker {
    /// An input place held too few tokens.
    Place(PlaceIdx),
    /// An inhibitor place held too many.
    Inhibitor(PlaceIdx),
    /// An output place was at its capacity.
    Capacity(PlaceIdx),
    /// It was enabled but its guard was false.
    Guard,
    /// It was enabled with a true guard (or none) but a transition of higher rank took its tokens.
    Conflict,
    /// The container's program has no such transition.
    Absent,
}

/// What one scan did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScanOutcome {
    /// Transitions fired.
    pub fired: usize,
    /// True when no transition is enabled after the scan.
    pub deadlocked: bool,
}

impl Container {
    /// A container running `program` from its initial marking, with every place's timer started
    /// at `now_us` for the places marked at start.
    pub fn new(program: Arc<Program>, now_us: u64) -> Self {
        let engine = Engine::new(program.net().clone());
        let marking = engine.marking().to_vec();
        Self::assemble(program, engine, marking, now_us)
    }

    /// A container running `program` from a given marking and place timers (state transformation,
    /// warm start).
    pub fn with_state(
        program: Arc<Program>,
        marking: &[Tokens],
        place_since_us: &[Option<u64>],
        now_us: u64,
    ) -> Result<Self, cetratus_net::NetError> {
        let engine = Engine::with_marking(program.net().clone(), marking.to_vec().into())?;
        let mut c = Self::assemble(program, engine, marking.to_vec(), now_us);
        for (slot, (&since, &m)) in c
            .place_since_us
            .iter_mut()
            .zip(place_since_us.iter().zip(marking))
        {
            *slot = if m > 0 { since.or(Some(now_us)) } else { None };
        }
        Ok(c)
    }

    fn assemble(program: Arc<Program>, engine: Engine, marking: Vec<Tokens>, now_us: u64) -> Self {
        // Containers are built where a program is loaded or prepared, never on the scan thread:
        // the one place its ST is translated into machine code.
        program.prepare_machine_code();
        let place_since_us = marking.iter().map(|&m| (m > 0).then_some(now_us)).collect();
        let inputs: Vec<Value> = program.inputs().iter().map(|s| s.initial).collect();
        let vars: Vec<Value> = program.variables().iter().map(|s| s.initial).collect();
        let outputs: Vec<Value> = program.outputs().iter().map(|s| s.initial).collect();
        let actions = ActionState::new(&program);
        // An ST condition may read a step's time or a timer's output: never skipped.
        let timed_guard = (0..program.net().num_transitions() as u32)
            .map(|t| {
                let t = TransIdx(t);
                program.st_condition(t).is_some()
                    || program.guard(t).is_some_and(|g| !g.timers().is_empty())
            })
            .collect();
        Container {
            timed_guard,
            force_full: true,
            inputs_steady: false,
            fresh_state: true,
            resume: false,
            edge_memory: false,
            always_full: false,
            sole: SoleBody::of(&program),
            firings: vec![0; program.net().num_transitions()],
            place_dwell_us: vec![0; marking.len()],
            marking_at_start: marking,
            place_since_us,
            actions,
            prev_inputs: inputs.clone(),
            inputs,
            vars,
            outputs,
            engine,
            program,
            scans: 0,
        }
    }

    /// The program.
    pub fn program(&self) -> &Arc<Program> {
        &self.program
    }
    /// The marking, in place order.
    pub fn marking(&self) -> &[Tokens] {
        self.engine.marking()
    }
    /// When each place last went from empty to marked (`None` while empty).
    pub fn place_since_us(&self) -> &[Option<u64>] {
        &self.place_since_us
    }
    /// Per place, how long it was marked the last time it was (0 if never): what `P.dwell`
    /// reads while the place is empty.
    pub fn place_dwell_us(&self) -> &[u64] {
        &self.place_dwell_us
    }
    /// The output image computed by the last scan.
    pub fn outputs(&self) -> &[Value] {
        &self.outputs
    }
    /// The input image of the last scan.
    pub fn inputs(&self) -> &[Value] {
        &self.inputs
    }
    /// The variables.
    pub fn variables(&self) -> &[Value] {
        &self.vars
    }
    /// Firings per transition since the container started.
    pub fn firings(&self) -> &[u64] {
        &self.firings
    }
    /// Scans run since the container was built (an install or a retransform does not restart
    /// the count, as it does not restart [`Container::firings`]).
    pub fn scans(&self) -> u64 {
        self.scans
    }
    /// The transitions fired by the last scan.
    pub fn fired(&self) -> &[cetratus_net::TransIdx] {
        self.engine.fired()
    }
    /// The underlying engine (enabled set, last changes).
    pub fn engine(&self) -> &Engine {
        &self.engine
    }

    /// One scan: take the input image, fire under the program's policy with its guards, update
    /// place timers, then compute the actions into the output image.
    ///
    /// On error nothing has changed but the input image: the marking, timers, variables and
    /// outputs are as after the previous scan.
    pub fn scan(&mut self, now_us: u64, inputs: &[Value]) -> Result<ScanOutcome, RuntimeError> {
        self.scan_hinted(now_us, inputs, false)
    }

    /// [`Container::scan`] for a caller that knows `inputs` equals the image of the previous
    /// scan when `unchanged` is true (the Message Router does), which spares comparing them.
    pub fn scan_hinted(
        &mut self,
        now_us: u64,
        inputs: &[Value],
        unchanged: bool,
    ) -> Result<ScanOutcome, RuntimeError> {
        self.scan_within(now_us, inputs, unchanged, u64::MAX)
    }

    /// [`Container::scan_hinted`] stopped midway before it does more than `work_budget` units
    /// of [`Work`]: each guard evaluation costs its code's length, each firing one unit, and each
    /// action body that runs its code's length. A stopped scan fails like a faulted one
    /// ([`RuntimeError::WorkBudget`]). This bounds a runaway scan by what it does, not by a clock.
    pub fn scan_within(
        &mut self,
        now_us: u64,
        inputs: &[Value],
        unchanged: bool,
        work_budget: u64,
    ) -> Result<ScanOutcome, RuntimeError> {
        if inputs.len() != self.inputs.len() {
            return Err(RuntimeError::InputImage {
                expected: self.inputs.len(),
                got: inputs.len(),
            });
        }
        if let Some(sole) = self.sole.filter(|&sole| self.runs_sole(sole)) {
            return self.sole_scan(sole, now_us, inputs, work_budget);
        }
        if self.is_quiet(inputs, unchanged) {
            return self.quiet_scan(now_us, work_budget);
        }
        self.force_full = false;
        self.take_inputs(inputs);
        let mut work = Work::within(work_budget);
        let fired = self.fire(now_us, &mut work)?;
        self.follow_changes(now_us);
        self.act(now_us, Scan::Full, &mut work)?;
        Ok(self.outcome(fired))
    }

    /// Takes the scan's input image, keeping the last one for `rise`/`fall`.
    #[inline]
    fn take_inputs(&mut self, inputs: &[Value]) {
        if self.edge_memory {
            self.prev_inputs.copy_from_slice(&self.inputs);
        } else {
            // No past: rise/fall compare against the same image, so the first scan sees no edge.
            self.prev_inputs.copy_from_slice(inputs);
        }
        self.inputs.copy_from_slice(inputs);
        self.edge_memory = true;
        self.inputs_steady = self.prev_inputs == self.inputs;
    }

    /// Fires under the program's policy, each guard reading the marking as it was at the start
    /// of the scan and charging its cost to `work`; returns how many transitions fired.
    #[inline]
    fn fire(&mut self, now_us: u64, work: &mut Work) -> Result<usize, RuntimeError> {
        let program = &*self.program;
        let ctx = EvalCtx {
            inputs: &self.inputs,
            prev_inputs: &self.prev_inputs,
            vars: &self.vars,
            marking: &self.marking_at_start,
            place_since_us: &self.place_since_us,
            place_dwell_us: &self.place_dwell_us,
            now_us,
        };
        let policy = program.policy();
        let guard = |t| program.eval_guard(t, &ctx).map_err(Stop::Guard);
        // A chart's ST conditions read its state, with this scan's inputs and step flags; any
        // other program keeps the plain guard path.
        let result = match (
            program.st().filter(|s| s.is_chart()),
            self.actions.st_state_mut(),
        ) {
            (Some(st), Some(state)) => {
                st.prepare(&ctx, state);
                self.engine.scan(policy, |t| {
                    charged(program, t, work, |work| match program.st_condition(t) {
                        Some(k) => (st.condition(k, state, now_us, work)).map_err(condition_fault),
                        None => guard(t),
                    })
                })
            }
            _ => (self.engine).scan(policy, |t| charged(program, t, work, |_| guard(t))),
        }
        .map(|f| f.len());
        result.map_err(|e| {
            // The failing guard must fail again on the next scan, not be skipped as quiet.
            self.force_full = true;
            fire_error(program, e, work.budget())
        })
    }

    /// Counts the firings and moves the place timers with the marking's changes, which the
    /// guards of the next scan read.
    #[inline]
    fn follow_changes(&mut self, now_us: u64) {
        for &t in self.engine.fired() {
            self.firings[t.index()] += 1;
        }
        let marking = self.engine.marking();
        for &(p, old) in self.engine.changes() {
            let new = marking[p.index()];
            self.marking_at_start[p.index()] = new;
            if old == 0 && new > 0 {
                self.place_since_us[p.index()] = Some(now_us);
            } else if new == 0 {
                // IEC's Step.T: the dwell is kept until the place is marked again.
                if let Some(since) = self.place_since_us[p.index()].take() {
                    self.place_dwell_us[p.index()] = now_us.saturating_sub(since);
                }
            }
        }
    }

    /// Computes the actions from the marking after firing, and counts the scan even when a
    /// body fails (which forces the next scan to run in full, so it fails again). The first full
    /// scan from a fresh state enters every marked place, unless it resumes; a quiet scan
    /// changed no place.
    #[inline]
    fn act(&mut self, now_us: u64, scan: Scan, work: &mut Work) -> Result<(), RuntimeError> {
        let program = &*self.program;
        let view = EvalCtx {
            inputs: &self.inputs,
            prev_inputs: &self.prev_inputs,
            vars: &[],
            marking: self.engine.marking(),
            place_since_us: &self.place_since_us,
            place_dwell_us: &self.place_dwell_us,
            now_us,
        };
        let changes = match scan {
            Scan::Full => self.engine.changes(),
            Scan::Quiet => &[],
        };
        let enters_all = scan == Scan::Full
            && std::mem::take(&mut self.fresh_state)
            && !std::mem::take(&mut self.resume);
        let acted = if enters_all {
            // The first scan enters every marked place: P1 and S actions of M0 take effect.
            self.actions
                .start(program, &view, &mut self.outputs, &mut self.vars, work)
        } else {
            let (outputs, vars) = (&mut self.outputs, &mut self.vars);
            self.actions
                .apply(program, &view, changes, outputs, vars, work)
        };
        self.scans += 1;
        acted.map_err(|e| {
            self.force_full = true;
            act_error(e, work.budget())
        })
    }

    /// What a scan that fired `fired` transitions leaves behind.
    #[inline]
    fn outcome(&self, fired: usize) -> ScanOutcome {
        ScanOutcome {
            fired,
            deadlocked: self.engine.deadlocked(),
        }
    }

    /// Whether this scan can be skipped: nothing fired in the last scan, the input image has not
    /// changed for two scans (so `rise`/`fall` are false as they were), the actions changed no
    /// variable, and no enabled transition has a guard on a place timer. Then every guard gives
    /// what it gave in the last scan, which fired nothing: this scan fires nothing either. This is
    /// what makes a scan cost what the activity costs (docs/design.md §3).
    fn is_quiet(&self, inputs: &[Value], unchanged: bool) -> bool {
        !self.always_full
            && !self.force_full
            && !self.fresh_state
            && self.engine.fired().is_empty()
            && self.actions.last_was_quiet()
            && self.inputs_steady
            && (unchanged || inputs == self.inputs.as_slice())
            && !self
                .engine
                .enabled()
                .iter()
                .any(|t| self.timed_guard[t.index()])
    }

    /// Whether this scan of a [`SoleBody`] program is one run of its body: not the first from
    /// this state, nor one that must run in full.
    fn runs_sole(&self, sole: SoleBody) -> bool {
        !self.always_full
            && !self.force_full
            && !self.fresh_state
            && self.actions.runs_sole(sole, self.engine.marking())
    }

    /// The scan of a [`SoleBody`] program: the inputs taken, the body run; no transition can
    /// fire and no place change, so nothing else moves.
    fn sole_scan(
        &mut self,
        sole: SoleBody,
        now_us: u64,
        inputs: &[Value],
        work_budget: u64,
    ) -> Result<ScanOutcome, RuntimeError> {
        // No guard reads `rise`/`fall`, and a scan on the full path takes its own past image
        // first: only this image is kept.
        self.inputs.copy_from_slice(inputs);
        self.edge_memory = true;
        let mut work = Work::within(work_budget);
        let (program, outputs) = (&*self.program, &mut self.outputs);
        let ran = (self.actions).run_sole(program, sole, &self.inputs, outputs, now_us, &mut work);
        self.scans += 1;
        ran.map_err(|e| {
            self.force_full = true;
            act_error(e, work.budget())
        })?;
        Ok(self.outcome(0))
    }

    /// A scan that fires nothing: the actions still run, for their timers.
    fn quiet_scan(&mut self, now_us: u64, work_budget: u64) -> Result<ScanOutcome, RuntimeError> {
        self.act(now_us, Scan::Quiet, &mut Work::within(work_budget))?;
        Ok(self.outcome(0))
    }

    /// False when the last scan certainly left the outputs and variables as they were.
    pub fn outputs_may_have_changed(&self) -> bool {
        !self.actions.last_was_quiet()
    }

    /// Takes over the S/R latches and the variables of `from` (the primary) through the maps
    /// built by the Updater: `latch_map[i]` is `from`'s latch for this program's latch `i`,
    /// `var_map[i]` `from`'s variable for variable `i`, and `st` the variables of its
    /// Structured Text. Allocates nothing.
    pub fn carry_from(
        &mut self,
        from: &Container,
        latch_map: &[Option<u32>],
        var_map: &[Option<u32>],
        st: &StCarry,
    ) {
        carry(
            &mut self.actions,
            &mut self.vars,
            from,
            latch_map,
            var_map,
            st,
        );
        self.force_full = true;
    }

    /// What this program would drive if its state became `marking` (entered at `since`), with
    /// the latches and variables of `carried` if given: the first scan after a
    /// [`Container::set_state`], before any firing, rehearsed on the inputs of the last scan in
    /// `r`. The container is left as it is, and nothing is allocated unless a body fails; the
    /// outputs are in `r.outputs`.
    pub(crate) fn rehearse(
        &self,
        marking: &[Tokens],
        since: &[Option<u64>],
        carried: Option<Carry<'_>>,
        now_us: u64,
        budget: u64,
        r: &mut Rehearsal,
    ) -> Result<(), RuntimeError> {
        r.actions.copy_from(&self.actions);
        copy_into(&mut r.outputs, &self.outputs);
        copy_into(&mut r.vars, &self.vars);
        if let Some(c) = carried {
            carry(
                &mut r.actions,
                &mut r.vars,
                c.from,
                c.latch_map,
                c.var_map,
                c.st,
            );
        }
        let view = EvalCtx {
            inputs: &self.inputs,
            prev_inputs: &self.inputs,
            vars: &[],
            marking,
            place_since_us: since,
            place_dwell_us: &[],
            now_us,
        };
        let mut work = Work::within(budget);
        r.actions
            .start(&self.program, &view, &mut r.outputs, &mut r.vars, &mut work)
            .map_err(|e| act_error(e, budget))
    }

    /// Continues edge detection from `previous`, the input image (in this program's input order)
    /// that the program running before this one saw in its last scan: the next scan's
    /// `rise`/`fall` compare against it, so an edge in the cycle of an install or a substitution
    /// is seen rather than lost. Allocates nothing; values past this program's inputs are ignored.
    pub fn continue_edges_from(&mut self, previous: impl IntoIterator<Item = Value>) {
        for (v, p) in self.inputs.iter_mut().zip(previous) {
            *v = p;
        }
        self.edge_memory = true;
        self.force_full = true;
    }

    /// The next scan resumes rather than starts: marked places are not entered again, so P1
    /// pulses and S/R actions of the saved marking do not fire a second time (warm start).
    pub fn resume_without_entry(&mut self) {
        self.resume = true;
    }

    /// Makes every scan run in full, for comparing against the quiet path in tests.
    pub fn set_always_full(&mut self, on: bool) {
        self.always_full = on;
        self.actions.set_never_quiet(on);
    }

    /// Replaces the marking and place timers without allocating (an update's install, a
    /// retransform at substitution). The next scan enters every marked place, as a first scan does.
    pub fn set_state(
        &mut self,
        marking: &[Tokens],
        place_since_us: &[Option<u64>],
    ) -> Result<(), cetratus_net::NetError> {
        if place_since_us.len() != marking.len() {
            return Err(cetratus_net::NetError::MarkingLength {
                expected: marking.len(),
                got: place_since_us.len(),
            });
        }
        self.engine.set_marking(marking)?;
        self.marking_at_start.copy_from_slice(marking);
        self.place_since_us.copy_from_slice(place_since_us);
        // A new state has no past: the dwell of every empty place starts again from 0.
        self.place_dwell_us.iter_mut().for_each(|d| *d = 0);
        // `scans` goes on, as `firings` do: the Monitor counts both since the install.
        self.fresh_state = true;
        self.force_full = true;
        Ok(())
    }

    /// The tokens place `p` held before the last scan, from the marking after it and the
    /// firings of the scan.
    pub fn tokens_before_last_scan(&self, p: PlaceIdx) -> i64 {
        let net = self.program.net();
        let mut m = i64::from(self.engine.marking()[p.index()]);
        for &t in self.engine.fired() {
            if let Ok(k) = net.delta(t).binary_search_by_key(&p, |&(q, _)| q) {
                m -= net.delta(t)[k].1;
            }
        }
        m
    }

    /// Why transition `t` did not fire in the last scan: the first input place short of tokens,
    /// an inhibitor, a capacity, or else its guard (or a conflict with a transition of higher rank).
    pub fn blocker(&self, t: TransIdx) -> Blocker {
        let net = self.program.net();
        for &(p, w) in net.pre(t) {
            if self.tokens_before_last_scan(p) < i64::from(w) {
                return Blocker::Place(p);
            }
        }
        for &(p, w) in net.inhibitors(t) {
            if self.tokens_before_last_scan(p) >= i64::from(w) {
                return Blocker::Inhibitor(p);
            }
        }
        for &(p, d) in net.delta(t) {
            if let Some(cap) = net.capacity(p) {
                if d > 0 && self.tokens_before_last_scan(p) + d > i64::from(cap) {
                    return Blocker::Capacity(p);
                }
            }
        }
        if self.program.has_guard(t) {
            Blocker::Guard
        } else {
            Blocker::Conflict
        }
    }

    /// The S/R latches of the action state, in the program's action-target order.
    pub fn latches(&self) -> &[bool] {
        self.actions.latches()
    }

    /// Copies the RETAIN variables of the program's Structured Text into `out` (cleared when it
    /// has none), reusing its buffers.
    pub fn st_retained_into(&self, out: &mut Vec<RetainedSt>) {
        match (self.program.st(), self.actions.st_state()) {
            (Some(st), Some(state)) => st.retained_into(state, out),
            _ => out.clear(),
        }
    }

    /// The value of the program's Structured Text variable `path` (see
    /// [`cetratus_program::st::StProgram::watch`]), if the program has one of that name.
    pub fn st_watch(&self, path: &str) -> Option<Value> {
        let (st, state) = (self.program.st()?, self.actions.st_state()?);
        st.watch(state, path)
    }

    /// The value of a watched name (`cetratus run --watch`): a variable of the program
    /// (`[[variable]]`), else one of its Structured Text ([`Container::st_watch`]).
    pub fn watch(&self, name: &str) -> Option<Value> {
        match self.program.variable_index(name) {
            Some(i) => self.vars.get(i).copied(),
            None => self.st_watch(name),
        }
    }

    /// Restores the RETAIN variables of the program's Structured Text (warm start); the names of
    /// the saved ones that could not be restored and start from their initial values.
    pub fn restore_st_retained(&mut self, saved: &[RetainedSt]) -> Vec<String> {
        let program = self.program.clone();
        self.force_full = true;
        match (program.st(), self.actions.st_state_mut()) {
            (Some(st), Some(state)) => st.restore_retained(state, saved),
            _ => saved
                .iter()
                .map(|r| r.name.chars().take(64).collect())
                .collect(),
        }
    }

    /// Restores variables and latches (warm start).
    pub fn restore_retained(&mut self, vars: &[Value], latches: &[bool]) {
        for ((v, s), new) in self.vars.iter_mut().zip(self.program.variables()).zip(vars) {
            if s.retain && new.ty() == s.ty {
                *v = *new;
            }
        }
        if latches.len() == self.actions.latches().len() {
            self.actions.set_latches(latches);
        }
        self.force_full = true;
    }

    /// Writes the program's declared safe output values into `out`.
    pub fn safe_outputs(&self, out: &mut [Value]) {
        self.program.safe_outputs(out);
    }
}

pub use cetratus_vocab::Slot;
