//! Preparing an update away from the scan thread: an [`UpdateContext`] (what the running PLC
//! lends for it) verifies a package, resolves it against the running program and builds the
//! candidate container, its quarantine and everything its install needs, into a
//! [`PreparedUpdate`] that the [`crate::Updater`] installs at a cycle boundary.

use std::sync::Arc;

use cetratus_program::{
    OtherBase, PackageMeta, Program, ResolvedUpdate, Signal, StateTransform, TrustStore, Unsigned,
    UpdatePackage, Value,
};

use cetratus_program::st::{carry_plan, carry_what_fits, StCarry};

use crate::container::Rehearsal;
use crate::error::PrepareError;
use crate::monitor::{ContainerStats, Verdict};
use crate::phase::{Quarantine, UpdatePlan};
use crate::router::{map_by_name, safe_image, IoGrowth};
use crate::updater::{SubstituteMode, SubstituteRequest};
use crate::{Container, SharedAdmission, Slot};

/// An update verified, resolved and built away from the scan thread, ready to install.
pub struct PreparedUpdate {
    pub(crate) base_hash: [u8; 32],
    // The quarantine the install enters, built here with the candidate container and the plan:
    // the install at the cycle boundary fills in its start and allocates nothing of its own.
    pub(crate) quarantine: Box<Quarantine>,
    pub(crate) in_map: Vec<usize>,
    pub(crate) out_map: Vec<Option<usize>>,
    // The Router's input image of the candidate and its Monitor figures.
    pub(crate) image: Vec<Value>,
    pub(crate) stats: ContainerStats,
    // The message of `quarantine_started`, for a candidate in A and in B.
    pub(crate) installed: [String; 2],
    // The signals the install appends to the I/O map.
    pub(crate) grow: IoGrowth,
    // Entries the install touches: the cost model of a virtual run charges by it.
    pub(crate) work: u64,
}

impl PreparedUpdate {
    /// The package's metadata.
    pub fn meta(&self) -> &PackageMeta {
        &self.quarantine.plan.meta
    }
    /// The candidate's program.
    pub fn program(&self) -> &Arc<Program> {
        self.quarantine.candidate.program()
    }
    /// The state transformation the install will apply.
    pub fn transform(&self) -> &StateTransform {
        &self.quarantine.plan.transform
    }
    /// Attaches a validation verdict: published in the `exec_info` of the update's program and
    /// as a `verdict` event when the load is accepted.
    pub fn add_verdict(&mut self, v: Verdict) {
        self.quarantine.plan.verdicts.push(v);
    }
    /// The verdicts attached so far.
    pub fn verdicts(&self) -> &[Verdict] {
        &self.quarantine.plan.verdicts
    }
}

/// What building an update needs from the running PLC, cloned so it can be done on any thread.
#[derive(Clone)]
pub struct UpdateContext {
    /// The running primary program.
    pub primary: Arc<Program>,
    /// Input names of the I/O map.
    pub io_inputs: Vec<String>,
    /// Output names of the I/O map.
    pub io_outputs: Vec<String>,
    /// The primary's marking when the context was taken (the analysis gate starts from it).
    pub primary_marking: Vec<cetratus_net::Tokens>,
    /// The cycle whose boundary the context was taken at: `primary_marking` is the marking an
    /// install at that boundary would transform.
    pub cycle: u64,
    /// Whether the node's I/O can serve signals the I/O map lacks; `None`: it cannot.
    pub admission: Option<SharedAdmission>,
}

impl UpdateContext {
    /// Verifies a package file against the trusted keys, resolves it against the running program
    /// and builds the candidate container: everything but the in-cycle install.
    pub fn prepare_package(
        &self,
        bytes: &[u8],
        trust: &TrustStore,
        unsigned: Unsigned,
        base: OtherBase,
    ) -> Result<PreparedUpdate, PrepareError> {
        let pkg = UpdatePackage::verify(bytes, trust, unsigned)?;
        let resolved = pkg.resolve(&self.primary, base)?;
        self.prepare(resolved)
    }

    /// Compiles a substitution request against the primary program.
    pub fn substitute_request(
        &self,
        mode: SubstituteMode,
        when: Option<&str>,
        within_us: Option<u64>,
        force: bool,
    ) -> Result<SubstituteRequest, PrepareError> {
        let when = match when {
            Some(text) => Some((
                text.to_string(),
                self.primary
                    .compile_condition(text)
                    .map_err(|source| PrepareError::Condition {
                        text: text.to_string(),
                        source,
                    })?,
            )),
            None => None,
        };
        Ok(SubstituteRequest {
            mode,
            when,
            within_us,
            force,
        })
    }

    /// The signals of `program` that the I/O map lacks (inputs, outputs), once the node's I/O
    /// has admitted them; without an admission, the first one is the error.
    fn new_signals(&self, program: &Program) -> Result<(Vec<Signal>, Vec<Signal>), PrepareError> {
        let missing = |signals: &[Signal], have: &[String]| -> Vec<Signal> {
            let new = signals.iter().filter(|s| !have.contains(&s.name));
            new.cloned().collect()
        };
        let new_inputs = missing(program.inputs(), &self.io_inputs);
        let new_outputs = missing(program.outputs(), &self.io_outputs);
        if new_inputs.is_empty() && new_outputs.is_empty() {
            return Ok((new_inputs, new_outputs));
        }
        if let Some(a) = &self.admission {
            a.admit(&new_inputs, &new_outputs)
                .map_err(PrepareError::NewSignals)?;
        } else if let Some(s) = new_inputs.first() {
            return Err(PrepareError::MissingInput {
                signal: s.name.clone(),
                available: self.io_inputs.join(", "),
            });
        } else if let Some(s) = new_outputs.first() {
            return Err(PrepareError::MissingOutput {
                signal: s.name.clone(),
                available: self.io_outputs.join(", "),
            });
        }
        Ok((new_inputs, new_outputs))
    }

    /// Builds a resolved update: the candidate container, its I/O maps and the transition
    /// correspondence used by the Monitor. A candidate signal the I/O map lacks is appended to
    /// it at the install when the node's I/O admits it ([`UpdateContext::admission`]: its address
    /// maps to a configured channel); otherwise the candidate is refused.
    pub fn prepare(&self, update: ResolvedUpdate) -> Result<PreparedUpdate, PrepareError> {
        let primary = &*self.primary;
        let program = update.program.clone();
        let (new_inputs, new_outputs) = self.new_signals(&program)?;
        let io_inputs: Vec<String> = self
            .io_inputs
            .iter()
            .cloned()
            .chain(new_inputs.iter().map(|s| s.name.clone()))
            .collect();
        let io_outputs: Vec<String> = self
            .io_outputs
            .iter()
            .cloned()
            .chain(new_outputs.iter().map(|s| s.name.clone()))
            .collect();
        let in_map: Vec<usize> = program
            .inputs()
            .iter()
            .filter_map(|s| io_inputs.iter().position(|n| *n == s.name))
            .collect();
        let out_map = map_by_name(&io_outputs, program.outputs());
        let (st_map, back_st_map) = st_maps(primary, &program, &update.meta.changes.variables)?;
        let (pn, cn) = (primary.net(), program.net());
        let np = cn.num_places();
        let work =
            (update.transform.rows() + update.transform.cols() + np + cn.num_transitions()) as u64;
        let plan = UpdatePlan {
            to_primary: cn
                .transitions()
                .iter()
                .map(|t| pn.transition_by_id(&t.id))
                .collect(),
            from_primary: pn
                .transitions()
                .iter()
                .map(|t| cn.transition_by_id(&t.id))
                .collect(),
            scratch_marking: vec![0; np],
            scratch_since: vec![None; np],
            safe: safe_image(&out_map, &program),
            latch_map: retained_latch_map(&program, primary),
            var_map: retained_var_map(&program, primary),
            st_map,
            back_st_map,
            back_latch_map: retained_latch_map(primary, &program),
            back_var_map: retained_var_map(primary, &program),
            verdicts: Vec::new(),
            back_marking: vec![0; pn.num_places()],
            back_since: vec![None; pn.num_places()],
            rehearsal: Rehearsal::new(primary),
            meta: update.meta,
            transform: update.transform,
            projection: update.projection,
        };
        let container = Container::new(program, 0);
        let installed = [Slot::A, Slot::B].map(|s| {
            format!(
                "{} {} installed in {} within one cycle; it runs in quarantine, its outputs withheld",
                plan.meta.name,
                plan.meta.version,
                s.as_str()
            )
        });
        Ok(PreparedUpdate {
            base_hash: primary.hash(),
            image: container.inputs().to_vec(),
            stats: ContainerStats::new(self.io_outputs.len() + new_outputs.len()),
            installed,
            quarantine: Box::new(Quarantine {
                candidate: container,
                plan,
                pending: None,
                started_us: 0,
            }),
            in_map,
            out_map,
            grow: IoGrowth {
                from: (self.io_inputs.len(), self.io_outputs.len()),
                inputs: new_inputs,
                outputs: new_outputs,
            },
            work,
        })
    }
}

/// How the primary's Structured Text carries into the candidate's at the switch (refused, naming
/// the variable, when a type changed or a RETAIN value would be lost and the manifest does not
/// say so), and back at a revert, which carries whatever keeps its name and layout.
fn st_maps(
    primary: &Program,
    program: &Program,
    map: &std::collections::BTreeMap<String, String>,
) -> Result<(StCarry, StCarry), PrepareError> {
    let forward =
        carry_plan(primary.st(), program.st(), map).map_err(|w| PrepareError::StState {
            variable: w.name,
            message: w.message,
        })?;
    Ok((forward, carry_what_fits(program.st(), primary.st())))
}

/// For each variable of `program`, the variable of `primary` of the same name and type.
fn retained_var_map(program: &Program, primary: &Program) -> Vec<Option<u32>> {
    let theirs = primary.variables();
    program
        .variables()
        .iter()
        .map(|v| {
            let same = theirs.iter().position(|w| w.name == v.name && w.ty == v.ty);
            same.map(|j| j as u32)
        })
        .collect()
}

/// For each latch (action target) of `program`, the latch of `primary` driving the signal of the
/// same kind and name.
fn retained_latch_map(program: &Program, primary: &Program) -> Vec<Option<u32>> {
    use cetratus_program::Target;
    let name = |p: &Program, t: &Target| match *t {
        Target::Output(i) => (0u8, p.outputs()[i as usize].name.clone()),
        Target::Variable(i) => (1u8, p.variables()[i as usize].name.clone()),
        Target::Body(i) => (2u8, p.bodies()[i as usize].name().to_string()),
        Target::St(at) => {
            let name = p.st().and_then(|s| s.slot_name(at)).unwrap_or_default();
            (3u8, name.to_ascii_uppercase())
        }
    };
    let theirs: Vec<(u8, String)> = primary
        .action_targets()
        .iter()
        .map(|t| name(primary, t))
        .collect();
    program
        .action_targets()
        .iter()
        .map(|t| {
            let mine = name(program, t);
            theirs.iter().position(|x| *x == mine).map(|j| j as u32)
        })
        .collect()
}
