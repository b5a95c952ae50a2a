//! Expression helpers: the generic standard functions and calls.

use super::*;

// ------------------------------------------------------------------------------------------
// Expression helpers

/// Functions whose result type is the type of their (non-selector) arguments.
pub(super) const GENERIC: [&str; 8] = ["ABS", "MIN", "MAX", "LIMIT", "SEL", "MUX", "SQRT", "EXPT"];

impl ProgramGen<'_> {
    /// `e` as an operand of an operator of precedence `min`; now and then in parentheses that
    /// the precedence does not need.
    pub(super) fn operand(&mut self, e: &Expr, min: u8) -> String {
        if e.prec < P_ATOM && e.prec >= min && self.rng.pct(8) {
            format!("({})", e.text)
        } else {
            e.at(min)
        }
    }

    pub(super) fn binop(&mut self, l: Expr, op: &str, prec: u8, r: Expr, val: Val) -> Expr {
        let lt = self.operand(&l, prec);
        let rt = self.operand(&r, prec + 1);
        Expr {
            text: format!("{lt} {op} {rt}"),
            prec,
            val,
            typed: l.typed || r.typed,
            konst: l.konst && r.konst,
        }
    }

    /// A call of a standard or user function with positional arguments.
    pub(super) fn call(&mut self, name: &str, args: &[Expr], val: Val) -> Expr {
        let texts: Vec<&str> = args.iter().map(|a| a.text.as_str()).collect();
        let typed = !GENERIC.contains(&name) || args.iter().any(|a| a.typed);
        Expr::atom(format!("{name}({})", texts.join(", ")), val, typed)
    }

    /// `MUX(k, args…)` with `k` always selecting one of them.
    pub(super) fn mux(&mut self, args: Vec<Expr>, d: u32) -> Expr {
        let kty = *self.rng.pick(INT_TYPES);
        let k = self.int(
            kty,
            Iv::new(0, args.len() as i128 - 1),
            true,
            d.saturating_sub(1),
        );
        let val = args.iter().skip(1).fold(args[0].val, |v, a| v.join(a.val));
        let typed = args.iter().any(|a| a.typed);
        let mut all = vec![k];
        all.extend(args);
        let mut e = self.call("MUX", &all, val);
        e.typed = typed;
        e
    }

    pub(super) fn sel(&mut self, a: Expr, b: Expr, d: u32) -> Expr {
        let g = self.boolean(d.saturating_sub(1));
        let val = a.val.join(b.val);
        let typed = a.typed || b.typed;
        let mut e = self.call("SEL", &[g, a, b], val);
        e.typed = typed;
        e
    }

    /// A call of a user function returning `sty`, positional or formal, if there is one.
    pub(super) fn user_call(&mut self, sty: Sty, d: u32) -> Option<Expr> {
        let fns: Vec<usize> = (0..self.pou.callable)
            .filter(|&f| Sty::E(self.funcs[f].ret) == sty)
            .collect();
        if fns.is_empty() || d == 0 {
            return None;
        }
        let f = *self.rng.pick(&fns);
        Some(self.call_fn(f, d))
    }

    /// A call of user function `f`, with positional or formal arguments in its parameters'
    /// domains.
    pub(super) fn call_fn(&mut self, f: usize, d: u32) -> Expr {
        let f = self.funcs[f].clone();
        let d = d.max(1);
        let formal = self.rng.pct(40);
        let mut args = Vec::new();
        for p in &f.params {
            let a = self.value(p.sty, p.dom, d - 1);
            args.push(if formal {
                format!("{} := {}", p.name, a.text)
            } else {
                a.text
            });
        }
        Expr::atom(format!("{}({})", f.name, args.join(", ")), f.dom, true)
    }

    /// An expression of `sty` whose value fits the domain `dom` (bit strings may be dirty:
    /// this is for stores and arguments, which truncate).
    pub(super) fn value(&mut self, sty: Sty, dom: Val, d: u32) -> Expr {
        match (sty, dom) {
            (Sty::Enum(e), _) => self.enumeration(e),
            (Sty::E(Ty::Bool), _) => self.boolean(d),
            (Sty::E(t), Val::Int(iv)) => self.int(t, iv, false, d),
            (Sty::E(t), Val::Real(rv)) => self.real(t, rv, false, d),
            (Sty::E(Ty::Time), Val::Time { clean, range }) => self.time(clean, range, d),
            (Sty::E(Ty::String), Val::Str { max, .. }) => self.string(max, d),
            (Sty::E(t), _) => self.bits(t, Bits::PLAIN, d),
        }
    }

    pub(super) fn enumeration(&mut self, e: usize) -> Expr {
        let places = self.places(Sty::Enum(e), false);
        if !places.is_empty() && self.rng.pct(40) {
            let (p, dom) = *self.rng.pick(&places);
            return self.read(p, dom);
        }
        let decl = &self.enums[e];
        let v = self.rng.pick(&decl.values).clone();
        let text = if self.rng.pct(25) {
            format!("{}#{v}", decl.name)
        } else {
            v
        };
        Expr::atom(text, Val::Enum(e), true)
    }

    // --------------------------------------------------------------------------------------
    // BOOL

    pub(super) fn boolean(&mut self, d: u32) -> Expr {
        if d == 0 || self.rng.pct(25) {
            return self.bool_leaf();
        }
        match self.rng.below(30) {
            0..=11 => self.compare(d),
            12..=15 => {
                let op = if self.rng.pct(25) { "&" } else { "AND" };
                self.bool_bin(op, P_AND, d)
            }
            16..=18 => self.bool_bin("OR", P_OR, d),
            19..=20 => self.bool_bin("XOR", P_XOR, d),
            21..=23 => {
                let x = self.boolean(d - 1);
                let text = format!("NOT {}", x.at(P_ATOM));
                Expr {
                    text,
                    prec: P_UNARY,
                    val: Val::Bool,
                    typed: true,
                    konst: false,
                }
            }
            24..=25 if self.rng.pct(15) => self.string_to_bool(d),
            24..=25 => {
                let src = *self.rng.pick(&CONV_TYPES[1..]);
                let a = self.any_of(src, d - 1);
                self.call(&format!("{}_TO_BOOL", src.name()), &[a], Val::Bool)
            }
            26 => {
                let (a, b) = (self.boolean(d - 1), self.boolean(d - 1));
                self.sel(a, b, d)
            }
            27 => {
                let args = (0..self.rng.range(2, 3))
                    .map(|_| self.boolean(d - 1))
                    .collect();
                self.mux(args, d)
            }
            _ => match self.user_call(Sty::E(Ty::Bool), d) {
                Some(e) => e,
                None => self.bool_leaf(),
            },
        }
    }

    pub(super) fn bool_leaf(&mut self) -> Expr {
        let places = self.places(Sty::E(Ty::Bool), false);
        if places.is_empty() || self.rng.pct(8) {
            let v = if self.rng.pct(50) { "TRUE" } else { "FALSE" };
            return Expr::lit(v.to_string(), Val::Bool, true);
        }
        let (p, dom) = *self.rng.pick(&places);
        self.read(p, dom)
    }

    pub(super) fn bool_bin(&mut self, op: &str, prec: u8, d: u32) -> Expr {
        let l = self.boolean(d - 1);
        let r = self.boolean(d - 1);
        self.binop(l, op, prec, r, Val::Bool)
    }

    /// Any value of `ty` for a conversion's argument or a comparison's operand.
    pub(super) fn any_of(&mut self, ty: Ty, d: u32) -> Expr {
        if ty.is_int() {
            self.int(ty, ty.full(), false, d)
        } else if ty.is_bits() {
            self.bits(ty, Bits::PLAIN, d)
        } else if ty.is_real() {
            self.real(ty, free_real(ty), false, d)
        } else {
            self.boolean(d)
        }
    }

    /// A comparison of two values of a random type (rules 5, 8 and 11: clean bit strings and
    /// TIMEs, and at least one typed operand).
    pub(super) fn compare(&mut self, d: u32) -> Expr {
        let mut types: Vec<Sty> = ALL_TYPES.iter().map(|&t| Sty::E(t)).collect();
        types.extend((0..self.enums.len()).map(Sty::Enum));
        let sty = *self.rng.pick(&types);
        let ordered = matches!(sty, Sty::E(t) if t != Ty::Bool);
        let (l, r) = match sty {
            Sty::Enum(e) => (self.enumeration(e), self.enumeration(e)),
            Sty::E(Ty::Bool) => (self.boolean(d - 1), self.boolean(d - 1)),
            Sty::E(Ty::Time) => (
                self.time(true, TIME_FREE, d - 1),
                self.time(true, TIME_FREE, d - 1),
            ),
            Sty::E(Ty::String) => (self.string(STR_CAP, d - 1), self.string(STR_CAP, d - 1)),
            Sty::E(t) if t.is_int() => {
                let l = self.int(t, t.full(), false, d - 1);
                let r = self.int(t, t.full(), !l.typed, d - 1);
                (l, r)
            }
            Sty::E(t) if t.is_bits() => {
                let clean = Bits::PLAIN.with_clean(true);
                let l = self.bits(t, clean, d - 1);
                let r = self.bits(t, clean.with_typed(!l.typed), d - 1);
                (l, r)
            }
            Sty::E(t) => {
                let l = self.real(t, free_real(t), false, d - 1);
                let r = self.real(t, free_real(t), !l.typed, d - 1);
                (l, r)
            }
        };
        let ops: &[&str] = if ordered {
            &["=", "<>", "<", ">", "<=", ">="]
        } else {
            &["=", "<>"]
        };
        let op = *self.rng.pick(ops);
        let prec = if op == "=" || op == "<>" { P_EQ } else { P_CMP };
        let lt = self.operand(&l, prec + 1);
        let rt = self.operand(&r, prec + 1);
        Expr {
            text: format!("{lt} {op} {rt}"),
            prec,
            val: Val::Bool,
            typed: true,
            konst: false,
        }
    }

    // --------------------------------------------------------------------------------------
    // BYTE, WORD, DWORD, LWORD

    /// A bit string of type `ty`; `clean`: no bits above its width in C (rule 5).
    pub(super) fn bits(&mut self, ty: Ty, want: Bits, d: u32) -> Expr {
        let Bits { clean, typed } = want;
        if d == 0 || self.rng.pct(30) {
            return self.bits_leaf(ty, typed);
        }
        match self.rng.below(26) {
            0..=8 => {
                let (op, prec) =
                    *self
                        .rng
                        .pick(&[("AND", P_AND), ("&", P_AND), ("OR", P_OR), ("XOR", P_XOR)]);
                let and = prec == P_AND;
                let l = self.bits(ty, want.with_clean(clean && !and), d - 1);
                let r = self.bits(
                    ty,
                    Bits::PLAIN.with_clean(clean && (!and || l.val.dirty())),
                    d - 1,
                );
                let dirty = if and {
                    l.val.dirty() && r.val.dirty()
                } else {
                    l.val.dirty() || r.val.dirty()
                };
                self.binop(l, op, prec, r, Val::Bits { dirty })
            }
            9..=11 if !clean || !ty.narrow() => {
                // MATIEC cannot type `NOT 16#F0F`: the operand is typed.
                let x = self.bits(ty, Bits::PLAIN.with_typed(true), d - 1);
                let text = format!("NOT {}", x.at(P_ATOM));
                let val = Val::Bits { dirty: ty.narrow() };
                Expr {
                    text,
                    prec: P_UNARY,
                    val,
                    typed: x.typed,
                    konst: false,
                }
            }
            12..=16 => self.bits_shift(ty, typed, d),
            17..=18 => {
                let n = self.rng.range(2, 3);
                let args: Vec<Expr> = (0..n)
                    .map(|i| self.bits(ty, Bits::PLAIN.with_typed(typed && i == 0), d - 1))
                    .collect();
                let name = if self.rng.pct(50) { "MIN" } else { "MAX" };
                self.call(name, &args, Val::Bits { dirty: false })
            }
            19 => {
                let mn = self.bits_lit(ty, typed);
                let x = self.bits(ty, Bits::PLAIN, d - 1);
                let mx = Expr::lit(
                    format!("{}#{}", ty.name(), ty.full().hi),
                    Val::Bits { dirty: false },
                    true,
                );
                self.call("LIMIT", &[mn, x, mx], Val::Bits { dirty: false })
            }
            20 => {
                let a = self.bits(ty, want, d - 1);
                let b = self.bits(ty, Bits::PLAIN.with_clean(clean), d - 1);
                let mut e = self.sel(a, b, d);
                e.val = Val::Bits { dirty: false };
                e
            }
            21 => {
                let args = (0..self.rng.range(2, 4))
                    .map(|i| self.bits(ty, Bits::PLAIN.with_typed(typed && i == 0), d - 1))
                    .collect();
                let mut e = self.mux(args, d);
                e.val = Val::Bits { dirty: false };
                e
            }
            22..=24 => self.conv_to_bits(ty, d),
            _ => match self.user_call(Sty::E(ty), d) {
                Some(e) => e,
                None => self.bits_leaf(ty, typed),
            },
        }
    }

    /// SHL, SHR (by 0 … width-1), ROL, ROR (by 1 … width-1) (rule 4).
    pub(super) fn bits_shift(&mut self, ty: Ty, typed: bool, d: u32) -> Expr {
        let w = i128::from(ty.width());
        let name = *self.rng.pick(&["SHL", "SHR", "ROL", "ROR"]);
        let x = self.bits(
            ty,
            Bits {
                clean: false,
                typed,
            },
            d - 1,
        );
        let nty = *self.rng.pick(INT_TYPES);
        let n = if name.starts_with("RO") {
            // A rotation by 0 is a C shift by the width (rule 4).
            self.rotation(nty, w, d - 1)
        } else {
            self.int(nty, Iv::new(0, w - 1), true, d - 1)
        };
        let typed = x.typed;
        let mut e = self.call(name, &[x, n], Val::Bits { dirty: false });
        e.typed = typed;
        e
    }

    /// A rotation count in `1..w`.
    pub(super) fn rotation(&mut self, nty: Ty, w: i128, d: u32) -> Expr {
        let n = self.int(nty, Iv::new(0, w - 2), true, d);
        let ni = n.val.iv();
        if ni.lo >= 1 {
            n
        } else if !n.konst && self.rng.pct(60) {
            let one = self.int_lit(nty, 1, false);
            self.binop(n, "+", P_ADD, one, Val::Int(Iv::new(ni.lo + 1, ni.hi + 1)))
        } else {
            let v = self.rng.int(1, w - 1);
            self.int_lit(nty, v, true)
        }
    }

    pub(super) fn bits_leaf(&mut self, ty: Ty, typed: bool) -> Expr {
        let places = self.places(Sty::E(ty), false);
        if !places.is_empty() && self.rng.pct(65) {
            let (p, dom) = *self.rng.pick(&places);
            return self.read(p, dom);
        }
        self.bits_lit(ty, typed)
    }

    pub(super) fn conv_to_bits(&mut self, ty: Ty, d: u32) -> Expr {
        if self.rng.pct(10) {
            return self.string_to_bits(ty, d);
        }
        let src = *self.rng.pick(CONV_TYPES);
        let arg = if src == ty {
            return self.bits_leaf(ty, true);
        } else if src.is_real() {
            let hi = (ty.full().hi as f64).min(free_real(src).hi);
            self.real(src, Rv::new(0.0, hi), false, d - 1)
        } else {
            self.any_of(src, d - 1)
        };
        let name = format!("{}_TO_{}", src.name(), ty.name());
        self.call(&name, &[arg], Val::Bits { dirty: false })
    }
}
