//! The translation of one piece of code into Cranelift's IR, instruction by instruction, with the
//! interpreter's semantics (`crate::vm`): the same wrapping at each type's width, the same
//! promotion of the small integers, the same IEEE operations, the same checks and faults.
//!
//! Slots live in memory, and in a straight run of code their values live in registers: a slot's
//! value, once loaded or computed, is reused from its register until something may have written
//! the slot (an instruction handed back, an indirect store) or control may have come from
//! elsewhere (a jump's target). A value computed is stored to its slot only when memory must be
//! whole: before a jump, an instruction handed back to the interpreter, an indirect access, the
//! end, and on the way out of a fault, so that whoever reads the state then (the interpreter, the
//! next scan, the fault's reader) finds every value where the interpreter would have left it; a
//! temporary overwritten before that is never stored at all.

use std::collections::HashMap;

use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{
    types, AbiParam, Block, Function, InstBuilder, MemFlagsData, SigRef, Signature, Value,
};
use cranelift_codegen::isa::TargetIsa;
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Variable};

use super::offset;
use crate::ast::Rel;
use crate::code::{Arith, Code, Op, Slot};
use crate::types::Elem;
use crate::vm::{promote, signed_order};

mod stdfb;

/// The largest slot index whose byte offset fits the 32-bit offset of a load.
const FARTHEST: Slot = (i32::MAX / 8) as Slot;

/// Translates `code` into `func` (whose signature is set): one past the largest fixed slot index
/// the generated code reads or writes, or `None` when the code cannot be translated here.
pub(super) fn lower(code: &Code, func: &mut Function, isa: &dyn TargetIsa) -> Option<usize> {
    let past_end = code.ops.iter().any(|op| match *op {
        Op::Jump { to }
        | Op::JumpIf { to, .. }
        | Op::JumpUnless { to, .. }
        | Op::Loop { to, .. } => to as usize > code.ops.len(),
        _ => false,
    });
    if isa.pointer_type() != types::I64 || past_end {
        return None;
    }
    let mut fctx = FunctionBuilderContext::new();
    let mut b = FunctionBuilder::new(func, &mut fctx);
    let mut l = Lower::start(&mut b, code, isa);
    for (pc, &op) in code.ops.iter().enumerate() {
        l.at(pc);
        l.op(pc, op);
    }
    let (needs, too_far) = l.finish();
    b.seal_all_blocks();
    b.finalize(isa.frontend_config());
    (!too_far).then_some(needs)
}

/// The translation under way.
struct Lower<'a, 'f> {
    b: &'a mut FunctionBuilder<'f>,
    code: &'a Code,
    /// The frame, the slots' base address, their number, the budget and the call back.
    frame: Value,
    base: Value,
    len: Value,
    budget: Value,
    back: Value,
    /// The scan's time, in nanoseconds.
    now: Value,
    back_sig: SigRef,
    /// Work charged so far.
    used: Variable,
    /// The block that starts at each jump's target (the end included).
    blocks: HashMap<usize, Block>,
    /// The value each slot holds, where it is known in a register, and whether it is stored.
    known: HashMap<Slot, (Value, bool)>,
    /// The slots whose known value is not stored yet, in the order they were first written.
    dirty: Vec<Slot>,
    /// Blocks that leave with a fault at an instruction: the block, the instruction, whether the
    /// instruction is first handed to the interpreter, and the values to store on the way out.
    fails: Vec<Fail>,
    needs: usize,
    too_far: bool,
}

/// A way out with a fault.
struct Fail {
    block: Block,
    pc: usize,
    hand_back: bool,
    stores: Vec<(Slot, Value)>,
}

const TRUSTED: MemFlagsData = MemFlagsData::trusted();

impl<'a, 'f> Lower<'a, 'f> {
    /// The entry block: the frame's fields loaded, a block made for each jump's target.
    fn start(b: &'a mut FunctionBuilder<'f>, code: &'a Code, isa: &dyn TargetIsa) -> Self {
        let entry = b.create_block();
        b.append_block_params_for_function_params(entry);
        b.switch_to_block(entry);
        let frame = b.block_params(entry)[0];
        let load = |b: &mut FunctionBuilder<'f>, at| b.ins().load(types::I64, TRUSTED, frame, at);
        let base = load(b, offset::SLOTS);
        let len = load(b, offset::LEN);
        let used0 = load(b, offset::USED);
        let budget = load(b, offset::BUDGET);
        let back = load(b, offset::BACK);
        let now = load(b, offset::NOW);
        let used = b.declare_var(types::I64);
        b.def_var(used, used0);
        let mut sig = Signature::new(isa.default_call_conv());
        sig.params.push(AbiParam::new(types::I64));
        sig.params.push(AbiParam::new(types::I64));
        sig.returns.push(AbiParam::new(types::I64));
        let back_sig = b.import_signature(sig);
        let mut blocks = HashMap::new();
        for op in &code.ops {
            if let Op::Jump { to }
            | Op::JumpIf { to, .. }
            | Op::JumpUnless { to, .. }
            | Op::Loop { to, .. } = *op
            {
                blocks
                    .entry(to as usize)
                    .or_insert_with(|| b.create_block());
            }
        }
        Lower {
            b,
            code,
            frame,
            base,
            len,
            budget,
            back,
            now,
            back_sig,
            used,
            blocks,
            known: HashMap::new(),
            dirty: Vec::new(),
            fails: Vec::new(),
            needs: 0,
            too_far: false,
        }
    }

    /// Before instruction `pc`: when a jump goes there, a new block that the code so far falls
    /// into, where nothing is known of the slots.
    fn at(&mut self, pc: usize) {
        if let Some(&block) = self.blocks.get(&pc) {
            self.flush();
            self.b.ins().jump(block, &[]);
            self.b.switch_to_block(block);
            self.known.clear();
        }
    }

    /// The end: the code returns 0, and each fault block returns its instruction plus one.
    fn finish(mut self) -> (usize, bool) {
        let end = self.code.ops.len();
        self.at(end);
        // What is still not stored is temporaries, which nothing reads after the run.
        self.dirty.clear();
        let zero = self.b.ins().iconst(types::I64, 0);
        self.leave(zero);
        for fail in std::mem::take(&mut self.fails) {
            self.b.switch_to_block(fail.block);
            for (s, v) in fail.stores {
                self.store(s, v);
            }
            if fail.hand_back {
                self.call_back(fail.pc);
            }
            let status = self.b.ins().iconst(types::I64, fail.pc as i64 + 1);
            self.leave(status);
        }
        (self.needs, self.too_far)
    }

    /// Stores the work charged and returns `status`.
    fn leave(&mut self, status: Value) {
        let used = self.b.use_var(self.used);
        self.b.ins().store(TRUSTED, used, self.frame, offset::USED);
        self.b.ins().return_(&[status]);
    }

    /// After an unconditional jump: a block that nothing reaches, for the code that follows up
    /// to the next target.
    fn fresh(&mut self) {
        let block = self.b.create_block();
        self.b.switch_to_block(block);
        self.known.clear();
    }

    /// Goes on when `ok` is non-zero; else leaves with a fault at `pc`, storing what is not
    /// stored yet.
    fn fail_unless(&mut self, ok: Value, pc: usize, hand_back: bool) {
        let block = self.b.create_block();
        self.b.set_cold_block(block);
        let stores = self.dirty.iter().map(|s| (*s, self.known[s].0)).collect();
        self.fails.push(Fail {
            block,
            pc,
            hand_back,
            stores,
        });
        let next = self.b.create_block();
        self.b.ins().brif(ok, next, &[], block, &[]);
        self.b.switch_to_block(next);
    }

    /// Stores every value not stored yet.
    fn flush(&mut self) {
        for s in std::mem::take(&mut self.dirty) {
            if let Some((v, stored)) = self.known.get_mut(&s) {
                *stored = true;
                let v = *v;
                self.store(s, v);
            }
        }
    }

    /// `v` into slot `s`'s memory.
    fn store(&mut self, s: Slot, v: Value) {
        let at = self.offset(s);
        self.b.ins().store(TRUSTED, v, self.base, at);
    }

    /// Slot `s`'s value.
    fn get(&mut self, s: Slot) -> Value {
        if let Some(&(v, _)) = self.known.get(&s) {
            return v;
        }
        let at = self.offset(s);
        let v = self.b.ins().load(types::I64, TRUSTED, self.base, at);
        self.known.insert(s, (v, true));
        v
    }

    /// `v` into slot `s`: stored at once, and known in a register for the instructions that
    /// read it next. A temporary is only kept in the register, and stored by the next
    /// [`Lower::flush`], where the code jumps, hands an instruction back or faults; what nothing
    /// reads after the run is never stored.
    fn set(&mut self, s: Slot, v: Value) {
        if !self.code.is_temp(s) {
            self.store(s, v);
            self.known.insert(s, (v, true));
            return;
        }
        self.offset(s);
        let pending = self
            .known
            .insert(s, (v, false))
            .is_some_and(|(_, stored)| !stored);
        if !pending {
            self.dirty.push(s);
        }
    }

    /// The byte offset of slot `s`, recorded among the slots the code needs.
    fn offset(&mut self, s: Slot) -> i32 {
        self.needs = self.needs.max(s as usize + 1);
        if s > FARTHEST {
            self.too_far = true;
            return 0;
        }
        (s * 8) as i32
    }

    /// Hands instruction `pc` to the interpreter: its result, 0 when it went through.
    fn call_back(&mut self, pc: usize) -> Value {
        let pc = self.b.ins().iconst(types::I64, pc as i64);
        let call = self
            .b
            .ins()
            .call_indirect(self.back_sig, self.back, &[self.frame, pc]);
        self.b.inst_results(call)[0]
    }

    /// Instruction `pc` on the interpreter, in line: a fault leaves; what it may have written is
    /// no longer known.
    fn slow(&mut self, pc: usize, op: Op) {
        self.flush();
        let r = self.call_back(pc);
        let ok = self.b.ins().icmp_imm_s(IntCC::Equal, r, 0);
        self.fail_unless(ok, pc, false);
        match written(op) {
            Written::Nothing => {}
            Written::One(s) => {
                self.known.remove(&s);
            }
            Written::Span(s, n) => self
                .known
                .retain(|k, _| !(s..s.saturating_add(n)).contains(k)),
            Written::Any => self.known.clear(),
        }
    }

    /// One instruction.
    fn op(&mut self, pc: usize, op: Op) {
        match op {
            Op::Const { dst, bits } => {
                let v = self.b.ins().iconst(types::I64, bits as i64);
                self.set(dst, v);
            }
            Op::Move { dst, src } => {
                let v = self.get(src);
                self.set(dst, v);
            }
            Op::Arith {
                op: f,
                e,
                dst,
                a,
                b,
            } if !e.is_real() => self.int_arith(pc, f, e, dst, a, b),
            Op::Arith {
                op: f,
                e,
                dst,
                a,
                b,
            } if real_inline(f) => self.real_arith(f, e, dst, a, b),
            Op::Cmp {
                op: r,
                e,
                dst,
                a,
                b,
            } => self.compare(r, e, dst, a, b),
            Op::Neg { e, dst, a } => {
                let x = self.get(a);
                let v = match e.is_real() {
                    true => {
                        let f = self.real(e, x);
                        let n = self.b.ins().fneg(f);
                        self.bits(e, n)
                    }
                    false => {
                        let n = self.b.ins().ineg(x);
                        self.wrap(promote(e), n)
                    }
                };
                self.set(dst, v);
            }
            Op::Not { e, dst, a } => {
                let x = self.get(a);
                let v = match e {
                    Elem::Bool => {
                        let c = self.b.ins().icmp_imm_s(IntCC::Equal, x, 0);
                        self.b.ins().uextend(types::I64, c)
                    }
                    _ => {
                        let n = self.b.ins().bnot(x);
                        self.wrap(promote(e), n)
                    }
                };
                self.set(dst, v);
            }
            Op::Conv { from, to, dst, a } if conv_inline(from, to) => {
                self.convert(from, to, dst, a)
            }
            Op::Select { dst, c, a, b } => {
                let (c, a, b) = (self.get(c), self.get(a), self.get(b));
                let v = self.b.ins().select(c, a, b);
                self.set(dst, v);
            }
            Op::Jump { to } => {
                self.flush();
                let block = self.blocks[&(to as usize)];
                self.b.ins().jump(block, &[]);
                self.fresh();
            }
            Op::JumpIf { c, to } | Op::JumpUnless { c, to } => {
                let v = self.get(c);
                self.flush();
                let (target, next) = (self.blocks[&(to as usize)], self.b.create_block());
                match matches!(op, Op::JumpIf { .. }) {
                    true => self.b.ins().brif(v, target, &[], next, &[]),
                    false => self.b.ins().brif(v, next, &[], target, &[]),
                };
                self.b.switch_to_block(next);
            }
            Op::Loop { to, cost } => self.charge(pc, to, cost),
            Op::StdFb { fb, base } => self.std_fb(fb, base),
            _ => self.addressing(pc, op),
        }
    }

    /// The instructions that compute and use slot addresses, and the rest, handed back.
    fn addressing(&mut self, pc: usize, op: Op) {
        match op {
            Op::Index {
                e,
                acc,
                idx,
                lo,
                len,
            } => {
                let at = self.bounded(pc, e, idx, lo, len);
                let a = self.get(acc);
                let m = self.b.ins().imul_imm_s(a, i64::from(len));
                let v = self.b.ins().iadd(m, at);
                self.set(acc, v);
            }
            Op::Index1 {
                e,
                dst,
                idx,
                lo,
                len,
                base,
            } => {
                let at = self.bounded(pc, e, idx, lo, len);
                let v = self.b.ins().iadd_imm_s(at, i64::from(base));
                self.set(dst, v);
            }
            Op::Addr {
                dst,
                lin,
                stride,
                base,
            } => {
                let l = self.get(lin);
                let m = self.b.ins().imul_imm_s(l, i64::from(stride));
                let v = self.b.ins().iadd_imm_s(m, i64::from(base));
                self.set(dst, v);
            }
            Op::LoadInd { dst, addr, off } => {
                let at = self.indirect(pc, addr, off);
                let v = self.b.ins().load(types::I64, TRUSTED, at, 0);
                self.set(dst, v);
            }
            Op::StoreInd { addr, off, src } => {
                let v = self.get(src);
                let at = self.indirect(pc, addr, off);
                self.b.ins().store(TRUSTED, v, at, 0);
                self.known.clear();
            }
            _ => self.slow(pc, op),
        }
    }

    /// The address of slot `slots[addr] + off`, after checking that it is a slot of the state;
    /// past the state, the instruction is handed to the interpreter, whose slice index panics.
    fn indirect(&mut self, pc: usize, addr: Slot, off: u32) -> Value {
        let a = self.get(addr);
        self.flush();
        let i = self.b.ins().iadd_imm_s(a, i64::from(off));
        let inside = self.b.ins().icmp(IntCC::UnsignedLessThan, i, self.len);
        self.fail_unless(inside, pc, true);
        let bytes = self.b.ins().ishl_imm_s(i, 3);
        self.b.ins().iadd(self.base, bytes)
    }

    /// `idx - lo`, after checking `lo <= idx < lo + len` as `crate::vm::index` does; out of
    /// bounds leaves with a fault.
    fn bounded(&mut self, pc: usize, e: Elem, idx: Slot, lo: i32, len: u32) -> Value {
        let i = self.get(idx);
        let (lo, hi) = (i64::from(lo), i64::from(lo) + i64::from(len) - 1);
        let ge = self
            .b
            .ins()
            .icmp_imm_s(IntCC::SignedGreaterThanOrEqual, i, lo);
        let le = self.b.ins().icmp_imm_s(IntCC::SignedLessThanOrEqual, i, hi);
        let mut ok = self.b.ins().band(ge, le);
        if !(e.is_signed() || e == Elem::Bool) {
            // An unsigned index past `i64::MAX` is out of every bound.
            let small = self
                .b
                .ins()
                .icmp_imm_s(IntCC::SignedGreaterThanOrEqual, i, 0);
            ok = self.b.ins().band(ok, small);
        }
        self.fail_unless(ok, pc, false);
        self.b.ins().iadd_imm_s(i, -lo)
    }

    /// The backward jump of a loop: charges `cost`, or leaves with a fault when the budget
    /// would be passed.
    fn charge(&mut self, pc: usize, to: u32, cost: u32) {
        self.flush();
        let used = self.b.use_var(self.used);
        let left = self.b.ins().isub(self.budget, used);
        let ok = self
            .b
            .ins()
            .icmp_imm_s(IntCC::UnsignedGreaterThanOrEqual, left, i64::from(cost));
        self.fail_unless(ok, pc, false);
        let used = self.b.ins().iadd_imm_s(used, i64::from(cost));
        self.b.def_var(self.used, used);
        let block = self.blocks[&(to as usize)];
        self.b.ins().jump(block, &[]);
        self.fresh();
    }

    /// An integer operation, as `crate::vm::int_op`.
    fn int_arith(&mut self, pc: usize, f: Arith, e: Elem, dst: Slot, a: Slot, b: Slot) {
        let (x, y) = (self.get(a), self.get(b));
        let signed = e.is_signed();
        let v = match f {
            Arith::Add => self.b.ins().iadd(x, y),
            Arith::Sub => self.b.ins().isub(x, y),
            Arith::Mul => self.b.ins().imul(x, y),
            Arith::And => self.b.ins().band(x, y),
            Arith::Or => self.b.ins().bor(x, y),
            Arith::Xor => self.b.ins().bxor(x, y),
            Arith::Div => self.divide(pc, signed, x, y),
            Arith::Mod => self.modulo(signed, x, y),
            // The interpreter's `**` on integers gives its first operand, unwrapped.
            Arith::Pow => return self.set(dst, x),
            Arith::Max | Arith::Min => {
                let cc = match (f == Arith::Max, signed_order(e)) {
                    (true, true) => IntCC::SignedGreaterThan,
                    (true, false) => IntCC::UnsignedGreaterThan,
                    (false, true) => IntCC::SignedLessThan,
                    (false, false) => IntCC::UnsignedLessThan,
                };
                let c = self.b.ins().icmp(cc, x, y);
                self.b.ins().select(c, x, y)
            }
        };
        let v = self.wrap(promote(e), v);
        self.set(dst, v);
    }

    /// `x / y`: a division by zero leaves with a fault; `MIN / -1` wraps, as Rust's
    /// `wrapping_div`, where the machine's division would trap.
    fn divide(&mut self, pc: usize, signed: bool, x: Value, y: Value) -> Value {
        let nonzero = self.b.ins().icmp_imm_s(IntCC::NotEqual, y, 0);
        self.fail_unless(nonzero, pc, false);
        if !signed {
            return self.b.ins().udiv(x, y);
        }
        let minus_one = self.b.ins().icmp_imm_s(IntCC::Equal, y, -1);
        let one = self.b.ins().iconst(types::I64, 1);
        let safe = self.b.ins().select(minus_one, one, y);
        let q = self.b.ins().sdiv(x, safe);
        let n = self.b.ins().ineg(x);
        self.b.ins().select(minus_one, n, q)
    }

    /// `x MOD y`: 0 by zero (MATIEC's MOD), and by -1, where the machine's remainder would trap.
    fn modulo(&mut self, signed: bool, x: Value, y: Value) -> Value {
        let mut zero_result = self.b.ins().icmp_imm_s(IntCC::Equal, y, 0);
        if signed {
            let minus_one = self.b.ins().icmp_imm_s(IntCC::Equal, y, -1);
            zero_result = self.b.ins().bor(zero_result, minus_one);
        }
        let one = self.b.ins().iconst(types::I64, 1);
        let safe = self.b.ins().select(zero_result, one, y);
        let r = match signed {
            true => self.b.ins().srem(x, safe),
            false => self.b.ins().urem(x, safe),
        };
        let zero = self.b.ins().iconst(types::I64, 0);
        self.b.ins().select(zero_result, zero, r)
    }

    /// A REAL or LREAL `+ - * /`, MAX or MIN. REAL is computed in `f32`: the interpreter
    /// computes it in `f64` and rounds, which gives the same `f32` for these four operations
    /// (`crate::vm::real_op`).
    fn real_arith(&mut self, f: Arith, e: Elem, dst: Slot, a: Slot, b: Slot) {
        let (x, y) = (self.get(a), self.get(b));
        let (x, y) = (self.real(e, x), self.real(e, y));
        let r = match f {
            Arith::Add => self.b.ins().fadd(x, y),
            Arith::Sub => self.b.ins().fsub(x, y),
            Arith::Mul => self.b.ins().fmul(x, y),
            Arith::Div => self.b.ins().fdiv(x, y),
            // MATIEC's `x < y ? y : x` and `x > y ? y : x`.
            _ => {
                let cc = match f == Arith::Max {
                    true => FloatCC::LessThan,
                    false => FloatCC::GreaterThan,
                };
                let c = self.b.ins().fcmp(cc, x, y);
                self.b.ins().select(c, y, x)
            }
        };
        let v = self.bits(e, r);
        self.set(dst, v);
    }

    /// A comparison, as `crate::vm::compare` and `Rel::holds_partial`.
    fn compare(&mut self, r: Rel, e: Elem, dst: Slot, a: Slot, b: Slot) {
        let (x, y) = (self.get(a), self.get(b));
        let c = if e.is_real() {
            let (x, y) = (self.real(e, x), self.real(e, y));
            let cc = match r {
                Rel::Lt => FloatCC::LessThan,
                Rel::Gt => FloatCC::GreaterThan,
                Rel::Le => FloatCC::LessThanOrEqual,
                Rel::Ge => FloatCC::GreaterThanOrEqual,
                Rel::Eq => FloatCC::Equal,
                Rel::Ne => FloatCC::NotEqual,
            };
            self.b.ins().fcmp(cc, x, y)
        } else {
            let signed = signed_order(e);
            let cc = match r {
                Rel::Lt if signed => IntCC::SignedLessThan,
                Rel::Gt if signed => IntCC::SignedGreaterThan,
                Rel::Le if signed => IntCC::SignedLessThanOrEqual,
                Rel::Ge if signed => IntCC::SignedGreaterThanOrEqual,
                Rel::Lt => IntCC::UnsignedLessThan,
                Rel::Gt => IntCC::UnsignedGreaterThan,
                Rel::Le => IntCC::UnsignedLessThanOrEqual,
                Rel::Ge => IntCC::UnsignedGreaterThanOrEqual,
                Rel::Eq => IntCC::Equal,
                Rel::Ne => IntCC::NotEqual,
            };
            self.b.ins().icmp(cc, x, y)
        };
        let v = self.b.ins().uextend(types::I64, c);
        self.set(dst, v);
    }

    /// The conversions [`conv_inline`] admits, as `crate::vm::convert`.
    fn convert(&mut self, from: Elem, to: Elem, dst: Slot, a: Slot) {
        let x = self.get(a);
        let v = match (from, to) {
            (Elem::Lreal, Elem::Real) | (Elem::Real, Elem::Lreal) => {
                let f = self.real(from, x);
                let g = match to {
                    Elem::Real => self.b.ins().fdemote(types::F32, f),
                    _ => self.b.ins().fpromote(types::F64, f),
                };
                self.bits(to, g)
            }
            (_, Elem::Real | Elem::Lreal) if from.is_signed() => {
                let g = self.b.ins().fcvt_from_sint(float_type(to), x);
                self.bits(to, g)
            }
            (_, Elem::Real | Elem::Lreal) => x,
            (_, Elem::Bool) if from.is_real() => {
                let f = self.real(from, x);
                let zero = match from {
                    Elem::Real => self.b.ins().f32const(0.0),
                    _ => self.b.ins().f64const(0.0),
                };
                let c = self.b.ins().fcmp(FloatCC::NotEqual, f, zero);
                self.b.ins().uextend(types::I64, c)
            }
            (_, Elem::Bool) => {
                let c = self.b.ins().icmp_imm_s(IntCC::NotEqual, x, 0);
                self.b.ins().uextend(types::I64, c)
            }
            _ => self.wrap(to, x),
        };
        self.set(dst, v);
    }

    /// The slot value `v` as the float of REAL or LREAL `e`.
    fn real(&mut self, e: Elem, v: Value) -> Value {
        match e {
            Elem::Real => {
                let low = self.b.ins().ireduce(types::I32, v);
                self.b.ins().bitcast(types::F32, MemFlagsData::new(), low)
            }
            _ => self.b.ins().bitcast(types::F64, MemFlagsData::new(), v),
        }
    }

    /// The float `f` of REAL or LREAL `e` as a slot value.
    fn bits(&mut self, e: Elem, f: Value) -> Value {
        match e {
            Elem::Real => {
                let low = self.b.ins().bitcast(types::I32, MemFlagsData::new(), f);
                self.b.ins().uextend(types::I64, low)
            }
            _ => self.b.ins().bitcast(types::I64, MemFlagsData::new(), f),
        }
    }

    /// `v` cut to the width of `e`, as [`crate::types::wrap`].
    fn wrap(&mut self, e: Elem, v: Value) -> Value {
        let sign = |l: &mut Self, t| {
            let low = l.b.ins().ireduce(t, v);
            l.b.ins().sextend(types::I64, low)
        };
        match e {
            Elem::Sint => sign(self, types::I8),
            Elem::Int => sign(self, types::I16),
            Elem::Dint => sign(self, types::I32),
            Elem::Usint | Elem::Byte => self.b.ins().band_imm_s(v, 0xff),
            Elem::Uint | Elem::Word => self.b.ins().band_imm_s(v, 0xffff),
            Elem::Udint | Elem::Dword => self.b.ins().band_imm_s(v, 0xffff_ffff),
            Elem::Bool => {
                let c = self.b.ins().icmp_imm_s(IntCC::NotEqual, v, 0);
                self.b.ins().uextend(types::I64, c)
            }
            _ => v,
        }
    }
}

/// Cranelift's type for REAL or LREAL.
fn float_type(e: Elem) -> types::Type {
    match e {
        Elem::Real => types::F32,
        _ => types::F64,
    }
}

/// Whether a REAL operation is translated: `**` calls `pow`, and the others do not apply to
/// reals (the interpreter gives the first operand).
fn real_inline(f: Arith) -> bool {
    matches!(
        f,
        Arith::Add | Arith::Sub | Arith::Mul | Arith::Div | Arith::Max | Arith::Min
    )
}

/// Whether a conversion is translated, not handed back: not to or from TIME (milliseconds), not
/// from a real to an integer (MATIEC's rounding), not from an unsigned integer to a real (Rust's
/// rounding of `u64 as f32`, which the machine has no one instruction for).
fn conv_inline(from: Elem, to: Elem) -> bool {
    let time = (from == Elem::Time) != (to == Elem::Time);
    let to_int = !to.is_real() && to != Elem::Bool;
    let to_real_unsigned = to.is_real() && !from.is_real() && !from.is_signed();
    let real_to_int = from.is_real() && to_int;
    !(time || real_to_int || to_real_unsigned)
}

/// What an instruction handed back may write among the slots.
enum Written {
    Nothing,
    One(Slot),
    Span(Slot, u32),
    Any,
}

fn written(mut op: Op) -> Written {
    if let Some(dst) = op.result_mut() {
        return Written::One(*dst);
    }
    match op {
        Op::Index { acc, .. } => Written::One(acc),
        Op::Copy { dst, len, .. } | Op::CopyFromInd { dst, len, .. } => Written::Span(dst, len),
        Op::CopyText { .. }
        | Op::TextFromInd { .. }
        | Op::TextToInd { .. }
        | Op::StrLit { .. }
        | Op::StrMove { .. }
        | Op::ToStr { .. }
        | Op::Str { .. }
        | Op::Jump { .. }
        | Op::JumpIf { .. }
        | Op::JumpUnless { .. }
        | Op::Loop { .. } => Written::Nothing,
        // Stores through an address, and whatever is handed back later: the answer that is
        // always safe.
        _ => Written::Any,
    }
}
