//! The guard language: a hand-written lexer and recursive-descent parser, a printer, a type
//! checker, and an allocation-free evaluator over flat postfix code.
//!
//! Guards compile once, at load, to a sequence of [`Op`]s run on a fixed-size stack whose depth is
//! computed at compile time; evaluation never touches the heap.

mod ast;
mod lexer;
mod parser;

use std::fmt;

pub use ast::{BinOp, Expr, ExprKind, Func, UnOp};
pub use parser::{parse, MAX_DEPTH, MAX_NESTING, MAX_TOKENS};

pub(crate) use ast::write_duration;

use cetratus_net::{Net, Tokens};

use crate::value::{Signal, Type, Value};

/// Most stack slots a guard may need; deeper guards are refused at load.
pub const MAX_STACK: usize = 32;

/// A syntax or type error inside a guard, at a byte offset of the guard text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SyntaxError {
    /// Byte offset in the guard text.
    pub offset: usize,
    /// What is wrong and what was expected.
    pub message: String,
}

impl SyntaxError {
    pub(crate) fn new(offset: usize, message: impl Into<String>) -> Self {
        SyntaxError {
            offset,
            message: message.into(),
        }
    }
}

impl fmt::Display for SyntaxError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "at offset {}: {}", self.offset, self.message)
    }
}

/// What went wrong while evaluating a guard.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EvalErrorKind {
    /// Division (int or real) by zero.
    DivisionByZero,
    /// An int operation overflowed i64, or a real operation gave an infinite or NaN result, or
    /// `int(x)` got a real outside the int range.
    Overflow,
    /// The context's slices are shorter than the program's signals or the net's places.
    MissingValue,
    /// An input or variable in the context does not have its declared type.
    WrongType,
}

/// A guard evaluation failure; the column is 1-based within the guard text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EvalError {
    /// What went wrong.
    pub kind: EvalErrorKind,
    /// Column (byte offset + 1) of the operation in the guard text.
    pub column: u32,
}

impl fmt::Display for EvalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = match self.kind {
            EvalErrorKind::DivisionByZero => "division by zero",
            EvalErrorKind::Overflow => "arithmetic overflow",
            EvalErrorKind::MissingValue => {
                "the evaluation context is shorter than the program's signals or places"
            }
            EvalErrorKind::WrongType => {
                "a signal in the evaluation context does not have its declared type"
            }
        };
        write!(f, "{what} at column {} of the guard", self.column)
    }
}

impl std::error::Error for EvalError {}

/// Everything a guard may read in one scan. Times are in microseconds.
#[derive(Clone, Copy, Debug)]
pub struct EvalCtx<'a> {
    /// The input image of this scan, in declaration order.
    pub inputs: &'a [Value],
    /// The input image of the previous scan (for `rise`/`fall`); equal to `inputs` on the first scan.
    pub prev_inputs: &'a [Value],
    /// Variables, in declaration order.
    pub vars: &'a [Value],
    /// The marking, in place order.
    pub marking: &'a [Tokens],
    /// Per place: the start of the scan in which it went from 0 to more tokens; `None` while empty.
    pub place_since_us: &'a [Option<u64>],
    /// The start of this scan.
    pub now_us: u64,
}

/// A comparison, as carried by the typed compare instructions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Cmp {
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
}

/// One instruction of the postfix code. Values on the stack are 64-bit patterns whose meaning
/// the type checker fixed: bools are 0/1, ints and durations (µs) are i64, reals are f64 bits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Op {
    Const(u64),
    Input(u32, Type),
    Var(u32, Type),
    Tokens(u32),
    Timer(u32),
    Rise(u32),
    Fall(u32),
    Not,
    NegInt,
    NegReal,
    AddInt,
    SubInt,
    MulInt,
    DivInt,
    AddReal,
    SubReal,
    MulReal,
    DivReal,
    CmpInt(Cmp),
    CmpReal(Cmp),
    ToReal,
    ToInt,
    /// `&&`: if the top is false jump (keeping it), else pop it and go on with the right side.
    AndJump(u32),
    /// `||`: if the top is true jump (keeping it), else pop it and go on with the right side.
    OrJump(u32),
}

/// The static type of a guard expression; durations exist only inside guards.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum GType {
    Bool,
    Int,
    Real,
    Duration,
}

impl GType {
    fn name(self) -> &'static str {
        match self {
            GType::Bool => "bool",
            GType::Int => "int",
            GType::Real => "real",
            GType::Duration => "duration",
        }
    }
}

impl From<Type> for GType {
    fn from(t: Type) -> Self {
        match t {
            Type::Bool => GType::Bool,
            Type::Int => GType::Int,
            Type::Real => GType::Real,
        }
    }
}

/// The names a guard can refer to.
pub(crate) struct Scope<'a> {
    pub inputs: &'a [Signal],
    pub outputs: &'a [Signal],
    pub vars: &'a [Signal],
    pub net: &'a Net,
}

/// A guard compiled for one transition.
#[derive(Clone, Debug)]
pub struct Guard {
    source: String,
    expr: Expr,
    code: Vec<(Op, u32)>,
    stack: usize,
    inputs: Vec<u32>,
    vars: Vec<u32>,
    places: Vec<u32>,
    timers: Vec<u32>,
}

impl Guard {
    /// The guard as written in the program file.
    pub fn source(&self) -> &str {
        &self.source
    }
    /// The parsed guard.
    pub fn expr(&self) -> &Expr {
        &self.expr
    }
    /// Stack slots the evaluator needs for it.
    pub fn stack_depth(&self) -> usize {
        self.stack
    }
    /// Indices of the inputs it reads (including through `rise`/`fall`), sorted.
    pub fn inputs(&self) -> &[u32] {
        &self.inputs
    }
    /// Indices of the variables it reads, sorted.
    pub fn variables(&self) -> &[u32] {
        &self.vars
    }
    /// Places whose token count it reads, sorted.
    pub fn places(&self) -> &[u32] {
        &self.places
    }
    /// Places whose timer it reads, sorted.
    pub fn timers(&self) -> &[u32] {
        &self.timers
    }

    /// Parses, type-checks and compiles a guard; it must be a bool.
    pub(crate) fn compile(source: &str, scope: &Scope) -> Result<Guard, SyntaxError> {
        let expr = parse(source)?;
        let mut c = Compiler {
            scope,
            code: Vec::new(),
            depth: 0,
            max: 0,
            inputs: Vec::new(),
            vars: Vec::new(),
            places: Vec::new(),
            timers: Vec::new(),
        };
        let ty = c.expr(&expr)?;
        if ty != GType::Bool {
            return Err(SyntaxError::new(
                0,
                format!(
                    "a guard must be a condition (bool) but this one is {} {}; compare it, e.g. `{} > 0`",
                    article(ty),
                    ty.name(),
                    expr
                ),
            ));
        }
        if c.max > MAX_STACK {
            return Err(SyntaxError::new(
                0,
                format!(
                    "this guard needs {} evaluation stack slots but the evaluator has {MAX_STACK}; split it or reorder it so the deepest part comes first",
                    c.max
                ),
            ));
        }
        for v in [&mut c.inputs, &mut c.vars, &mut c.places, &mut c.timers] {
            v.sort_unstable();
            v.dedup();
        }
        Ok(Guard {
            source: source.to_string(),
            expr,
            code: c.code,
            stack: c.max,
            inputs: c.inputs,
            vars: c.vars,
            places: c.places,
            timers: c.timers,
        })
    }

    /// Evaluates the guard. Never allocates.
    pub fn eval(&self, ctx: &EvalCtx) -> Result<bool, EvalError> {
        eval(&self.code, ctx)
    }
}

fn article(t: GType) -> &'static str {
    match t {
        GType::Int => "an",
        _ => "a",
    }
}

struct Compiler<'s, 'a> {
    scope: &'s Scope<'a>,
    code: Vec<(Op, u32)>,
    depth: usize,
    max: usize,
    inputs: Vec<u32>,
    vars: Vec<u32>,
    places: Vec<u32>,
    timers: Vec<u32>,
}

impl Compiler<'_, '_> {
    fn emit(&mut self, op: Op, pos: usize, stack_change: isize) {
        self.code.push((op, pos as u32));
        self.depth = self.depth.saturating_add_signed(stack_change);
        self.max = self.max.max(self.depth);
    }

    fn known_names(&self) -> String {
        let mut names: Vec<&str> = self.scope.inputs.iter().map(|s| s.name.as_str()).collect();
        names.extend(self.scope.vars.iter().map(|s| s.name.as_str()));
        let more = names.len() > 12;
        names.truncate(12);
        let mut s = names.join(", ");
        if more {
            s.push_str(", …");
        }
        if s.is_empty() {
            s.push_str("none declared");
        }
        s
    }

    fn place(&self, name: &str, pos: usize, what: &str) -> Result<u32, SyntaxError> {
        self.scope
            .net
            .place_by_id(name)
            .map(|p| p.0)
            .ok_or_else(|| {
                SyntaxError::new(
                    pos,
                    format!("unknown place `{name}` in {what}; expected a place id of the net"),
                )
            })
    }

    fn bool_input(&mut self, name: &str, pos: usize, func: &str) -> Result<u32, SyntaxError> {
        match self.scope.inputs.iter().position(|s| s.name == name) {
            Some(i) if self.scope.inputs[i].ty == Type::Bool => {
                self.inputs.push(i as u32);
                Ok(i as u32)
            }
            Some(i) => Err(SyntaxError::new(
                pos,
                format!("`{func}({name})` needs a bool input but `{name}` is {}", self.scope.inputs[i].ty),
            )),
            None => Err(SyntaxError::new(
                pos,
                format!("`{func}(…)` needs a bool input; `{name}` is not an input (inputs have a previous value, variables and places do not)"),
            )),
        }
    }

    fn expr(&mut self, e: &Expr) -> Result<GType, SyntaxError> {
        let pos = e.pos;
        match &e.kind {
            ExprKind::Bool(b) => {
                self.emit(Op::Const(u64::from(*b)), pos, 1);
                Ok(GType::Bool)
            }
            ExprKind::Int(i) => {
                self.emit(Op::Const(*i as u64), pos, 1);
                Ok(GType::Int)
            }
            ExprKind::Real(r) => {
                self.emit(Op::Const(r.to_bits()), pos, 1);
                Ok(GType::Real)
            }
            ExprKind::Duration(d) => {
                // The lexer refuses durations above i64::MAX µs.
                self.emit(Op::Const(*d), pos, 1);
                Ok(GType::Duration)
            }
            ExprKind::Name(n) => {
                if let Some(i) = self.scope.inputs.iter().position(|s| &s.name == n) {
                    let ty = self.scope.inputs[i].ty;
                    self.inputs.push(i as u32);
                    self.emit(Op::Input(i as u32, ty), pos, 1);
                    Ok(ty.into())
                } else if let Some(i) = self.scope.vars.iter().position(|s| &s.name == n) {
                    let ty = self.scope.vars[i].ty;
                    self.vars.push(i as u32);
                    self.emit(Op::Var(i as u32, ty), pos, 1);
                    Ok(ty.into())
                } else if let Some(p) = self.scope.net.place_by_id(n) {
                    self.places.push(p.0);
                    self.emit(Op::Tokens(p.0), pos, 1);
                    Ok(GType::Int)
                } else if self.scope.outputs.iter().any(|s| &s.name == n) {
                    Err(SyntaxError::new(
                        pos,
                        format!("`{n}` is an output; guards read inputs, variables, places (token count) and place timers"),
                    ))
                } else {
                    Err(SyntaxError::new(
                        pos,
                        format!(
                            "unknown name `{n}`; expected an input, a variable or a place (signals: {})",
                            self.known_names()
                        ),
                    ))
                }
            }
            ExprKind::Timer(p) => {
                let p = self.place(p, pos, "a timer")?;
                self.timers.push(p);
                self.emit(Op::Timer(p), pos, 1);
                Ok(GType::Duration)
            }
            ExprKind::Rise(x) => {
                let i = self.bool_input(x, pos, "rise")?;
                self.emit(Op::Rise(i), pos, 1);
                Ok(GType::Bool)
            }
            ExprKind::Fall(x) => {
                let i = self.bool_input(x, pos, "fall")?;
                self.emit(Op::Fall(i), pos, 1);
                Ok(GType::Bool)
            }
            ExprKind::Call(func, arg) => {
                let t = self.expr(arg)?;
                match (func, t) {
                    (Func::Real, GType::Int) => {
                        self.emit(Op::ToReal, pos, 0);
                        Ok(GType::Real)
                    }
                    (Func::Int, GType::Real) => {
                        self.emit(Op::ToInt, pos, 0);
                        Ok(GType::Int)
                    }
                    (Func::Real, t) => Err(SyntaxError::new(
                        pos,
                        format!(
                            "`real(…)` converts an int, but its argument is {} {}",
                            article(t),
                            t.name()
                        ),
                    )),
                    (Func::Int, t) => Err(SyntaxError::new(
                        pos,
                        format!(
                            "`int(…)` converts a real, but its argument is {} {}",
                            article(t),
                            t.name()
                        ),
                    )),
                }
            }
            ExprKind::Unary(op, arg) => {
                let t = self.expr(arg)?;
                match (op, t) {
                    (UnOp::Not, GType::Bool) => self.emit(Op::Not, pos, 0),
                    (UnOp::Neg, GType::Int) => self.emit(Op::NegInt, pos, 0),
                    (UnOp::Neg, GType::Real) => self.emit(Op::NegReal, pos, 0),
                    (UnOp::Not, t) => {
                        return Err(SyntaxError::new(
                            pos,
                            format!("`!` needs a bool but got {} {}", article(t), t.name()),
                        ))
                    }
                    (UnOp::Neg, t) => {
                        return Err(SyntaxError::new(
                            pos,
                            format!(
                                "`-` needs an int or a real but got {} {}",
                                article(t),
                                t.name()
                            ),
                        ))
                    }
                }
                Ok(t)
            }
            ExprKind::Binary(op @ (BinOp::And | BinOp::Or), l, r) => {
                let lt = self.expr(l)?;
                let jump_at = self.code.len();
                let jump = if *op == BinOp::And {
                    Op::AndJump(0)
                } else {
                    Op::OrJump(0)
                };
                // Not taken, the jump pops the left value; the right side pushes one again.
                self.emit(jump, pos, -1);
                let rt = self.expr(r)?;
                for (side, t) in [("left", lt), ("right", rt)] {
                    if t != GType::Bool {
                        return Err(SyntaxError::new(
                            pos,
                            format!(
                                "`{}` needs bools on both sides but the {side} side is {} {}",
                                op.symbol(),
                                article(t),
                                t.name()
                            ),
                        ));
                    }
                }
                let target = self.code.len() as u32;
                self.code[jump_at].0 = if *op == BinOp::And {
                    Op::AndJump(target)
                } else {
                    Op::OrJump(target)
                };
                Ok(GType::Bool)
            }
            ExprKind::Binary(op, l, r) => {
                let lt = self.expr(l)?;
                let rt = self.expr(r)?;
                if lt != rt {
                    let verb = if op.is_comparison() {
                        "compare"
                    } else {
                        "combine"
                    };
                    let hint = match (lt, rt) {
                        (GType::Int, GType::Real) | (GType::Real, GType::Int) => {
                            "; ints and reals do not mix implicitly, convert with `real(…)` or `int(…)`"
                        }
                        (GType::Duration, _) | (_, GType::Duration) => {
                            "; a duration goes with a duration, e.g. `P30.t >= 3s`"
                        }
                        _ => "",
                    };
                    return Err(SyntaxError::new(
                        pos,
                        format!(
                            "cannot {verb} {} with {} using `{}`{hint}",
                            lt.name(),
                            rt.name(),
                            op.symbol()
                        ),
                    ));
                }
                let cmp = match op {
                    BinOp::Eq => Some(Cmp::Eq),
                    BinOp::Ne => Some(Cmp::Ne),
                    BinOp::Lt => Some(Cmp::Lt),
                    BinOp::Le => Some(Cmp::Le),
                    BinOp::Gt => Some(Cmp::Gt),
                    BinOp::Ge => Some(Cmp::Ge),
                    _ => None,
                };
                if let Some(c) = cmp {
                    let inst = match lt {
                        GType::Bool if matches!(c, Cmp::Eq | Cmp::Ne) => Op::CmpInt(c),
                        GType::Bool => {
                            return Err(SyntaxError::new(
                                pos,
                                format!("`{}` does not order bools; use `==` or `!=`", op.symbol()),
                            ))
                        }
                        GType::Int | GType::Duration => Op::CmpInt(c),
                        GType::Real => Op::CmpReal(c),
                    };
                    self.emit(inst, pos, -1);
                    return Ok(GType::Bool);
                }
                let inst = match (op, lt) {
                    (BinOp::Add, GType::Int | GType::Duration) => Op::AddInt,
                    (BinOp::Sub, GType::Int | GType::Duration) => Op::SubInt,
                    (BinOp::Mul, GType::Int) => Op::MulInt,
                    (BinOp::Div, GType::Int) => Op::DivInt,
                    (BinOp::Add, GType::Real) => Op::AddReal,
                    (BinOp::Sub, GType::Real) => Op::SubReal,
                    (BinOp::Mul, GType::Real) => Op::MulReal,
                    (BinOp::Div, GType::Real) => Op::DivReal,
                    (_, t) => {
                        let allowed = if matches!(op, BinOp::Add | BinOp::Sub) {
                            "ints, reals or durations"
                        } else {
                            "ints or reals"
                        };
                        return Err(SyntaxError::new(
                            pos,
                            format!(
                                "`{}` applies to {allowed}, not to {}",
                                op.symbol(),
                                t.name()
                            ),
                        ));
                    }
                };
                self.emit(inst, pos, -1);
                Ok(lt)
            }
        }
    }
}

/// Runs postfix code on a fixed-size stack. Never allocates, never panics: an inconsistent
/// stack (impossible after type checking) reports `MissingValue` rather than indexing out of range.
pub(crate) fn eval(code: &[(Op, u32)], ctx: &EvalCtx) -> Result<bool, EvalError> {
    let mut stack = [0u64; MAX_STACK];
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
            Op::Var(i, ty) => push!(value(ctx.vars.get(i as usize), ty)?),
            Op::Tokens(p) => {
                let m = ctx
                    .marking
                    .get(p as usize)
                    .ok_or(err(EvalErrorKind::MissingValue))?;
                push!(u64::from(*m))
            }
            Op::Timer(p) => {
                let m = *ctx
                    .marking
                    .get(p as usize)
                    .ok_or(err(EvalErrorKind::MissingValue))?;
                let since = *ctx
                    .place_since_us
                    .get(p as usize)
                    .ok_or(err(EvalErrorKind::MissingValue))?;
                let t = match since {
                    Some(s) if m > 0 => ctx.now_us.saturating_sub(s).min(i64::MAX as u64),
                    _ => 0,
                };
                push!(t)
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
    match (sp, stack[0]) {
        (1, v) => Ok(v == 1),
        _ => Err(EvalError {
            kind: EvalErrorKind::MissingValue,
            column: 1,
        }),
    }
}

fn compare(c: Cmp, o: Option<std::cmp::Ordering>) -> bool {
    use std::cmp::Ordering::*;
    match (c, o) {
        // Computed reals are checked finite, but a real input may carry NaN: every comparison
        // with it is false except `!=`, as in IEEE 754.
        (Cmp::Ne, None) => true,
        (_, None) => false,
        (Cmp::Eq, Some(o)) => o == Equal,
        (Cmp::Ne, Some(o)) => o != Equal,
        (Cmp::Lt, Some(o)) => o == Less,
        (Cmp::Le, Some(o)) => o != Greater,
        (Cmp::Gt, Some(o)) => o == Greater,
        (Cmp::Ge, Some(o)) => o != Less,
    }
}

/// Lexes an invariant with the guard lexer and keeps the tokens the invariant syntax uses.
pub(crate) fn lex_for_invariant(
    src: &str,
) -> Result<Vec<(crate::invariant::InvTok, usize)>, SyntaxError> {
    use crate::invariant::InvTok;
    use lexer::Tok;
    let mut out = Vec::new();
    for t in lexer::lex(src)? {
        let k = match t.kind {
            Tok::Ident(n) => InvTok::Name(n),
            Tok::Int(i) => InvTok::Int(i),
            Tok::Plus => InvTok::Plus,
            Tok::Minus => InvTok::Minus,
            Tok::Star => InvTok::Star,
            Tok::Assign | Tok::EqEq => InvTok::Eq,
            Tok::End => InvTok::End,
            other => {
                return Err(SyntaxError::new(
                    t.offset,
                    format!(
                        "unexpected {} in invariant; expected a weighted sum of places, `=`, and an integer, e.g. `H + B + 2*P14 = 7`",
                        other.describe()
                    ),
                ))
            }
        };
        out.push((k, t.offset));
    }
    Ok(out)
}

/// Parses a duration literal such as `10ms` (for settings like the scan period).
pub(crate) fn parse_duration(src: &str) -> Result<u64, SyntaxError> {
    let toks = lexer::lex(src)?;
    match toks.as_slice() {
        [lexer::Token {
            kind: lexer::Tok::Duration(d),
            ..
        }, lexer::Token {
            kind: lexer::Tok::End,
            ..
        }] => Ok(*d),
        _ => Err(SyntaxError::new(
            0,
            "expected a duration such as `10ms`, `1s` or `500us`",
        )),
    }
}
