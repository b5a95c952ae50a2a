//! Constant expressions: array bounds, string capacities, CASE labels, initial values and task
//! intervals, evaluated while compiling.

use crate::ast::{BinOp, Expr, ExprKind, Init, Literal, UnOp};
use crate::error::Diagnostic;
use crate::types::{Elem, Size, Ty};

use super::decl::offset;
use super::{Compiler, Loc};

/// A constant's value, before it is given a type.
#[derive(Clone, Debug, PartialEq)]
pub enum Const {
    /// An integer (any integer or bit-string type).
    Int(i128),
    /// A real.
    Real(f64),
    /// TRUE or FALSE.
    Bool(bool),
    /// A duration in nanoseconds.
    Time(i64),
    /// A string's bytes.
    Str(Vec<u8>),
    /// An enumeration value: its type and integer.
    Enum(u32, i64),
}

impl<'a> Compiler<'a> {
    /// A constant integer expression.
    pub fn const_int(&self, e: &Expr) -> Result<i128, Diagnostic> {
        match self.constant(e, None)? {
            Const::Int(v) => Ok(v),
            _ => Err(Diagnostic::new(e.pos, "expected a constant integer")),
        }
    }

    /// A constant TIME expression, in nanoseconds.
    pub fn const_time(&self, e: &Expr) -> Result<i64, Diagnostic> {
        match self.constant(e, None)? {
            Const::Time(v) => Ok(v),
            _ => Err(Diagnostic::new(
                e.pos,
                "expected a TIME literal such as T#20ms",
            )),
        }
    }

    /// Evaluates a constant expression; `want` resolves enumeration value names.
    pub fn constant(&self, e: &Expr, want: Option<Ty>) -> Result<Const, Diagnostic> {
        match &e.kind {
            ExprKind::Lit(lit) => self.literal_const(lit, e.pos),
            ExprKind::Name(id) => self.named_const(&id.key(), want, e.pos),
            ExprKind::Unary(UnOp::Neg, inner) => match self.constant(inner, want)? {
                Const::Int(v) => Ok(Const::Int(-v)),
                Const::Real(v) => Ok(Const::Real(-v)),
                Const::Time(v) => Ok(Const::Time(v.wrapping_neg())),
                _ => Err(Diagnostic::new(
                    e.pos,
                    "`-` applies to numbers and durations",
                )),
            },
            ExprKind::Unary(UnOp::Not, inner) => match self.constant(inner, want)? {
                Const::Bool(b) => Ok(Const::Bool(!b)),
                _ => Err(Diagnostic::new(e.pos, "NOT in a constant applies to BOOL")),
            },
            ExprKind::Binary(op, a, b) => {
                let (x, y) = (self.constant(a, want)?, self.constant(b, want)?);
                const_binary(*op, x, y, e.pos)
            }
            _ => Err(Diagnostic::new(
                e.pos,
                "expected a constant: a literal, a CONSTANT variable, or arithmetic on them",
            )),
        }
    }

    fn literal_const(&self, lit: &Literal, pos: u32) -> Result<Const, Diagnostic> {
        Ok(match lit {
            Literal::Int { value, .. } => Const::Int(*value),
            Literal::Real { value, .. } => Const::Real(*value),
            Literal::Bool(b) => Const::Bool(*b),
            Literal::Time(t) => Const::Time(*t),
            Literal::String(s) => Const::Str(s.clone()),
            Literal::Enum { ty, value } => {
                let key = ty.key();
                let named = self.named.get(&key).map(|n| n.ty);
                let Some(Ty::Enum(id)) = named else {
                    return Err(Diagnostic::new(
                        pos,
                        format!("`{}` is not an enumeration type", ty.text),
                    ));
                };
                self.enum_const(id, &value.key(), pos)?
            }
        })
    }

    fn enum_const(&self, id: u32, key: &str, pos: u32) -> Result<Const, Diagnostic> {
        let e = &self.types.enums[id as usize];
        e.values
            .iter()
            .find(|(k, _)| k == key)
            .map(|&(_, v)| Const::Enum(id, v))
            .ok_or_else(|| {
                Diagnostic::new(
                    pos,
                    format!("`{key}` is not a value of the enumeration {}", e.name),
                )
            })
    }

    /// A name in a constant: a CONSTANT variable already initialised, or an enumeration value.
    fn named_const(&self, key: &str, want: Option<Ty>, pos: u32) -> Result<Const, Diagnostic> {
        if let Some(v) = self.scope().vars.get(key) {
            if let (true, Loc::Static(at)) = (v.constant, v.loc) {
                return Ok(self.read_const(v.ty, at));
            }
            return Err(Diagnostic::new(pos, format!("`{key}` is a variable, not a constant; declare it in VAR CONSTANT to use it here")));
        }
        if let Some(Ty::Enum(id)) = want {
            if let Ok(c) = self.enum_const(id, key, pos) {
                return Ok(c);
            }
        }
        let found = self.types.enums.iter().enumerate().find_map(|(id, e)| {
            e.values
                .iter()
                .find(|(k, _)| k == key)
                .map(|&(_, v)| Const::Enum(id as u32, v))
        });
        found.ok_or_else(|| Diagnostic::new(pos, format!("unknown name `{key}` in a constant")))
    }

    /// The value a constant variable was initialised with.
    fn read_const(&self, ty: Ty, at: Size) -> Const {
        let bits = self.init.slots.get(at.slots as usize).copied().unwrap_or(0);
        match ty {
            Ty::Elem(Elem::Bool) => Const::Bool(bits != 0),
            Ty::Elem(Elem::Real) => Const::Real(f64::from(f32::from_bits(bits as u32))),
            Ty::Elem(Elem::Lreal) => Const::Real(f64::from_bits(bits)),
            Ty::Elem(Elem::Time) => Const::Time(bits as i64),
            Ty::Elem(e) if e.is_signed() => Const::Int(i128::from(bits as i64)),
            Ty::Elem(_) => Const::Int(i128::from(bits)),
            Ty::Enum(id) => Const::Enum(id, bits as i64),
            _ => {
                let at = at.text as usize;
                let len = self
                    .init
                    .text
                    .get(at..at + 2)
                    .map_or(0, |b| u16::from_le_bytes([b[0], b[1]]) as usize);
                Const::Str(
                    self.init
                        .text
                        .get(at + 2..at + 2 + len)
                        .unwrap_or_default()
                        .to_vec(),
                )
            }
        }
    }

    /// The slot bits of constant `c` as a value of `ty`, checked to fit.
    pub fn const_bits(&self, c: &Const, ty: Ty, pos: u32) -> Result<u64, Diagnostic> {
        let mismatch = || {
            Diagnostic::new(
                pos,
                format!("a constant of the wrong type for {}", self.describe(ty)),
            )
        };
        match (ty, c) {
            (Ty::Elem(Elem::Bool), Const::Bool(b)) => Ok(*b as u64),
            (Ty::Elem(Elem::Bool), Const::Int(v @ (0 | 1))) => Ok(*v as u64),
            (Ty::Elem(Elem::Real), Const::Real(v)) => Ok(u64::from((*v as f32).to_bits())),
            (Ty::Elem(Elem::Lreal), Const::Real(v)) => Ok(v.to_bits()),
            (Ty::Elem(Elem::Real), Const::Int(v)) => Ok(u64::from((*v as f32).to_bits())),
            (Ty::Elem(Elem::Lreal), Const::Int(v)) => Ok((*v as f64).to_bits()),
            (Ty::Elem(Elem::Time), Const::Time(t)) => Ok(*t as u64),
            (Ty::Elem(e), Const::Int(v)) if e.is_int() || e.is_bits() => {
                let (lo, hi) = e.int_range();
                if *v < lo || *v > hi {
                    return Err(Diagnostic::new(
                        pos,
                        format!("{v} does not fit in {e} ({lo}..{hi})"),
                    ));
                }
                Ok(crate::types::wrap(e, *v as i64 as u64))
            }
            (Ty::Enum(id), Const::Enum(cid, v)) if id == *cid => Ok(*v as u64),
            _ => Err(mismatch()),
        }
    }

    /// Writes the initial value `init` of a `ty` at `at` into the initial state.
    pub fn init_value(&mut self, ty: Ty, at: Size, init: &Init) -> Result<(), Diagnostic> {
        match (ty, init) {
            (Ty::String(cap), Init::Expr(e)) => match self.constant(e, Some(ty))? {
                Const::Str(bytes) => {
                    let n = bytes.len().min(usize::from(cap));
                    let at = at.text as usize;
                    self.init.text[at..at + 2].copy_from_slice(&(n as u16).to_le_bytes());
                    self.init.text[at + 2..at + 2 + n].copy_from_slice(&bytes[..n]);
                    Ok(())
                }
                _ => Err(Diagnostic::new(
                    e.pos,
                    "a STRING's initial value is a string literal",
                )),
            },
            (Ty::Elem(_) | Ty::Enum(_), Init::Expr(e)) => {
                let c = self.constant(e, Some(ty))?;
                self.init.slots[at.slots as usize] = self.const_bits(&c, ty, e.pos)?;
                Ok(())
            }
            (Ty::Array(id), Init::Array(items, pos)) => self.init_array(id, at, items, *pos),
            (Ty::Struct(_) | Ty::Fb(_), Init::Struct(members, _)) => {
                self.init_default(ty, at)?;
                for (name, value) in members {
                    let Some((fty, fat)) = self.member_of(ty, &name.key()) else {
                        return Err(Diagnostic::new(
                            name.pos,
                            format!("{} has no member `{}`", self.describe(ty), name.text),
                        ));
                    };
                    self.init_value(fty, offset(at, fat), value)?;
                }
                Ok(())
            }
            _ => Err(Diagnostic::new(
                init.pos(),
                format!("this initial value does not fit a {}", self.describe(ty)),
            )),
        }
    }

    fn init_array(
        &mut self,
        id: u32,
        at: Size,
        items: &[(Option<Expr>, Init)],
        pos: u32,
    ) -> Result<(), Diagnostic> {
        let a = self.types.arrays[id as usize].clone();
        self.init_default(Ty::Array(id), at)?;
        let mut i = 0u64;
        for (count, value) in items {
            let n = match count {
                Some(c) => u64::try_from(self.const_int(c)?)
                    .map_err(|_| Diagnostic::new(c.pos, "a repeat count is not negative"))?,
                None => 1,
            };
            for _ in 0..n {
                if i >= a.count() {
                    return Err(Diagnostic::new(
                        pos,
                        format!(
                            "more initial values than the array's {} elements",
                            a.count()
                        ),
                    ));
                }
                let el = Size {
                    slots: at.slots + a.elem_size.slots * i as u32,
                    text: at.text + a.elem_size.text * i as u32,
                };
                self.init_value(a.elem, el, value)?;
                i += 1;
            }
        }
        Ok(())
    }

    /// A member of a structure or FB instance type: its type and offset.
    pub fn member_of(&self, ty: Ty, key: &str) -> Option<(Ty, Size)> {
        match ty {
            Ty::Struct(id) => self.types.structs[id as usize]
                .fields
                .iter()
                .find(|f| f.key == key)
                .map(|f| (f.ty, f.at)),
            Ty::Fb(id) => self.fbs[id as usize]
                .fields
                .iter()
                .find(|(f, _)| f.key == key)
                .map(|(f, _)| (f.ty, f.at)),
            _ => None,
        }
    }
}

fn const_binary(op: BinOp, x: Const, y: Const, pos: u32) -> Result<Const, Diagnostic> {
    let out = match (x, y) {
        (Const::Int(a), Const::Int(b)) => match op {
            BinOp::Add => a.checked_add(b),
            BinOp::Sub => a.checked_sub(b),
            BinOp::Mul => a.checked_mul(b),
            BinOp::Div if b != 0 => Some(a / b),
            BinOp::Mod if b != 0 => Some(a % b),
            _ => None,
        }
        .map(Const::Int),
        (Const::Real(a), Const::Real(b)) => match op {
            BinOp::Add => Some(a + b),
            BinOp::Sub => Some(a - b),
            BinOp::Mul => Some(a * b),
            BinOp::Div => Some(a / b),
            _ => None,
        }
        .map(Const::Real),
        (Const::Time(a), Const::Time(b)) => match op {
            BinOp::Add => a.checked_add(b),
            BinOp::Sub => a.checked_sub(b),
            _ => None,
        }
        .map(Const::Time),
        _ => None,
    };
    out.ok_or_else(|| Diagnostic::new(pos, format!("`{}` cannot be computed here: a constant must be integer, real or TIME arithmetic without overflow or division by zero", op.symbol())))
}
