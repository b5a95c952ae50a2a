//! Expressions and places: type checking, and the instructions that compute a value into a
//! slot or read and write a variable, a member or an element.
//!
//! A literal costs nothing at run time: it is a slot (or text) that holds its value from the
//! start and that nothing writes. A variable at a fixed place is read where it is, without a
//! copy. An operation writes a fresh temporary, and an assignment of that temporary to a
//! variable at a fixed place makes the operation write the variable instead.

use crate::ast::{BinOp, Expr, ExprKind, Literal, Pos, Section};
use crate::code::{Arith, Op, Slot, TextAt};
use crate::error::Diagnostic;
use crate::types::{Elem, Size, Ty};

use super::konst::Const;
use super::{Compiler, Loc};

/// A value an expression computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Val {
    /// An elementary or enumeration value in a slot.
    Scalar(Ty, Slot),
    /// A string of this capacity at this text offset.
    Str(u16, TextAt),
    /// An array, structure or FB instance where it lies.
    Agg(Ty, Loc),
}

impl Val {
    /// Its type.
    pub fn ty(self) -> Ty {
        match self {
            Val::Scalar(ty, _) | Val::Agg(ty, _) => ty,
            Val::Str(cap, _) => Ty::String(cap),
        }
    }
}

/// A place that can be read or written, with what may be done to it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Place {
    /// Its type.
    pub ty: Ty,
    /// Where it is.
    pub loc: Loc,
    /// Whether an assignment may write it, and if not, why.
    pub write: Result<(), &'static str>,
}

impl<'a> Compiler<'a> {
    /// Compiles `e`, whose type must be `want` when a literal needs a context.
    pub fn expr(&mut self, e: &Expr, want: Option<Ty>) -> Result<Val, Diagnostic> {
        match &e.kind {
            ExprKind::Lit(lit) => self.literal(lit, want, e.pos),
            ExprKind::Name(id) if !self.scope().vars.contains_key(&id.key()) => {
                let unknown = || {
                    let what = format!("unknown variable `{}`: declare it in the POU", id.text);
                    Diagnostic::new(e.pos, what)
                };
                let Ok(Const::Enum(ty, v)) = self.constant(e, want) else {
                    return Err(unknown());
                };
                Ok(Val::Scalar(Ty::Enum(ty), self.const_slot(v as u64, e.pos)?))
            }
            ExprKind::Name(_) | ExprKind::Member(..) | ExprKind::Index(..) => {
                let p = self.place(e)?;
                self.read(p, e.pos)
            }
            ExprKind::Call(call) => self.call_expr(call, want),
            ExprKind::Unary(..) | ExprKind::Binary(..) => {
                let (v, wide) = self.operand(e, want)?;
                self.narrow(v, wide, e.pos)
            }
        }
    }

    /// Compiles `e` as a scalar of type `ty` exactly.
    pub fn scalar(&mut self, e: &Expr, ty: Ty) -> Result<Slot, Diagnostic> {
        match self.expr(e, Some(ty))? {
            Val::Scalar(t, slot) if t == ty => Ok(slot),
            v => Err(self.mismatch(e.pos, ty, v.ty())),
        }
    }

    /// Compiles `e` as a BOOL.
    pub fn condition(&mut self, e: &Expr) -> Result<Slot, Diagnostic> {
        self.scalar(e, Ty::Elem(Elem::Bool))
    }

    /// "expected X, found Y" with the conversion to write.
    pub fn mismatch(&self, pos: Pos, want: Ty, got: Ty) -> Diagnostic {
        let (w, g) = (self.describe(want), self.describe(got));
        let hint = match (want, got) {
            (Ty::Elem(a), Ty::Elem(b)) if a != b => format!("; convert it with {b}_TO_{a}"),
            _ => String::new(),
        };
        Diagnostic::new(pos, format!("type mismatch: expected {w}, found {g}{hint}"))
    }

    /// A slot that holds `bits` from the start and is never written.
    pub fn const_slot(&mut self, bits: u64, pos: Pos) -> Result<Slot, Diagnostic> {
        if let Some(&slot) = self.consts.get(&bits) {
            return Ok(slot);
        }
        let slot = self.alloc(Size { slots: 1, text: 0 }, pos)?.slots;
        self.init.slots[slot as usize] = bits;
        self.consts.insert(bits, slot);
        Ok(slot)
    }

    /// A literal as a constant slot (or text).
    pub fn literal(
        &mut self,
        lit: &Literal,
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        if let Literal::String(bytes) = lit {
            let cap = u16::try_from(bytes.len())
                .ok()
                .filter(|&n| n <= crate::types::MAX_STRING)
                .ok_or_else(|| {
                    Diagnostic::new(pos, "the string literal is longer than a STRING can be")
                })?;
            let at = self.string_temp(cap, pos)? as usize;
            self.init.text[at..at + 2].copy_from_slice(&cap.to_le_bytes());
            self.init.text[at + 2..at + 2 + bytes.len()].copy_from_slice(bytes);
            return Ok(Val::Str(cap, at as TextAt));
        }
        // 0 and 1 are BOOL literals too where a BOOL is wanted (IEC 61131-3 table 5; MATIEC
        // takes `x := 1` for a BOOL `x`).
        if let (Literal::Int { value, ty: None }, Some(Ty::Elem(Elem::Bool))) = (lit, want) {
            if matches!(value, 0 | 1) {
                let bool_ty = Ty::Elem(Elem::Bool);
                return Ok(Val::Scalar(bool_ty, self.const_slot(*value as u64, pos)?));
            }
        }
        let ty = self.literal_type(lit, want, pos)?;
        let c = self.constant(
            &Expr {
                kind: ExprKind::Lit(lit.clone()),
                pos,
            },
            want,
        )?;
        let bits = self.const_bits(&c, ty, pos)?;
        Ok(Val::Scalar(ty, self.const_slot(bits, pos)?))
    }

    /// The type of a literal: its prefix, else what the context wants, else DINT, LREAL.
    fn literal_type(
        &mut self,
        lit: &Literal,
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<Ty, Diagnostic> {
        let prefixed = |id: &crate::ast::Ident| {
            Elem::from_name(&id.key()).map(Ty::Elem).ok_or_else(|| {
                Diagnostic::new(
                    id.pos,
                    format!("`{}#` is not an elementary type prefix", id.text),
                )
            })
        };
        let want_num = want.filter(|t| t.elem().is_some_and(|e| e.is_num() || e.is_bits()));
        Ok(match lit {
            Literal::Int { ty: Some(id), .. } | Literal::Real { ty: Some(id), .. } => prefixed(id)?,
            Literal::Int { value, .. } => want_num.unwrap_or(if i32::try_from(*value).is_ok() {
                Ty::Elem(Elem::Dint)
            } else {
                Ty::Elem(Elem::Lint)
            }),
            Literal::Real { .. } => want
                .filter(|t| t.elem().is_some_and(Elem::is_real))
                .unwrap_or(Ty::Elem(Elem::Lreal)),
            Literal::Bool(_) => Ty::Elem(Elem::Bool),
            Literal::Time(_) => Ty::Elem(Elem::Time),
            Literal::Enum { .. } => match self.constant(
                &Expr {
                    kind: ExprKind::Lit(lit.clone()),
                    pos,
                },
                want,
            )? {
                Const::Enum(id, _) => Ty::Enum(id),
                _ => return Err(Diagnostic::new(pos, "expected an enumeration value")),
            },
            Literal::String(_) => {
                return Err(Diagnostic::new(
                    pos,
                    "a string literal here is not supported",
                ))
            }
        })
    }

    /// The type of `e` when it has one without context (not an untyped literal).
    pub fn peek(&mut self, e: &Expr) -> Option<Ty> {
        match &e.kind {
            ExprKind::Lit(Literal::Int { ty: None, .. } | Literal::Real { ty: None, .. }) => None,
            ExprKind::Lit(Literal::String(s)) => {
                Some(Ty::String(s.len().min(usize::from(u16::MAX)) as u16))
            }
            ExprKind::Lit(lit) => self.literal_type(lit, None, e.pos).ok(),
            ExprKind::Name(id) => match self.scope().vars.get(&id.key()) {
                Some(v) => Some(v.ty),
                None => match self.constant(e, None) {
                    Ok(Const::Enum(id, _)) => Some(Ty::Enum(id)),
                    _ => None,
                },
            },
            ExprKind::Member(..) | ExprKind::Index(..) => self.peek_place(e),
            ExprKind::Call(call) => self.peek_call(call),
            ExprKind::Unary(_, inner) => self.peek(inner),
            ExprKind::Binary(op, a, b) => match op {
                BinOp::Cmp(_) => Some(Ty::Elem(Elem::Bool)),
                _ => self.peek(a).or_else(|| self.peek(b)),
            },
        }
    }

    /// The type of a member or element, found without compiling anything.
    fn peek_place(&mut self, e: &Expr) -> Option<Ty> {
        match &e.kind {
            ExprKind::Name(id) => self.scope().vars.get(&id.key()).map(|v| v.ty),
            ExprKind::Member(base, field) => {
                let ty = self.peek_place(base)?;
                self.member_of(ty, &field.key()).map(|(t, _)| t)
            }
            ExprKind::Index(base, _) => match self.peek_place(base)? {
                Ty::Array(id) => Some(self.types.arrays[id as usize].elem),
                _ => None,
            },
            _ => None,
        }
    }

    /// Reads a place: a scalar or string where it lies, or copied out of a computed place.
    pub fn read(&mut self, p: Place, pos: Pos) -> Result<Val, Diagnostic> {
        match (p.ty, p.loc) {
            (Ty::Elem(_) | Ty::Enum(_), Loc::Static(at)) => Ok(Val::Scalar(p.ty, at.slots)),
            (Ty::Elem(_) | Ty::Enum(_), Loc::Dynamic { slot_addr, off, .. }) => {
                let dst = self.temp(pos)?;
                self.emit(
                    Op::LoadInd {
                        dst,
                        addr: slot_addr,
                        off: off.slots,
                    },
                    pos,
                )?;
                Ok(Val::Scalar(p.ty, dst))
            }
            (Ty::String(cap), Loc::Static(at)) => Ok(Val::Str(cap, at.text)),
            (Ty::String(cap), Loc::Dynamic { text_addr, off, .. }) => {
                let dst = self.string_temp(cap, pos)?;
                self.emit(
                    Op::TextFromInd {
                        dst,
                        addr: text_addr,
                        off: off.text,
                        len: u32::from(cap) + 2,
                    },
                    pos,
                )?;
                Ok(Val::Str(cap, dst))
            }
            (ty, loc) => Ok(Val::Agg(ty, loc)),
        }
    }

    /// The place `e` names: a variable, a member, an element.
    pub fn place(&mut self, e: &Expr) -> Result<Place, Diagnostic> {
        match &e.kind {
            ExprKind::Name(id) => {
                let Some(v) = self.scope().vars.get(&id.key()).cloned() else {
                    return Err(Diagnostic::new(
                        e.pos,
                        format!("unknown variable `{}`", id.text),
                    ));
                };
                let write = if v.constant {
                    Err("it is a CONSTANT")
                } else {
                    Ok(())
                };
                Ok(Place {
                    ty: v.ty,
                    loc: v.loc,
                    write,
                })
            }
            ExprKind::Member(base, field) => self.member_place(base, field),
            ExprKind::Index(base, idx) => self.element_place(base, idx, e.pos),
            _ => Err(Diagnostic::new(
                e.pos,
                "expected a variable, a member (a.b) or an element (a[i])",
            )),
        }
    }

    fn member_place(
        &mut self,
        base: &Expr,
        field: &crate::ast::Ident,
    ) -> Result<Place, Diagnostic> {
        let b = self.place(base)?;
        let Some((ty, at)) = self.member_of(b.ty, &field.key()) else {
            return Err(Diagnostic::new(
                field.pos,
                format!("{} has no member `{}`", self.describe(b.ty), field.text),
            ));
        };
        let write = match b.ty {
            Ty::Fb(id) => {
                let section = self.fbs[id as usize]
                    .fields
                    .iter()
                    .find(|(f, _)| f.key == field.key())
                    .map(|(_, s)| *s);
                match section {
                    Some(Section::Input | Section::InOut) => b.write,
                    Some(Section::Output) => Err("it is an output of the function block, which only the block writes"),
                    _ => return Err(Diagnostic::new(field.pos, format!("`{}` is internal to {}; only its inputs and outputs can be used outside it", field.text, self.describe(b.ty)))),
                }
            }
            _ => b.write,
        };
        Ok(Place {
            ty,
            loc: b.loc.offset(at),
            write,
        })
    }

    fn element_place(&mut self, base: &Expr, idx: &[Expr], pos: Pos) -> Result<Place, Diagnostic> {
        let b = self.place(base)?;
        let Ty::Array(id) = b.ty else {
            return Err(Diagnostic::new(
                pos,
                format!("{} is not an array", self.describe(b.ty)),
            ));
        };
        let a = self.types.arrays[id as usize].clone();
        if idx.len() != a.dims.len() {
            return Err(Diagnostic::new(
                pos,
                format!(
                    "the array has {} dimensions, indexed with {}",
                    a.dims.len(),
                    idx.len()
                ),
            ));
        }
        if let Some(lin) = self.constant_index(&a.dims, idx)? {
            let by = a.elem_size.times(lin).unwrap_or_default();
            return Ok(Place {
                ty: a.elem,
                loc: b.loc.offset(by),
                write: b.write,
            });
        }
        if let Some((fused, base)) = self.index1(b.loc, &a, pos)? {
            let i = &idx[0];
            let (e, slot) = self.integer(i, "an array index")?;
            let (lo, hi) = a.dims[0];
            self.emit(
                Op::Index1 {
                    e,
                    dst: fused,
                    idx: slot,
                    lo: lo as i32,
                    len: (hi - lo + 1) as u32,
                    base,
                },
                i.pos,
            )?;
            return Ok(Place {
                ty: a.elem,
                loc: Loc::Dynamic {
                    slot_addr: fused,
                    text_addr: fused,
                    off: Size::default(),
                },
                write: b.write,
            });
        }
        let acc = self.temp(pos)?;
        self.emit(Op::Const { dst: acc, bits: 0 }, pos)?;
        for (&(lo, hi), i) in a.dims.iter().zip(idx) {
            let (e, slot) = self.integer(i, "an array index")?;
            self.emit(
                Op::Index {
                    e,
                    acc,
                    idx: slot,
                    lo: lo as i32,
                    len: (hi - lo + 1) as u32,
                },
                i.pos,
            )?;
        }
        let loc = self.element_loc(b.loc, acc, a.elem_size, pos)?;
        Ok(Place {
            ty: a.elem,
            loc,
            write: b.write,
        })
    }

    /// A temporary for [`Op::Index1`] and the array's slot, when an element of `a` at `base` can
    /// be addressed in one instruction: a fixed place, one dimension, elements of one slot and
    /// no text (an elementary type or an enumeration; only their slot address is ever read).
    fn index1(
        &mut self,
        base: Loc,
        a: &crate::types::ArrayTy,
        pos: Pos,
    ) -> Result<Option<(Slot, u32)>, Diagnostic> {
        let one = Size { slots: 1, text: 0 };
        match base {
            Loc::Static(at) if a.dims.len() == 1 && a.elem_size == one => {
                Ok(Some((self.temp(pos)?, at.slots)))
            }
            _ => Ok(None),
        }
    }

    /// The linear index of constant indices, checked against the bounds.
    fn constant_index(&self, dims: &[(i64, i64)], idx: &[Expr]) -> Result<Option<u64>, Diagnostic> {
        let mut lin = 0u64;
        for (&(lo, hi), i) in dims.iter().zip(idx) {
            let Ok(v) = self.const_int(i) else {
                return Ok(None);
            };
            if v < i128::from(lo) || v > i128::from(hi) {
                return Err(Diagnostic::new(
                    i.pos,
                    format!("index {v} is outside the bounds {lo}..{hi}"),
                ));
            }
            lin = lin * (hi - lo + 1) as u64 + (v - i128::from(lo)) as u64;
        }
        Ok(Some(lin))
    }

    /// The computed place of the element at linear index `acc` of an array at `base`.
    fn element_loc(
        &mut self,
        base: Loc,
        acc: Slot,
        size: Size,
        pos: Pos,
    ) -> Result<Loc, Diagnostic> {
        let (slot_addr, text_addr) = (self.temp(pos)?, self.temp(pos)?);
        let (bs, bt, off) = match base {
            Loc::Static(at) => (at.slots, at.text, Size::default()),
            Loc::Dynamic { off, .. } => (0, 0, off),
        };
        self.emit(
            Op::Addr {
                dst: slot_addr,
                lin: acc,
                stride: size.slots,
                base: bs,
            },
            pos,
        )?;
        self.emit(
            Op::Addr {
                dst: text_addr,
                lin: acc,
                stride: size.text,
                base: bt,
            },
            pos,
        )?;
        if let Loc::Dynamic {
            slot_addr: s0,
            text_addr: t0,
            ..
        } = base
        {
            let e = Elem::Ulint;
            self.emit(
                Op::Arith {
                    op: Arith::Add,
                    e,
                    dst: slot_addr,
                    a: slot_addr,
                    b: s0,
                },
                pos,
            )?;
            self.emit(
                Op::Arith {
                    op: Arith::Add,
                    e,
                    dst: text_addr,
                    a: text_addr,
                    b: t0,
                },
                pos,
            )?;
        }
        Ok(Loc::Dynamic {
            slot_addr,
            text_addr,
            off,
        })
    }

    /// Writes `v` to the place `p`.
    pub fn store(&mut self, p: Place, v: Val, pos: Pos) -> Result<(), Diagnostic> {
        if let Err(why) = p.write {
            return Err(Diagnostic::new(pos, format!("cannot assign here: {why}")));
        }
        match (p.ty, p.loc, v) {
            (Ty::Elem(_) | Ty::Enum(_), loc, Val::Scalar(t, src)) if t == p.ty => {
                self.store_scalar(loc, src, pos)
            }
            (Ty::String(cap), loc, Val::Str(_, src)) => self.store_string(cap, loc, src, pos),
            (ty, loc, Val::Agg(t, from)) if t == ty => self.store_agg(ty, loc, from, pos),
            _ => Err(self.mismatch(pos, p.ty, v.ty())),
        }
    }

    fn store_scalar(&mut self, loc: Loc, src: Slot, pos: Pos) -> Result<(), Diagnostic> {
        match loc {
            Loc::Static(at) => {
                if !self.retarget(src, at.slots) {
                    self.emit(Op::Move { dst: at.slots, src }, pos)?;
                }
            }
            Loc::Dynamic { slot_addr, off, .. } => {
                self.emit(
                    Op::StoreInd {
                        addr: slot_addr,
                        off: off.slots,
                        src,
                    },
                    pos,
                )?;
            }
        }
        Ok(())
    }

    /// Makes the last instruction write `dst` instead of `temp`, when it wrote the temporary
    /// `temp` that nothing else reads; true if it did.
    fn retarget(&mut self, temp: Slot, dst: Slot) -> bool {
        if self.temps.binary_search(&temp).is_err() {
            return false;
        }
        let Some(d) = self.code.ops.last_mut().and_then(Op::result_mut) else {
            return false;
        };
        if *d != temp {
            return false;
        }
        *d = dst;
        true
    }

    fn store_string(
        &mut self,
        cap: u16,
        loc: Loc,
        src: TextAt,
        pos: Pos,
    ) -> Result<(), Diagnostic> {
        match loc {
            Loc::Static(at) => {
                self.emit(
                    Op::StrMove {
                        dst: at.text,
                        cap,
                        src,
                    },
                    pos,
                )?;
            }
            Loc::Dynamic { text_addr, off, .. } => {
                let tmp = self.string_temp(cap, pos)?;
                self.emit(Op::StrMove { dst: tmp, cap, src }, pos)?;
                self.emit(
                    Op::TextToInd {
                        addr: text_addr,
                        off: off.text,
                        src: tmp,
                        len: u32::from(cap) + 2,
                    },
                    pos,
                )?;
            }
        }
        Ok(())
    }

    fn store_agg(&mut self, ty: Ty, to: Loc, from: Loc, pos: Pos) -> Result<(), Diagnostic> {
        let size = self.size_of(ty);
        let src = match from {
            Loc::Static(at) => at,
            Loc::Dynamic {
                slot_addr,
                text_addr,
                off,
            } => {
                let tmp = self.alloc(size, pos)?;
                self.emit(
                    Op::CopyFromInd {
                        dst: tmp.slots,
                        addr: slot_addr,
                        off: off.slots,
                        len: size.slots,
                    },
                    pos,
                )?;
                self.emit(
                    Op::TextFromInd {
                        dst: tmp.text,
                        addr: text_addr,
                        off: off.text,
                        len: size.text,
                    },
                    pos,
                )?;
                tmp
            }
        };
        match to {
            Loc::Static(at) => {
                self.emit(
                    Op::Copy {
                        dst: at.slots,
                        src: src.slots,
                        len: size.slots,
                    },
                    pos,
                )?;
                self.emit(
                    Op::CopyText {
                        dst: at.text,
                        src: src.text,
                        len: size.text,
                    },
                    pos,
                )?;
            }
            Loc::Dynamic {
                slot_addr,
                text_addr,
                off,
            } => {
                self.emit(
                    Op::CopyToInd {
                        addr: slot_addr,
                        off: off.slots,
                        src: src.slots,
                        len: size.slots,
                    },
                    pos,
                )?;
                self.emit(
                    Op::TextToInd {
                        addr: text_addr,
                        off: off.text,
                        src: src.text,
                        len: size.text,
                    },
                    pos,
                )?;
            }
        }
        Ok(())
    }
}
