//! The standard functions of IEC 61131-3 (§6.6.2.5): conversions, numeric, arithmetic, bit
//! shift, bitwise, selection, comparison and string functions, each with the semantics of
//! MATIEC's library where the standard leaves a choice (docs/st.md, *The standard library*).

use crate::ast::{Arg, BinOp, Expr, ExprKind, Ident, Pos, Rel, UnOp};
use crate::code::{Arith, MathFn, Op, ShiftFn, Slot, StrArgs, StrFn};
use crate::error::Diagnostic;
use crate::types::{Elem, Ty, MAX_STRING};

use super::expr::Val;
use super::Compiler;

/// The functions with fixed parameter names, for formal calls (`LEFT(IN := s, L := 2)`).
const PARAMS: &[(&str, &[&str])] = &[
    ("LEFT", &["IN", "L"]),
    ("RIGHT", &["IN", "L"]),
    ("MID", &["IN", "L", "P"]),
    ("INSERT", &["IN1", "IN2", "P"]),
    ("DELETE", &["IN", "L", "P"]),
    ("REPLACE", &["IN1", "IN2", "L", "P"]),
    ("FIND", &["IN1", "IN2"]),
    ("LEN", &["IN"]),
    ("SEL", &["G", "IN0", "IN1"]),
    ("LIMIT", &["MN", "IN", "MX"]),
    ("SHL", &["IN", "N"]),
    ("SHR", &["IN", "N"]),
    ("ROL", &["IN", "N"]),
    ("ROR", &["IN", "N"]),
    ("EXPT", &["IN1", "IN2"]),
];

const MATH: [(&str, MathFn); 11] = [
    ("ABS", MathFn::Abs),
    ("SQRT", MathFn::Sqrt),
    ("LN", MathFn::Ln),
    ("LOG", MathFn::Log),
    ("EXP", MathFn::Exp),
    ("SIN", MathFn::Sin),
    ("COS", MathFn::Cos),
    ("TAN", MathFn::Tan),
    ("ASIN", MathFn::Asin),
    ("ACOS", MathFn::Acos),
    ("ATAN", MathFn::Atan),
];

const OPERATORS: [(&str, BinOp); 13] = [
    ("ADD", BinOp::Add),
    ("SUB", BinOp::Sub),
    ("MUL", BinOp::Mul),
    ("DIV", BinOp::Div),
    ("MOD", BinOp::Mod),
    ("AND", BinOp::And),
    ("OR", BinOp::Or),
    ("XOR", BinOp::Xor),
    ("GT", BinOp::Cmp(Rel::Gt)),
    ("GE", BinOp::Cmp(Rel::Ge)),
    ("EQ", BinOp::Cmp(Rel::Eq)),
    ("LE", BinOp::Cmp(Rel::Le)),
    ("LT", BinOp::Cmp(Rel::Lt)),
];

/// Whether `key` (upper case) names a standard function.
pub fn is_standard(key: &str) -> bool {
    conversion(key).is_some()
        || from_string(key).is_some()
        || key
            .strip_suffix("_TO_STRING")
            .and_then(Elem::from_name)
            .is_some()
        || MATH.iter().any(|m| m.0 == key)
        || OPERATORS.iter().any(|o| o.0 == key)
        || PARAMS.iter().any(|p| p.0 == key)
        || matches!(
            key,
            "TRUNC" | "MOVE" | "NOT" | "NE" | "MAX" | "MIN" | "MUX" | "CONCAT"
        )
}

/// `STRING_TO_B` for an elementary type B.
fn from_string(key: &str) -> Option<Elem> {
    key.strip_prefix("STRING_TO_").and_then(Elem::from_name)
}

/// `A_TO_B` between elementary types.
fn conversion(key: &str) -> Option<(Elem, Elem)> {
    let (a, b) = key.split_once("_TO_")?;
    Some((Elem::from_name(a)?, Elem::from_name(b)?))
}

/// A call's arguments in parameter order, formal ones placed by name.
fn ordered<'e>(name: &Ident, args: &'e [Arg]) -> Result<Vec<&'e Expr>, Diagnostic> {
    let key = name.key();
    let names = PARAMS.iter().find(|p| p.0 == key).map(|p| p.1);
    let mut out: Vec<Option<&Expr>> = Vec::new();
    for (i, arg) in args.iter().enumerate() {
        let (at, e) = match arg {
            Arg::Positional(e) => (i, e),
            Arg::Input(p, e) => {
                let pk = p.key();
                let at = match names {
                    Some(ns) => ns.iter().position(|n| *n == pk),
                    None => formal_index(&pk),
                };
                let Some(at) = at else {
                    return Err(Diagnostic::new(
                        p.pos,
                        format!("{} has no input named `{}`", name.text, p.text),
                    ));
                };
                (at, e)
            }
            Arg::Output { name: o, .. } => {
                return Err(Diagnostic::new(
                    o.pos,
                    format!(
                        "{} is a function: its result is its value, it has no `=>` outputs",
                        name.text
                    ),
                ))
            }
        };
        if out.len() <= at {
            out.resize(at + 1, None);
        }
        out[at] = Some(e);
    }
    out.into_iter()
        .enumerate()
        .map(|(i, e)| {
            e.ok_or_else(|| {
                Diagnostic::new(
                    name.pos,
                    format!("{}: argument {} is missing", name.text, i + 1),
                )
            })
        })
        .collect()
}

/// `IN`, `IN0`, `IN1` … and `K`, `G` of the extensible functions, as positions.
fn formal_index(key: &str) -> Option<usize> {
    match key {
        "IN" | "K" | "G" => Some(0),
        _ => key.strip_prefix("IN").and_then(|n| n.parse::<usize>().ok()),
    }
}

impl<'a> Compiler<'a> {
    /// A standard function's call.
    pub fn standard_call(
        &mut self,
        name: &Ident,
        args: &[Arg],
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        let key = name.key();
        let args = ordered(name, args)?;
        let arity = |n: usize| {
            if args.len() == n {
                Ok(())
            } else {
                Err(Diagnostic::new(
                    pos,
                    format!(
                        "{} takes {n} argument{}, found {}",
                        name.text,
                        if n == 1 { "" } else { "s" },
                        args.len()
                    ),
                ))
            }
        };
        if let Some(from) = key.strip_suffix("_TO_STRING").and_then(Elem::from_name) {
            arity(1)?;
            return self.converted_to_string(args[0], from, pos);
        }
        if matches!(key.as_str(), "MAX" | "MIN" | "LIMIT" | "MUX") {
            if let Some(v) = self.string_selection(&key, &args, pos) {
                return v;
            }
        }
        if let Some((from, to)) = conversion(&key) {
            arity(1)?;
            return self.convert(args[0], from, to, pos);
        }
        if let Some(to) = from_string(&key) {
            arity(1)?;
            return self.converted_from_string(args[0], to, pos);
        }
        if let Some(&(_, f)) = MATH.iter().find(|m| m.0 == key) {
            arity(1)?;
            return self.math(f, args[0], want, pos);
        }
        if let Some(&(_, op)) = OPERATORS.iter().find(|o| o.0 == key) {
            return self.operator_chain(op, &args, want, pos);
        }
        match key.as_str() {
            "NE" => self.operator_chain(BinOp::Cmp(Rel::Ne), &args, want, pos),
            "NOT" => {
                arity(1)?;
                self.expr(
                    &Expr {
                        kind: ExprKind::Unary(UnOp::Not, Box::new(args[0].clone())),
                        pos,
                    },
                    want,
                )
            }
            "MOVE" => {
                arity(1)?;
                self.expr(args[0], want)
            }
            "EXPT" => {
                arity(2)?;
                self.expr(
                    &Expr {
                        kind: ExprKind::Binary(
                            BinOp::Pow,
                            Box::new(args[0].clone()),
                            Box::new(args[1].clone()),
                        ),
                        pos,
                    },
                    want,
                )
            }
            "TRUNC" => {
                arity(1)?;
                self.trunc(args[0], want, pos)
            }
            "SHL" | "SHR" | "ROL" | "ROR" => {
                arity(2)?;
                self.shift(&key, args[0], args[1], want, pos)
            }
            "MAX" | "MIN" => self.extreme(&key, &args, want, pos),
            "LIMIT" => {
                arity(3)?;
                self.limit(&args, want, pos)
            }
            "SEL" => {
                arity(3)?;
                self.select(&args, want, pos)
            }
            "MUX" => self.mux(&args, want, pos),
            _ => self.string_call(name, &key, &args, want, pos),
        }
    }

    /// The result type of a standard function, if it can be told without context.
    pub fn peek_standard(&mut self, key: &str, args: &[Arg]) -> Option<Ty> {
        if let Some((_, to)) = conversion(key) {
            return Some(Ty::Elem(to));
        }
        if let Some(to) = from_string(key) {
            return Some(Ty::Elem(to));
        }
        if key.ends_with("_TO_STRING") {
            return Some(Ty::String(40));
        }
        let values: Vec<Expr> = args
            .iter()
            .filter_map(|a| match a {
                Arg::Positional(e) | Arg::Input(_, e) => Some(e.clone()),
                Arg::Output { .. } => None,
            })
            .collect();
        // The inputs whose type is the result's: all of them, but for the selector of SEL and
        // MUX and the bit count of the shifts.
        let typed = match key {
            "GT" | "GE" | "EQ" | "LE" | "LT" | "NE" => return Some(Ty::Elem(Elem::Bool)),
            "LEN" | "FIND" | "TRUNC" => return None,
            "LEFT" | "RIGHT" | "MID" | "INSERT" | "DELETE" | "REPLACE" | "CONCAT" => {
                return Some(Ty::String(MAX_STRING))
            }
            "SEL" | "MUX" => values.get(1..).unwrap_or_default(),
            "SHL" | "SHR" | "ROL" | "ROR" | "EXPT" => values.get(..1).unwrap_or_default(),
            _ => &values[..],
        };
        typed.iter().find_map(|e| self.peek(e))
    }

    fn convert(&mut self, arg: &Expr, from: Elem, to: Elem, pos: Pos) -> Result<Val, Diagnostic> {
        let a = self.scalar(arg, Ty::Elem(from))?;
        if from == to {
            return Ok(Val::Scalar(Ty::Elem(to), a));
        }
        self.emit_to_temp(to, pos, |dst| Op::Conv { from, to, dst, a })
    }

    /// Emits the operation `op` makes for a new temporary, and gives the temporary as a value
    /// of type `to`.
    fn emit_to_temp(
        &mut self,
        to: Elem,
        pos: Pos,
        op: impl FnOnce(Slot) -> Op,
    ) -> Result<Val, Diagnostic> {
        let dst = self.temp(pos)?;
        self.emit(op(dst), pos)?;
        Ok(Val::Scalar(Ty::Elem(to), dst))
    }

    fn math(
        &mut self,
        f: MathFn,
        arg: &Expr,
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        let v = self.expr(arg, want.or(Some(Ty::Elem(Elem::Lreal))))?;
        let Val::Scalar(Ty::Elem(e), a) = v else {
            return Err(Diagnostic::new(
                pos,
                format!("expected a number, found {}", self.describe(v.ty())),
            ));
        };
        let ok = if f == MathFn::Abs {
            e.is_num()
        } else {
            e.is_real()
        };
        if !ok {
            return Err(Diagnostic::new(
                pos,
                format!(
                    "this function takes {}, found {e}",
                    if f == MathFn::Abs {
                        "a number"
                    } else {
                        "a REAL or LREAL"
                    }
                ),
            ));
        }
        let dst = self.temp(pos)?;
        self.emit(Op::Math { f, e, dst, a }, pos)?;
        Ok(Val::Scalar(Ty::Elem(e), dst))
    }

    fn trunc(&mut self, arg: &Expr, want: Option<Ty>, pos: Pos) -> Result<Val, Diagnostic> {
        let v = self.expr(arg, Some(Ty::Elem(Elem::Lreal)))?;
        let Val::Scalar(Ty::Elem(from), a) = v else {
            return Err(Diagnostic::new(pos, "TRUNC takes a REAL or LREAL"));
        };
        let to = want
            .and_then(Ty::elem)
            .filter(|e| e.is_int())
            .unwrap_or(Elem::Dint);
        if !from.is_real() {
            return Err(Diagnostic::new(
                pos,
                format!("TRUNC takes a REAL or LREAL, found {from}"),
            ));
        }
        self.emit_to_temp(to, pos, |dst| Op::Trunc { from, to, dst, a })
    }

    /// `ADD(a, b, c)` as `(a + b) + c`; the comparisons take two arguments.
    fn operator_chain(
        &mut self,
        op: BinOp,
        args: &[&Expr],
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        let extensible = matches!(
            op,
            BinOp::Add | BinOp::Mul | BinOp::And | BinOp::Or | BinOp::Xor
        );
        if args.len() < 2 || (!extensible && args.len() != 2) {
            return Err(Diagnostic::new(
                pos,
                format!(
                    "`{}` as a function takes {} arguments",
                    op.symbol(),
                    if extensible { "two or more" } else { "two" }
                ),
            ));
        }
        let mut e = args[0].clone();
        for b in &args[1..] {
            e = Expr {
                kind: ExprKind::Binary(op, Box::new(e), Box::new((*b).clone())),
                pos,
            };
        }
        self.expr(&e, want)
    }

    fn shift(
        &mut self,
        key: &str,
        value: &Expr,
        n: &Expr,
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        let f = match key {
            "SHL" => ShiftFn::Shl,
            "SHR" => ShiftFn::Shr,
            "ROL" => ShiftFn::Rol,
            _ => ShiftFn::Ror,
        };
        let v = self.expr(value, want)?;
        let Val::Scalar(Ty::Elem(e), a) = v else {
            return Err(Diagnostic::new(
                pos,
                "shifts and rotations take a bit string (BYTE, WORD, DWORD, LWORD)",
            ));
        };
        if !e.is_bits() {
            return Err(Diagnostic::new(
                value.pos,
                format!("{key} takes a bit string (BYTE, WORD, DWORD, LWORD), found {e}"),
            ));
        }
        let (_, ns) = self.integer(n, "the bit count N")?;
        let dst = self.temp(pos)?;
        self.emit(
            Op::Shift {
                f,
                e,
                dst,
                a,
                n: ns,
            },
            pos,
        )?;
        Ok(Val::Scalar(Ty::Elem(e), dst))
    }

    /// Compiles all `args` as scalars of one type (the first that has one, else `want`).
    fn same_scalars(
        &mut self,
        args: &[&Expr],
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<(Ty, Vec<Slot>), Diagnostic> {
        let hint = args.iter().find_map(|a| self.peek(a)).or(want);
        let mut ty = hint;
        let mut out = Vec::new();
        for a in args {
            match self.expr(a, ty)? {
                Val::Scalar(t, s) if ty.is_none_or(|ty| ty == t) => {
                    ty = Some(t);
                    out.push(s);
                }
                v => return Err(self.mismatch(a.pos, ty.unwrap_or(v.ty()), v.ty())),
            }
        }
        let ty = ty.ok_or_else(|| Diagnostic::new(pos, "missing arguments"))?;
        Ok((ty, out))
    }

    fn extreme(
        &mut self,
        key: &str,
        args: &[&Expr],
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        if args.len() < 2 {
            return Err(Diagnostic::new(
                pos,
                format!("{key} takes two or more arguments"),
            ));
        }
        let (ty, slots) = self.same_scalars(args, want, pos)?;
        let e = self.ordered(ty, key, pos)?;
        let op = if key == "MAX" { Arith::Max } else { Arith::Min };
        let mut acc = slots[0];
        for &b in &slots[1..] {
            let dst = self.temp(pos)?;
            self.emit(
                Op::Arith {
                    op,
                    e,
                    dst,
                    a: acc,
                    b,
                },
                pos,
            )?;
            acc = dst;
        }
        Ok(Val::Scalar(ty, acc))
    }

    /// The elementary type of the inputs of MAX, MIN or LIMIT (`name`): numbers, bit strings or
    /// durations (strings go through `string_selection`).
    fn ordered(&self, ty: Ty, name: &str, pos: Pos) -> Result<Elem, Diagnostic> {
        ty.elem()
            .filter(|e| e.is_num() || e.is_bits() || *e == Elem::Time)
            .ok_or_else(|| {
                Diagnostic::new(
                    pos,
                    format!(
                        "{name} takes numbers, bit strings or durations, found {}",
                        self.describe(ty)
                    ),
                )
            })
    }

    /// LIMIT(MN, IN, MX) as MATIEC computes it: `IN > MN ? (IN < MX ? IN : MX) : MN`.
    fn limit(&mut self, args: &[&Expr], want: Option<Ty>, pos: Pos) -> Result<Val, Diagnostic> {
        let (ty, s) = self.same_scalars(args, want, pos)?;
        let e = self.ordered(ty, "LIMIT", pos)?;
        let (mn, x, mx) = (s[0], s[1], s[2]);
        let above = self.compare(Rel::Gt, e, x, mn, pos)?;
        let below = self.compare(Rel::Lt, e, x, mx, pos)?;
        let inner = self.choose(below, x, mx, pos)?;
        let dst = self.choose(above, inner, mn, pos)?;
        Ok(Val::Scalar(ty, dst))
    }

    /// SEL(G, IN0, IN1): IN1 when G.
    fn select(&mut self, args: &[&Expr], want: Option<Ty>, pos: Pos) -> Result<Val, Diagnostic> {
        let g = self.condition(args[0])?;
        if let Some(Ty::String(_)) = self.peek(args[1]).or(want) {
            let (a, b) = (self.expr(args[1], None)?, self.expr(args[2], None)?);
            let (Val::Str(ca, ta), Val::Str(cb, tb)) = (a, b) else {
                return Err(Diagnostic::new(pos, "SEL takes two values of one type"));
            };
            let cap = ca.max(cb);
            let dst = self.string_temp(cap, pos)?;
            let skip = self.emit(Op::JumpIf { c: g, to: 0 }, pos)?;
            self.emit(Op::StrMove { dst, cap, src: ta }, pos)?;
            let end = self.emit(Op::Jump { to: 0 }, pos)?;
            let other = self.here();
            self.patch(skip, other);
            self.emit(Op::StrMove { dst, cap, src: tb }, pos)?;
            let after = self.here();
            self.patch(end, after);
            return Ok(Val::Str(cap, dst));
        }
        let (ty, s) = self.same_scalars(&args[1..], want, pos)?;
        let dst = self.temp(pos)?;
        self.emit(
            Op::Select {
                dst,
                c: g,
                a: s[1],
                b: s[0],
            },
            pos,
        )?;
        Ok(Val::Scalar(ty, dst))
    }

    /// A temporary that holds whether MUX's selector `k` (of type `ke`) picks input `i`.
    pub(crate) fn selects(
        &mut self,
        ke: Elem,
        k: Slot,
        i: usize,
        pos: Pos,
    ) -> Result<Slot, Diagnostic> {
        let idx = self.const_slot(i as u64, pos)?;
        self.compare(Rel::Eq, ke, k, idx, pos)
    }

    /// A temporary that holds `a op b`, both of type `e`.
    pub(crate) fn compare(
        &mut self,
        op: Rel,
        e: Elem,
        a: Slot,
        b: Slot,
        pos: Pos,
    ) -> Result<Slot, Diagnostic> {
        let dst = self.temp(pos)?;
        self.emit(Op::Cmp { op, e, dst, a, b }, pos)?;
        Ok(dst)
    }

    /// A temporary that holds `a` when `c`, else `b`.
    fn choose(&mut self, c: Slot, a: Slot, b: Slot, pos: Pos) -> Result<Slot, Diagnostic> {
        let dst = self.temp(pos)?;
        self.emit(Op::Select { dst, c, a, b }, pos)?;
        Ok(dst)
    }

    /// MUX(K, IN0, …): the input numbered K, or the type's zero when K is out of range (MATIEC).
    fn mux(&mut self, args: &[&Expr], want: Option<Ty>, pos: Pos) -> Result<Val, Diagnostic> {
        if args.len() < 2 {
            return Err(Diagnostic::new(
                pos,
                "MUX takes a selector K and at least one input",
            ));
        }
        let (ke, k) = self.integer(args[0], "MUX's selector K")?;
        let (ty, s) = self.same_scalars(&args[1..], want, pos)?;
        let dst = self.temp(pos)?;
        let zero = self.const_slot(0, pos)?;
        self.emit(Op::Move { dst, src: zero }, pos)?;
        for (i, &input) in s.iter().enumerate() {
            let hit = self.selects(ke, k, i, pos)?;
            self.emit(
                Op::Select {
                    dst,
                    c: hit,
                    a: input,
                    b: dst,
                },
                pos,
            )?;
        }
        Ok(Val::Scalar(ty, dst))
    }

    fn string_call(
        &mut self,
        name: &Ident,
        key: &str,
        args: &[&Expr],
        want: Option<Ty>,
        pos: Pos,
    ) -> Result<Val, Diagnostic> {
        let int = want
            .and_then(Ty::elem)
            .filter(|e| e.is_int())
            .unwrap_or(Elem::Int);
        let (f, strings, ints): (Option<StrFn>, usize, usize) = match key {
            "LEN" => (None, 1, 0),
            "FIND" => (None, 2, 0),
            "CONCAT" => (Some(StrFn::Concat), args.len(), 0),
            "LEFT" => (Some(StrFn::Left), 1, 1),
            "RIGHT" => (Some(StrFn::Right), 1, 1),
            "MID" => (Some(StrFn::Mid), 1, 2),
            "INSERT" => (Some(StrFn::Insert), 2, 1),
            "DELETE" => (Some(StrFn::Delete), 1, 2),
            "REPLACE" => (Some(StrFn::Replace), 2, 2),
            _ => {
                return Err(Diagnostic::new(
                    name.pos,
                    format!(
                        "unknown function `{}`: not a FUNCTION of the file nor a standard function",
                        name.text
                    ),
                ))
            }
        };
        if args.len() != strings + ints || (key == "CONCAT" && args.len() < 2) {
            return Err(Diagnostic::new(
                pos,
                format!(
                    "{} takes {} arguments, found {}",
                    name.text,
                    if key == "CONCAT" {
                        "two or more".to_string()
                    } else {
                        (strings + ints).to_string()
                    },
                    args.len()
                ),
            ));
        }
        let mut texts = Vec::new();
        for a in &args[..strings] {
            match self.expr(a, None)? {
                Val::Str(cap, at) => texts.push((cap, at)),
                v => {
                    return Err(self.mismatch(
                        a.pos,
                        Ty::String(crate::types::DEFAULT_STRING),
                        v.ty(),
                    ))
                }
            }
        }
        let (n, p, ie) = self.string_ints(&args[strings..], pos)?;
        match f {
            None => {
                let dst = self.temp(pos)?;
                let op = if key == "LEN" {
                    Op::StrLen {
                        e: int,
                        dst,
                        s: texts[0].1,
                    }
                } else {
                    Op::StrFind {
                        e: int,
                        dst,
                        a: texts[0].1,
                        b: texts[1].1,
                    }
                };
                self.emit(op, pos)?;
                Ok(Val::Scalar(Ty::Elem(int), dst))
            }
            Some(StrFn::Concat) => self.concat(&texts, pos),
            Some(f) => {
                let cap = texts
                    .iter()
                    .map(|t| u32::from(t.0))
                    .sum::<u32>()
                    .min(u32::from(MAX_STRING)) as u16;
                let dst = self.string_temp(cap, pos)?;
                let b = texts.get(1).map_or(texts[0].1, |t| t.1);
                let args = StrArgs {
                    dst,
                    cap,
                    a: texts[0].1,
                    b,
                    n,
                    p,
                    int: ie,
                };
                self.string_op(f, args, pos)?;
                Ok(Val::Str(cap, dst))
            }
        }
    }

    /// The L and P arguments of a string function, in one integer type.
    fn string_ints(&mut self, args: &[&Expr], pos: Pos) -> Result<(Slot, Slot, Elem), Diagnostic> {
        let zero = self.const_slot(0, pos)?;
        if args.is_empty() {
            return Ok((zero, zero, Elem::Int));
        }
        let (ty, s) = self.same_scalars(args, Some(Ty::Elem(Elem::Int)), pos)?;
        let Some(e) = ty.elem().filter(|e| e.is_int()) else {
            return Err(Diagnostic::new(
                pos,
                format!(
                    "string positions and lengths are integers, found {}",
                    self.describe(ty)
                ),
            ));
        };
        // The one-number functions (LEFT, RIGHT, INSERT) take it as L, except INSERT's P.
        Ok(match s.as_slice() {
            [one] => (*one, *one, e),
            [n, p, ..] => (*n, *p, e),
            [] => (zero, zero, e),
        })
    }

    fn string_op(&mut self, f: StrFn, args: StrArgs, pos: Pos) -> Result<(), Diagnostic> {
        self.code.string_args.push(args);
        let at = self.code.string_args.len() as u32 - 1;
        self.emit(Op::Str { f, args: at }, pos).map(|_| ())
    }

    /// CONCAT of two or more strings, as a chain of two-string concatenations.
    fn concat(&mut self, texts: &[(u16, u32)], pos: Pos) -> Result<Val, Diagnostic> {
        let zero = self.const_slot(0, pos)?;
        let mut acc = texts[0];
        for &(cap, at) in &texts[1..] {
            let cap = (u32::from(acc.0) + u32::from(cap)).min(u32::from(MAX_STRING)) as u16;
            let dst = self.string_temp(cap, pos)?;
            self.string_op(
                StrFn::Concat,
                StrArgs {
                    dst,
                    cap,
                    a: acc.1,
                    b: at,
                    n: zero,
                    p: zero,
                    int: Elem::Int,
                },
                pos,
            )?;
            acc = (cap, dst);
        }
        Ok(Val::Str(acc.0, acc.1))
    }
}
