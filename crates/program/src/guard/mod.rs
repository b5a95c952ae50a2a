//! The guard language: a hand-written lexer and recursive-descent parser, a printer, a type
//! checker, and an allocation-free evaluator over flat postfix code.
//!
//! Guards compile once, at load, to a sequence of [`Op`]s run on a fixed-size stack whose depth is
//! computed at compile time; evaluation never touches the heap.

mod ast;
mod eval;
mod lexer;
mod parser;

use std::fmt;

pub use ast::{BinOp, Expr, ExprKind, Func, UnOp};
pub use parser::{parse, MAX_DEPTH, MAX_NESTING, MAX_TOKENS};

pub(crate) use ast::write_duration;
pub(crate) use eval::{eval, run, Store};

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
    /// Per place: how long it was marked the last time it was (0 if never), read by `P.dwell`
    /// while the place is empty; a shorter slice reads 0.
    pub place_dwell_us: &'a [u64],
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
    Dwell(u32),
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
    /// Action bodies only: push an output's value.
    Out(u32, Type),
    /// Action bodies only: pop a value of the type into a variable.
    StoreVar(u32, Type),
    /// Action bodies only: pop a value of the type into an output.
    StoreOut(u32, Type),
    /// Action bodies only: pop a bool and jump forward when it is false.
    JumpIfFalse(u32),
    /// Action bodies only: jump forward.
    Jump(u32),
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
            base: 0,
            depth: 0,
            max: 0,
            inputs: Vec::new(),
            vars: Vec::new(),
            places: Vec::new(),
            timers: Vec::new(),
            body: false,
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

pub(crate) struct Compiler<'s, 'a> {
    pub(crate) scope: &'s Scope<'a>,
    pub(crate) code: Vec<(Op, u32)>,
    /// Added to every position: where the expression starts in a longer text (an action body).
    pub(crate) base: usize,
    pub(crate) depth: usize,
    pub(crate) max: usize,
    pub(crate) inputs: Vec<u32>,
    pub(crate) vars: Vec<u32>,
    pub(crate) places: Vec<u32>,
    pub(crate) timers: Vec<u32>,
    /// Compiling an action body, which may read outputs (it may assign them too).
    pub(crate) body: bool,
}

impl Compiler<'_, '_> {
    pub(crate) fn emit(&mut self, op: Op, pos: usize, stack_change: isize) {
        self.code.push((op, (pos + self.base) as u32));
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

    /// Compiles `e`; its type comes back as a signal type, durations refused (action bodies
    /// store values into signals, and no signal is a duration).
    pub(crate) fn value(&mut self, e: &Expr) -> Result<Type, SyntaxError> {
        match self.expr(e)? {
            GType::Bool => Ok(Type::Bool),
            GType::Int => Ok(Type::Int),
            GType::Real => Ok(Type::Real),
            GType::Duration => Err(SyntaxError::new(
                e.pos,
                "this is a duration, and no signal holds one; compare it instead, e.g. `S2.t >= 3s`",
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
                } else if let (true, Some(i)) = (
                    self.body,
                    self.scope.outputs.iter().position(|s| &s.name == n),
                ) {
                    let ty = self.scope.outputs[i].ty;
                    self.emit(Op::Out(i as u32, ty), pos, 1);
                    Ok(ty.into())
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
            ExprKind::Dwell(p) => {
                let p = self.place(p, pos, "a step time")?;
                self.timers.push(p);
                self.emit(Op::Dwell(p), pos, 1);
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
