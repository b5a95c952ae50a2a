//! Runs compiled code on a program's state: one pass over the instructions per call, no
//! allocation, and every backward jump paid for out of the work budget, so that no program can
//! hold the scan thread longer than its budget allows.
//!
//! The arithmetic is IEC 61131-3's as MATIEC compiles it (docs/st.md): integers wrap at their
//! type's width; REAL is `f32` and LREAL `f64`; the functions of one REAL (SQRT, SIN, `**` …)
//! are computed in `f64` and rounded to `f32`, as MATIEC's C calls `sqrt` and `pow` on doubles.

use std::cmp::Ordering;

use crate::code::{Arith, Code, FaultKind, MathFn, Op, ShiftFn, StrArgs, StrFn};
use crate::types::{wrap, Elem};
use crate::work::Work;

/// The state of a compiled program: its slots and its text (module doc of `types`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct State {
    /// One `u64` per elementary value and temporary.
    pub slots: Vec<u64>,
    /// The bytes of the strings.
    pub text: Vec<u8>,
}

/// A run that stopped: what happened, and where in the source.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fault {
    /// What happened.
    pub kind: FaultKind,
    /// The byte offset in the source of the instruction that faulted.
    pub pos: u32,
}

/// Runs `code` once on `state` at time `now` (nanoseconds), charging `work`. On a fault the
/// state holds what the code had written up to the fault.
pub fn run(
    code: &Code,
    cost: u64,
    state: &mut State,
    now: i64,
    work: &mut Work,
) -> Result<(), Fault> {
    let fault = |pc: usize, kind| Fault {
        kind,
        pos: code.pos.get(pc).copied().unwrap_or(0),
    };
    if !work.charge(cost) {
        return Err(fault(0, FaultKind::Budget));
    }
    let s = &mut state.slots[..];
    let t = &mut state.text[..];
    let mut pc = 0usize;
    while let Some(op) = code.ops.get(pc) {
        pc += 1;
        match exec(op, code, s, t, now, work) {
            Flow::Next => {}
            Flow::Goto(to) => pc = to as usize,
            Flow::Fault => return Err(fault(pc - 1, fault_of(*op, s))),
        }
    }
    Ok(())
}

/// Where the code goes after an instruction.
pub(crate) enum Flow {
    /// To the next instruction.
    Next,
    /// To this one.
    Goto(u32),
    /// Nowhere: the instruction faulted, and wrote nothing; [`fault_of`] says why.
    Fault,
}

/// Runs one instruction: the body of [`run`]'s loop (one match, one dispatch an instruction), and
/// what machine code calls for the instructions it does not compile itself (`jit`). A loop's
/// backward jump charges `work`. (The fault is read back by [`fault_of`], not returned: a small
/// [`Flow`] comes back in registers, and the instructions that cannot fault pay nothing for it.)
#[inline(always)]
pub(crate) fn exec(
    op: &Op,
    code: &Code,
    s: &mut [u64],
    t: &mut [u8],
    now: i64,
    work: &mut Work,
) -> Flow {
    match *op {
        Op::Const { dst, bits } => s[dst as usize] = bits,
        Op::Move { dst, src } => s[dst as usize] = s[src as usize],
        Op::Copy { dst, src, len } => copy_slots(s, dst, src, len),
        Op::CopyText { dst, src, len } => copy_text(t, dst, src, len),
        Op::Arith { op, e, dst, a, b } => match arith(op, e, s[a as usize], s[b as usize]) {
            Ok(v) => s[dst as usize] = v,
            Err(_) => return Flow::Fault,
        },
        Op::Cmp { op, e, dst, a, b } => {
            s[dst as usize] = op.holds_partial(compare(e, s[a as usize], s[b as usize])) as u64
        }
        Op::Neg { e, dst, a } => s[dst as usize] = neg(e, s[a as usize]),
        Op::Not { e, dst, a } => {
            s[dst as usize] = match e {
                Elem::Bool => u64::from(s[a as usize] == 0),
                _ => wrap(promote(e), !s[a as usize]),
            }
        }
        Op::Conv { from, to, dst, a } => s[dst as usize] = convert(from, to, s[a as usize]),
        Op::Trunc { from, to, dst, a } => s[dst as usize] = trunc(from, to, s[a as usize]),
        Op::Math { f, e, dst, a } => s[dst as usize] = math(f, e, s[a as usize]),
        Op::Shift { f, e, dst, a, n } => {
            s[dst as usize] = shift(f, e, s[a as usize], s[n as usize])
        }
        Op::Select { dst, c, a, b } => {
            s[dst as usize] = if s[c as usize] != 0 {
                s[a as usize]
            } else {
                s[b as usize]
            }
        }
        Op::Index {
            e,
            acc,
            idx,
            lo,
            len,
        } => {
            let Ok(at) = index(e, s[idx as usize], lo, len) else {
                return Flow::Fault;
            };
            s[acc as usize] = s[acc as usize] * u64::from(len) + at;
        }
        Op::Index1 {
            e,
            dst,
            idx,
            lo,
            len,
            base,
        } => {
            let Ok(at) = index(e, s[idx as usize], lo, len) else {
                return Flow::Fault;
            };
            s[dst as usize] = u64::from(base) + at;
        }
        Op::Addr {
            dst,
            lin,
            stride,
            base,
        } => s[dst as usize] = u64::from(base) + s[lin as usize] * u64::from(stride),
        Op::LoadInd { dst, addr, off } => s[dst as usize] = s[ind(s, addr, off)],
        Op::StoreInd { addr, off, src } => s[ind(s, addr, off)] = s[src as usize],
        Op::CopyFromInd {
            dst,
            addr,
            off,
            len,
        } => copy_slots(s, dst, ind(s, addr, off) as u32, len),
        Op::CopyToInd {
            addr,
            off,
            src,
            len,
        } => copy_slots(s, ind(s, addr, off) as u32, src, len),
        Op::TextFromInd {
            dst,
            addr,
            off,
            len,
        } => copy_text(t, dst, ind(s, addr, off) as u32, len),
        Op::TextToInd {
            addr,
            off,
            src,
            len,
        } => copy_text(t, ind(s, addr, off) as u32, src, len),
        Op::StrLit { .. }
        | Op::StrMove { .. }
        | Op::StrLen { .. }
        | Op::FromStr { .. }
        | Op::StrFind { .. }
        | Op::StrCmp { .. }
        | Op::Str { .. }
        | Op::ToStr { .. } => text_op(*op, code, s, t),
        Op::TimeScale { div, dst, a, f } => {
            let factor = f64::from_bits(s[f as usize]);
            s[dst as usize] = crate::format::time_scale(div, s[a as usize] as i64, factor) as u64
        }
        Op::StdFb { fb, base } => fb.step(&mut s[base as usize..], now),
        Op::Jump { to } => return Flow::Goto(to),
        Op::JumpIf { c, to } if s[c as usize] != 0 => return Flow::Goto(to),
        Op::JumpUnless { c, to } if s[c as usize] == 0 => return Flow::Goto(to),
        Op::JumpIf { .. } | Op::JumpUnless { .. } => {}
        Op::Loop { to, cost } => {
            return match work.charge(u64::from(cost)) {
                true => Flow::Goto(to),
                false => Flow::Fault,
            }
        }
    }
    Flow::Next
}

/// Why `op` faulted, read from the state it left unwritten: a division by zero, an index out of
/// its bounds, or else (a loop's backward jump) the work budget.
#[cold]
pub(crate) fn fault_of(op: Op, s: &[u64]) -> FaultKind {
    let index_fault = |e, idx: u32, lo, len| {
        let i = s.get(idx as usize).copied().unwrap_or(0);
        index(e, i, lo, len).err()
    };
    let kind = match op {
        Op::Arith { .. } => Some(FaultKind::DivisionByZero),
        Op::Index {
            e, idx, lo, len, ..
        }
        | Op::Index1 {
            e, idx, lo, len, ..
        } => index_fault(e, idx, lo, len),
        _ => None,
    };
    kind.unwrap_or(FaultKind::Budget)
}

/// The instructions on strings, out of the dispatch loop: each moves up to a string's bytes,
/// so one call more is nothing beside its work.
fn text_op(op: Op, code: &Code, s: &mut [u64], t: &mut [u8]) {
    match op {
        Op::StrLit { dst, cap, lit } => set_str(t, dst, cap, &code.literals[lit as usize]),
        Op::StrMove { dst, cap, src } => str_move(t, dst, cap, src),
        Op::StrLen { e, dst, s: at } => s[dst as usize] = wrap(e, str_len(t, at) as u64),
        Op::FromStr { e, dst, s: at } => {
            s[dst as usize] = crate::format::from_text(e, str_of(t, at))
        }
        Op::StrFind { e, dst, a, b } => s[dst as usize] = wrap(e, find(str_of(t, a), str_of(t, b))),
        Op::StrCmp { op, dst, a, b } => {
            s[dst as usize] = op.holds(str_of(t, a).cmp(str_of(t, b))) as u64
        }
        Op::Str { f, args } => string_fn(f, &code.string_args[args as usize], s, t),
        Op::ToStr { e, dst, cap, a } => {
            let mut buf = [0u8; 48];
            let n = crate::format::iec_text(e, s[a as usize], &mut buf);
            set_str(t, dst, cap, &buf[..n]);
        }
        _ => {}
    }
}

/// The slot `slots[addr] + off`.
#[inline]
fn ind(s: &[u64], addr: u32, off: u32) -> usize {
    s[addr as usize] as usize + off as usize
}

#[inline]
fn copy_slots(s: &mut [u64], dst: u32, src: u32, len: u32) {
    let (dst, src, len) = (dst as usize, src as usize, len as usize);
    s.copy_within(src..src + len, dst);
}

#[inline]
fn copy_text(t: &mut [u8], dst: u32, src: u32, len: u32) {
    let (dst, src, len) = (dst as usize, src as usize, len as usize);
    t.copy_within(src..src + len, dst);
}

#[inline]
fn f32_of(v: u64) -> f32 {
    f32::from_bits(v as u32)
}

#[inline]
fn of_f32(x: f32) -> u64 {
    u64::from(x.to_bits())
}

/// `a op b` in type `e`; integer division and MOD as MATIEC's C: `/` truncates toward zero (a
/// division by zero faults, where C would trap), MOD by zero is 0 (MATIEC's `MOD` function).
/// `i - lo` for an index `i` of integer type `e`, when `lo <= i < lo + len`.
#[inline]
pub(crate) fn index(e: Elem, i: u64, lo: i32, len: u32) -> Result<u64, FaultKind> {
    let at = if e.is_signed() || e == Elem::Bool {
        (i as i64).checked_sub(i64::from(lo))
    } else {
        i64::try_from(i)
            .ok()
            .and_then(|i| i.checked_sub(i64::from(lo)))
    };
    match at {
        Some(at) if (0..i64::from(len)).contains(&at) => Ok(at as u64),
        _ => {
            let hi = (i64::from(lo) + i64::from(len) - 1) as i32;
            Err(FaultKind::IndexOutOfRange {
                index: i as i64,
                lo,
                hi,
            })
        }
    }
}

fn arith(op: Arith, e: Elem, a: u64, b: u64) -> Result<u64, FaultKind> {
    match e {
        Elem::Real => Ok(of_f32(
            real_op(op, f64::from(f32_of(a)), f64::from(f32_of(b))) as f32,
        )),
        Elem::Lreal => Ok(real_op(op, f64::from_bits(a), f64::from_bits(b)).to_bits()),
        _ => int_op(op, e, a, b),
    }
}

/// A REAL or LREAL operation in `f64`. For REAL the operands are exact in `f64`, and `+ - * /`
/// rounded to `f64` then to `f32` give the correctly rounded `f32` result (double rounding is
/// harmless when the wider type has more than twice the bits plus two), so one path serves
/// both; `**` is MATIEC's `pow` on doubles either way.
fn real_op(op: Arith, x: f64, y: f64) -> f64 {
    match op {
        Arith::Add => x + y,
        Arith::Sub => x - y,
        Arith::Mul => x * y,
        Arith::Div => x / y,
        Arith::Pow => x.powf(y),
        // MATIEC's `op1 = (op1 < tmp) ? tmp : op1`: with a NaN, the first operand.
        Arith::Max => {
            if x < y {
                y
            } else {
                x
            }
        }
        Arith::Min => {
            if x > y {
                y
            } else {
                x
            }
        }
        Arith::Mod | Arith::And | Arith::Or | Arith::Xor => x,
    }
}

fn int_op(op: Arith, e: Elem, a: u64, b: u64) -> Result<u64, FaultKind> {
    let signed = e.is_signed();
    let v = match op {
        Arith::Add => a.wrapping_add(b),
        Arith::Sub => a.wrapping_sub(b),
        Arith::Mul => a.wrapping_mul(b),
        Arith::Div if b == 0 => return Err(FaultKind::DivisionByZero),
        Arith::Div if signed => (a as i64).wrapping_div(b as i64) as u64,
        Arith::Div => a / b,
        Arith::Mod if b == 0 => 0,
        Arith::Mod if signed => (a as i64).wrapping_rem(b as i64) as u64,
        Arith::Mod => a % b,
        Arith::Pow => return Ok(a),
        Arith::And => a & b,
        Arith::Or => a | b,
        Arith::Xor => a ^ b,
        Arith::Max => {
            if compare(e, a, b) == Some(Ordering::Greater) {
                a
            } else {
                b
            }
        }
        Arith::Min => {
            if compare(e, a, b) == Some(Ordering::Less) {
                a
            } else {
                b
            }
        }
    };
    Ok(wrap(promote(e), v))
}

/// The type C computes `e` in: SINT … UINT, BYTE and WORD are promoted to a 32-bit `int`
/// (docs/st.md, *Operators*); the result is cut to `e` where it is stored.
#[inline]
pub(crate) fn promote(e: Elem) -> Elem {
    match e {
        Elem::Sint | Elem::Int | Elem::Usint | Elem::Uint | Elem::Byte | Elem::Word => Elem::Dint,
        e => e,
    }
}

/// Orders two values of type `e`; `None` for REALs that do not compare (a NaN), which
/// [`crate::code::Rel::holds_partial`] makes unequal and unordered: every comparison but `<>` is
/// false, as in C.
#[inline]
pub(crate) fn compare(e: Elem, a: u64, b: u64) -> Option<Ordering> {
    match e {
        Elem::Real => f32_of(a).partial_cmp(&f32_of(b)),
        Elem::Lreal => f64::from_bits(a).partial_cmp(&f64::from_bits(b)),
        e if signed_order(e) => Some((a as i64).cmp(&(b as i64))),
        _ => Some(a.cmp(&b)),
    }
}

/// Whether integers of type `e` are ordered as signed: the signed types, TIME, and the types
/// promoted to DINT (module doc), which compare as the signed 32-bit ints C makes them.
#[inline]
pub(crate) fn signed_order(e: Elem) -> bool {
    e.is_signed() || e == Elem::Time || promote(e) == Elem::Dint
}

fn neg(e: Elem, a: u64) -> u64 {
    match e {
        Elem::Real => of_f32(-f32_of(a)),
        Elem::Lreal => (-f64::from_bits(a)).to_bits(),
        _ => wrap(promote(e), a.wrapping_neg()),
    }
}

/// MATIEC's rounding of a real to an integer (`__real_round` and `__preal_to_sint`): add or
/// subtract one half, then truncate, except that an exact half goes to the even neighbour.
fn round_matiec(x: f64) -> i64 {
    fn real_round(x: f64) -> i64 {
        if x % 1.0 == 0.0 {
            ((x as i64) / 2) * 2
        } else {
            x as i64
        }
    }
    if x >= 0.0 {
        real_round(x + 0.5)
    } else {
        real_round(x - 0.5)
    }
}

/// The value of `a` (of type `e`) as an `f64`.
fn as_f64(e: Elem, a: u64) -> f64 {
    match e {
        Elem::Real => f64::from(f32_of(a)),
        Elem::Lreal => f64::from_bits(a),
        e if e.is_signed() || e == Elem::Time => a as i64 as f64,
        _ => a as f64,
    }
}

/// `<from>_TO_<to>`, as MATIEC's library converts (docs/st.md, *Conversions*), except TIME,
/// which converts to and from milliseconds as CODESYS does (MATIEC counts seconds).
fn convert(from: Elem, to: Elem, a: u64) -> u64 {
    const NS_PER_MS: i64 = 1_000_000;
    if from == Elem::Time && to != Elem::Time {
        return convert(Elem::Lint, to, ((a as i64) / NS_PER_MS) as u64);
    }
    if to == Elem::Time && from != Elem::Time {
        return match from {
            Elem::Real | Elem::Lreal => (as_f64(from, a) * NS_PER_MS as f64) as i64 as u64,
            _ => (a as i64).wrapping_mul(NS_PER_MS) as u64,
        };
    }
    let signed = from.is_signed();
    match to {
        Elem::Real => match from {
            Elem::Real => a,
            Elem::Lreal => of_f32(f64::from_bits(a) as f32),
            _ if signed => of_f32(a as i64 as f32),
            _ => of_f32(a as f32),
        },
        Elem::Lreal => match from {
            Elem::Real | Elem::Lreal => as_f64(from, a).to_bits(),
            _ if signed => (a as i64 as f64).to_bits(),
            _ => (a as f64).to_bits(),
        },
        Elem::Bool if from.is_real() => (as_f64(from, a) != 0.0) as u64,
        Elem::Bool => (a != 0) as u64,
        to if from.is_real() => {
            let x = as_f64(from, a);
            match to.is_signed() {
                true => wrap(to, round_matiec(x) as u64),
                false if x >= 0.0 => wrap(to, round_matiec(x) as u64),
                false => 0,
            }
        }
        to => wrap(to, a),
    }
}

/// TRUNC: toward zero.
fn trunc(from: Elem, to: Elem, a: u64) -> u64 {
    let x = as_f64(from, a);
    if to.is_signed() {
        wrap(to, x as i64 as u64)
    } else {
        wrap(to, x as u64)
    }
}

fn math(f: MathFn, e: Elem, a: u64) -> u64 {
    if !e.is_real() {
        // ABS is the one function of this kind defined on integers.
        return match e {
            e if e.is_signed() && (a as i64) < 0 => wrap(e, a.wrapping_neg()),
            _ => a,
        };
    }
    let x = as_f64(e, a);
    let r = match f {
        // MATIEC's `op < 0 ? -op : op`: ABS(-0.0) is -0.0.
        MathFn::Abs => {
            if x < 0.0 {
                -x
            } else {
                x
            }
        }
        MathFn::Sqrt => x.sqrt(),
        MathFn::Ln => x.ln(),
        MathFn::Log => x.log10(),
        MathFn::Exp => x.exp(),
        MathFn::Sin => x.sin(),
        MathFn::Cos => x.cos(),
        MathFn::Tan => x.tan(),
        MathFn::Asin => x.asin(),
        MathFn::Acos => x.acos(),
        MathFn::Atan => x.atan(),
    };
    if e == Elem::Real {
        of_f32(r as f32)
    } else {
        r.to_bits()
    }
}

/// SHL, SHR, ROL, ROR on a bit string of type `e`; `n` counts bits. A shift by the width or
/// more gives 0; a rotation goes round modulo the width.
fn shift(f: ShiftFn, e: Elem, a: u64, n: u64) -> u64 {
    let bits = u64::from(e.bits());
    match f {
        ShiftFn::Shl if n >= bits => 0,
        ShiftFn::Shr if n >= bits => 0,
        ShiftFn::Shl => wrap(e, a << n),
        ShiftFn::Shr => a >> n,
        ShiftFn::Rol | ShiftFn::Ror => {
            let n = n % bits;
            if n == 0 {
                return a;
            }
            let n = if f == ShiftFn::Rol { n } else { bits - n };
            wrap(e, (a << n) | (a >> (bits - n)))
        }
    }
}

/// The length of the string at `at`.
#[inline]
fn str_len(t: &[u8], at: u32) -> usize {
    let at = at as usize;
    usize::from(u16::from_le_bytes([t[at], t[at + 1]]))
}

/// The characters of the string at `at`.
#[inline]
fn str_of(t: &[u8], at: u32) -> &[u8] {
    let len = str_len(t, at);
    &t[at as usize + 2..at as usize + 2 + len]
}

/// Writes `bytes`, cut to `cap`, as the string at `dst`.
#[inline]
fn set_str(t: &mut [u8], dst: u32, cap: u16, bytes: &[u8]) {
    let n = bytes.len().min(usize::from(cap));
    let at = dst as usize;
    t[at..at + 2].copy_from_slice(&(n as u16).to_le_bytes());
    t[at + 2..at + 2 + n].copy_from_slice(&bytes[..n]);
}

/// The string at `src` into `dst`, cut to `cap`: the two may overlap.
#[inline]
fn str_move(t: &mut [u8], dst: u32, cap: u16, src: u32) {
    let n = str_len(t, src).min(usize::from(cap));
    let (dst, src) = (dst as usize, src as usize);
    t.copy_within(src + 2..src + 2 + n, dst + 2);
    t[dst..dst + 2].copy_from_slice(&(n as u16).to_le_bytes());
}

/// FIND: the 1-based position of `b` in `a`, 0 when absent or `b` is empty.
fn find(a: &[u8], b: &[u8]) -> u64 {
    if b.is_empty() || b.len() > a.len() {
        return 0;
    }
    a.windows(b.len())
        .position(|w| w == b)
        .map_or(0, |i| i as u64 + 1)
}

/// An integer argument of a string function: `None` when negative (the function then gives
/// an empty string, as MATIEC's, whose ENO goes false), else clamped to what a string holds.
fn int_arg(e: Elem, v: u64) -> Option<usize> {
    if e.is_signed() && (v as i64) < 0 {
        return None;
    }
    Some(
        usize::try_from(v)
            .unwrap_or(usize::MAX)
            .min(usize::from(u16::MAX)),
    )
}

/// Runs a string function. The result is built in a small fixed buffer on the stack, so that
/// `dst` may be one of the operands; strings are at most [`crate::types::MAX_STRING`] bytes.
/// Positions count from 1; a position past the end means the end (IEC 61131-3 Table 29, and
/// MATIEC's library where the standard is silent).
fn string_fn(f: StrFn, a: &StrArgs, s: &[u64], t: &mut [u8]) {
    let mut buf = [0u8; crate::types::MAX_STRING as usize * 2];
    let (Some(n), Some(p)) = (
        int_arg(a.int, s[a.n as usize]),
        int_arg(a.int, s[a.p as usize]),
    ) else {
        set_str(t, a.dst, a.cap, &[]);
        return;
    };
    let x = str_of(t, a.a);
    // The characters from position `p` (1-based), `n` of them, within `x`.
    let span = |p: usize, n: usize| {
        let from = p.saturating_sub(1).min(x.len());
        (from, from.saturating_add(n).min(x.len()))
    };
    let len = match f {
        StrFn::Concat => join(&mut buf, &[x, str_of(t, a.b)]),
        StrFn::Left => join(&mut buf, &[&x[..n.min(x.len())]]),
        StrFn::Right => join(&mut buf, &[&x[x.len() - n.min(x.len())..]]),
        StrFn::Mid => {
            let (from, to) = span(p, n);
            join(&mut buf, &[&x[from..to]])
        }
        StrFn::Insert => {
            let at = p.min(x.len());
            join(&mut buf, &[&x[..at], str_of(t, a.b), &x[at..]])
        }
        StrFn::Delete => {
            let (from, to) = span(p, n);
            join(&mut buf, &[&x[..from], &x[to..]])
        }
        StrFn::Replace => {
            let (from, to) = span(p, n);
            join(&mut buf, &[&x[..from], str_of(t, a.b), &x[to..]])
        }
    };
    set_str(t, a.dst, a.cap, &buf[..len]);
}

/// Lays `parts` end to end in `buf`, as much as fits; the length written.
fn join(buf: &mut [u8], parts: &[&[u8]]) -> usize {
    let mut at = 0;
    for part in parts {
        let n = part.len().min(buf.len() - at);
        buf[at..at + n].copy_from_slice(&part[..n]);
        at += n;
    }
    at
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reals_round_to_integers_as_matiec_s_library_does() {
        let to_int = |x: f64| convert(Elem::Lreal, Elem::Int, x.to_bits()) as i64;
        assert_eq!(to_int(2.5), 2);
        assert_eq!(to_int(3.5), 4);
        assert_eq!(to_int(-2.5), -2);
        assert_eq!(to_int(2.4), 2);
        assert_eq!(to_int(-2.6), -3);
        assert_eq!(convert(Elem::Lreal, Elem::Uint, (-3.0f64).to_bits()), 0);
    }

    #[test]
    fn integer_arithmetic_wraps_and_mod_by_zero_is_zero() {
        // INT is computed in 32 bits; DINT wraps at its width.
        assert_eq!(int_op(Arith::Add, Elem::Int, 32767, 1), Ok(32768));
        let max = i32::MAX as i64 as u64;
        assert_eq!(
            int_op(Arith::Add, Elem::Dint, max, 1),
            Ok(i32::MIN as i64 as u64)
        );
        assert_eq!(int_op(Arith::Mod, Elem::Dint, 7, 0), Ok(0));
        assert_eq!(
            int_op(Arith::Mod, Elem::Dint, (-7i64) as u64, 3),
            Ok((-1i64) as u64)
        );
        assert_eq!(
            int_op(Arith::Div, Elem::Dint, 7, 0),
            Err(FaultKind::DivisionByZero)
        );
    }

    #[test]
    fn rotations_go_round_the_width_of_the_type() {
        assert_eq!(shift(ShiftFn::Rol, Elem::Byte, 0x81, 1), 0x03);
        assert_eq!(shift(ShiftFn::Ror, Elem::Byte, 0x81, 1), 0xc0);
        assert_eq!(shift(ShiftFn::Shl, Elem::Word, 0x8001, 1), 0x0002);
    }

    #[test]
    fn string_positions_are_one_based_and_clamped() {
        assert_eq!(find(b"hello", b"ll"), 3);
        assert_eq!(find(b"hello", b""), 0);
    }
}
