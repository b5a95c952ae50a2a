//! The Structured Text subset of docs/sfc.md: a hand-written lexer and parser that type-check
//! as they go and build guard expressions (`cetratus_program::guard::Expr`), so a condition is
//! printed once into the guard language and compiled by the program loader like any guard.
//!
//! Bounded: a text has at most [`MAX_TOKENS`] tokens and at most [`MAX_NESTING`] nested
//! parentheses, unary operators and IF statements; binary chains are loops, and the tree is
//! checked against the guard language's depth limit before anything walks it recursively.

use cetratus_program::guard::{self, BinOp, Expr, ExprKind, UnOp};

/// Most tokens in one condition or action body.
pub const MAX_TOKENS: usize = guard::MAX_TOKENS;

/// Most nested parentheses, unary operators and IF statements.
pub const MAX_NESTING: usize = 32;

/// The types of the subset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ty {
    /// BOOL.
    Bool,
    /// SINT … LINT, USINT … ULINT, BYTE … LWORD: a Cetratus `int` (i64).
    Int,
    /// REAL, LREAL: a Cetratus `real` (f64).
    Real,
    /// TIME literals and `Step.T`.
    Time,
}

impl Ty {
    /// The IEC name, for messages.
    pub fn iec(self) -> &'static str {
        match self {
            Ty::Bool => "BOOL",
            Ty::Int => "INT",
            Ty::Real => "REAL",
            Ty::Time => "TIME",
        }
    }
}

/// What a name in ST stands for.
#[derive(Clone, Debug, PartialEq)]
pub enum Resolved {
    /// A variable, by its Cetratus name, with its type.
    Var(String, Ty),
    /// A step, by its place id.
    Step(String),
    /// A name that exists but cannot be used here, with the reason (a variable of a type outside
    /// the subset, an output in a condition).
    Unusable(String),
}

/// Resolves the names of a POU (case-insensitively, as IEC wants).
pub trait Names {
    /// What `name` stands for, if anything.
    fn resolve(&self, name: &str) -> Option<Resolved>;
}

/// An error in ST text: a byte offset into the text, and whether it names a construct outside
/// the subset (rather than a mistake in the text).
#[derive(Debug, Clone, PartialEq)]
pub struct StError {
    /// Byte offset into the text.
    pub offset: usize,
    /// What is wrong and what to do.
    pub message: String,
    /// The construct outside the subset, when that is the reason.
    pub construct: Option<String>,
}

impl StError {
    fn new(offset: usize, message: impl Into<String>) -> Self {
        StError {
            offset,
            message: message.into(),
            construct: None,
        }
    }

    fn unsupported(
        offset: usize,
        construct: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        StError {
            offset,
            message: message.into(),
            construct: Some(construct.into()),
        }
    }
}

/// A statement of an action body.
#[derive(Clone, Debug, PartialEq)]
pub enum Stmt {
    /// `target := value;`, with the target's Cetratus name and type.
    Assign {
        /// The variable assigned.
        target: String,
        /// Its type.
        ty: Ty,
        /// The value, as a guard expression.
        value: Expr,
        /// Byte offset of the target in the text.
        at: usize,
    },
    /// `IF c THEN … {ELSIF c THEN …} [ELSE …] END_IF;`
    If {
        /// The conditions and their branches, in order.
        arms: Vec<(Expr, Vec<Stmt>)>,
        /// The ELSE branch (empty when there is none).
        otherwise: Vec<Stmt>,
        /// Byte offset of `IF`.
        at: usize,
    },
}

use lex::{lex, time_literal, Tok, KEYWORDS_OUTSIDE};

mod lex;

struct Parser<'n> {
    toks: Vec<(Tok, usize)>,
    i: usize,
    depth: usize,
    names: &'n dyn Names,
}

type Typed = (Expr, Ty);

fn at(kind: ExprKind, pos: usize) -> Expr {
    Expr { kind, pos }
}

impl Parser<'_> {
    fn peek(&self) -> &Tok {
        &self.toks[self.i].0
    }
    fn offset(&self) -> usize {
        self.toks[self.i].1
    }
    fn bump(&mut self) -> (Tok, usize) {
        let t = self.toks[self.i].clone();
        if self.i + 1 < self.toks.len() {
            self.i += 1;
        }
        t
    }
    fn is_kw(&self, kw: &str) -> bool {
        matches!(self.peek(), Tok::Ident(w) if w.eq_ignore_ascii_case(kw))
    }
    fn is_sym(&self, s: &str) -> bool {
        matches!(self.peek(), Tok::Sym(x) if *x == s)
    }
    fn describe(&self) -> String {
        match self.peek() {
            Tok::Ident(w) => format!("`{w}`"),
            Tok::Int(n) => format!("`{n}`"),
            Tok::Real(r) => format!("`{r}`"),
            Tok::Time(_) => "a time literal".into(),
            Tok::Sym(s) => format!("`{s}`"),
            Tok::End => "the end of the text".into(),
        }
    }
    fn expect_sym(&mut self, s: &str, what: &str) -> Result<(), StError> {
        if self.is_sym(s) {
            self.bump();
            Ok(())
        } else {
            Err(StError::new(
                self.offset(),
                format!("expected `{s}` {what}, found {}", self.describe()),
            ))
        }
    }
    fn enter(&mut self) -> Result<(), StError> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            return Err(StError::new(
                self.offset(),
                format!("nested more than {MAX_NESTING} levels deep (parentheses, NOT, minus, IF); simplify"),
            ));
        }
        Ok(())
    }

    fn expr(&mut self) -> Result<Typed, StError> {
        self.enter()?;
        let r = self.chain(0);
        self.depth -= 1;
        r
    }

    /// Binary operators by IEC precedence level, loosest first.
    fn chain(&mut self, level: usize) -> Result<Typed, StError> {
        if level == 6 {
            return self.unary();
        }
        let mut left = self.chain(level + 1)?;
        loop {
            let pos = self.offset();
            let op = match (level, self.peek()) {
                (0, Tok::Ident(w)) if w.eq_ignore_ascii_case("OR") => "OR",
                (1, Tok::Ident(w)) if w.eq_ignore_ascii_case("XOR") => "XOR",
                (2, Tok::Ident(w)) if w.eq_ignore_ascii_case("AND") => "AND",
                (2, Tok::Sym("&")) => "AND",
                (3, Tok::Sym(s @ ("=" | "<>"))) => s,
                (4, Tok::Sym(s @ ("<" | ">" | "<=" | ">="))) => s,
                (5, Tok::Sym(s @ ("+" | "-" | "*" | "/"))) => s,
                (5, Tok::Ident(w)) if w.eq_ignore_ascii_case("MOD") => {
                    return Err(StError::unsupported(
                        pos,
                        "MOD",
                        "the guard language has no remainder",
                    ))
                }
                (5, Tok::Sym("**")) => {
                    return Err(StError::unsupported(
                        pos,
                        "`**`",
                        "the guard language has no power",
                    ))
                }
                _ => return Ok(left),
            };
            self.bump();
            // `*` and `/` bind tighter than `+` and `-`: read their right side one level down.
            let right = if level == 5 && matches!(op, "+" | "-") {
                self.product()?
            } else if level == 5 {
                self.unary()?
            } else {
                self.chain(level + 1)?
            };
            left = binary(op, left, right, pos)?;
        }
    }

    /// `unary (('*'|'/') unary)*`, for the right side of `+` and `-`.
    fn product(&mut self) -> Result<Typed, StError> {
        let mut left = self.unary()?;
        while self.is_sym("*") || self.is_sym("/") {
            let pos = self.offset();
            let (Tok::Sym(op), _) = self.bump() else {
                unreachable!("checked above")
            };
            let right = self.unary()?;
            left = binary(op, left, right, pos)?;
        }
        Ok(left)
    }

    fn unary(&mut self) -> Result<Typed, StError> {
        let pos = self.offset();
        if self.is_kw("NOT") || self.is_sym("-") {
            let not = self.is_kw("NOT");
            self.bump();
            self.enter()?;
            let (e, ty) = self.unary()?;
            self.depth -= 1;
            return match (not, ty) {
                (true, Ty::Bool) => Ok((at(ExprKind::Unary(UnOp::Not, Box::new(e)), pos), ty)),
                (true, _) => Err(StError::unsupported(
                    pos,
                    format!("NOT on {}", ty.iec()),
                    "the subset has NOT on BOOL only (no bitwise operators)",
                )),
                (false, Ty::Int | Ty::Real) => {
                    Ok((at(ExprKind::Unary(UnOp::Neg, Box::new(e)), pos), ty))
                }
                (false, _) => Err(StError::new(pos, format!("cannot negate a {}", ty.iec()))),
            };
        }
        self.primary()
    }

    fn primary(&mut self) -> Result<Typed, StError> {
        let pos = self.offset();
        match self.bump().0 {
            Tok::Int(n) => Ok((at(ExprKind::Int(n), pos), Ty::Int)),
            Tok::Real(r) => Ok((at(ExprKind::Real(r), pos), Ty::Real)),
            Tok::Time(us) => Ok((at(ExprKind::Duration(us), pos), Ty::Time)),
            Tok::Sym("(") => {
                let e = self.expr()?;
                self.expect_sym(")", "to close the parenthesis")?;
                Ok(e)
            }
            Tok::Ident(w) => {
                if w.eq_ignore_ascii_case("TRUE") || w.eq_ignore_ascii_case("FALSE") {
                    let v = w.eq_ignore_ascii_case("TRUE");
                    return Ok((at(ExprKind::Bool(v), pos), Ty::Bool));
                }
                if let Some(kw) = reserved(&w) {
                    return Err(StError::unsupported(
                        pos,
                        kw,
                        "the subset has expressions, assignments and IF only",
                    ));
                }
                if self.is_sym("(") {
                    return Err(StError::unsupported(
                        pos,
                        format!("the call `{w}(…)`"),
                        "functions and function blocks are not in the subset; compute the value in another POU and read it as a variable",
                    ));
                }
                if self.is_sym(".") {
                    self.bump();
                    let fpos = self.offset();
                    let Tok::Ident(field) = self.bump().0 else {
                        return Err(StError::new(
                            fpos,
                            format!("expected `X` or `T` after `{w}.`"),
                        ));
                    };
                    return match self.names.resolve(&w) {
                        Some(Resolved::Step(p)) if field.eq_ignore_ascii_case("X") => {
                            let count = at(ExprKind::Name(p), pos);
                            let zero = at(ExprKind::Int(0), fpos);
                            Ok((
                                at(
                                    ExprKind::Binary(BinOp::Gt, Box::new(count), Box::new(zero)),
                                    fpos,
                                ),
                                Ty::Bool,
                            ))
                        }
                        Some(Resolved::Step(p)) if field.eq_ignore_ascii_case("T") => {
                            Ok((at(ExprKind::Dwell(p), pos), Ty::Time))
                        }
                        Some(Resolved::Step(_)) => Err(StError::new(
                            fpos,
                            format!(
                                "a step has `.X` (active) and `.T` (time active), not `.{field}`"
                            ),
                        )),
                        Some(Resolved::Unusable(why)) => {
                            Err(StError::unsupported(pos, format!("`{w}`"), why))
                        }
                        Some(Resolved::Var(..)) => Err(StError::unsupported(
                            pos,
                            format!("the member access `{w}.{field}`"),
                            "structures and function block outputs are not in the subset",
                        )),
                        None => Err(unknown(pos, &w)),
                    };
                }
                match self.names.resolve(&w) {
                    Some(Resolved::Var(name, ty)) => Ok((at(ExprKind::Name(name), pos), ty)),
                    Some(Resolved::Step(p)) => {
                        let count = at(ExprKind::Name(p), pos);
                        let zero = at(ExprKind::Int(0), pos);
                        Ok((
                            at(
                                ExprKind::Binary(BinOp::Gt, Box::new(count), Box::new(zero)),
                                pos,
                            ),
                            Ty::Bool,
                        ))
                    }
                    Some(Resolved::Unusable(why)) => {
                        Err(StError::unsupported(pos, format!("`{w}`"), why))
                    }
                    None => Err(unknown(pos, &w)),
                }
            }
            Tok::Sym(s) => Err(StError::new(pos, format!("expected a value, found `{s}`"))),
            Tok::End => Err(StError::new(
                pos,
                "expected a value, found the end of the text",
            )),
        }
    }

    fn statements(&mut self, until: &[&str]) -> Result<Vec<Stmt>, StError> {
        let mut out = Vec::new();
        loop {
            if matches!(self.peek(), Tok::End) || until.iter().any(|k| self.is_kw(k)) {
                return Ok(out);
            }
            if self.is_sym(";") {
                self.bump();
                continue;
            }
            out.push(self.statement()?);
        }
    }

    fn statement(&mut self) -> Result<Stmt, StError> {
        let pos = self.offset();
        if self.is_kw("IF") {
            self.bump();
            self.enter()?;
            let mut arms = Vec::new();
            let mut otherwise = Vec::new();
            loop {
                let cpos = self.offset();
                let (c, ty) = self.expr()?;
                if ty != Ty::Bool {
                    return Err(StError::new(
                        cpos,
                        format!("an IF condition must be BOOL, this is {}", ty.iec()),
                    ));
                }
                if !self.is_kw("THEN") {
                    return Err(StError::new(
                        self.offset(),
                        format!("expected THEN, found {}", self.describe()),
                    ));
                }
                self.bump();
                let body = self.statements(&["ELSIF", "ELSE", "END_IF"])?;
                arms.push((c, body));
                if self.is_kw("ELSIF") {
                    self.bump();
                    continue;
                }
                if self.is_kw("ELSE") {
                    self.bump();
                    otherwise = self.statements(&["END_IF"])?;
                }
                if !self.is_kw("END_IF") {
                    return Err(StError::new(
                        self.offset(),
                        format!("expected END_IF, found {}", self.describe()),
                    ));
                }
                self.bump();
                // CODESYS and TwinCAT accept a body that ends in `END_IF` without its `;`
                // (docs/sfc.md); anywhere else the `;` is required.
                if !matches!(self.peek(), Tok::End) {
                    self.expect_sym(";", "after END_IF")?;
                }
                break;
            }
            self.depth -= 1;
            return Ok(Stmt::If {
                arms,
                otherwise,
                at: pos,
            });
        }
        let Tok::Ident(w) = self.peek().clone() else {
            return Err(StError::new(
                pos,
                format!("expected a statement, found {}", self.describe()),
            ));
        };
        if let Some(kw) = reserved(&w) {
            return Err(StError::unsupported(
                pos,
                kw,
                "the subset has assignments and IF/ELSIF/ELSE only",
            ));
        }
        self.bump();
        if self.is_sym("(") {
            return Err(StError::unsupported(
                pos,
                format!("the call `{w}(…)`"),
                "calls are not in the subset",
            ));
        }
        let (target, ty) = match self.names.resolve(&w) {
            Some(Resolved::Var(n, ty)) => (n, ty),
            Some(Resolved::Step(_)) => {
                return Err(StError::new(
                    pos,
                    format!("`{w}` is a step; a step cannot be assigned"),
                ))
            }
            Some(Resolved::Unusable(why)) => {
                return Err(StError::unsupported(pos, format!("`{w}`"), why))
            }
            None => return Err(unknown(pos, &w)),
        };
        self.expect_sym(":=", "in an assignment")?;
        let vpos = self.offset();
        let (value, vty) = self.expr()?;
        if vty != ty && !(ty == Ty::Bool && vty == Ty::Int && is_bit(&value)) {
            return Err(StError::new(
                vpos,
                format!(
                    "`{w}` is {} and the value is {}; convert it",
                    ty.iec(),
                    vty.iec()
                ),
            ));
        }
        let value = match (ty, &value.kind) {
            (Ty::Bool, ExprKind::Int(n)) => at(ExprKind::Bool(*n != 0), value.pos),
            _ => value,
        };
        self.expect_sym(";", "after the assignment")?;
        Ok(Stmt::Assign {
            target,
            ty,
            value,
            at: pos,
        })
    }
}

/// `0` and `1` are accepted for BOOL values, as IEC editors do.
fn is_bit(e: &Expr) -> bool {
    matches!(e.kind, ExprKind::Int(0 | 1))
}

fn unknown(pos: usize, name: &str) -> StError {
    StError::new(
        pos,
        format!("unknown name `{name}`: neither a variable of the POU nor a step; declare it in the POU's interface"),
    )
}

fn reserved(w: &str) -> Option<String> {
    let up = w.to_ascii_uppercase();
    KEYWORDS_OUTSIDE.contains(&up.as_str()).then_some(up)
}

fn binary(op: &str, (l, lt): Typed, (r, rt): Typed, pos: usize) -> Result<Typed, StError> {
    let mismatch = || {
        StError::new(
            pos,
            format!(
                "`{op}` between {} and {}; both sides must have the same type (the subset has no implicit conversions)",
                lt.iec(),
                rt.iec()
            ),
        )
    };
    if lt != rt {
        return Err(mismatch());
    }
    let (bop, ty) = match op {
        "OR" | "XOR" | "AND" => {
            if lt != Ty::Bool {
                return Err(StError::unsupported(
                    pos,
                    format!("{op} on {}", lt.iec()),
                    "the subset has AND, OR and XOR on BOOL only (no bitwise operators)",
                ));
            }
            let b = match op {
                "OR" => BinOp::Or,
                "AND" => BinOp::And,
                _ => BinOp::Ne,
            };
            (b, Ty::Bool)
        }
        "=" => (BinOp::Eq, Ty::Bool),
        "<>" => (BinOp::Ne, Ty::Bool),
        "<" | ">" | "<=" | ">=" => {
            if lt == Ty::Bool {
                return Err(StError::new(
                    pos,
                    format!("`{op}` does not order BOOL values"),
                ));
            }
            let b = match op {
                "<" => BinOp::Lt,
                ">" => BinOp::Gt,
                "<=" => BinOp::Le,
                _ => BinOp::Ge,
            };
            (b, Ty::Bool)
        }
        _ => {
            let b = match op {
                "+" => BinOp::Add,
                "-" => BinOp::Sub,
                "*" => BinOp::Mul,
                _ => BinOp::Div,
            };
            let ok = match b {
                BinOp::Add | BinOp::Sub => matches!(lt, Ty::Int | Ty::Real | Ty::Time),
                _ => matches!(lt, Ty::Int | Ty::Real),
            };
            if !ok {
                return Err(StError::new(
                    pos,
                    format!("`{op}` is not defined on {}", lt.iec()),
                ));
            }
            (b, lt)
        }
    };
    Ok((at(ExprKind::Binary(bop, Box::new(l), Box::new(r)), pos), ty))
}

fn check_depth(e: &Expr, offset: usize) -> Result<(), StError> {
    // Iterative: the tree's depth is what is being checked.
    let mut stack = vec![(e, 1usize)];
    while let Some((e, d)) = stack.pop() {
        if d > guard::MAX_DEPTH {
            return Err(StError::new(
                offset,
                format!("the expression is more than {} operators deep; group it with parentheses or split it", guard::MAX_DEPTH),
            ));
        }
        match &e.kind {
            ExprKind::Unary(_, x) | ExprKind::Call(_, x) => stack.push((x, d + 1)),
            ExprKind::Binary(_, l, r) => {
                stack.push((l, d + 1));
                stack.push((r, d + 1));
            }
            _ => {}
        }
    }
    Ok(())
}

/// Parses a transition condition: one BOOL expression, an optional trailing `;`.
pub fn condition(text: &str, names: &dyn Names) -> Result<Expr, StError> {
    let mut p = Parser {
        toks: lex(text)?,
        i: 0,
        depth: 0,
        names,
    };
    if matches!(p.peek(), Tok::End) {
        return Err(StError::new(
            0,
            "the condition is empty; write one, such as TRUE",
        ));
    }
    if p.is_kw("IF") || matches!(p.toks.get(1), Some((Tok::Sym(":="), _))) {
        return Err(StError::unsupported(
            p.offset(),
            "a statement in a condition",
            "a condition is one BOOL expression",
        ));
    }
    let (e, ty) = p.expr()?;
    if p.is_sym(";") {
        p.bump();
    }
    if !matches!(p.peek(), Tok::End) {
        return Err(StError::new(
            p.offset(),
            format!("expected the end of the condition, found {}", p.describe()),
        ));
    }
    if ty != Ty::Bool {
        return Err(StError::new(
            0,
            format!("a condition must be BOOL, this is {}", ty.iec()),
        ));
    }
    check_depth(&e, 0)?;
    Ok(e)
}

/// Parses an action body: statements.
pub fn body(text: &str, names: &dyn Names) -> Result<Vec<Stmt>, StError> {
    let mut p = Parser {
        toks: lex(text)?,
        i: 0,
        depth: 0,
        names,
    };
    let out = p.statements(&[])?;
    let mut stack: Vec<&Stmt> = out.iter().collect();
    while let Some(s) = stack.pop() {
        match s {
            Stmt::Assign { value, at, .. } => check_depth(value, *at)?,
            Stmt::If {
                arms,
                otherwise,
                at,
            } => {
                for (c, b) in arms {
                    check_depth(c, *at)?;
                    stack.extend(b);
                }
                stack.extend(otherwise);
            }
        }
    }
    Ok(out)
}

/// Reads a duration written as an IEC time literal (`T#2s`, `TIME#1m30s`), for the `duration`
/// of a timed action.
pub fn duration(text: &str) -> Result<u64, StError> {
    let t = text.trim();
    let lead = text.len() - text.trim_start().len();
    let Some(hash) = t.find('#') else {
        return Err(StError::unsupported(
            lead,
            format!("the duration `{t}`"),
            "it is not an IEC time literal; write it as T#10s",
        ));
    };
    if !(t[..hash].eq_ignore_ascii_case("T") || t[..hash].eq_ignore_ascii_case("TIME")) {
        return Err(StError::new(
            lead,
            format!("`{t}` is not an IEC time literal; write it as T#10s"),
        ));
    }
    let (us, end) = time_literal(t, hash + 1)?;
    if end != t.len() {
        return Err(StError::new(
            lead + end,
            format!("unexpected text after the time literal `{t}`"),
        ));
    }
    Ok(us)
}

#[cfg(test)]
mod tests;
