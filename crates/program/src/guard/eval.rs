//! The evaluator of the flat postfix code that guards and action bodies compile to: a loop over
//! the instructions on a fixed-size stack, never allocating, never looping back.

use super::{BinOp, EvalCtx, EvalError, EvalErrorKind, Op, MAX_STACK};
use crate::value::{Type, Value};

/// Runs a guard's postfix code: one bool left on the stack.
pub(crate) fn eval(code: &[(Op, u32)], ctx: &EvalCtx) -> Result<bool, EvalError> {
    let mut stack = [0u64; MAX_STACK];
    match run(code, ctx, None, &mut stack)? {
        1 => Ok(stack[0] == 1),
        _ => Err(EvalError {
            kind: EvalErrorKind::MissingValue,
            column: 1,
        }),
    }
}

/// Where an action body's stores go: the variables (which its reads see, too) and the outputs.
pub(crate) struct Store<'a> {
    pub vars: &'a mut [Value],
    pub outputs: &'a mut [Value],
}

/// Runs postfix code on a fixed-size stack and returns how many values are left on it. Never
/// allocates, never panics: an inconsistent stack (impossible after type checking) reports
/// `MissingValue` rather than indexing out of range. With `store`, variables are read from and
/// written to it (an action body); without, the store instructions fail (a guard has none).
/// Jumps only go forward, so a run costs at most one step per instruction.
pub(crate) fn run(
    code: &[(Op, u32)],
    ctx: &EvalCtx,
    mut store: Option<Store>,
    stack: &mut [u64; MAX_STACK],
) -> Result<usize, EvalError> {
    let mut sp = 0usize;
    let mut pc = 0usize;
    while let Some(&(op, pos)) = code.get(pc) {
        let err = |kind| EvalError {
            kind,
            column: pos + 1,
        };
        pc += 1;
        macro_rules! pop {
            () => {{
                sp = sp.checked_sub(1).ok_or(err(EvalErrorKind::MissingValue))?;
                stack[sp]
            }};
        }
        macro_rules! push {
            ($v:expr) => {{
                let v: u64 = $v;
                *stack.get_mut(sp).ok_or(err(EvalErrorKind::MissingValue))? = v;
                sp += 1;
            }};
        }
        let value = |v: Option<&Value>, ty: Type| -> Result<u64, EvalError> {
            match (v, ty) {
                (Some(Value::Bool(b)), Type::Bool) => Ok(u64::from(*b)),
                (Some(Value::Int(i)), Type::Int) => Ok(*i as u64),
                (Some(Value::Real(r)), Type::Real) => Ok(r.to_bits()),
                (None, _) => Err(err(EvalErrorKind::MissingValue)),
                _ => Err(err(EvalErrorKind::WrongType)),
            }
        };
        let int = |r: Option<i64>| r.map(|v| v as u64).ok_or(err(EvalErrorKind::Overflow));
        let real = |r: f64| {
            if r.is_finite() {
                Ok(r.to_bits())
            } else {
                Err(err(EvalErrorKind::Overflow))
            }
        };
        let input_bool = |i: u32, image: &[Value]| value(image.get(i as usize), Type::Bool);
        match op {
            Op::Const(v) => push!(v),
            Op::Input(i, ty) => push!(value(ctx.inputs.get(i as usize), ty)?),
            Op::Var(i, ty) => {
                let vars: &[Value] = match &store {
                    Some(s) => s.vars,
                    None => ctx.vars,
                };
                push!(value(vars.get(i as usize), ty)?)
            }
            Op::Out(i, ty) => {
                let s = store.as_ref().ok_or(err(EvalErrorKind::MissingValue))?;
                push!(value(s.outputs.get(i as usize), ty)?)
            }
            Op::StoreVar(i, ty) | Op::StoreOut(i, ty) => {
                let bits = pop!();
                let v = match ty {
                    Type::Bool => Value::Bool(bits == 1),
                    Type::Int => Value::Int(bits as i64),
                    Type::Real => Value::Real(f64::from_bits(bits)),
                };
                let s = store.as_mut().ok_or(err(EvalErrorKind::MissingValue))?;
                let cells: &mut [Value] = if matches!(op, Op::StoreVar(..)) {
                    s.vars
                } else {
                    s.outputs
                };
                *cells
                    .get_mut(i as usize)
                    .ok_or(err(EvalErrorKind::MissingValue))? = v;
            }
            // Backward jumps are refused, so no code can loop, whatever it holds.
            Op::JumpIfFalse(target) | Op::Jump(target) if (target as usize) < pc => {
                return Err(err(EvalErrorKind::MissingValue))
            }
            Op::JumpIfFalse(target) => {
                if pop!() == 0 {
                    pc = target as usize;
                }
            }
            Op::Jump(target) => pc = target as usize,
            Op::Tokens(p) => {
                let m = ctx
                    .marking
                    .get(p as usize)
                    .ok_or(err(EvalErrorKind::MissingValue))?;
                push!(u64::from(*m))
            }
            Op::Timer(p) => {
                let marked = marked_for(ctx, p).ok_or(err(EvalErrorKind::MissingValue))?;
                push!(marked.map_or(0, |t| t.min(i64::MAX as u64)))
            }
            Op::Dwell(p) => {
                let marked = marked_for(ctx, p).ok_or(err(EvalErrorKind::MissingValue))?;
                let t = marked
                    .unwrap_or_else(|| ctx.place_dwell_us.get(p as usize).copied().unwrap_or(0));
                push!(t.min(i64::MAX as u64))
            }
            Op::Rise(i) => {
                let now = input_bool(i, ctx.inputs)?;
                let before = input_bool(i, ctx.prev_inputs)?;
                push!(u64::from(now == 1 && before == 0))
            }
            Op::Fall(i) => {
                let now = input_bool(i, ctx.inputs)?;
                let before = input_bool(i, ctx.prev_inputs)?;
                push!(u64::from(now == 0 && before == 1))
            }
            Op::Not => {
                let a = pop!();
                push!(a ^ 1)
            }
            Op::NegInt => {
                let a = pop!() as i64;
                push!(int(a.checked_neg())?)
            }
            Op::NegReal => {
                let a = f64::from_bits(pop!());
                push!((-a).to_bits())
            }
            Op::AddInt | Op::SubInt | Op::MulInt | Op::DivInt => {
                let b = pop!() as i64;
                let a = pop!() as i64;
                let r = match op {
                    Op::AddInt => a.checked_add(b),
                    Op::SubInt => a.checked_sub(b),
                    Op::MulInt => a.checked_mul(b),
                    _ if b == 0 => return Err(err(EvalErrorKind::DivisionByZero)),
                    _ => a.checked_div(b),
                };
                push!(int(r)?)
            }
            Op::AddReal | Op::SubReal | Op::MulReal | Op::DivReal => {
                let b = f64::from_bits(pop!());
                let a = f64::from_bits(pop!());
                let r = match op {
                    Op::AddReal => a + b,
                    Op::SubReal => a - b,
                    Op::MulReal => a * b,
                    _ if b == 0.0 => return Err(err(EvalErrorKind::DivisionByZero)),
                    _ => a / b,
                };
                push!(real(r)?)
            }
            Op::CmpInt(c) => {
                let b = pop!() as i64;
                let a = pop!() as i64;
                push!(u64::from(compare(c, a.partial_cmp(&b))))
            }
            Op::CmpReal(c) => {
                let b = f64::from_bits(pop!());
                let a = f64::from_bits(pop!());
                push!(u64::from(compare(c, a.partial_cmp(&b))))
            }
            Op::ToReal => {
                let a = pop!() as i64;
                push!((a as f64).to_bits())
            }
            Op::ToInt => {
                let a = f64::from_bits(pop!()).trunc();
                // i64::MAX as f64 rounds up to 2^63, which is already out of range.
                if !(a >= i64::MIN as f64 && a < i64::MAX as f64) {
                    return Err(err(EvalErrorKind::Overflow));
                }
                push!(a as i64 as u64)
            }
            Op::AndJump(target) | Op::OrJump(target) => {
                let top = *stack
                    .get(sp.wrapping_sub(1))
                    .ok_or(err(EvalErrorKind::MissingValue))?;
                let short = if matches!(op, Op::AndJump(_)) {
                    top == 0
                } else {
                    top == 1
                };
                if short {
                    pc = target as usize;
                } else {
                    sp -= 1;
                }
            }
        }
    }
    Ok(sp)
}

/// How long place `p` has been marked at `ctx.now_us`, `None` while it is empty; the outer
/// `None` is a context shorter than the net.
#[inline]
fn marked_for(ctx: &EvalCtx, p: u32) -> Option<Option<u64>> {
    let m = *ctx.marking.get(p as usize)?;
    let since = *ctx.place_since_us.get(p as usize)?;
    Some(
        since
            .filter(|_| m > 0)
            .map(|s| ctx.now_us.saturating_sub(s)),
    )
}

/// Applies a comparison operator to an ordering; the compiler emits compare instructions for
/// the six comparisons only, so any other operator is false.
pub(super) fn compare(op: BinOp, o: Option<std::cmp::Ordering>) -> bool {
    use std::cmp::Ordering::*;
    match (op, o) {
        // Computed reals are checked finite, but a real input may carry NaN: every comparison
        // with it is false except `!=`, as in IEEE 754.
        (BinOp::Ne, None) => true,
        (_, None) => false,
        (BinOp::Eq, Some(o)) => o == Equal,
        (BinOp::Ne, Some(o)) => o != Equal,
        (BinOp::Lt, Some(o)) => o == Less,
        (BinOp::Le, Some(o)) => o != Greater,
        (BinOp::Gt, Some(o)) => o == Greater,
        (BinOp::Ge, Some(o)) => o != Less,
        (BinOp::Or | BinOp::And | BinOp::Add | BinOp::Sub | BinOp::Mul | BinOp::Div, _) => false,
    }
}
