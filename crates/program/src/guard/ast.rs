//! The guard syntax tree and its printer.

use std::fmt;

use crate::duration::UNITS;

/// A unary operator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum UnOp {
    /// `!`: logical not.
    Not,
    /// `-`: arithmetic negation.
    Neg,
}

/// A binary operator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BinOp {
    /// `||`
    Or,
    /// `&&`
    And,
    /// `==`
    Eq,
    /// `!=`
    Ne,
    /// `<`
    Lt,
    /// `<=`
    Le,
    /// `>`
    Gt,
    /// `>=`
    Ge,
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
}

impl BinOp {
    /// How it is written.
    pub fn symbol(self) -> &'static str {
        match self {
            BinOp::Or => "||",
            BinOp::And => "&&",
            BinOp::Eq => "==",
            BinOp::Ne => "!=",
            BinOp::Lt => "<",
            BinOp::Le => "<=",
            BinOp::Gt => ">",
            BinOp::Ge => ">=",
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Mul => "*",
            BinOp::Div => "/",
        }
    }

    /// Binding strength: higher binds tighter.
    pub fn precedence(self) -> u8 {
        match self {
            BinOp::Or => 1,
            BinOp::And => 2,
            BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => 3,
            BinOp::Add | BinOp::Sub => 4,
            BinOp::Mul | BinOp::Div => 5,
        }
    }

    /// True for the six comparisons, which do not chain (`a < b < c` is refused).
    pub fn is_comparison(self) -> bool {
        self.precedence() == 3
    }
}

/// A built-in function of one argument.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Func {
    /// `real(x)`: an int as a real.
    Real,
    /// `int(x)`: a real truncated towards zero.
    Int,
}

/// A guard expression.
///
/// `pos` is the byte offset in the guard text of the node's main token (the operator of an
/// operation, the start of an atom); it is for error messages and is not part of the tree's
/// meaning, so equality ignores it.
#[derive(Clone, Debug)]
pub struct Expr {
    /// What the node is.
    pub kind: ExprKind,
    /// Byte offset of the node's main token in the guard text.
    pub pos: usize,
}

impl PartialEq for Expr {
    fn eq(&self, other: &Self) -> bool {
        self.kind == other.kind
    }
}

/// The kinds of guard expression.
#[derive(Clone, Debug, PartialEq)]
pub enum ExprKind {
    /// `true` or `false`.
    Bool(bool),
    /// A non-negative int literal (a minus sign is a [`UnOp::Neg`]).
    Int(i64),
    /// A non-negative, finite real literal.
    Real(f64),
    /// A duration literal, in microseconds.
    Duration(u64),
    /// A name: an input, a variable, or a place (its token count).
    Name(String),
    /// `P.t` or `t(P)`: how long place P has been marked.
    Timer(String),
    /// `P.dwell`: as `P.t` while the place is marked; once it empties, how long it was last
    /// marked, until it is marked again (IEC 61131-3's `Step.T`).
    Dwell(String),
    /// `rise(x)`: bool input x went from false to true in this scan.
    Rise(String),
    /// `fall(x)`: bool input x went from true to false in this scan.
    Fall(String),
    /// A conversion function.
    Call(Func, Box<Expr>),
    /// A unary operation.
    Unary(UnOp, Box<Expr>),
    /// A binary operation.
    Binary(BinOp, Box<Expr>, Box<Expr>),
}

impl Expr {
    /// A node at offset 0 (for building trees in code).
    pub fn new(kind: ExprKind) -> Self {
        Expr { kind, pos: 0 }
    }

    /// Binding strength of the node as printed (atoms bind tightest).
    fn precedence(&self) -> u8 {
        match &self.kind {
            ExprKind::Binary(op, _, _) => op.precedence(),
            ExprKind::Unary(..) => 6,
            _ => 7,
        }
    }

    /// The depth of the tree, a leaf counting one: the evaluator's stack depth is bounded by it,
    /// and every recursive walk of the tree (this one too) recurses this deep. The parser builds
    /// no tree deeper than [`MAX_DEPTH`](super::MAX_DEPTH).
    pub fn nesting(&self) -> usize {
        match &self.kind {
            ExprKind::Call(_, e) | ExprKind::Unary(_, e) => 1 + e.nesting(),
            ExprKind::Binary(_, l, r) => 1 + l.nesting().max(r.nesting()),
            _ => 1,
        }
    }
}

/// Writes a duration with the largest unit that divides it exactly.
pub(crate) fn write_duration(f: &mut impl fmt::Write, micros: u64) -> fmt::Result {
    if micros == 0 {
        return f.write_str("0s");
    }
    for (unit, scale) in UNITS {
        if micros.is_multiple_of(scale) {
            return write!(f, "{}{unit}", micros / scale);
        }
    }
    write!(f, "{micros}us")
}

/// Prints with the fewest parentheses that parse back to the same tree.
impl fmt::Display for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.kind {
            ExprKind::Bool(b) => write!(f, "{b}"),
            ExprKind::Int(i) => write!(f, "{i}"),
            // `{:?}` is the shortest text that reads back as the same f64, and always has a `.` or
            // an exponent, so it lexes as a real and not as an int.
            ExprKind::Real(r) => write!(f, "{r:?}"),
            ExprKind::Duration(d) => write_duration(f, *d),
            ExprKind::Name(n) => f.write_str(n),
            ExprKind::Timer(p) => write!(f, "{p}.t"),
            ExprKind::Dwell(p) => write!(f, "{p}.dwell"),
            ExprKind::Rise(x) => write!(f, "rise({x})"),
            ExprKind::Fall(x) => write!(f, "fall({x})"),
            ExprKind::Call(func, e) => {
                let name = match func {
                    Func::Real => "real",
                    Func::Int => "int",
                };
                write!(f, "{name}({e})")
            }
            ExprKind::Unary(op, e) => {
                f.write_str(match op {
                    UnOp::Not => "!",
                    UnOp::Neg => "-",
                })?;
                if e.precedence() < 6 {
                    write!(f, "({e})")
                } else {
                    write!(f, "{e}")
                }
            }
            ExprKind::Binary(op, l, r) => {
                let p = op.precedence();
                // Left-associative: the left operand may sit at the same level, the right may not.
                // Comparisons do not chain, so neither side may be a comparison.
                let left_parens = l.precedence() < p || (op.is_comparison() && l.precedence() == p);
                let right_parens = r.precedence() <= p;
                if left_parens {
                    write!(f, "({l})")?;
                } else {
                    write!(f, "{l}")?;
                }
                write!(f, " {} ", op.symbol())?;
                if right_parens {
                    write!(f, "({r})")
                } else {
                    write!(f, "{r}")
                }
            }
        }
    }
}
