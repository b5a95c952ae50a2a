//! REAL and LREAL expressions.

use super::*;

// ------------------------------------------------------------------------------------------
// REAL and LREAL

/// Divisors and factors whose effect on a bound is easy to know (rule 7).
pub(super) const REAL_DIVISORS: [(f64, &str); 9] = [
    (2.0, "2.0"),
    (4.0, "4.0"),
    (0.5, "0.5"),
    (8.0, "8.0"),
    (10.0, "10.0"),
    (2.5, "2.5"),
    (-2.0, "-2.0"),
    (1.5, "1.5"),
    (3.0, "3.0"),
];

impl ProgramGen<'_> {
    /// A REAL/LREAL expression whose value is finite and always in `want` (which holds 0).
    pub(super) fn real(&mut self, ty: Ty, want: Rv, typed: bool, d: u32) -> Expr {
        if want.lo == want.hi {
            return self.real_lit(ty, want, typed);
        }
        let e = if d == 0 || self.rng.pct(30) {
            None
        } else {
            self.real_op(ty, want, typed, d)
        };
        let e = match e {
            Some(e) => e,
            None => self.real_leaf(ty, want, typed),
        };
        self.fit_real(e, ty, want, typed)
    }

    pub(super) fn real_leaf(&mut self, ty: Ty, want: Rv, typed: bool) -> Expr {
        let places = self.places(Sty::E(ty), false);
        if !places.is_empty() && self.rng.pct(65) {
            let (p, dom) = *self.rng.pick(&places);
            return self.read(p, dom);
        }
        self.real_lit(ty, want, typed)
    }

    /// A typed literal of a divisor or bound, e.g. `REAL#2.5`.
    pub(super) fn real_const(&mut self, ty: Ty, text: &str, v: f64) -> Expr {
        let typed = ty == Ty::Real || self.rng.pct(50);
        let text = if typed {
            format!("{}#{text}", ty.name())
        } else {
            text.to_string()
        };
        Expr::lit(text, Val::Real(Rv::new(v, v)), typed)
    }

    pub(super) fn real_op(&mut self, ty: Ty, want: Rv, typed: bool, d: u32) -> Option<Expr> {
        Some(match self.rng.below(30) {
            0..=9 => self.real_arith(ty, want, typed, d),
            10..=12 => self.real_div(ty, want, typed, d),
            13..=16 => self.real_sign(ty, want, typed, d),
            17..=18 if want.hi >= 1.0 => {
                let m = (want.hi * 0.99).powi(2).min(free_real(ty).hi);
                let x = self.non_negative(ty, m, typed, d - 1);
                let a = x.val.rv();
                self.call(
                    "SQRT",
                    &[x],
                    Val::Real(Rv::padded(a.lo.sqrt(), a.hi.sqrt())),
                )
            }
            19..=20 if want.hi >= 1.0 => self.expt(ty, want, typed, d, Depth::Nested),
            21..=25 => self.real_select(ty, want, typed, d),
            26..=28 => return self.conv_to_real(ty, want, d),
            _ => return self.user_call(Sty::E(ty), d),
        })
    }

    /// `+`, `-` (operands in half the budget each) and `*` (by a factor of known size).
    pub(super) fn real_arith(&mut self, ty: Ty, want: Rv, typed: bool, d: u32) -> Expr {
        if self.rng.pct(60) {
            let l = self.real(ty, want.scaled(0.49), false, d - 1);
            let r = self.real(ty, want.scaled(0.49), typed && !l.typed, d - 1);
            let (a, b) = (l.val.rv(), r.val.rv());
            return if self.rng.pct(50) {
                self.binop(
                    l,
                    "+",
                    P_ADD,
                    r,
                    Val::Real(Rv::padded(a.lo + b.lo, a.hi + b.hi)),
                )
            } else {
                self.binop(
                    l,
                    "-",
                    P_ADD,
                    r,
                    Val::Real(Rv::padded(a.lo - b.hi, a.hi - b.lo)),
                )
            };
        }
        let free = free_real(ty);
        let r = if self.rng.pct(60) {
            let (v, t) = *self.rng.pick(&REAL_DIVISORS);
            self.real_const(ty, t, v)
        } else {
            self.real(ty, Rv::new(-4.0, 4.0), false, d - 1)
        };
        let m = r.val.rv().mag().max(1e-3);
        let lb = want.scaled(0.99 / m);
        let lb = Rv::new(lb.lo.max(free.lo), lb.hi.min(free.hi));
        let l = self.real(ty, lb, typed && !r.typed, d - 1);
        let val = Val::Real(rcorners(l.val.rv(), r.val.rv(), |a, b| a * b));
        self.binop(l, "*", P_MUL, r, val)
    }

    /// Unary `-` and ABS.
    pub(super) fn real_sign(&mut self, ty: Ty, want: Rv, typed: bool, d: u32) -> Expr {
        if self.rng.pct(50) {
            let l = self.real(ty, Rv::new(-want.hi, -want.lo), typed, d - 1);
            let a = l.val.rv();
            let text = format!("-{}", l.at(P_ATOM + u8::from(l.konst)));
            return Expr {
                text,
                prec: P_UNARY,
                val: Val::Real(Rv::new(-a.hi, -a.lo)),
                typed: l.typed,
                konst: l.konst,
            };
        }
        let l = self.real(ty, Rv::new(-want.hi, want.hi), typed, d - 1);
        let a = l.val.rv();
        let val = if a.lo >= 0.0 {
            a
        } else if a.hi <= 0.0 {
            Rv::new(-a.hi, -a.lo)
        } else {
            Rv::new(0.0, a.mag())
        };
        self.call("ABS", &[l], Val::Real(val))
    }

    /// MIN, MAX, LIMIT, SEL and MUX of reals.
    pub(super) fn real_select(&mut self, ty: Ty, want: Rv, typed: bool, d: u32) -> Expr {
        match self.rng.below(5) {
            0 | 1 => {
                let n = self.rng.range(2, 3);
                let args: Vec<Expr> = (0..n)
                    .map(|i| self.real(ty, want, typed && i == 0, d - 1))
                    .collect();
                let lo = args.iter().map(|a| a.val.rv().lo);
                let hi = args.iter().map(|a| a.val.rv().hi);
                let (name, rv) = if self.rng.pct(50) {
                    (
                        "MIN",
                        Rv::new(
                            lo.fold(f64::INFINITY, f64::min),
                            hi.fold(f64::INFINITY, f64::min),
                        ),
                    )
                } else {
                    (
                        "MAX",
                        Rv::new(
                            lo.fold(f64::NEG_INFINITY, f64::max),
                            hi.fold(f64::NEG_INFINITY, f64::max),
                        ),
                    )
                };
                self.call(name, &args, Val::Real(rv))
            }
            2 => {
                let x = self.real(ty, free_real(ty), typed, d - 1);
                self.limit_real(x, ty, want)
            }
            3 => {
                let a = self.real(ty, want, typed, d - 1);
                let b = self.real(ty, want, false, d - 1);
                self.sel(a, b, d)
            }
            _ => {
                let args = (0..self.rng.range(2, 4))
                    .map(|i| self.real(ty, want, typed && i == 0, d - 1))
                    .collect();
                self.mux(args, d)
            }
        }
    }

    pub(super) fn real_div(&mut self, ty: Ty, want: Rv, typed: bool, d: u32) -> Expr {
        let free = free_real(ty);
        if self.rng.pct(65) {
            let (v, t) = *self.rng.pick(&REAL_DIVISORS);
            let r = self.real_const(ty, t, v);
            let lb = want.scaled(0.99 * v);
            let lb = Rv::new(lb.lo.min(lb.hi).max(free.lo), lb.hi.max(lb.lo).min(free.hi));
            let l = self.real(ty, lb, typed && !r.typed, d - 1);
            let val = Val::Real(rcorners(l.val.rv(), r.val.rv(), |a, b| a / b));
            self.binop(l, "/", P_MUL, r, val)
        } else {
            let l = self.real(ty, want.scaled(0.99), typed, d - 1);
            let x = self.real(ty, Rv::new(-100.0, 100.0), false, d.saturating_sub(2));
            let one = self.real_const(ty, "1.0", 1.0);
            let text = format!("(ABS({}) + {})", x.text, one.text);
            let r = Expr::atom(text, Val::Real(Rv::new(1.0, 101.0)), true);
            let a = l.val.rv();
            let val = Val::Real(Rv::padded(a.lo.min(0.0), a.hi.max(0.0)));
            self.binop(l, "/", P_MUL, r, val)
        }
    }

    /// A value ≥ 0 and ≤ `max`: non-negative by construction or `ABS(…)`.
    pub(super) fn non_negative(&mut self, ty: Ty, max: f64, typed: bool, d: u32) -> Expr {
        let x = self.real(ty, Rv::new(-max, max), typed, d);
        let a = x.val.rv();
        if a.lo >= 0.0 {
            x
        } else {
            self.call("ABS", &[x], Val::Real(Rv::new(0.0, a.mag())))
        }
    }

    /// `EXPT(b, p)` with `b >= 0` and a small exponent; `**` for LREAL, or for REAL at
    /// [`Depth::Statement`] (the whole right-hand side of an assignment, rule 7).
    pub(super) fn expt(&mut self, ty: Ty, want: Rv, typed: bool, d: u32, at: Depth) -> Expr {
        let top = at == Depth::Statement;
        let (p, pt) = *self.rng.pick(&[
            (2.0, "2"),
            (3.0, "3"),
            (0.5, "0.5"),
            (1.5, "1.5"),
            (2.0, "2.0"),
        ]);
        let b = (want.hi * 0.99).powf(1.0 / p).min(free_real(ty).hi);
        let base = self.non_negative(ty, b, typed, d - 1);
        let a = base.val.rv();
        let val = Val::Real(Rv::padded(a.lo.powf(p), a.hi.powf(p)));
        let exp = if pt.contains('.') {
            self.real_const(ty, pt, p)
        } else {
            Expr::lit(pt.to_string(), Val::Int(Iv::point(p as i128)), false)
        };
        if (ty == Ty::Lreal || top) && self.rng.pct(50) {
            // `**` binds differently in the editions of IEC 61131-3: always parenthesise it.
            let text = format!("{} ** {}", base.at(P_ATOM), exp.at(P_ATOM));
            Expr {
                text,
                prec: 0,
                val,
                typed: base.typed,
                konst: false,
            }
        } else {
            let typed = base.typed;
            let mut e = self.call("EXPT", &[base, exp], val);
            e.typed = typed;
            e
        }
    }

    pub(super) fn conv_to_real(&mut self, ty: Ty, want: Rv, d: u32) -> Option<Expr> {
        if self.rng.pct(10) {
            return Some(self.string_to_real(ty, want));
        }
        let src = *self.rng.pick(CONV_TYPES);
        if src == ty {
            return None;
        }
        let (arg, val) = if src == Ty::Bool {
            (self.boolean(d - 1), Rv::new(0.0, 1.0))
        } else if src.is_int() {
            let ib = Iv::new(want.lo.ceil() as i128, want.hi.floor() as i128).meet(src.full());
            let a = self.int(src, ib, false, d - 1);
            let ai = a.val.iv();
            (a, Rv::padded(ai.lo as f64, ai.hi as f64))
        } else if src.is_bits() {
            let a = self.bits(src, Bits::PLAIN, d - 1);
            (a, Rv::padded(0.0, src.full().hi as f64))
        } else {
            let free = free_real(src);
            let b = Rv::new(want.lo.max(free.lo), want.hi.min(free.hi));
            let a = self.real(src, b, false, d - 1);
            let r = a.val.rv();
            (a, Rv::padded(r.lo, r.hi))
        };
        let name = format!("{}_TO_{}", src.name(), ty.name());
        Some(self.call(&name, &[arg], Val::Real(val)))
    }

    pub(super) fn fit_real(&mut self, e: Expr, ty: Ty, want: Rv, typed: bool) -> Expr {
        let r = e.val.rv();
        if r.within(want) && (e.typed || !typed) {
            return e;
        }
        if r.within(want) {
            return self.real_lit(ty, want, true);
        }
        let side = want.hi.min(-want.lo);
        if side > 0.0 && !e.konst && self.rng.pct(25) {
            // Divide by a power of two: exact, and the bound is known.
            let k = (r.mag() / side).log2().ceil().max(0.0) + 1.0;
            let k = 2f64.powi(k as i32);
            let kt = real_text(k);
            let div = self.real_const(ty, &kt, k);
            let val = Val::Real(Rv::padded(r.lo / k, r.hi / k));
            return self.binop(e, "/", P_MUL, div, val);
        }
        self.limit_real(e, ty, want)
    }

    /// `LIMIT(lo, e, hi)`, or `MIN(MAX(e, lo), hi)`, with literal bounds inside `want`.
    pub(super) fn limit_real(&mut self, e: Expr, ty: Ty, want: Rv) -> Expr {
        let r = e.val.rv();
        let lo_b = Rv::new(want.lo.max(r.lo.min(0.0)), 0.0);
        let hi_b = Rv::new(0.0, want.hi.min(r.hi.max(0.0)));
        let typed = !e.typed;
        let mn = self.real_lit(ty, lo_b, typed);
        let mx = self.real_lit(ty, hi_b, false);
        let (lo, hi) = (mn.val.rv().lo, mx.val.rv().hi);
        let val = Val::Real(Rv::new(r.lo.max(lo).min(hi), r.hi.min(hi).max(lo)));
        if self.rng.pct(20) {
            let inner = self.call("MAX", &[e, mn], Val::Real(Rv::new(lo, r.hi.max(lo))));
            self.call("MIN", &[inner, mx], val)
        } else {
            self.call("LIMIT", &[mn, e, mx], val)
        }
    }

    // --------------------------------------------------------------------------------------
    // TIME

    /// A TIME of at most `want` (which holds 0) nanoseconds; `clean`: normalised in MATIEC,
    /// so that it may be compared (rule 8).
    pub(super) fn time(&mut self, clean: bool, want: Iv, d: u32) -> Expr {
        if want.hi == 0 {
            return self.time_lit(false, 0);
        }
        let e = if d == 0 || self.rng.pct(35) {
            None
        } else {
            self.time_op(clean, want, d)
        };
        let e = match e {
            Some(e) => e,
            None => self.time_leaf(want),
        };
        self.fit_time(e, want, clean)
    }

    pub(super) fn time_op(&mut self, clean: bool, want: Iv, d: u32) -> Option<Expr> {
        let range = |e: &Expr| match e.val {
            Val::Time { range, .. } => range,
            other => unreachable!("not a TIME: {other:?}"),
        };
        let dirty = |range| Val::Time {
            clean: false,
            range,
        };
        Some(match self.rng.below(12) {
            0..=3 if !clean => {
                let l = self.time(false, want.half(), d - 1);
                let a = range(&l);
                if self.rng.pct(50) {
                    let r = self.time(false, Iv::new(want.lo - a.lo, want.hi - a.hi), d - 1);
                    let b = range(&r);
                    self.binop(l, "+", P_ADD, r, dirty(Iv::new(a.lo + b.lo, a.hi + b.hi)))
                } else {
                    let r = self.time(false, Iv::new(a.hi - want.hi, a.lo - want.lo), d - 1);
                    let b = range(&r);
                    self.binop(l, "-", P_ADD, r, dirty(Iv::new(a.lo - b.hi, a.hi - b.lo)))
                }
            }
            4 if !clean => {
                let op = if self.rng.pct(50) { "*" } else { "/" };
                let t = self.time(true, Iv::new(want.lo / 2, want.hi / 2), d - 1);
                let a = range(&t);
                let val = if op == "*" {
                    Iv::new(a.lo * 2, a.hi * 2)
                } else {
                    Iv::new(a.lo / 2, a.hi / 2)
                };
                let two = Expr::lit("2".to_string(), Val::Int(Iv::point(2)), false);
                self.binop(t, op, P_MUL, two, dirty(val))
            }
            5..=6 => {
                let args: Vec<Expr> = (0..self.rng.range(2, 3))
                    .map(|_| self.time(true, want, d - 1))
                    .collect();
                let rs: Vec<Iv> = args.iter().map(range).collect();
                let (name, iv) = if self.rng.pct(50) {
                    (
                        "MIN",
                        Iv::new(
                            rs.iter().map(|r| r.lo).min()?,
                            rs.iter().map(|r| r.hi).min()?,
                        ),
                    )
                } else {
                    (
                        "MAX",
                        Iv::new(
                            rs.iter().map(|r| r.lo).max()?,
                            rs.iter().map(|r| r.hi).max()?,
                        ),
                    )
                };
                self.call(
                    name,
                    &args,
                    Val::Time {
                        clean: true,
                        range: iv,
                    },
                )
            }
            7 => {
                let x = self.time(true, TIME_FREE, d - 1);
                self.limit_time(x, want)
            }
            8 => {
                let (a, b) = (self.time(clean, want, d - 1), self.time(clean, want, d - 1));
                self.sel(a, b, d)
            }
            9 => {
                let args = (0..self.rng.range(2, 3))
                    .map(|_| self.time(clean, want, d - 1))
                    .collect();
                self.mux(args, d)
            }
            _ => return self.user_call(Sty::E(Ty::Time), d),
        })
    }

    pub(super) fn time_leaf(&mut self, want: Iv) -> Expr {
        let places = self.places(Sty::E(Ty::Time), false);
        if !places.is_empty() && self.rng.pct(70) {
            let (p, dom) = *self.rng.pick(&places);
            return self.read(p, dom);
        }
        self.time_lit(false, want.hi)
    }

    /// `e` within `want` and, if `clean`, normalised: `e * 1` normalises (MATIEC's
    /// `__time_mul`), then `LIMIT(T#0s, e, T#…)` bounds.
    pub(super) fn fit_time(&mut self, e: Expr, want: Iv, clean: bool) -> Expr {
        let Val::Time { clean: c, range } = e.val else {
            unreachable!("not a TIME: {:?}", e.val);
        };
        if range.within(want) && (c || !clean) {
            return e;
        }
        let e = if c {
            e
        } else {
            let one = Expr::lit("1".to_string(), Val::Int(Iv::point(1)), false);
            self.binop(e, "*", P_MUL, one, Val::Time { clean: true, range })
        };
        if range.within(want) {
            return e;
        }
        self.limit_time(e, want)
    }

    /// `LIMIT(T#a, e, T#b)` of a clean `e`, with `0 <= a <= b <= want.hi`.
    pub(super) fn limit_time(&mut self, e: Expr, want: Iv) -> Expr {
        let range = match e.val {
            Val::Time { range, .. } => range,
            other => unreachable!("not a TIME: {other:?}"),
        };
        let a = self.time_lit(true, want.hi);
        let b = self.time_lit(false, want.hi);
        let (a, b) = if a.val_time_lo() <= b.val_time_lo() {
            (a, b)
        } else {
            (b, a)
        };
        let (lo, hi) = (a.val_time_lo(), b.val_time_lo());
        let val = limit_range(Iv::point(lo), range, Iv::point(hi));
        self.call(
            "LIMIT",
            &[a, e, b],
            Val::Time {
                clean: true,
                range: val,
            },
        )
    }

    // --------------------------------------------------------------------------------------
    // STRING

    /// A STRING of at most `max` (≤ 80) characters, every intermediate value too (rule 9).
    pub(super) fn string(&mut self, max: u32, d: u32) -> Expr {
        if d == 0 || self.rng.pct(30) {
            return self.str_leaf(max);
        }
        let d = d - 1;
        match self.rng.below(20) {
            0..=4 => {
                let n = if self.rng.pct(25) { 3 } else { 2 };
                let mut args = Vec::new();
                let mut left = max;
                for i in 0..n {
                    let budget = if i == n - 1 {
                        left
                    } else {
                        self.rng.int(0, left.into()) as u32
                    };
                    let a = self.string(budget, d);
                    left -= a.val.strlen().1;
                    args.push(a);
                }
                let min = args.iter().map(|a| a.val.strlen().0).sum();
                let max = args.iter().map(|a| a.val.strlen().1).sum();
                self.call("CONCAT", &args, Val::Str { min, max })
            }
            5..=10 => self.substring(max, d),
            11 => {
                let args: Vec<Expr> = (0..self.rng.range(2, 3))
                    .map(|_| self.string(max, d))
                    .collect();
                let val = args.iter().skip(1).fold(args[0].val, |v, a| v.join(a.val));
                let name = if self.rng.pct(50) { "MIN" } else { "MAX" };
                self.call(name, &args, val)
            }
            12 => {
                let (a, b) = (self.string(max, d), self.string(max, d));
                self.sel(a, b, d + 1)
            }
            13 => {
                let args = (0..self.rng.range(2, 3))
                    .map(|_| self.string(max, d))
                    .collect();
                self.mux(args, d + 1)
            }
            14..=16 => {
                let src = *self.rng.pick(&CONV_TYPES[..9]);
                let digits = decimal_digits(src);
                if digits > max {
                    return self.str_leaf(max);
                }
                let a = self.any_of(src, d);
                let min = if src == Ty::Bool { 4 } else { 1 };
                self.call(
                    &format!("{}_TO_STRING", src.name()),
                    &[a],
                    Val::Str { min, max: digits },
                )
            }
            17 => match self.user_call(Sty::E(Ty::String), d + 1) {
                Some(e) if e.val.strlen().1 <= max => e,
                _ => self.str_leaf(max),
            },
            _ => self.str_leaf(max),
        }
    }

    /// LEFT, RIGHT, MID, INSERT, DELETE and REPLACE, with positions and lengths inside the
    /// string (rule 9), of at most `max` characters.
    pub(super) fn substring(&mut self, max: u32, d: u32) -> Expr {
        match self.rng.below(6) {
            0 | 1 => {
                let k = self.rng.int(0, max.min(10).into()) as u32;
                let s = self.str_min(k, STR_CAP, d);
                let name = if self.rng.pct(50) { "LEFT" } else { "RIGHT" };
                let n = self.count(k);
                self.call(name, &[s, n], Val::Str { min: k, max: k })
            }
            2 => {
                let l = self.rng.int(0, max.min(8).into()) as u32;
                let p = self.rng.int(1, 6) as u32;
                let s = self.str_min(p + l - 1, STR_CAP, d);
                let (l_e, p_e) = (self.count(l), self.count(p));
                self.call("MID", &[s, l_e, p_e], Val::Str { min: l, max: l })
            }
            3 => {
                let p = self.rng.int(0, 5.min(max).into()) as u32;
                let b1 = self.rng.int(p.into(), max.into()) as u32;
                let s1 = self.str_min(p, b1, d);
                let (m1, x1) = s1.val.strlen();
                let s2 = self.string(max - x1, d);
                let (m2, x2) = s2.val.strlen();
                let p_e = self.count(p);
                self.call(
                    "INSERT",
                    &[s1, s2, p_e],
                    Val::Str {
                        min: m1 + m2,
                        max: x1 + x2,
                    },
                )
            }
            4 => {
                let l = self.rng.int(0, 5) as u32;
                let p = self.rng.int(1, (max + 1).min(5).into()) as u32;
                let s = self.str_min(p + l - 1, STR_CAP.min(max + l), d);
                let (m, x) = s.val.strlen();
                let (l_e, p_e) = (self.count(l), self.count(p));
                self.call(
                    "DELETE",
                    &[s, l_e, p_e],
                    Val::Str {
                        min: m - l,
                        max: x - l,
                    },
                )
            }
            _ => {
                let (l, p) = (self.rng.int(0, 6) as u32, self.rng.int(1, 5) as u32);
                let s2 = self.string(l.min(max), d);
                let (m2, x2) = s2.val.strlen();
                let b1 = STR_CAP.min(max + l - x2);
                if p + l - 1 > b1 {
                    return self.str_leaf(max);
                }
                let s1 = self.str_min(p + l - 1, b1, d);
                let (m1, x1) = s1.val.strlen();
                let (l_e, p_e) = (self.count(l), self.count(p));
                let val = Val::Str {
                    min: m1 - l + m2,
                    max: x1 - l + x2,
                };
                self.call("REPLACE", &[s1, s2, l_e, p_e], val)
            }
        }
    }

    pub(super) fn str_leaf(&mut self, max: u32) -> Expr {
        let places: Vec<(Place, Val)> = self
            .places(Sty::E(Ty::String), false)
            .into_iter()
            .filter(|(_, dom)| dom.strlen().1 <= max)
            .collect();
        if !places.is_empty() && self.rng.pct(70) {
            let (p, dom) = *self.rng.pick(&places);
            return self.read(p, dom);
        }
        self.str_lit(0, max.min(10))
    }

    /// A STRING of at least `min` and at most `max` characters (`min <= max`): a literal, or a
    /// CONCAT of one with anything.
    pub(super) fn str_min(&mut self, min: u32, max: u32, d: u32) -> Expr {
        debug_assert!(min <= max);
        if min == 0 {
            return self.string(max, d);
        }
        let lit = self.str_lit(min, max.min(min + 4));
        let n = lit.val.strlen().0;
        if n == max || self.rng.pct(30) {
            return lit;
        }
        let x = self.string(max - n, d);
        let (m, xm) = x.val.strlen();
        let val = Val::Str {
            min: n + m,
            max: n + xm,
        };
        if self.rng.pct(50) {
            self.call("CONCAT", &[x, lit], val)
        } else {
            self.call("CONCAT", &[lit, x], val)
        }
    }

    /// A character count or position argument with the value `v`.
    pub(super) fn count(&mut self, v: u32) -> Expr {
        let v = i128::from(v);
        if self.rng.pct(80) {
            Expr::lit(v.to_string(), Val::Int(Iv::point(v)), false)
        } else {
            self.int_lit(Ty::Int, v, true)
        }
    }

    /// The one-character string FIND looks for (rule 9).
    pub(super) fn needle(&mut self) -> Expr {
        let c = *self.rng.pick(b"abcxyzAB 01");
        Expr::lit(
            format!("'{}'", c as char),
            Val::Str { min: 1, max: 1 },
            true,
        )
    }
}

/// The range of `f(a, b)` over the corners of two intervals, padded (for a monotonic `f`).
pub(super) fn rcorners(a: Rv, b: Rv, f: impl Fn(f64, f64) -> f64) -> Rv {
    let xs = [f(a.lo, b.lo), f(a.lo, b.hi), f(a.hi, b.lo), f(a.hi, b.hi)];
    let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    Rv::padded(lo, hi)
}

/// The longest `<ty>_TO_STRING` (BOOL: `FALSE`).
pub(super) fn decimal_digits(ty: Ty) -> u32 {
    match ty {
        Ty::Bool => 5,
        Ty::Sint => 4,
        Ty::Int => 6,
        Ty::Dint => 11,
        Ty::Usint => 3,
        Ty::Uint => 5,
        Ty::Udint => 10,
        _ => 20,
    }
}
