//! The guard language: a hand-written lexer and recursive-descent parser, a printer, a type
//! checker, and an allocation-free evaluator over flat postfix code.
//!
//! Guards compile once, at load, to a sequence of [`Op`]s run on a fixed-size stack whose depth is
//! computed at compile time; evaluation never touches the heap.

mod ast;
mod eval;
mod lexer;
mod parser;

use std::collections::HashMap;
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
    /// Structured Text indexed an array outside its bounds.
    IndexOutOfRange,
}

/// A guard evaluation failure; the column is 1-based within the guard text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EvalError {
    /// What went wrong.
    pub kind: EvalErrorKind,
    /// Column (byte offset + 1) of the operation in the guard text.
    pub column: u32,
}

impl EvalErrorKind {
    /// The fault in words; a context that does not fit the program is worded by the caller,
    /// which knows who built that context.
    pub(crate) fn describe(self, missing: &'static str, wrong_type: &'static str) -> &'static str {
        match self {
            EvalErrorKind::DivisionByZero => "division by zero",
            EvalErrorKind::Overflow => "arithmetic overflow",
            EvalErrorKind::MissingValue => missing,
            EvalErrorKind::WrongType => wrong_type,
            EvalErrorKind::IndexOutOfRange => "array index out of its bounds",
        }
    }
}

impl fmt::Display for EvalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = self.kind.describe(
            "the evaluation context is shorter than the program's signals or places",
            "a signal in the evaluation context does not have its declared type",
        );
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
    /// Compares two ints (or durations, or bools) with a comparison operator of the guard.
    CmpInt(BinOp),
    /// Compares two reals with a comparison operator of the guard.
    CmpReal(BinOp),
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
    /// Each list's positions by name, so that a name costs one lookup however many signals
    /// the program declares.
    index: [HashMap<&'a str, usize>; 3],
}

impl<'a> Scope<'a> {
    /// The scope of a program's `inputs`, `outputs` and `vars`, and its net's places.
    pub(crate) fn new(
        inputs: &'a [Signal],
        outputs: &'a [Signal],
        vars: &'a [Signal],
        net: &'a Net,
    ) -> Self {
        let index = [inputs, outputs, vars].map(|list| {
            let mut at = HashMap::with_capacity(list.len());
            for (i, s) in list.iter().enumerate() {
                at.entry(s.name.as_str()).or_insert(i);
            }
            at
        });
        Scope {
            inputs,
            outputs,
            vars,
            net,
            index,
        }
    }

    /// The position of the input `name`.
    pub(crate) fn input(&self, name: &str) -> Option<usize> {
        self.index[0].get(name).copied()
    }

    /// The position of the output `name`.
    pub(crate) fn output(&self, name: &str) -> Option<usize> {
        self.index[1].get(name).copied()
    }

    /// The position of the variable `name`.
    pub(crate) fn var(&self, name: &str) -> Option<usize> {
        self.index[2].get(name).copied()
    }
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
        let mut c = Compiler::new(scope);
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

    /// What one evaluation costs in units of [`crate::Work`]: the length of its code, at least 1.
    pub fn cost(&self) -> u64 {
        (self.code.len() as u64).max(1)
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

impl<'s, 'a> Compiler<'s, 'a> {
    /// A compiler for a guard, which reads no output; an action body sets `body`.
    pub(crate) fn new(scope: &'s Scope<'a>) -> Self {
        Compiler {
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
        }
    }

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
        match self.scope.input(name) {
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

    /// Type-checks and compiles `e`. Every recursive call is made here, never in a helper, so a
    /// level of the tree costs one frame of this function; the parser's [`MAX_DEPTH`] bounds them.
    fn expr(&mut self, e: &Expr) -> Result<GType, SyntaxError> {
        let pos = e.pos;
        match &e.kind {
            ExprKind::Bool(b) => Ok(self.constant(u64::from(*b), pos, GType::Bool)),
            ExprKind::Int(i) => Ok(self.constant(*i as u64, pos, GType::Int)),
            ExprKind::Real(r) => Ok(self.constant(r.to_bits(), pos, GType::Real)),
            // The lexer refuses durations above i64::MAX µs.
            ExprKind::Duration(d) => Ok(self.constant(*d, pos, GType::Duration)),
            ExprKind::Name(n) => self.name(n, pos),
            ExprKind::Timer(p) => self.place_time(p, pos, "a timer", Op::Timer),
            ExprKind::Dwell(p) => self.place_time(p, pos, "a step time", Op::Dwell),
            ExprKind::Rise(x) => self.edge(x, pos, "rise", Op::Rise),
            ExprKind::Fall(x) => self.edge(x, pos, "fall", Op::Fall),
            ExprKind::Call(func, arg) => {
                let t = self.expr(arg)?;
                self.call(*func, t, pos)
            }
            ExprKind::Unary(op, arg) => {
                let t = self.expr(arg)?;
                self.unary(*op, t, pos)
            }
            ExprKind::Binary(op @ (BinOp::And | BinOp::Or), l, r) => {
                let lt = self.expr(l)?;
                let jump_at = self.code.len();
                // Not taken, the jump pops the left value; the right side pushes one again.
                self.emit(short_circuit(*op, 0), pos, -1);
                let rt = self.expr(r)?;
                logical_operands(*op, lt, rt, pos)?;
                self.code[jump_at].0 = short_circuit(*op, self.code.len() as u32);
                Ok(GType::Bool)
            }
            ExprKind::Binary(op, l, r) => {
                let lt = self.expr(l)?;
                let rt = self.expr(r)?;
                self.binary(*op, lt, rt, pos)
            }
        }
    }

    /// A literal is its value's bits, already in the evaluator's representation of `ty`.
    fn constant(&mut self, bits: u64, pos: usize, ty: GType) -> GType {
        self.emit(Op::Const(bits), pos, 1);
        ty
    }

    /// A bare name reads an input, a variable or a place's token count (the program keeps
    /// signal names and place ids apart); only a body may read an output.
    fn name(&mut self, n: &str, pos: usize) -> Result<GType, SyntaxError> {
        if let Some(i) = self.scope.input(n) {
            let ty = self.scope.inputs[i].ty;
            self.inputs.push(i as u32);
            self.emit(Op::Input(i as u32, ty), pos, 1);
            Ok(ty.into())
        } else if let Some(i) = self.scope.var(n) {
            let ty = self.scope.vars[i].ty;
            self.vars.push(i as u32);
            self.emit(Op::Var(i as u32, ty), pos, 1);
            Ok(ty.into())
        } else if let Some(p) = self.scope.net.place_by_id(n) {
            self.places.push(p.0);
            self.emit(Op::Tokens(p.0), pos, 1);
            Ok(GType::Int)
        } else if let (true, Some(i)) = (self.body, self.scope.output(n)) {
            let ty = self.scope.outputs[i].ty;
            self.emit(Op::Out(i as u32, ty), pos, 1);
            Ok(ty.into())
        } else if self.scope.output(n).is_some() {
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

    /// `P.t` and `P.dwell` read a place's timer, so the place joins [`Guard::timers`].
    fn place_time(
        &mut self,
        place: &str,
        pos: usize,
        what: &str,
        op: fn(u32) -> Op,
    ) -> Result<GType, SyntaxError> {
        let p = self.place(place, pos, what)?;
        self.timers.push(p);
        self.emit(op(p), pos, 1);
        Ok(GType::Duration)
    }

    /// `rise(x)` and `fall(x)` compare a bool input with its previous scan's value, which only
    /// inputs have.
    fn edge(
        &mut self,
        x: &str,
        pos: usize,
        func: &str,
        op: fn(u32) -> Op,
    ) -> Result<GType, SyntaxError> {
        let i = self.bool_input(x, pos, func)?;
        self.emit(op(i), pos, 1);
        Ok(GType::Bool)
    }

    /// `real(…)` and `int(…)` are the only conversions: ints and reals never mix implicitly.
    fn call(&mut self, func: Func, t: GType, pos: usize) -> Result<GType, SyntaxError> {
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

    /// `!` and `-` keep their operand's type, so the instruction depends on it.
    fn unary(&mut self, op: UnOp, t: GType, pos: usize) -> Result<GType, SyntaxError> {
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

    /// An arithmetic operator or a comparison: both operands have one type, which picks the
    /// instruction (there is no implicit conversion).
    fn binary(
        &mut self,
        op: BinOp,
        lt: GType,
        rt: GType,
        pos: usize,
    ) -> Result<GType, SyntaxError> {
        if lt != rt {
            return Err(mixed_operands(op, lt, rt, pos));
        }
        let (inst, ty) = if op.is_comparison() {
            (comparison(op, lt, pos)?, GType::Bool)
        } else {
            (arithmetic(op, lt, pos)?, lt)
        };
        self.emit(inst, pos, -1);
        Ok(ty)
    }
}

/// The jump of `&&` or `||`, taken when the left side alone decides; `target` is patched once
/// the right side is compiled.
fn short_circuit(op: BinOp, target: u32) -> Op {
    if op == BinOp::And {
        Op::AndJump(target)
    } else {
        Op::OrJump(target)
    }
}

/// `&&` and `||` take bools only; the left side is reported first.
fn logical_operands(op: BinOp, lt: GType, rt: GType, pos: usize) -> Result<(), SyntaxError> {
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
    Ok(())
}

/// Operands of two types, with a hint at the conversion or the unit that would make them agree.
fn mixed_operands(op: BinOp, lt: GType, rt: GType, pos: usize) -> SyntaxError {
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
    SyntaxError::new(
        pos,
        format!(
            "cannot {verb} {} with {} using `{}`{hint}",
            lt.name(),
            rt.name(),
            op.symbol()
        ),
    )
}

/// The compare instruction for two operands of type `t`: durations compare as ints, and bools
/// are equal or not but never ordered.
fn comparison(op: BinOp, t: GType, pos: usize) -> Result<Op, SyntaxError> {
    match t {
        GType::Bool if matches!(op, BinOp::Eq | BinOp::Ne) => Ok(Op::CmpInt(op)),
        GType::Bool => Err(SyntaxError::new(
            pos,
            format!("`{}` does not order bools; use `==` or `!=`", op.symbol()),
        )),
        GType::Int | GType::Duration => Ok(Op::CmpInt(op)),
        GType::Real => Ok(Op::CmpReal(op)),
    }
}

/// The arithmetic instruction for two operands of type `t`: durations add and subtract as
/// ints, but a product or quotient of durations would not be a duration.
fn arithmetic(op: BinOp, t: GType, pos: usize) -> Result<Op, SyntaxError> {
    match (op, t) {
        (BinOp::Add, GType::Int | GType::Duration) => Ok(Op::AddInt),
        (BinOp::Sub, GType::Int | GType::Duration) => Ok(Op::SubInt),
        (BinOp::Mul, GType::Int) => Ok(Op::MulInt),
        (BinOp::Div, GType::Int) => Ok(Op::DivInt),
        (BinOp::Add, GType::Real) => Ok(Op::AddReal),
        (BinOp::Sub, GType::Real) => Ok(Op::SubReal),
        (BinOp::Mul, GType::Real) => Ok(Op::MulReal),
        (BinOp::Div, GType::Real) => Ok(Op::DivReal),
        (_, t) => {
            let allowed = if matches!(op, BinOp::Add | BinOp::Sub) {
                "ints, reals or durations"
            } else {
                "ints or reals"
            };
            Err(SyntaxError::new(
                pos,
                format!(
                    "`{}` applies to {allowed}, not to {}",
                    op.symbol(),
                    t.name()
                ),
            ))
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
