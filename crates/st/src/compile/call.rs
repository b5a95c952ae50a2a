//! Calls of user functions and function blocks, expanded where they are made.
//!
//! A function block call sets the instance's inputs, runs its body on the instance's state, and
//! copies its outputs where `=>` sends them. A function call runs the function's body on a frame
//! of its own for this call site, which starts from the function's initial values each time
//! (IEC 61131-3 §6.6.2.2: a function has no memory). VAR_IN_OUT is copied in before the body
//! and back after it, which is passing by reference for every call that does not name one
//! variable twice (docs/st.md).

use crate::ast::{Arg, Call, Expr, ExprKind, Ident, Pos, Pou, PouKind, Section};
use crate::code::Op;
use crate::error::Diagnostic;
use crate::types::{Elem, FbId, Size, Ty};

use super::decl::{members, offset};
use super::expr::{Place, Val};
use super::{Compiler, FbKind, Loc, Scope, VarRef, MAX_CALL_DEPTH};

/// A member of a callee's frame: its name, section, type and place.
struct Param {
    key: String,
    section: Section,
    ty: Ty,
    at: Size,
}

impl<'a> Compiler<'a> {
    /// A call as a statement: an FB instance's call, or a function whose result is dropped.
    pub fn call_stmt(&mut self, call: &Call) -> Result<(), Diagnostic> {
        if let ExprKind::Name(id) = &call.callee.kind {
            if !self.scope().vars.contains_key(&id.key()) {
                return self.call_expr(call, None).map(|_| ());
            }
        }
        let p = self.place(&call.callee)?;
        let Ty::Fb(id) = p.ty else {
            return Err(Diagnostic::new(
                call.pos,
                format!(
                    "{} is not a function block instance, so it cannot be called",
                    self.describe(p.ty)
                ),
            ));
        };
        self.fb_call(id, p.loc, &call.args, call.pos)
    }

    /// A call in an expression: a user or standard function.
    pub fn call_expr(&mut self, call: &Call, want: Option<Ty>) -> Result<Val, Diagnostic> {
        let ExprKind::Name(id) = &call.callee.kind else {
            return Err(Diagnostic::new(call.pos, "only functions can be called in an expression; call a function block instance as a statement and read its outputs"));
        };
        let key = id.key();
        if let Some(&pou) = self.functions.get(&key) {
            return self.function_call(pou, &call.args, call.pos);
        }
        if self
            .scope()
            .vars
            .get(&key)
            .is_some_and(|v| matches!(v.ty, Ty::Fb(_)))
        {
            return Err(Diagnostic::new(call.pos, format!("`{}` is a function block instance: call it as a statement, then read its outputs (`{}.Q`)", id.text, id.text)));
        }
        self.standard_call(id, &call.args, want, call.pos)
    }

    /// The result type of a call, without compiling it.
    pub fn peek_call(&mut self, call: &Call) -> Option<Ty> {
        let ExprKind::Name(id) = &call.callee.kind else {
            return None;
        };
        let key = id.key();
        if let Some(&pou) = self.functions.get(&key) {
            let PouKind::Function(ret) = &pou.kind else {
                return None;
            };
            return self.resolve_type(ret).ok();
        }
        self.peek_standard(&key, &call.args)
    }

    fn fb_call(&mut self, id: FbId, loc: Loc, args: &[Arg], pos: Pos) -> Result<(), Diagnostic> {
        let size = self.fbs[id as usize].size;
        // An instance at a computed place (an element of an array of instances) runs on a copy.
        let at = match loc {
            Loc::Static(at) => at,
            Loc::Dynamic { .. } => {
                let tmp = self.alloc(size, pos)?;
                let from = Val::Agg(Ty::Fb(id), loc);
                self.store(
                    Place {
                        ty: Ty::Fb(id),
                        loc: Loc::Static(tmp),
                        write: Ok(()),
                    },
                    from,
                    pos,
                )?;
                tmp
            }
        };
        let params: Vec<Param> = self.fbs[id as usize]
            .fields
            .iter()
            .map(|(f, s)| Param {
                key: f.key.clone(),
                section: *s,
                ty: f.ty,
                at: offset(at, f.at),
            })
            .collect();
        let outs = self.bind_inputs(&params, args, &self.fbs[id as usize].name.clone())?;
        match self.fbs[id as usize].kind.clone() {
            FbKind::Std(fb) => {
                self.emit(Op::StdFb { fb, base: at.slots }, pos)?;
            }
            FbKind::User(pou) => self.expand(pou, &params, true, pos)?,
        }
        self.bind_outputs(&params, &outs)?;
        if let Loc::Dynamic { .. } = loc {
            let back = Place {
                ty: Ty::Fb(id),
                loc,
                write: Ok(()),
            };
            self.store(back, Val::Agg(Ty::Fb(id), Loc::Static(at)), pos)?;
        }
        Ok(())
    }

    fn function_call(&mut self, pou: &'a Pou, args: &[Arg], pos: Pos) -> Result<Val, Diagnostic> {
        let PouKind::Function(ret) = &pou.kind else {
            return Err(Diagnostic::new(pos, "not a function"));
        };
        let ret = self.resolve_type(ret)?;
        let mut params = vec![];
        let frame_start = self.alloc(Size::default(), pos)?;
        let result = self.alloc(self.size_of(ret), pos)?;
        params.push(Param {
            key: pou.name.key(),
            section: Section::Output,
            ty: ret,
            at: result,
        });
        for (name, m) in members(pou) {
            if m.section == Section::External {
                continue;
            }
            let ty = self.resolve_type(&m.decl.ty)?;
            let at = self.alloc(self.size_of(ty), name.pos)?;
            self.init_var(ty, at, m.decl.init.as_ref())?;
            params.push(Param {
                key: name.key(),
                section: m.section,
                ty,
                at,
            });
        }
        let frame_end = self.alloc(Size::default(), pos)?;
        let frame = Size {
            slots: frame_end.slots - frame_start.slots,
            text: frame_end.text - frame_start.text,
        };
        self.reinit(frame_start, frame, pos)?;
        let outs = self.bind_inputs(&params[1..], args, &pou.name.text)?;
        self.expand(pou, &params, false, pos)?;
        self.bind_outputs(&params[1..], &outs)?;
        self.read(
            Place {
                ty: ret,
                loc: Loc::Static(result),
                write: Ok(()),
            },
            pos,
        )
    }

    /// Sets a callee's inputs and in-outs from the arguments; the `=>` outputs and in-outs to
    /// copy back after the call.
    fn bind_inputs<'e>(
        &mut self,
        params: &[Param],
        args: &'e [Arg],
        callee: &str,
    ) -> Result<Vec<(usize, &'e Expr, bool)>, Diagnostic> {
        let mut outs = Vec::new();
        let inputs: Vec<usize> = (0..params.len())
            .filter(|&i| matches!(params[i].section, Section::Input | Section::InOut))
            .collect();
        for (n, arg) in args.iter().enumerate() {
            let (i, value) = match arg {
                Arg::Positional(e) => match inputs.get(n) {
                    Some(&i) => (i, e),
                    None => {
                        return Err(Diagnostic::new(
                            e.pos,
                            format!(
                                "`{callee}` takes {} inputs, this is argument {}",
                                inputs.len(),
                                n + 1
                            ),
                        ))
                    }
                },
                Arg::Input(name, e) => (
                    self.param(params, name, &[Section::Input, Section::InOut], callee)?,
                    e,
                ),
                Arg::Output {
                    name,
                    target,
                    negated,
                } => {
                    outs.push((
                        self.param(params, name, &[Section::Output, Section::InOut], callee)?,
                        target,
                        *negated,
                    ));
                    continue;
                }
            };
            let p = &params[i];
            let to = Place {
                ty: p.ty,
                loc: Loc::Static(p.at),
                write: Ok(()),
            };
            let v = self.expr(value, Some(p.ty))?;
            self.store(to, v, value.pos)?;
            if p.section == Section::InOut {
                outs.push((i, value, false));
            }
        }
        Ok(outs)
    }

    fn param(
        &self,
        params: &[Param],
        name: &Ident,
        sections: &[Section],
        callee: &str,
    ) -> Result<usize, Diagnostic> {
        let key = name.key();
        if key == "EN" || key == "ENO" {
            return Err(Diagnostic::new(
                name.pos,
                "EN and ENO are not supported: call the block inside an IF instead",
            ));
        }
        params
            .iter()
            .position(|p| p.key == key && sections.contains(&p.section))
            .ok_or_else(|| {
                let kinds: Vec<&str> = sections.iter().map(|s| s.keyword()).collect();
                Diagnostic::new(
                    name.pos,
                    format!(
                        "`{callee}` has no {} named `{}`",
                        kinds.join(" or "),
                        name.text
                    ),
                )
            })
    }

    /// Copies the outputs and in-outs a call sends back.
    fn bind_outputs(
        &mut self,
        params: &[Param],
        outs: &[(usize, &Expr, bool)],
    ) -> Result<(), Diagnostic> {
        for &(i, target, negated) in outs {
            let p = &params[i];
            let mut v = self.read(
                Place {
                    ty: p.ty,
                    loc: Loc::Static(p.at),
                    write: Ok(()),
                },
                target.pos,
            )?;
            if negated {
                let Val::Scalar(Ty::Elem(Elem::Bool), a) = v else {
                    return Err(Diagnostic::new(
                        target.pos,
                        "NOT before `=>` applies to a BOOL output",
                    ));
                };
                let dst = self.temp(target.pos)?;
                self.emit(
                    Op::Not {
                        e: Elem::Bool,
                        dst,
                        a,
                    },
                    target.pos,
                )?;
                v = Val::Scalar(Ty::Elem(Elem::Bool), dst);
            }
            let to = self.place(target)?;
            self.store(to, v, target.pos)?;
        }
        Ok(())
    }

    /// Compiles the body of `pou` in a scope of its parameters.
    fn expand(
        &mut self,
        pou: &'a Pou,
        params: &[Param],
        in_fb: bool,
        pos: Pos,
    ) -> Result<(), Diagnostic> {
        let key = pou.name.key();
        if self.scopes.iter().any(|s| s.pou == key) {
            return Err(Diagnostic::new(pos, format!("`{}` calls itself, directly or through others; IEC 61131-3 does not allow recursion", pou.name.text)));
        }
        if self.scopes.len() > MAX_CALL_DEPTH {
            return Err(Diagnostic::new(
                pos,
                format!("calls nested more than {MAX_CALL_DEPTH} deep"),
            ));
        }
        let mut scope = Scope {
            pou: key,
            ..Scope::default()
        };
        let mut temps = Vec::new();
        for p in params {
            scope.vars.insert(
                p.key.clone(),
                VarRef {
                    ty: p.ty,
                    loc: Loc::Static(p.at),
                    constant: false,
                },
            );
            if in_fb && p.section == Section::Temp {
                temps.push((p.at, self.size_of(p.ty)));
            }
        }
        for (name, m) in members(pou) {
            if m.section == Section::External {
                let global = self.external(&name, &m)?;
                scope.vars.insert(name.key(), global);
            }
        }
        self.scopes.push(scope);
        let done = temps
            .into_iter()
            .try_for_each(|(at, size)| self.reinit(at, size, pos))
            .and_then(|()| self.body(&pou.body));
        self.scopes.pop();
        done
    }
}
