//! Statements: assignments, calls, IF, CASE, the three loops, EXIT and RETURN.
//!
//! Every loop closes with an [`Op::Loop`] that charges its body's cost to the work budget each
//! time round, so the budget bounds what any loop can do; code outside loops only jumps forward.

use crate::ast::{CaseLabel, Expr, ExprKind, Pos, Rel, Stmt, StmtKind};
use crate::code::{Arith, Op, Slot};
use crate::error::Diagnostic;
use crate::types::{Elem, Size, Ty};

use super::expr::Val;
use super::{Compiler, Loc, LoopCtx};

impl<'a> Compiler<'a> {
    /// Compiles the body of a POU; its `RETURN`s jump to its end.
    pub fn body(&mut self, stmts: &[Stmt]) -> Result<(), Diagnostic> {
        self.returns.push(Vec::new());
        let outer_loops = std::mem::take(&mut self.loops);
        let done = self.statements(stmts);
        self.loops = outer_loops;
        let end = self.here();
        for j in self.returns.pop().unwrap_or_default() {
            self.patch(j, end);
        }
        done
    }

    fn statements(&mut self, stmts: &[Stmt]) -> Result<(), Diagnostic> {
        stmts.iter().try_for_each(|s| self.statement(s))
    }

    fn statement(&mut self, s: &Stmt) -> Result<(), Diagnostic> {
        match &s.kind {
            StmtKind::Assign { target, value } => {
                let p = self.place(target)?;
                let v = self.expr(value, Some(p.ty))?;
                self.store(p, v, s.pos)
            }
            StmtKind::Call(call) => self.call_stmt(call),
            StmtKind::If { arms, otherwise } => self.if_stmt(arms, otherwise),
            StmtKind::Case {
                selector,
                arms,
                otherwise,
            } => self.case_stmt(selector, arms, otherwise, s.pos),
            StmtKind::For {
                var,
                from,
                to,
                by,
                body,
            } => {
                let var = Expr {
                    kind: ExprKind::Name(var.clone()),
                    pos: var.pos,
                };
                self.for_stmt(&var, from, to, by.as_ref(), body, s.pos)
            }
            StmtKind::While { cond, body } => self.while_stmt(cond, body, s.pos),
            StmtKind::Repeat { body, until } => self.repeat_stmt(body, until, s.pos),
            StmtKind::Exit => {
                let j = self.emit(Op::Jump { to: 0 }, s.pos)?;
                match self.loops.last_mut() {
                    Some(l) => l.exits.push(j),
                    None => {
                        return Err(Diagnostic::new(
                            s.pos,
                            "EXIT outside a loop: it leaves the innermost FOR, WHILE or REPEAT",
                        ))
                    }
                }
                Ok(())
            }
            StmtKind::Return => {
                let j = self.emit(Op::Jump { to: 0 }, s.pos)?;
                if let Some(r) = self.returns.last_mut() {
                    r.push(j);
                }
                Ok(())
            }
            StmtKind::Empty => Ok(()),
        }
    }

    fn if_stmt(
        &mut self,
        arms: &[(Expr, Vec<Stmt>)],
        otherwise: &[Stmt],
    ) -> Result<(), Diagnostic> {
        let mut ends = Vec::new();
        for (i, (cond, body)) in arms.iter().enumerate() {
            let c = self.condition(cond)?;
            let skip = self.emit(Op::JumpUnless { c, to: 0 }, cond.pos)?;
            self.statements(body)?;
            if i + 1 < arms.len() || !otherwise.is_empty() {
                ends.push(self.emit(Op::Jump { to: 0 }, cond.pos)?);
            }
            self.patch_here(skip);
        }
        self.close_arms(otherwise, ends)
    }

    /// Points the jump at `j` here.
    fn patch_here(&mut self, j: usize) {
        let here = self.here();
        self.patch(j, here);
    }

    /// The ELSE of an IF or CASE, then the end its arms' jumps `ends` go to.
    fn close_arms(&mut self, otherwise: &[Stmt], ends: Vec<usize>) -> Result<(), Diagnostic> {
        self.statements(otherwise)?;
        ends.into_iter().for_each(|j| self.patch_here(j));
        Ok(())
    }

    fn case_stmt(
        &mut self,
        selector: &Expr,
        arms: &[(Vec<CaseLabel>, Vec<Stmt>)],
        otherwise: &[Stmt],
        pos: Pos,
    ) -> Result<(), Diagnostic> {
        let sel = self.expr(selector, None)?;
        let (ty, s) = match sel {
            Val::Scalar(ty @ Ty::Enum(_), s) => (ty, s),
            Val::Scalar(ty @ Ty::Elem(e), s) if e.is_int() || e.is_bits() => (ty, s),
            v => {
                return Err(Diagnostic::new(
                    selector.pos,
                    format!(
                        "a CASE selector is an integer or an enumeration, found {}",
                        self.describe(v.ty())
                    ),
                ))
            }
        };
        let e = ty.elem().unwrap_or(Elem::Lint);
        let mut ends = Vec::new();
        for (labels, body) in arms {
            let mut hits = Vec::new();
            for label in labels {
                hits.push(self.case_label(label, ty, e, s)?);
            }
            let miss = self.emit(Op::Jump { to: 0 }, pos)?;
            let start = self.here();
            hits.into_iter().for_each(|j| self.patch(j, start));
            self.statements(body)?;
            ends.push(self.emit(Op::Jump { to: 0 }, pos)?);
            self.patch_here(miss);
        }
        self.close_arms(otherwise, ends)
    }

    /// The test of one CASE label: a jump taken when the selector `s` matches.
    fn case_label(
        &mut self,
        label: &CaseLabel,
        ty: Ty,
        e: Elem,
        s: Slot,
    ) -> Result<usize, Diagnostic> {
        match label {
            CaseLabel::Value(v) => {
                let b = self.case_value(v, ty)?;
                let t = self.temp(v.pos)?;
                self.emit(
                    Op::Cmp {
                        op: Rel::Eq,
                        e,
                        dst: t,
                        a: s,
                        b,
                    },
                    v.pos,
                )?;
                self.emit(Op::JumpIf { c: t, to: 0 }, v.pos)
            }
            CaseLabel::Range(lo, hi) => {
                let (l, h) = (self.case_value(lo, ty)?, self.case_value(hi, ty)?);
                let (t1, t2, t) = (self.temp(lo.pos)?, self.temp(lo.pos)?, self.temp(lo.pos)?);
                self.emit(
                    Op::Cmp {
                        op: Rel::Ge,
                        e,
                        dst: t1,
                        a: s,
                        b: l,
                    },
                    lo.pos,
                )?;
                self.emit(
                    Op::Cmp {
                        op: Rel::Le,
                        e,
                        dst: t2,
                        a: s,
                        b: h,
                    },
                    hi.pos,
                )?;
                self.emit(
                    Op::Arith {
                        op: Arith::And,
                        e: Elem::Bool,
                        dst: t,
                        a: t1,
                        b: t2,
                    },
                    lo.pos,
                )?;
                self.emit(Op::JumpIf { c: t, to: 0 }, lo.pos)
            }
        }
    }

    /// A CASE label's value: a constant of the selector's type.
    fn case_value(&mut self, v: &Expr, ty: Ty) -> Result<Slot, Diagnostic> {
        let c = self.constant(v, Some(ty))?;
        let bits = self.const_bits(&c, ty, v.pos)?;
        self.const_slot(bits, v.pos)
    }

    /// FOR: the bounds and step are evaluated once, before the first iteration (docs/st.md).
    fn for_stmt(
        &mut self,
        var: &Expr,
        from: &Expr,
        to: &Expr,
        by: Option<&Expr>,
        body: &[Stmt],
        pos: Pos,
    ) -> Result<(), Diagnostic> {
        let p = self.place(var)?;
        let (Ty::Elem(e), Loc::Static(at)) = (p.ty, p.loc) else {
            return Err(Diagnostic::new(
                var.pos,
                "a FOR loop's control variable is an integer variable",
            ));
        };
        if !e.is_int() {
            return Err(Diagnostic::new(
                var.pos,
                format!("a FOR loop's control variable is an integer, found {e}"),
            ));
        }
        let v = at.slots;
        let first = self.expr(from, Some(p.ty))?;
        self.store(p, first, from.pos)?;
        let last = self.copied(to, p.ty)?;
        let step = match by {
            Some(b) => self.copied(b, p.ty)?,
            None => self.const_slot(1, pos)?,
        };
        let direction = by.map_or(Ok(1), |b| self.const_int(b).map(|v| v.signum()));
        let head = self.here();
        let go = self.for_test(e, v, last, step, direction.ok(), pos)?;
        let exit = self.emit(Op::JumpUnless { c: go, to: 0 }, pos)?;
        self.loop_body(body)?;
        self.emit(
            Op::Arith {
                op: Arith::Add,
                e,
                dst: v,
                a: v,
                b: step,
            },
            pos,
        )?;
        if super::operator::promoted(e) {
            self.emit(
                Op::Conv {
                    from: Elem::Dint,
                    to: e,
                    dst: v,
                    a: v,
                },
                pos,
            )?;
        }
        self.close_loop(head, exit, pos)
    }

    /// `e` evaluated once into a slot of its own, so that the body cannot change it.
    fn copied(&mut self, e: &Expr, ty: Ty) -> Result<Slot, Diagnostic> {
        let src = self.scalar(e, ty)?;
        let dst = self.temp(e.pos)?;
        self.emit(Op::Move { dst, src }, e.pos)?;
        Ok(dst)
    }

    /// Whether the FOR loop goes on: `v <= last` for a positive step, `v >= last` for a negative
    /// one, and a test of the step's sign when it is not a constant.
    fn for_test(
        &mut self,
        e: Elem,
        v: Slot,
        last: Slot,
        step: Slot,
        direction: Option<i128>,
        pos: Pos,
    ) -> Result<Slot, Diagnostic> {
        match direction {
            Some(d) if d > 0 => self.compare(Rel::Le, e, v, last, pos),
            Some(d) if d < 0 => self.compare(Rel::Ge, e, v, last, pos),
            _ => {
                // (step > 0 AND v <= last) OR (NOT step > 0 AND v >= last)
                let zero = self.const_slot(0, pos)?;
                let up = self.compare(Rel::Gt, e, step, zero, pos)?;
                let le = self.compare(Rel::Le, e, v, last, pos)?;
                let ge = self.compare(Rel::Ge, e, v, last, pos)?;
                let rising = self.logic(Arith::And, up, le, pos)?;
                let down = self.temp(pos)?;
                let bool_ = Elem::Bool;
                self.emit(
                    Op::Not {
                        e: bool_,
                        dst: down,
                        a: up,
                    },
                    pos,
                )?;
                let falling = self.logic(Arith::And, down, ge, pos)?;
                self.logic(Arith::Or, rising, falling, pos)
            }
        }
    }

    /// A temporary that holds `a op b` of two BOOLs.
    fn logic(&mut self, op: Arith, a: Slot, b: Slot, pos: Pos) -> Result<Slot, Diagnostic> {
        let dst = self.temp(pos)?;
        let e = Elem::Bool;
        self.emit(Op::Arith { op, e, dst, a, b }, pos)?;
        Ok(dst)
    }

    fn while_stmt(&mut self, cond: &Expr, body: &[Stmt], pos: Pos) -> Result<(), Diagnostic> {
        let head = self.here();
        let c = self.condition(cond)?;
        let exit = self.emit(Op::JumpUnless { c, to: 0 }, cond.pos)?;
        self.loop_body(body)?;
        self.close_loop(head, exit, pos)
    }

    fn repeat_stmt(&mut self, body: &[Stmt], until: &Expr, pos: Pos) -> Result<(), Diagnostic> {
        let head = self.here();
        self.loop_body(body)?;
        let c = self.condition(until)?;
        let exit = self.emit(Op::JumpIf { c, to: 0 }, until.pos)?;
        self.close_loop(head, exit, pos)
    }

    /// A loop's statements, with a context for their `EXIT`s.
    fn loop_body(&mut self, body: &[Stmt]) -> Result<(), Diagnostic> {
        self.loops.push(LoopCtx::default());
        self.statements(body)
    }

    /// The backward jump to `head`, charging what one time round costs; `exit` and the loop's
    /// `EXIT`s jump past it.
    fn close_loop(&mut self, head: u32, exit: usize, pos: Pos) -> Result<(), Diagnostic> {
        let code = &self.code;
        let cost: u64 = code.ops[head as usize..]
            .iter()
            .map(|op| op.cost(code))
            .sum::<u64>()
            + 1;
        self.emit(
            Op::Loop {
                to: head,
                cost: u32::try_from(cost).unwrap_or(u32::MAX),
            },
            pos,
        )?;
        let end = self.here();
        self.patch(exit, end);
        if let Some(ctx) = self.loops.pop() {
            ctx.exits.into_iter().for_each(|j| self.patch(j, end));
        }
        Ok(())
    }

    /// Copies the initial values at `at` to a template, and emits the copy that puts them back:
    /// for variables that start afresh at every call (VAR_TEMP, a function's variables).
    pub fn reinit(&mut self, at: Size, size: Size, pos: Pos) -> Result<(), Diagnostic> {
        if size == Size::default() {
            return Ok(());
        }
        let tpl = self.alloc(size, pos)?;
        let (s, t) = (at.slots as usize, at.text as usize);
        self.init
            .slots
            .copy_within(s..s + size.slots as usize, tpl.slots as usize);
        self.init
            .text
            .copy_within(t..t + size.text as usize, tpl.text as usize);
        if size.slots > 0 {
            self.emit(
                Op::Copy {
                    dst: at.slots,
                    src: tpl.slots,
                    len: size.slots,
                },
                pos,
            )?;
        }
        if size.text > 0 {
            self.emit(
                Op::CopyText {
                    dst: at.text,
                    src: tpl.text,
                    len: size.text,
                },
                pos,
            )?;
        }
        Ok(())
    }
}
