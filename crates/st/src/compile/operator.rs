//! Operators, computed as C computes them in MATIEC's translation (and as CODESYS evaluates
//! intermediate results in the register's width):
//!
//! * SINT, INT, USINT, UINT, BYTE and WORD operands are computed in 32 bits: `x * 1000 / 1000`
//!   with `x : INT := 100` is 100, and `x + 1 > x` is TRUE at 32767.
//! * An untyped real literal is an LREAL (a C `double`), and a REAL operation with one is done
//!   in LREAL, up through the operations above it: `r > 0.1` compares in double.
//! * `**` gives an LREAL that flows into the expression above it.
//!
//! A value in its wider type is cut to its IEC type where it is stored: assigned, passed to a
//! function or a function block, used as a CASE selector ([`Compiler::narrow`]). An operand
//! (`operand`) is left wide; every other use of an expression (`expr`) is narrowed.

use crate::ast::{BinOp, Expr, ExprKind, Literal, Pos, Rel, UnOp};
use crate::code::{Arith, Op, Slot};
use crate::error::Diagnostic;
use crate::types::{Elem, Ty};

use super::expr::Val;
use super::Compiler;

/// Whether values of `e` are computed in 32 bits, wider than the type (C's integer promotion).
pub fn promoted(e: Elem) -> bool {
    matches!(
        e,
        Elem::Sint | Elem::Int | Elem::Usint | Elem::Uint | Elem::Byte | Elem::Word
    )
}

impl<'a> Compiler<'a> {
    /// `e` as an operand: possibly still in its wider type (the flag).
    pub fn operand(&mut self, e: &Expr, want: Option<Ty>) -> Result<(Val, bool), Diagnostic> {
        match &e.kind {
            ExprKind::Unary(op, inner) => self.unary(*op, inner, want, e.pos),
            ExprKind::Binary(op, a, b) => self.binary(*op, a, b, want, e.pos),
            ExprKind::Lit(Literal::Real { value, ty: None })
                if want == Some(Ty::Elem(Elem::Real)) =>
            {
                Ok((
                    Val::Scalar(
                        Ty::Elem(Elem::Real),
                        self.const_slot(value.to_bits(), e.pos)?,
                    ),
                    true,
                ))
            }
            _ => Ok((self.expr(e, want)?, false)),
        }
    }

    /// A value cut to its IEC type, if it is in its wider one.
    pub fn narrow(&mut self, v: Val, wide: bool, pos: Pos) -> Result<Val, Diagnostic> {
        let Val::Scalar(ty @ Ty::Elem(e), a) = v else {
            return Ok(v);
        };
        if !wide {
            return Ok(v);
        }
        let from = if e == Elem::Real {
            Elem::Lreal
        } else {
            Elem::Dint
        };
        let dst = self.temp(pos)?;
        self.emit(
            Op::Conv {
                from,
                to: e,
                dst,
                a,
            },
            pos,
        )?;
        Ok(Val::Scalar(ty, dst))
    }

    /// A REAL operand in LREAL: as it is when wide, converted when not.
    fn widened(&mut self, slot: Slot, wide: bool, pos: Pos) -> Result<Slot, Diagnostic> {
        if wide {
            return Ok(slot);
        }
        let dst = self.temp(pos)?;
        self.emit(
            Op::Conv {
                from: Elem::Real,
                to: Elem::Lreal,
                dst,
                a: slot,
            },
            pos,
        )?;
        Ok(dst)
    }

    fn unary(
        &mut self,
        op: UnOp,
        inner: &Expr,
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<(Val, bool), Diagnostic> {
        if let (UnOp::Neg, ExprKind::Lit(lit)) = (op, &inner.kind) {
            // `-32768` is one INT literal, not the negation of 32768, which INT cannot hold.
            let negated = match lit {
                Literal::Int { value, ty: None } => Some(Literal::Int {
                    value: -value,
                    ty: None,
                }),
                Literal::Real { value, ty: None } => Some(Literal::Real {
                    value: -value,
                    ty: None,
                }),
                _ => None,
            };
            if let Some(lit) = negated {
                let e = Expr {
                    kind: ExprKind::Lit(lit),
                    pos,
                };
                return self.operand(&e, want);
            }
        }
        let symbol = if op == UnOp::Neg { "-" } else { "NOT" };
        let (v, wide) = self.operand(inner, want)?;
        let Val::Scalar(ty @ Ty::Elem(e), a) = v else {
            return Err(Diagnostic::new(
                pos,
                format!(
                    "`{symbol}` applies to numbers and bits, not to {}",
                    self.describe(v.ty())
                ),
            ));
        };
        let dst = self.temp(pos)?;
        let in_double = e == Elem::Real && wide;
        let op = match op {
            UnOp::Neg if e.is_num() || e == Elem::Time => Op::Neg {
                e: if in_double { Elem::Lreal } else { e },
                dst,
                a,
            },
            UnOp::Not if e == Elem::Bool || e.is_bits() => Op::Not { e, dst, a },
            _ => {
                return Err(Diagnostic::new(
                    pos,
                    format!("`{symbol}` does not apply to {e}"),
                ))
            }
        };
        self.emit(op, pos)?;
        Ok((Val::Scalar(ty, dst), wide || promoted(e)))
    }

    fn binary(
        &mut self,
        op: BinOp,
        a: &Expr,
        b: &Expr,
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<(Val, bool), Diagnostic> {
        let compare = match op {
            BinOp::Cmp(rel) => Some(rel),
            _ => None,
        };
        let hint = self
            .peek(a)
            .or_else(|| self.peek(b))
            .or(if compare.is_some() { None } else { want });
        if op == BinOp::Pow {
            return self.power(a, b, hint, pos);
        }
        let (x, wx) = self.operand(a, hint)?;
        if matches!(op, BinOp::Mul | BinOp::Div) && x.ty() == Ty::Elem(Elem::Time) {
            return self
                .time_scale(op == BinOp::Div, x, b, pos)
                .map(|v| (v, false));
        }
        let (y, wy) = self.operand(b, Some(hint.unwrap_or(x.ty())))?;
        if let Some(rel) = compare {
            return Ok((self.comparison(rel, (x, wx), (y, wy), pos)?, false));
        }
        let (Val::Scalar(tx, sa), Val::Scalar(ty, sb)) = (x, y) else {
            return Err(Diagnostic::new(
                pos,
                format!(
                    "`{}` does not apply to {} and {}",
                    op.symbol(),
                    self.describe(x.ty()),
                    self.describe(y.ty())
                ),
            ));
        };
        if tx != ty {
            return Err(Diagnostic::new(
                pos,
                format!(
                    "`{}` needs two operands of one type, found {} and {}; convert one with *_TO_*",
                    op.symbol(),
                    self.describe(tx),
                    self.describe(ty)
                ),
            ));
        }
        let Some(e) = tx.elem().filter(|&e| allowed(op, e)) else {
            return Err(Diagnostic::new(
                pos,
                format!("`{}` does not apply to {}", op.symbol(), self.describe(tx)),
            ));
        };
        let dst = self.temp(pos)?;
        if e == Elem::Real && (wx || wy) {
            let (da, db) = (self.widened(sa, wx, pos)?, self.widened(sb, wy, pos)?);
            self.emit(
                Op::Arith {
                    op: arith(op),
                    e: Elem::Lreal,
                    dst,
                    a: da,
                    b: db,
                },
                pos,
            )?;
            return Ok((Val::Scalar(tx, dst), true));
        }
        self.emit(
            Op::Arith {
                op: arith(op),
                e,
                dst,
                a: sa,
                b: sb,
            },
            pos,
        )?;
        let bitwise = matches!(op, BinOp::And | BinOp::Or | BinOp::Xor);
        Ok((
            Val::Scalar(tx, dst),
            if bitwise { wx || wy } else { promoted(e) },
        ))
    }

    /// `t * x`, `t / x`: a TIME scaled by a number, which is converted to LREAL first, as
    /// MATIEC's `__time_mul` and `__time_div` take it.
    fn time_scale(&mut self, div: bool, t: Val, b: &Expr, pos: Pos) -> Result<Val, Diagnostic> {
        let Val::Scalar(_, a) = t else {
            return Err(Diagnostic::new(pos, "expected a TIME"));
        };
        let y = self.expr(b, None)?;
        let Val::Scalar(Ty::Elem(e), sb) = y else {
            return Err(Diagnostic::new(
                b.pos,
                "a TIME is multiplied or divided by a number",
            ));
        };
        if !e.is_num() {
            return Err(Diagnostic::new(
                b.pos,
                format!("a TIME is multiplied or divided by a number, not by {e}"),
            ));
        }
        let (f, dst) = (self.temp(pos)?, self.temp(pos)?);
        self.emit(
            Op::Conv {
                from: e,
                to: Elem::Lreal,
                dst: f,
                a: sb,
            },
            pos,
        )?;
        self.emit(Op::TimeScale { div, dst, a, f }, pos)?;
        Ok(Val::Scalar(Ty::Elem(Elem::Time), dst))
    }

    /// `a ** b`: MATIEC's `pow` on two LREALs; for a REAL `a`, an LREAL that flows on wide.
    fn power(
        &mut self,
        a: &Expr,
        b: &Expr,
        hint: Option<Ty>,
        pos: Pos,
    ) -> Result<(Val, bool), Diagnostic> {
        let want = hint
            .filter(|t| t.elem().is_some_and(Elem::is_real))
            .or(Some(Ty::Elem(Elem::Lreal)));
        let (x, wx) = self.operand(a, want)?;
        let y = self.expr(b, None)?;
        let (Val::Scalar(Ty::Elem(ex), sa), Val::Scalar(Ty::Elem(ey), sb)) = (x, y) else {
            return Err(Diagnostic::new(
                pos,
                "`**` takes a REAL or LREAL and a number",
            ));
        };
        if !ex.is_real() || !ey.is_num() {
            return Err(Diagnostic::new(
                pos,
                format!("`**` takes a REAL or LREAL and a number, found {ex} and {ey}"),
            ));
        }
        let l = Elem::Lreal;
        let da = if ex == Elem::Real {
            self.widened(sa, wx, pos)?
        } else {
            sa
        };
        let (db, dst) = (self.temp(pos)?, self.temp(pos)?);
        self.emit(
            Op::Conv {
                from: ey,
                to: l,
                dst: db,
                a: sb,
            },
            pos,
        )?;
        self.emit(
            Op::Arith {
                op: Arith::Pow,
                e: l,
                dst,
                a: da,
                b: db,
            },
            pos,
        )?;
        Ok((Val::Scalar(Ty::Elem(ex), dst), ex == Elem::Real))
    }

    fn comparison(
        &mut self,
        rel: Rel,
        (x, wx): (Val, bool),
        (y, wy): (Val, bool),
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        let dst = self.temp(pos)?;
        match (x, y) {
            (Val::Str(_, a), Val::Str(_, b)) => {
                self.emit(Op::StrCmp { op: rel, dst, a, b }, pos)?;
            }
            (Val::Scalar(tx, a), Val::Scalar(ty, b)) if tx == ty => {
                let (e, a, b) = match tx {
                    Ty::Elem(Elem::Real) if wx || wy => (
                        Elem::Lreal,
                        self.widened(a, wx, pos)?,
                        self.widened(b, wy, pos)?,
                    ),
                    Ty::Elem(e) => (e, a, b),
                    _ if matches!(rel, Rel::Eq | Rel::Ne) => (Elem::Lint, a, b),
                    _ => {
                        return Err(Diagnostic::new(
                            pos,
                            "enumeration values compare with = and <> only",
                        ))
                    }
                };
                self.emit(
                    Op::Cmp {
                        op: rel,
                        e,
                        dst,
                        a,
                        b,
                    },
                    pos,
                )?;
            }
            _ => {
                return Err(Diagnostic::new(
                    pos,
                    format!(
                        "`{}` compares two values of one type, found {} and {}",
                        rel.symbol(),
                        self.describe(x.ty()),
                        self.describe(y.ty())
                    ),
                ));
            }
        }
        Ok(Val::Scalar(Ty::Elem(Elem::Bool), dst))
    }
}

/// Whether arithmetic operator `op` applies to type `e`.
fn allowed(op: BinOp, e: Elem) -> bool {
    match op {
        BinOp::And | BinOp::Or | BinOp::Xor => e == Elem::Bool || e.is_bits(),
        BinOp::Add | BinOp::Sub => e.is_num() || e == Elem::Time,
        BinOp::Mul | BinOp::Div => e.is_num(),
        BinOp::Mod => e.is_int(),
        _ => false,
    }
}

fn arith(op: BinOp) -> Arith {
    match op {
        BinOp::Add => Arith::Add,
        BinOp::Sub => Arith::Sub,
        BinOp::Mul => Arith::Mul,
        BinOp::Div => Arith::Div,
        BinOp::Mod => Arith::Mod,
        BinOp::Pow => Arith::Pow,
        BinOp::And => Arith::And,
        BinOp::Or => Arith::Or,
        _ => Arith::Xor,
    }
}
