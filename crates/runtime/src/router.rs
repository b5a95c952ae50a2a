//! The Message Router of the paper's Figure 1: it moves I/O data between the Provider, the two
//! containers and the Dispatcher. The same inputs go to both containers, each through its own
//! input map; only PRIMARY's outputs reach the Dispatcher; in fault, the safe values do. An
//! output of the I/O map that PRIMARY lacks holds the safe value of the last program that
//! declared it.
//!
//! Images are rebuilt only when they can have changed (new inputs, a new install, a warm start),
//! and boolean images are kept as bit masks so that the Monitor compares two containers' outputs
//! in one instruction on most cycles. Nothing here allocates once built.

use cetratus_program::{Program, Signal, Type, Value};

use crate::mask::Mask;
use crate::{Container, Dispatcher, Provider};

/// The I/O map and the images of both containers.
pub struct MessageRouter {
    io_inputs: Vec<String>,
    io_outputs: Vec<String>,
    inputs: Vec<Value>,
    prev_inputs: Vec<Value>,
    images: [Vec<Value>; 2],
    in_maps: [Vec<usize>; 2],
    out_maps: [Vec<Option<usize>>; 2],
    outs: [Vec<Value>; 2],
    in_bits: Mask,
    out_bits: [Mask; 2],
    dispatched_bits: Mask,
    inputs_changed: bool,
    // Every output of the I/O map is boolean: images compare as bit masks.
    bool_outputs: bool,
    // A container's input image or mapped outputs must be rebuilt (new install, warm start).
    stale: [bool; 2],
    dispatched: Vec<Value>,
    // The safe values of the program that drives the outputs, and for the outputs it lacks
    // what `held` says.
    safe: Vec<Value>,
    // Per output of the I/O map, the safe value of the last program that declared it: what an
    // output no program drives holds (docs/io.md).
    held: Vec<Value>,
    // Per container, the outputs of the I/O map its program lacks (sized for the map, so that
    // refilling it never allocates).
    undriven: [Vec<usize>; 2],
    // Bumped whenever `safe` changes, so that the I/O hears of it once.
    safe_generation: u64,
}

/// The signals an update appends to the I/O map at its install, and the map's lengths (inputs,
/// outputs) it was prepared against.
#[derive(Clone, Debug, Default)]
pub(crate) struct IoGrowth {
    pub from: (usize, usize),
    pub inputs: Vec<Signal>,
    pub outputs: Vec<Signal>,
}

/// For each name of `from`, the index of the signal of that name in `to`.
pub(crate) fn map_by_name(from: &[String], to: &[Signal]) -> Vec<Option<usize>> {
    from.iter()
        .map(|n| to.iter().position(|s| &s.name == n))
        .collect()
}

/// A program's safe output values in the order of the I/O map, through its output map (off for
/// outputs it lacks).
pub(crate) fn safe_image(out_map: &[Option<usize>], program: &Program) -> Vec<Value> {
    let mut own = vec![Value::Bool(false); program.outputs().len()];
    program.safe_outputs(&mut own);
    out_map
        .iter()
        .map(|m| m.map_or(Value::Bool(false), |k| own[k]))
        .collect()
}

impl MessageRouter {
    /// The router of a PLC whose I/O map is `program`'s signals, with `program` in container `slot`.
    pub fn new(program: &Program, slot: usize) -> Self {
        let image: Vec<Value> = program.inputs().iter().map(|s| s.initial).collect();
        let image = &image[..];
        let io_inputs: Vec<String> = program.inputs().iter().map(|s| s.name.clone()).collect();
        let io_outputs: Vec<String> = program.outputs().iter().map(|s| s.name.clone()).collect();
        let n_out = io_outputs.len();
        let out_map: Vec<Option<usize>> = (0..n_out).map(Some).collect();
        let mut r = MessageRouter {
            images: [Vec::new(), Vec::new()],
            in_maps: [Vec::new(), Vec::new()],
            out_maps: [Vec::new(), Vec::new()],
            outs: [
                vec![Value::Bool(false); n_out],
                vec![Value::Bool(false); n_out],
            ],
            in_bits: Mask::of(image),
            out_bits: [Mask::new(n_out), Mask::new(n_out)],
            dispatched_bits: Mask::new(n_out),
            inputs_changed: true,
            bool_outputs: program.outputs().iter().all(|s| s.ty == Type::Bool),
            stale: [true, true],
            inputs: image.to_vec(),
            prev_inputs: image.to_vec(),
            dispatched: vec![Value::Bool(false); n_out],
            safe: safe_image(&out_map, program),
            held: safe_image(&out_map, program),
            undriven: [Vec::with_capacity(n_out), Vec::with_capacity(n_out)],
            safe_generation: 1,
            io_inputs,
            io_outputs,
        };
        r.images[slot] = image.to_vec();
        r.in_maps[slot] = (0..r.io_inputs.len()).collect();
        r.out_maps[slot] = out_map;
        r
    }

    /// Connects container `slot` running `program` through its own maps; refuses a program that
    /// reads an input the I/O map lacks, naming it. `program` drives the outputs from now on.
    pub(crate) fn attach_by_name(
        &mut self,
        slot: usize,
        program: &Program,
        image: &[Value],
    ) -> Result<(), String> {
        let in_map = program
            .inputs()
            .iter()
            .map(|s| {
                self.io_inputs
                    .iter()
                    .position(|n| *n == s.name)
                    .ok_or_else(|| s.name.clone())
            })
            .collect::<Result<Vec<_>, _>>()?;
        let out_map = map_by_name(&self.io_outputs, program.outputs());
        let mut safe = safe_image(&out_map, program);
        self.attach(slot, image.to_vec(), in_map, out_map, &safe);
        self.drive_safe(slot, &mut safe);
        Ok(())
    }

    /// Connects container `slot` through the given maps, for a program whose safe values in
    /// I/O-map order are `safe`; its images are rebuilt at its next scan. The outputs it
    /// declares hold its safe values whenever no program drives them.
    pub(crate) fn attach(
        &mut self,
        slot: usize,
        image: Vec<Value>,
        in_map: Vec<usize>,
        out_map: Vec<Option<usize>>,
        safe: &[Value],
    ) {
        self.images[slot] = image;
        self.in_maps[slot] = in_map;
        self.out_maps[slot] = out_map;
        self.stale[slot] = true;
        self.declare(slot, safe);
    }

    /// Takes the safe values of container `slot`'s program (I/O-map order) for the outputs it
    /// declares, and lists those it lacks.
    fn declare(&mut self, slot: usize, safe: &[Value]) {
        self.undriven[slot].clear();
        for (j, m) in self.out_maps[slot].iter().enumerate() {
            match (m, safe.get(j)) {
                (Some(_), Some(&v)) => self.held[j] = v,
                (Some(_), None) => {}
                (None, _) => self.undriven[slot].push(j),
            }
        }
    }

    /// Appends signals to the I/O map (an update that uses signals the running program does not):
    /// inputs start at their initial values, and no container drives the new outputs until the
    /// candidate that declares them is attached.
    pub(crate) fn grow(&mut self, inputs: &[Signal], outputs: &[Signal]) {
        for s in inputs {
            self.io_inputs.push(s.name.clone());
            self.inputs.push(s.initial);
            self.prev_inputs.push(s.initial);
        }
        for s in outputs {
            self.io_outputs.push(s.name.clone());
            for k in 0..2 {
                self.outs[k].push(Value::Bool(false));
                self.out_maps[k].push(None);
            }
            self.dispatched.push(Value::Bool(false));
            // Until a program that declares it is attached, an output no program drives.
            let held = s.safe.unwrap_or(s.ty.zero());
            self.held.push(held);
            self.safe.push(held);
            for u in &mut self.undriven {
                u.push(self.held.len() - 1);
            }
        }
        for u in &mut self.undriven {
            u.reserve(self.io_outputs.len().saturating_sub(u.len()));
        }
        self.safe_generation += 1;
        self.bool_outputs &= outputs.iter().all(|s| s.ty == Type::Bool);
        self.in_bits = Mask::of(&self.inputs);
        let n = self.io_outputs.len();
        self.out_bits = [Mask::new(n), Mask::new(n)];
        self.dispatched_bits = Mask::of(&self.dispatched);
        self.inputs_changed = true;
        self.stale = [true, true];
    }

    /// Reads the Provider into the input image.
    pub(crate) fn read<P: Provider + ?Sized>(&mut self, now_us: u64, io: &mut P) {
        self.prev_inputs.copy_from_slice(&self.inputs);
        io.read_inputs(now_us, &mut self.inputs);
        self.inputs_changed = self.inputs != self.prev_inputs;
        if self.inputs_changed {
            self.in_bits.set_from(&self.inputs);
        }
    }

    /// Container `slot`'s input image, rebuilt when the inputs changed or it is stale, and whether
    /// it is unchanged since its last scan.
    pub(crate) fn image(&mut self, slot: usize) -> (&[Value], bool) {
        let fresh = self.inputs_changed || self.stale[slot];
        if fresh {
            for (v, &j) in self.images[slot].iter_mut().zip(&self.in_maps[slot]) {
                *v = self.inputs[j];
            }
        }
        (&self.images[slot], !fresh)
    }

    /// Takes container `slot`'s outputs after its scan, in I/O-map order.
    pub(crate) fn collect(&mut self, slot: usize, c: &Container) {
        if c.outputs_may_have_changed() || self.stale[slot] {
            for (o, m) in self.outs[slot].iter_mut().zip(&self.out_maps[slot]) {
                *o = m.map_or(Value::Bool(false), |k| c.outputs()[k]);
            }
            self.out_bits[slot].set_from(&self.outs[slot]);
        }
        self.stale[slot] = false;
    }

    /// Hands PRIMARY's outputs to the Dispatcher.
    pub(crate) fn dispatch<D: Dispatcher + ?Sized>(
        &mut self,
        primary: usize,
        now_us: u64,
        io: &mut D,
    ) {
        self.dispatched.copy_from_slice(&self.outs[primary]);
        self.dispatched_bits.copy_from(&self.out_bits[primary]);
        // The outputs the primary lacks hold the safe value of the last program that declared
        // them (most programs declare every output of the map: nothing to do).
        if !self.undriven[primary].is_empty() {
            for &j in &self.undriven[primary] {
                self.dispatched[j] = self.held[j];
            }
            self.dispatched_bits.set_from(&self.dispatched);
        }
        io.write_outputs(now_us, &self.dispatched);
    }

    /// The outputs of the I/O map that would change if container `slot`'s program took over
    /// driving `outputs` (in its own output order), against what is dispatched now: its own
    /// outputs, and for those it lacks the safe value they would hold. Calls `each` with the
    /// index of each one in the I/O map, and returns how many there are. Allocates nothing.
    pub(crate) fn differing(
        &self,
        slot: usize,
        outputs: &[Value],
        mut each: impl FnMut(usize),
    ) -> u32 {
        let mut n = 0;
        for (j, (m, now)) in self.out_maps[slot].iter().zip(&self.dispatched).enumerate() {
            let would = match m {
                Some(k) => outputs.get(*k).copied(),
                None => self.held.get(j).copied(),
            };
            if would.is_some_and(|v| v != *now) {
                n += 1;
                each(j);
            }
        }
        n
    }

    /// Hands the safe values to the Dispatcher (fault).
    pub(crate) fn dispatch_safe<D: Dispatcher + ?Sized>(&mut self, now_us: u64, io: &mut D) {
        io.write_outputs(now_us, &self.safe);
        self.dispatched.copy_from_slice(&self.safe);
        self.dispatched_bits.set_from(&self.safe);
    }

    /// The input image of the last cycle as container `slot` reads it, through its input map:
    /// what a program that takes over from another continues its edge detection from.
    pub(crate) fn last_inputs_for(&self, slot: usize) -> impl Iterator<Item = Value> + '_ {
        self.in_maps[slot].iter().map(|&j| self.inputs[j])
    }

    /// Every image is rebuilt at the next scan (the inputs moved on while nothing scanned).
    pub(crate) fn mark_all_stale(&mut self) {
        self.stale = [true, true];
    }

    /// Container `slot`'s images are rebuilt at its next scan.
    pub(crate) fn mark_stale(&mut self, slot: usize) {
        self.stale[slot] = true;
    }

    /// Exchanges the safe values (I/O-map order) with those of the program in container `slot`,
    /// which now drives the outputs: the outputs it declares hold its safe values from now on,
    /// and those it lacks keep the safe value of the last program that declared them.
    pub(crate) fn drive_safe(&mut self, slot: usize, safe: &mut Vec<Value>) {
        std::mem::swap(&mut self.safe, safe);
        self.safe_generation += 1;
        for (j, m) in self.out_maps[slot].iter().enumerate() {
            match (m, self.safe.get_mut(j)) {
                (Some(_), Some(v)) => self.held[j] = *v,
                (None, Some(v)) => *v = self.held[j],
                (_, None) => {}
            }
        }
    }

    /// The outputs' safe values (I/O-map order): the driving program's, and the held values of
    /// the outputs it lacks.
    pub fn safe(&self) -> &[Value] {
        &self.safe
    }

    /// Changes whenever [`MessageRouter::safe`] does.
    pub(crate) fn safe_generation(&self) -> u64 {
        self.safe_generation
    }

    /// Per output of the I/O map, what it holds when no program drives it: the safe value of
    /// the last program that declared it, or false/0.
    pub fn held(&self) -> &[Value] {
        &self.held
    }

    /// Input names of the I/O map.
    pub fn io_inputs(&self) -> &[String] {
        &self.io_inputs
    }
    /// Output names of the I/O map.
    pub fn io_outputs(&self) -> &[String] {
        &self.io_outputs
    }
    /// The input image of the last cycle.
    pub fn inputs(&self) -> &[Value] {
        &self.inputs
    }
    /// Takes `image` as the input image of the last cycle (a PLC resumed on a fork of another
    /// one's state: what that PLC read last). Ignored unless it has the I/O map's length.
    pub(crate) fn set_last_inputs(&mut self, image: &[Value]) {
        if image.len() == self.inputs.len() {
            self.inputs.copy_from_slice(image);
            self.in_bits.set_from(&self.inputs);
            self.stale = [true, true];
        }
    }
    /// The input image of the cycle before.
    pub fn prev_inputs(&self) -> &[Value] {
        &self.prev_inputs
    }
    /// The inputs changed in the last cycle.
    pub fn inputs_changed(&self) -> bool {
        self.inputs_changed
    }
    /// What the Dispatcher got in the last cycle.
    pub fn dispatched(&self) -> &[Value] {
        &self.dispatched
    }
    /// Container `slot`'s outputs in I/O-map order.
    pub fn outputs(&self, slot: usize) -> &[Value] {
        &self.outs[slot]
    }
    /// The inputs as a bit mask.
    pub fn input_bits(&self) -> &Mask {
        &self.in_bits
    }
    /// Container `slot`'s outputs as a bit mask.
    pub fn output_bits(&self, slot: usize) -> &Mask {
        &self.out_bits[slot]
    }
    /// What the Dispatcher got in the last cycle, as a bit mask.
    pub fn dispatched_bits(&self) -> &Mask {
        &self.dispatched_bits
    }
    /// Every output is boolean: bit masks compare the outputs whole.
    pub fn bool_outputs(&self) -> bool {
        self.bool_outputs
    }
}
