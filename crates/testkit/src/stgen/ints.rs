//! Integer expressions, with the range of values each can take.

use super::*;

// ------------------------------------------------------------------------------------------
// Integer expressions

#[derive(Clone, Copy)]
pub(super) enum IntOp {
    Add,
    Sub,
    Mul,
    Div,
    Mod,
    Neg,
    Abs,
    MinMax,
    Limit,
    Sel,
    Mux,
    Conv,
    Call,
    Len,
    Find,
}

impl ProgramGen<'_> {
    /// An expression of integer type `ty` whose value is always in `want` (which holds 0) and
    /// whose every subexpression stays in `ty`'s range; `typed`: MATIEC must see its type.
    pub(super) fn int(&mut self, ty: Ty, want: Iv, typed: bool, d: u32) -> Expr {
        debug_assert!(want.lo <= 0 && 0 <= want.hi && want.within(ty.full()));
        if want.lo == want.hi {
            return self.int_lit(ty, want.lo, typed);
        }
        let e = if d == 0 || self.rng.pct(30) {
            None
        } else {
            self.int_op(ty, want, typed, d)
        };
        // Whatever `fit_int` does to it, a value outside the type never existed, and an
        // operation on untyped literals stays within C `int` (rule 1).
        let c_int = Iv::new(i128::from(i32::MIN), i128::from(i32::MAX));
        let e = match e {
            Some(e)
                if e.val.iv().within(ty.full())
                    && (!e.konst || e.typed || e.prec == P_ATOM || e.val.iv().within(c_int)) =>
            {
                e
            }
            _ => self.int_leaf(ty, want, typed),
        };
        self.fit_int(e, ty, want, typed)
    }

    pub(super) fn int_leaf(&mut self, ty: Ty, want: Iv, typed: bool) -> Expr {
        let places = self.places(Sty::E(ty), false);
        if !places.is_empty() && self.rng.pct(70) {
            let (p, dom) = *self.rng.pick(&places);
            return self.read(p, dom);
        }
        let v = self.pick_int(ty, want);
        self.int_lit(ty, v, typed)
    }

    pub(super) fn int_op(&mut self, ty: Ty, want: Iv, typed: bool, d: u32) -> Option<Expr> {
        let signed = ty.signed();
        let op = self.rng.weighted(&[
            (10, IntOp::Add),
            (7, IntOp::Sub),
            (6, IntOp::Mul),
            (4, IntOp::Div),
            (5, IntOp::Mod),
            (if signed { 2 } else { 0 }, IntOp::Neg),
            (if signed { 2 } else { 0 }, IntOp::Abs),
            (3, IntOp::MinMax),
            (3, IntOp::Limit),
            (2, IntOp::Sel),
            (2, IntOp::Mux),
            (7, IntOp::Conv),
            (3, IntOp::Call),
            (if typed { 0 } else { 2 }, IntOp::Len),
            (if typed { 0 } else { 1 }, IntOp::Find),
        ]);
        match op {
            IntOp::Add | IntOp::Sub | IntOp::Mul => self.int_arith(op, ty, want, typed, d),
            IntOp::Div => self.int_div(ty, want, typed, d),
            IntOp::Mod => self.int_mod(ty, want, typed, d),
            IntOp::Neg | IntOp::Abs => Some(self.int_sign(op, ty, want, typed, d)),
            IntOp::MinMax | IntOp::Limit | IntOp::Sel | IntOp::Mux => {
                Some(self.int_select(op, ty, want, typed, d))
            }
            IntOp::Conv => self.conv_to_int(ty, want, d),
            IntOp::Call => self.user_call(Sty::E(ty), d),
            IntOp::Len | IntOp::Find => Some(self.int_of_string(op, d)),
        }
    }

    /// `+`, `-` and `*`, each operand budgeted so that the result stays in `want`.
    pub(super) fn int_arith(
        &mut self,
        op: IntOp,
        ty: Ty,
        want: Iv,
        typed: bool,
        d: u32,
    ) -> Option<Expr> {
        let (signed, full) = (ty.signed(), ty.full());
        match op {
            IntOp::Add => {
                let lb = if self.rng.pct(30) { want } else { want.half() };
                let l = self.int(ty, lb, false, d - 1);
                let li = l.val.iv();
                let rb = Iv::new(want.lo - li.lo, want.hi - li.hi).meet(full);
                let r = self.int(ty, rb, typed && !l.typed, d - 1);
                let ri = r.val.iv();
                let val = Val::Int(Iv::new(li.lo + ri.lo, li.hi + ri.hi));
                Some(self.binop(l, "+", P_ADD, r, val))
            }
            IntOp::Sub if signed => {
                let lb = if self.rng.pct(30) { want } else { want.half() };
                let l = self.int(ty, lb, false, d - 1);
                let li = l.val.iv();
                let rb = Iv::new(li.hi - want.hi, li.lo - want.lo).meet(full);
                let r = self.int(ty, rb, typed && !l.typed, d - 1);
                let ri = r.val.iv();
                let val = Val::Int(Iv::new(li.lo - ri.hi, li.hi - ri.lo));
                Some(self.binop(l, "-", P_ADD, r, val))
            }
            IntOp::Sub => self.unsigned_sub(ty, want, typed, d),
            _ => {
                let k = self.rng.int(1, 6).min(want.mag().max(1));
                let rb = if signed {
                    Iv::new(-k, k)
                } else {
                    Iv::new(0, k)
                };
                let r = self.int(ty, rb, false, d - 1);
                let m = r.val.iv().mag().max(1);
                // Symmetric, as the factor's sign is unknown: |l * r| <= the smaller side.
                let side = if signed {
                    want.hi.min(-want.lo)
                } else {
                    want.hi
                };
                let lb = if signed {
                    Iv::new(-side / m, side / m)
                } else {
                    Iv::new(0, side / m)
                };
                let l = self.int(ty, lb, typed && !r.typed, d - 1);
                let val = Val::Int(corners(l.val.iv(), r.val.iv(), |a, b| a.checked_mul(b))?);
                Some(if self.rng.pct(50) {
                    self.binop(l, "*", P_MUL, r, val)
                } else {
                    self.binop(r, "*", P_MUL, l, val)
                })
            }
        }
    }

    /// Unary `-` and ABS, never of the most negative value (rule 2).
    pub(super) fn int_sign(&mut self, op: IntOp, ty: Ty, want: Iv, typed: bool, d: u32) -> Expr {
        let full = ty.full();
        if let IntOp::Neg = op {
            let l = self.int(ty, Iv::new(-want.hi, -want.lo).meet(full), typed, d - 1);
            let li = l.val.iv();
            let text = format!("-{}", l.at(P_ATOM + u8::from(l.konst)));
            return Expr {
                text,
                prec: P_UNARY,
                val: Val::Int(Iv::new(-li.hi, -li.lo)),
                typed: l.typed,
                konst: l.konst,
            };
        }
        let l = self.int(ty, Iv::new(-want.hi, want.hi).meet(full), typed, d - 1);
        let li = l.val.iv();
        let val = if li.lo >= 0 {
            li
        } else if li.hi <= 0 {
            Iv::new(-li.hi, -li.lo)
        } else {
            Iv::new(0, li.mag())
        };
        self.call("ABS", &[l], Val::Int(val))
    }

    /// MIN, MAX, LIMIT, SEL and MUX of integers.
    pub(super) fn int_select(&mut self, op: IntOp, ty: Ty, want: Iv, typed: bool, d: u32) -> Expr {
        match op {
            IntOp::MinMax => {
                let n = self.rng.range(2, 3);
                let args: Vec<Expr> = (0..n)
                    .map(|i| self.int(ty, want, typed && i == 0, d - 1))
                    .collect();
                let ivs: Vec<Iv> = args.iter().map(|a| a.val.iv()).collect();
                let lo = ivs.iter().map(|i| i.lo);
                let hi = ivs.iter().map(|i| i.hi);
                let (name, iv) = if self.rng.pct(50) {
                    ("MIN", Iv::new(lo.min().unwrap_or(0), hi.min().unwrap_or(0)))
                } else {
                    ("MAX", Iv::new(lo.max().unwrap_or(0), hi.max().unwrap_or(0)))
                };
                self.call(name, &args, Val::Int(iv))
            }
            IntOp::Limit => {
                let mn = self.int(ty, Iv::new(want.lo, 0), false, 0);
                let x = self.int(ty, ty.full(), typed && !mn.typed, d - 1);
                let mx = self.int(ty, Iv::new(0, want.hi), false, 0);
                let val = limit_range(mn.val.iv(), x.val.iv(), mx.val.iv());
                self.call("LIMIT", &[mn, x, mx], Val::Int(val))
            }
            IntOp::Sel => {
                let a = self.int(ty, want, typed, d - 1);
                let b = self.int(ty, want, false, d - 1);
                self.sel(a, b, d)
            }
            _ => {
                let args = (0..self.rng.range(2, 4))
                    .map(|i| self.int(ty, want, typed && i == 0, d - 1))
                    .collect();
                self.mux(args, d)
            }
        }
    }

    /// LEN and FIND, untyped: MATIEC takes their type from the context (rule 11).
    pub(super) fn int_of_string(&mut self, op: IntOp, d: u32) -> Expr {
        let s = self.string(STR_CAP, d - 1);
        let (min, max) = s.val.strlen();
        let mut e = if let IntOp::Len = op {
            self.call("LEN", &[s], Val::Int(Iv::new(min.into(), max.into())))
        } else {
            let c = self.needle();
            self.call("FIND", &[s, c], Val::Int(Iv::new(0, max.into())))
        };
        e.typed = false;
        e
    }

    /// `l + c - r` with `r <= c + l`: a subtraction of unsigned values that stays unsigned.
    pub(super) fn unsigned_sub(&mut self, ty: Ty, want: Iv, typed: bool, d: u32) -> Option<Expr> {
        if want.hi < 2 {
            return None;
        }
        let c = self.rng.int(1, (want.hi / 4).clamp(1, 1000));
        let l = self.int(ty, Iv::new(0, want.hi - c), false, d - 1);
        let li = l.val.iv();
        let sum_val = Val::Int(Iv::new(li.lo + c, li.hi + c));
        let c = self.int_lit(ty, c, typed && !l.typed);
        let sum = self.binop(l, "+", P_ADD, c, sum_val);
        let si = sum.val.iv();
        let r = self.int(ty, Iv::new(0, si.lo), false, d - 1);
        let ri = r.val.iv();
        Some(self.binop(
            sum,
            "-",
            P_ADD,
            r,
            Val::Int(Iv::new(si.lo - ri.hi, si.hi - ri.lo)),
        ))
    }

    /// Division by a literal other than 0 and -1, or by a guarded `(ABS(e MOD m) + 1)` (rule 2).
    pub(super) fn int_div(&mut self, ty: Ty, want: Iv, typed: bool, d: u32) -> Option<Expr> {
        let full = ty.full();
        if self.rng.pct(70) {
            let mut dv = self.rng.int(1, 10);
            if ty.signed() && self.rng.pct(25) && dv > 1 {
                dv = -dv;
            }
            let lb = if dv > 0 {
                Iv::new(want.lo * dv, want.hi * dv)
            } else {
                Iv::new(-want.hi * -dv, -want.lo * -dv)
            };
            let l = self.int(ty, lb.meet(full), typed, d - 1);
            let li = l.val.iv();
            let (a, b) = (li.lo / dv, li.hi / dv);
            let r = self.int_lit(ty, dv, false);
            Some(self.binop(l, "/", P_MUL, r, Val::Int(Iv::new(a.min(b), a.max(b)))))
        } else {
            let l = self.int(ty, want, typed, d - 1);
            let (r, m) = self.guarded_divisor(ty, d);
            let li = l.val.iv();
            let val = Iv::new(li.lo.min(li.lo / m), li.hi.max(li.hi / m));
            Some(self.binop(l, "/", P_MUL, r, Val::Int(val)))
        }
    }

    /// `(ABS(e MOD m) + 1)` (or without ABS for unsigned types): a divisor in `1..=m`.
    pub(super) fn guarded_divisor(&mut self, ty: Ty, d: u32) -> (Expr, i128) {
        let m = self.rng.int(2, 10);
        let e = self.int(ty, ty.full(), true, d.saturating_sub(2));
        let inner = format!("{} MOD {m}", e.at(P_MUL));
        let text = if ty.signed() {
            format!("(ABS({inner}) + 1)")
        } else {
            format!("({inner} + 1)")
        };
        (Expr::atom(text, Val::Int(Iv::new(1, m)), true), m)
    }

    pub(super) fn int_mod(&mut self, ty: Ty, want: Iv, typed: bool, d: u32) -> Option<Expr> {
        let full = ty.full();
        let side = if ty.signed() && want.lo < 0 {
            want.hi.min(-want.lo)
        } else {
            want.hi
        };
        let (r, m) = if self.rng.pct(80) {
            let m = self.rng.int(2, 100).min(full.hi);
            (self.int_lit(ty, m, false), m)
        } else {
            self.guarded_divisor(ty, d)
        };
        let lb = if m - 1 <= side { full } else { want };
        let lb = if ty.signed() && want.lo == 0 {
            Iv::new(0, lb.hi)
        } else {
            lb
        };
        let l = self.int(ty, lb, typed, d - 1);
        let li = l.val.iv();
        let val = Iv::new(li.lo.max(-(m - 1)).min(0), li.hi.min(m - 1).max(0));
        Some(self.binop(l, "MOD", P_MUL, r, Val::Int(val)))
    }

    /// `want` out of `e` when `e` may leave it: MOD, division, LIMIT or MIN/MAX.
    pub(super) fn fit_int(&mut self, e: Expr, ty: Ty, want: Iv, typed: bool) -> Expr {
        let iv = e.val.iv();
        if iv.within(want) && (e.typed || !typed) {
            return e;
        }
        if iv.within(want) {
            // Only its type is missing (a lone untyped literal): write the type.
            let v = self.pick_int(ty, want);
            return self.int_lit(ty, v, true);
        }
        // A signed value into a budget without negatives: ABS(e MOD m).
        let abs = ty.signed() && iv.lo < 0 && want.lo == 0;
        let side = if iv.lo < 0 && !abs {
            want.hi.min(-want.lo)
        } else {
            want.hi
        };
        match self.rng.below(4) {
            0 if side >= 1 && !e.konst => {
                let m = self.rng.int(2, (side + 1).min(1000).min(ty.full().hi));
                let text = format!("{} MOD {m}", e.at(P_MUL));
                let (text, prec) = if abs {
                    (format!("ABS({text})"), P_ATOM)
                } else {
                    (text, P_MUL)
                };
                let lo = if abs { 0 } else { iv.lo.max(-(m - 1)).min(0) };
                let hi = if abs { m - 1 } else { iv.hi.min(m - 1).max(0) };
                let val = Val::Int(Iv::new(lo, hi));
                Expr {
                    text,
                    prec,
                    val,
                    typed: e.typed,
                    konst: false,
                }
            }
            1 if !e.konst && (iv.lo >= 0 || want.lo < 0) => {
                let need_hi = if iv.hi > want.hi {
                    iv.hi / (want.hi + 1) + 1
                } else {
                    1
                };
                let need_lo = if iv.lo < want.lo {
                    iv.lo / (want.lo - 1) + 1
                } else {
                    1
                };
                let dv = need_hi.max(need_lo).max(2);
                if dv > ty.full().hi {
                    return self.limit_int(e, ty, want);
                }
                let val = Val::Int(Iv::new(iv.lo / dv, iv.hi / dv));
                let r = self.int_lit(ty, dv, false);
                self.binop(e, "/", P_MUL, r, val)
            }
            _ => self.limit_int(e, ty, want),
        }
    }

    pub(super) fn limit_int(&mut self, e: Expr, ty: Ty, want: Iv) -> Expr {
        let iv = e.val.iv();
        let lo = self.rng.int(want.lo.max(iv.lo.min(0)), 0);
        let hi = self.rng.int(0, want.hi.min(iv.hi.max(0)));
        let typed = !e.typed;
        let mn = self.int_lit(ty, lo, typed);
        let mx = self.int_lit(ty, hi, false);
        let val = limit_range(Iv::point(lo), iv, Iv::point(hi));
        self.call("LIMIT", &[mn, e, mx], Val::Int(val))
    }

    /// `<SRC>_TO_<ty>(e)` from any other numeric, bit-string or BOOL type (rule 3).
    pub(super) fn conv_to_int(&mut self, ty: Ty, want: Iv, d: u32) -> Option<Expr> {
        if self.rng.pct(10) {
            return Some(self.string_to_int(ty, want, d));
        }
        let src = *self.rng.pick(CONV_TYPES);
        if src == ty {
            return None;
        }
        let full = ty.full();
        let (arg, val) = if src == Ty::Bool {
            (self.boolean(d - 1), Iv::new(0, 1))
        } else if src.is_int() {
            let exact = want.meet(src.full());
            let sb = if self.rng.pct(75) { exact } else { src.full() };
            let mut a = self.int(src, sb, false, d - 1);
            if a.konst && !a.val.iv().within(full) {
                a = self.int(src, exact, false, d - 1);
            }
            let ai = a.val.iv();
            (a, if ai.within(full) { ai } else { full })
        } else if src.is_bits() {
            let a = self.bits(src, Bits::PLAIN, d - 1);
            let sf = src.full();
            (a, if sf.within(full) { sf } else { full })
        } else {
            let b = free_real(src);
            let rb = Rv::new((want.lo as f64).max(b.lo), (want.hi as f64).min(b.hi));
            let a = self.real(src, rb, false, d - 1);
            let r = a.val.rv();
            let lo = (r.lo.floor() as i128).max(want.lo);
            let hi = (r.hi.ceil() as i128).min(want.hi);
            (a, Iv::new(lo.min(hi), hi))
        };
        let name = format!("{}_TO_{}", src.name(), ty.name());
        Some(self.call(&name, &[arg], Val::Int(val)))
    }
}

/// The range of `f(a, b)` over the corners of two intervals (for a monotonic `f`).
pub(super) fn corners(a: Iv, b: Iv, f: impl Fn(i128, i128) -> Option<i128>) -> Option<Iv> {
    let xs = [
        f(a.lo, b.lo)?,
        f(a.lo, b.hi)?,
        f(a.hi, b.lo)?,
        f(a.hi, b.hi)?,
    ];
    Some(Iv::new(*xs.iter().min()?, *xs.iter().max()?))
}

/// The values of `LIMIT(mn, x, mx)` when `mn <= 0 <= mx` (so `mn <= mx`).
pub(super) fn limit_range(mn: Iv, x: Iv, mx: Iv) -> Iv {
    let lo = if x.lo >= mn.hi {
        x.lo.min(mx.lo)
    } else {
        mn.lo
    };
    let hi = if x.hi <= mx.lo {
        x.hi.max(mn.hi)
    } else {
        mx.hi
    };
    Iv::new(lo.min(hi), hi)
}
