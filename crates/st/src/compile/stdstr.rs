//! The selection functions on strings (MAX, MIN, LIMIT, MUX) and the conversions to STRING, with
//! MATIEC's semantics: strings compare byte-wise, the longer greater after a common prefix.

use crate::ast::{Expr, Pos, Rel};
use crate::code::{Op, Slot, TextAt};
use crate::error::Diagnostic;
use crate::types::{Elem, Ty, MAX_STRING};

use super::expr::Val;
use super::Compiler;

impl<'a> Compiler<'a> {
    /// MAX, MIN, LIMIT or MUX whose inputs are strings, if they are: `None` for numbers.
    pub fn string_selection(
        &mut self,
        key: &str,
        args: &[&Expr],
        pos: Pos,
    ) -> Option<Result<Val, Diagnostic>> {
        let inputs = if key == "MUX" { args.get(1..)? } else { args };
        let is_string = inputs
            .iter()
            .any(|a| matches!(self.peek(a), Some(Ty::String(_))));
        if !is_string {
            return None;
        }
        Some(match key {
            "MAX" => self.string_extreme(args, Rel::Lt, pos),
            "MIN" => self.string_extreme(args, Rel::Gt, pos),
            "LIMIT" => self.string_limit(args, pos),
            _ => self.string_mux(args, pos),
        })
    }

    /// Compiles each argument as a string.
    fn strings(&mut self, args: &[&Expr]) -> Result<Vec<(u16, TextAt)>, Diagnostic> {
        let mut out = Vec::with_capacity(args.len());
        for a in args {
            match self.expr(a, None)? {
                Val::Str(cap, at) => out.push((cap, at)),
                v => return Err(self.mismatch(a.pos, Ty::String(80), v.ty())),
            }
        }
        Ok(out)
    }

    /// A string temporary large enough for any of `texts`.
    fn string_result(
        &mut self,
        texts: &[(u16, TextAt)],
        pos: Pos,
    ) -> Result<(u16, TextAt), Diagnostic> {
        let cap = texts.iter().map(|t| t.0).max().unwrap_or(1).min(MAX_STRING);
        let at = self.string_temp(cap, pos)?;
        Ok((cap, at))
    }

    /// `dst := src` when slot `c` is true.
    fn move_if(
        &mut self,
        c: Slot,
        (cap, dst): (u16, TextAt),
        src: TextAt,
        pos: Pos,
    ) -> Result<(), Diagnostic> {
        let skip = self.emit(Op::JumpUnless { c, to: 0 }, pos)?;
        self.emit(Op::StrMove { dst, cap, src }, pos)?;
        let next = self.here();
        self.patch(skip, next);
        Ok(())
    }

    /// MATIEC's MAX (`op1 = (op1 < tmp) ? tmp : op1`) or MIN (with `>`), on strings.
    fn string_extreme(
        &mut self,
        args: &[&Expr],
        replace_when: Rel,
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        if args.len() < 2 {
            return Err(Diagnostic::new(
                pos,
                "MAX and MIN take two or more arguments",
            ));
        }
        let texts = self.strings(args)?;
        let out = self.string_result(&texts, pos)?;
        self.emit(
            Op::StrMove {
                dst: out.1,
                cap: out.0,
                src: texts[0].1,
            },
            pos,
        )?;
        for &(_, at) in &texts[1..] {
            let c = self.temp(pos)?;
            self.emit(
                Op::StrCmp {
                    op: replace_when,
                    dst: c,
                    a: out.1,
                    b: at,
                },
                pos,
            )?;
            self.move_if(c, out, at, pos)?;
        }
        Ok(Val::Str(out.0, out.1))
    }

    /// A temporary that holds `a op b` of two strings.
    fn str_compare(&mut self, op: Rel, a: TextAt, b: TextAt, pos: Pos) -> Result<Slot, Diagnostic> {
        let dst = self.temp(pos)?;
        self.emit(Op::StrCmp { op, dst, a, b }, pos)?;
        Ok(dst)
    }

    /// LIMIT(MN, IN, MX) on strings: `IN > MN ? (IN < MX ? IN : MX) : MN`.
    fn string_limit(&mut self, args: &[&Expr], pos: Pos) -> Result<Val, Diagnostic> {
        if args.len() != 3 {
            return Err(Diagnostic::new(
                pos,
                "LIMIT takes three arguments: MN, IN, MX",
            ));
        }
        let t = self.strings(args)?;
        let (mn, x, mx) = (t[0].1, t[1].1, t[2].1);
        let out = self.string_result(&t, pos)?;
        let above = self.str_compare(Rel::Gt, x, mn, pos)?;
        let below = self.str_compare(Rel::Lt, x, mx, pos)?;
        let not_above = self.temp(pos)?;
        self.emit(
            Op::Not {
                e: Elem::Bool,
                dst: not_above,
                a: above,
            },
            pos,
        )?;
        // Written in the order that leaves the right one last: MX, then IN if below, then MN.
        self.emit(
            Op::StrMove {
                dst: out.1,
                cap: out.0,
                src: mx,
            },
            pos,
        )?;
        self.move_if(below, out, x, pos)?;
        self.move_if(not_above, out, mn, pos)?;
        Ok(Val::Str(out.0, out.1))
    }

    /// MUX(K, IN0, …) on strings: the input numbered K, or '' when K is out of range.
    fn string_mux(&mut self, args: &[&Expr], pos: Pos) -> Result<Val, Diagnostic> {
        let (ke, k) = self.integer(args[0], "MUX's selector K")?;
        let texts = self.strings(&args[1..])?;
        let out = self.string_result(&texts, pos)?;
        self.code.literals.push(Vec::new());
        let empty = self.code.literals.len() as u32 - 1;
        self.emit(
            Op::StrLit {
                dst: out.1,
                cap: out.0,
                lit: empty,
            },
            pos,
        )?;
        for (i, &(_, at)) in texts.iter().enumerate() {
            let hit = self.selects(ke, k, i, pos)?;
            self.move_if(hit, out, at, pos)?;
        }
        Ok(Val::Str(out.0, out.1))
    }

    /// `<from>_TO_STRING(x)`, as MATIEC prints: `TRUE`/`FALSE`, decimal integers, bit strings
    /// as `16#…` in lower-case hex, reals as C's `%.10g`.
    pub fn converted_to_string(
        &mut self,
        arg: &Expr,
        from: Elem,
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        let a = self.scalar(arg, Ty::Elem(from))?;
        let cap = 40;
        let dst = self.string_temp(cap, pos)?;
        self.emit(
            Op::ToStr {
                e: from,
                dst,
                cap,
                a,
            },
            pos,
        )?;
        Ok(Val::Str(cap, dst))
    }

    /// `STRING_TO_<to>(s)`, read as MATIEC's library reads it (docs/st.md, *Strings*).
    pub fn converted_from_string(
        &mut self,
        arg: &Expr,
        to: Elem,
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        let texts = self.strings(&[arg])?;
        let dst = self.temp(pos)?;
        self.emit(
            Op::FromStr {
                e: to,
                dst,
                s: texts[0].1,
            },
            pos,
        )?;
        Ok(Val::Scalar(Ty::Elem(to), dst))
    }
}
