//! Statements: assignments, IF, CASE, loops, calls of FBs.

use super::*;

// ------------------------------------------------------------------------------------------
// Statements

#[derive(Clone, Copy)]
pub(super) enum Stmt {
    Assign,
    If,
    Case,
    For,
    While,
    Repeat,
    Call,
    Exit,
}

/// A FOR loop's numbers: `FOR i := start TO end BY by`.
pub(super) struct ForBounds {
    start: i128,
    /// `None`: a `LIMIT(…)` of inputs, to be generated.
    end: Option<i128>,
    by: i128,
    /// The values of the counter inside the loop.
    range: Iv,
    /// The counter must be of a signed type.
    signed: bool,
    /// The array variable the loop runs over, whose elements its body writes first.
    array: Option<usize>,
}

pub(super) fn line(out: &mut Vec<String>, ind: usize, text: impl AsRef<str>) {
    out.push(format!("{:w$}{}", "", text.as_ref(), w = ind * 2));
}

impl ProgramGen<'_> {
    /// `n` statements, and at least one line (MATIEC refuses an empty statement list).
    pub(super) fn block(&mut self, out: &mut Vec<String>, ind: usize, n: usize, depth: u32) {
        let before = out.len();
        for _ in 0..n {
            self.stmt(out, ind, depth);
        }
        if out.len() == before {
            self.literal_assign(out, ind);
        }
    }

    /// `target := literal;`, which is never `x := x`.
    pub(super) fn literal_assign(&mut self, out: &mut Vec<String>, ind: usize) {
        let Some((lv, sty, dom)) = self.target() else {
            unreachable!("every POU has a variable to write");
        };
        let e = self.literal(sty, dom);
        line(out, ind, format!("{lv} := {};", e.text));
    }

    /// A literal of `sty` in `dom`.
    pub(super) fn literal(&mut self, sty: Sty, dom: Val) -> Expr {
        match (sty, dom) {
            (Sty::Enum(e), _) => {
                let v = self.rng.pick(&self.enums[e].values).clone();
                Expr::atom(v, dom, true)
            }
            (_, Val::Bool) => Expr::lit("TRUE".to_string(), dom, true),
            (Sty::E(t), Val::Int(iv)) => {
                let v = self.pick_int(t, iv);
                self.int_lit(t, v, false)
            }
            (Sty::E(t), Val::Real(rv)) => self.real_lit(t, rv, false),
            (_, Val::Time { range, .. }) => self.time_lit(false, range.hi),
            (_, Val::Str { max, .. }) => self.str_lit(0, max.min(10)),
            (Sty::E(t), _) => self.bits_lit(t, false),
        }
    }

    pub(super) fn stmt(&mut self, out: &mut Vec<String>, ind: usize, depth: u32) {
        let nested = if depth > 0 { 1 } else { 0 };
        let fbs = !self.fb_vars().is_empty();
        let kind = self.rng.weighted(&[
            (14, Stmt::Assign),
            (4 * nested, Stmt::If),
            (2 * nested, Stmt::Case),
            (2 * nested, Stmt::For),
            (nested, Stmt::While),
            (nested, Stmt::Repeat),
            (if fbs { 2 } else { 0 }, Stmt::Call),
            (if self.pou.loops > 0 { 2 } else { 0 }, Stmt::Exit),
        ]);
        match kind {
            Stmt::Assign => self.assign(out, ind),
            Stmt::If => self.if_stmt(out, ind, depth),
            Stmt::Case => self.case_stmt(out, ind, depth),
            Stmt::For => self.for_loop(out, ind, depth),
            Stmt::While => self.while_loop(out, ind, depth),
            Stmt::Repeat => self.repeat_loop(out, ind, depth),
            Stmt::Call => self.fb_call(out, ind),
            Stmt::Exit => {
                let c = self.boolean(1);
                line(out, ind, format!("IF {} THEN", c.text));
                line(out, ind + 1, "EXIT;");
                line(out, ind, "END_IF;");
            }
        }
    }

    pub(super) fn assign(&mut self, out: &mut Vec<String>, ind: usize) {
        if let Some((lv, sty, dom)) = self.target() {
            self.store(out, ind, &lv, sty, dom);
        }
    }

    /// `lv := …;`, but not `lv := lv;`, which says nothing.
    pub(super) fn store(
        &mut self,
        out: &mut Vec<String>,
        ind: usize,
        lv: &str,
        sty: Sty,
        dom: Val,
    ) {
        for _ in 0..3 {
            let rhs = self.rhs(sty, dom, lv);
            if rhs.text != lv {
                line(out, ind, format!("{lv} := {};", rhs.text));
                return;
            }
        }
        let e = self.literal(sty, dom);
        line(out, ind, format!("{lv} := {};", e.text));
    }

    /// The right-hand side of an assignment to `lv`: where wrapping (rule 1), TRUNC (rule 3)
    /// and REAL `**` (rule 7) are allowed.
    pub(super) fn rhs(&mut self, sty: Sty, dom: Val, lv: &str) -> Expr {
        let d = self.rng.range(1, 3) as u32;
        if let (Sty::E(t), Val::Int(iv)) = (sty, dom) {
            if t.wraps() && iv == t.full() && self.rng.pct(30) {
                return self.wrap_rhs(t, lv, d);
            }
            if self.rng.pct(6) {
                let src = if self.rng.pct(50) {
                    Ty::Real
                } else {
                    Ty::Lreal
                };
                let free = free_real(src);
                let rb = Rv::new((iv.lo as f64).max(free.lo), (iv.hi as f64).min(free.hi));
                // Typed: of an argument of untyped literals only, MATIEC takes the REAL
                // TRUNC where an LREAL was meant (rule 3).
                let x = self.real(src, rb, true, d);
                return Expr::atom(format!("TRUNC({})", x.text), dom, true);
            }
            if self.rng.pct(25) {
                // Accumulate in the type's range, then bring back into the domain.
                let e = self.int(t, t.full(), false, d);
                return self.fit_int(e, t, iv, false);
            }
        }
        if let (Sty::E(Ty::Real), Val::Real(rv)) = (sty, dom) {
            if rv.hi >= 1.0 && self.rng.pct(10) {
                return self.expt(Ty::Real, rv, false, d, Depth::Statement);
            }
        }
        self.value(sty, dom, d)
    }

    /// `lv := lv + e` and the like, which may wrap around (rule 1): the state creeps to its
    /// limits and over them.
    pub(super) fn wrap_rhs(&mut self, t: Ty, lv: &str, d: u32) -> Expr {
        let full = t.full();
        let mut l = Expr::atom(lv.to_string(), Val::Int(full), true);
        if self.rng.pct(30) {
            let places = self.places(Sty::E(t), false);
            if !places.is_empty() {
                let (p, dom) = *self.rng.pick(&places);
                l = self.read(p, dom);
            }
        }
        let val = Val::Int(full);
        match self.rng.below(8) {
            0..=3 => {
                let r = self.int(t, full, false, d - 1);
                self.binop(l, "+", P_ADD, r, val)
            }
            4..=5 => {
                let r = self.int(t, full, false, d - 1);
                self.binop(l, "-", P_ADD, r, val)
            }
            6 if t.signed() => {
                let text = format!("-{}", l.at(P_ATOM));
                Expr {
                    text,
                    prec: P_UNARY,
                    val,
                    typed: true,
                    konst: false,
                }
            }
            _ => {
                // C `int` must hold the product of two 16-bit values (UINT: 65535 * 1000).
                let k = if t.narrow() { 1000 } else { full.hi };
                let rb = if t.signed() {
                    Iv::new(-k, k)
                } else {
                    Iv::new(0, k)
                };
                let r = self.int(t, rb.meet(full), false, d - 1);
                self.binop(l, "*", P_MUL, r, val)
            }
        }
    }

    pub(super) fn if_stmt(&mut self, out: &mut Vec<String>, ind: usize, depth: u32) {
        let c = self.boolean(2);
        line(out, ind, format!("IF {} THEN", c.text));
        let n = self.rng.range(1, 2);
        self.block(out, ind + 1, n, depth - 1);
        for _ in 0..self.rng.weighted(&[(7, 0), (3, 1)]) {
            let c = self.boolean(2);
            line(out, ind, format!("ELSIF {} THEN", c.text));
            self.block(out, ind + 1, 1, depth - 1);
        }
        if self.rng.pct(45) {
            line(out, ind, "ELSE");
            self.block(out, ind + 1, 1, depth - 1);
        }
        line(out, ind, "END_IF;");
    }

    pub(super) fn case_stmt(&mut self, out: &mut Vec<String>, ind: usize, depth: u32) {
        let enums: Vec<(Place, Val, usize)> = (0..self.enums.len())
            .flat_map(|e| {
                self.places(Sty::Enum(e), false)
                    .into_iter()
                    .map(move |(p, v)| (p, v, e))
            })
            .collect();
        let branches: Vec<String>;
        if !enums.is_empty() && self.rng.pct(40) {
            let (p, dom, e) = *self.rng.pick(&enums);
            let sel = self.read(p, dom);
            line(out, ind, format!("CASE {} OF", sel.text));
            let mut values = self.enums[e].values.clone();
            shuffle(self.rng, &mut values);
            let keep = self.rng.range(1, values.len());
            branches = values[..keep]
                .chunks(self.rng.range(1, 2))
                .map(|c| c.join(", "))
                .collect();
        } else {
            let ty = *self.rng.pick(&[
                Ty::Int,
                Ty::Dint,
                Ty::Sint,
                Ty::Usint,
                Ty::Uint,
                Ty::Lint,
                Ty::Udint,
            ]);
            let range = if ty.signed() {
                Iv::new(-5, 15)
            } else {
                Iv::new(0, 20)
            };
            let mut sel = self.int(ty, range, true, 2);
            for _ in 0..3 {
                if !sel.konst {
                    break;
                }
                sel = self.int(ty, range, true, 2);
            }
            line(out, ind, format!("CASE {} OF", sel.text));
            branches = self.case_labels(range);
        }
        for b in branches {
            line(out, ind + 1, format!("{b}:"));
            self.block(out, ind + 2, 1, depth - 1);
        }
        if self.rng.pct(60) {
            line(out, ind, "ELSE");
            self.block(out, ind + 1, 1, depth - 1);
        }
        line(out, ind, "END_CASE;");
    }

    /// Disjoint labels in `range`, values and `a..b` ranges, grouped into 2-4 branches.
    pub(super) fn case_labels(&mut self, range: Iv) -> Vec<String> {
        let mut items = Vec::new();
        let mut v = range.lo + self.rng.int(0, 2);
        while items.len() < 7 && v <= range.hi {
            if self.rng.pct(30) {
                let b = (v + self.rng.int(1, 4)).min(range.hi + 2);
                items.push(format!("{v}..{b}"));
                v = b + 1 + self.rng.int(0, 2);
            } else {
                items.push(v.to_string());
                v += 1 + self.rng.int(0, 2);
            }
        }
        shuffle(self.rng, &mut items);
        let k = self.rng.range(2, 3).min(items.len());
        let mut branches = vec![Vec::new(); k];
        for (i, item) in items.into_iter().enumerate() {
            let b = if i < k { i } else { self.rng.range(0, k - 1) };
            branches[b].push(item);
        }
        branches.into_iter().map(|b| b.join(", ")).collect()
    }

    /// A new loop counter of type `ty`, declared in the POU's VAR section.
    pub(super) fn counter(&mut self, ty: Ty, stem: &str) -> String {
        let name = self.fresh(stem);
        self.pou.counters.push((name.clone(), ty));
        name
    }

    /// The body of a loop whose counter is `live`; over an array, its first statement writes
    /// an element of `array`.
    pub(super) fn in_loop(
        &mut self,
        out: &mut Vec<String>,
        ind: usize,
        depth: u32,
        live: Live,
        array: Option<usize>,
    ) {
        self.pou.live.push(live);
        self.pou.loops += 1;
        if let Some(i) = array {
            let Kind::Array(_, elem) = self.pou.vars[i].kind.clone() else {
                unreachable!("an array");
            };
            let (field, sty, dom) = match elem {
                Elem::Scalar(sty, dom) => (None, sty, dom),
                Elem::Struct(s) => {
                    let f = self.rng.below(self.structs[s].fields.len() as u64) as usize;
                    let p = &self.structs[s].fields[f];
                    (Some(f), p.sty, p.dom)
                }
            };
            let lv = self.place_text(Place::Elem(i, field));
            self.store(out, ind, &lv, sty, dom);
        }
        let n = self.rng.range(1, 2);
        self.block(out, ind, n, depth - 1);
        self.pou.loops -= 1;
        self.pou.live.pop();
    }

    /// A FOR that runs zero times or at least twice (rule 10), over an array's bounds, over
    /// literals, or up to a bound that depends on inputs only.
    pub(super) fn for_loop(&mut self, out: &mut Vec<String>, ind: usize, depth: u32) {
        let ForBounds {
            start,
            end,
            by,
            range,
            signed,
            array,
        } = self.for_bounds();
        let ty = if signed {
            *self
                .rng
                .pick(&[Ty::Int, Ty::Int, Ty::Dint, Ty::Sint, Ty::Lint])
        } else {
            *self
                .rng
                .pick(&[Ty::Int, Ty::Uint, Ty::Usint, Ty::Udint, Ty::Dint])
        };
        let (end, range) = match end {
            Some(end) => (end.to_string(), range),
            None => {
                // LIMIT(start + by, e, start + by * (n - 1)) over inputs: 2..=n trips.
                let n = self.rng.int(3, 6);
                let (a, b) = (start + by, start + by * (n - 1));
                self.pou.stable = true;
                let e = self.int(ty, ty.full(), true, 1);
                self.pou.stable = false;
                let (mn, mx) = (a.min(b), a.max(b));
                let range = Iv::new(start.min(mn), start.max(mx));
                (format!("LIMIT({mn}, {}, {mx})", e.text), range)
            }
        };
        let name = self.counter(ty, "i");
        let step = if by == 1 && self.rng.pct(60) {
            String::new()
        } else {
            format!(" BY {by}")
        };
        line(out, ind, format!("FOR {name} := {start} TO {end}{step} DO"));
        self.in_loop(out, ind + 1, depth, Live { name, ty, range }, array);
        line(out, ind, "END_FOR;");
    }

    pub(super) fn for_bounds(&mut self) -> ForBounds {
        let dims: Vec<(usize, (i128, i128))> = (0..self.pou.vars.len())
            .filter(|&i| self.pou.vars[i].section != Section::Input)
            .flat_map(|i| match &self.pou.vars[i].kind {
                Kind::Array(dims, _) => dims.iter().map(|&d| (i, d)).collect(),
                _ => Vec::new(),
            })
            .collect();
        let mode = self.rng.below(3);
        if mode == 0 && !dims.is_empty() {
            let (i, (lo, hi)) = *self.rng.pick(&dims);
            let range = Iv::new(lo, hi);
            let (start, end, by) = match self.rng.below(6) {
                0 | 1 => (hi, lo, -1),
                2 if hi - lo >= 2 => (lo, hi, 2),
                _ => (lo, hi, 1),
            };
            return ForBounds {
                start,
                end: Some(end),
                by,
                range,
                // A negative step only with a signed counter (UDINT would wrap below 0).
                signed: lo < 0 || by < 0,
                array: Some(i),
            };
        }
        let signed = self.rng.pct(70);
        let by = if signed {
            *self.rng.pick(&[1, 1, 2, 3, -1, -2])
        } else {
            *self.rng.pick(&[1, 1, 2, 3])
        };
        let s = if signed {
            self.rng.int(-5, 5)
        } else {
            self.rng.int(3, 6)
        };
        if mode == 2 {
            return ForBounds {
                start: s,
                end: None,
                by,
                range: Iv::point(s),
                signed,
                array: None,
            };
        }
        let trips = if self.rng.pct(10) {
            0
        } else {
            self.rng.int(2, 6)
        };
        let last = s + by * (trips - 1).max(0);
        let end = if trips == 0 {
            s - by.signum() * self.rng.int(1, 3)
        } else {
            last + by.signum() * self.rng.int(0, by.abs() - 1)
        };
        ForBounds {
            start: s,
            end: Some(end),
            by,
            range: Iv::new(s.min(last), s.max(last)),
            signed,
            array: None,
        }
    }

    /// A counter of a loop's trips, set to 0 here: its name, its type, and the trips (2 to 8).
    fn trip_counter(&mut self, out: &mut Vec<String>, ind: usize) -> (String, Ty, i128) {
        let ty = *self
            .rng
            .pick(&[Ty::Int, Ty::Dint, Ty::Uint, Ty::Sint, Ty::Usint]);
        let name = self.counter(ty, "n");
        let n = self.rng.int(2, 8);
        line(out, ind, format!("{name} := 0;"));
        (name, ty, n)
    }

    /// The body of a WHILE or REPEAT loop that counts its trips with `counter` (name, type,
    /// trips), the count last.
    fn counted_body(
        &mut self,
        out: &mut Vec<String>,
        ind: usize,
        depth: u32,
        counter: (&str, Ty, i128),
    ) {
        let (name, ty, n) = counter;
        let live = Live {
            name: name.to_string(),
            ty,
            range: Iv::new(0, n - 1),
        };
        self.in_loop(out, ind + 1, depth, live, None);
        line(out, ind + 1, format!("{name} := {name} + 1;"));
    }

    /// `WHILE n < N …` with a counter that ends it after at most N (≤ 8) trips.
    pub(super) fn while_loop(&mut self, out: &mut Vec<String>, ind: usize, depth: u32) {
        let (name, ty, n) = self.trip_counter(out, ind);
        let bound = format!("{name} < {n}");
        let cond = match self.rng.below(3) {
            0 => bound,
            1 => format!("{bound} AND {}", self.boolean(1).at(P_AND + 1)),
            _ => format!("{} AND {bound}", self.boolean(1).at(P_AND)),
        };
        line(out, ind, format!("WHILE {cond} DO"));
        self.counted_body(out, ind, depth, (&name, ty, n));
        line(out, ind, "END_WHILE;");
    }

    pub(super) fn repeat_loop(&mut self, out: &mut Vec<String>, ind: usize, depth: u32) {
        let (name, ty, n) = self.trip_counter(out, ind);
        line(out, ind, "REPEAT");
        self.counted_body(out, ind, depth, (&name, ty, n));
        let until = if self.rng.pct(50) {
            format!("{name} >= {n}")
        } else {
            format!("{name} >= {n} OR {}", self.boolean(1).at(P_OR + 1))
        };
        line(out, ind, format!("UNTIL {until}"));
        line(out, ind, "END_REPEAT;");
    }

    /// The FB instances in scope.
    pub(super) fn fb_vars(&self) -> Vec<usize> {
        (0..self.pou.vars.len())
            .filter(|&i| matches!(self.pou.vars[i].kind, Kind::Fb(_)))
            .collect()
    }

    /// A formal call of an FB instance, sometimes binding an output with `=>`.
    pub(super) fn fb_call(&mut self, out: &mut Vec<String>, ind: usize) {
        let i = *self.rng.pick(&self.fb_vars());
        let line_text = self.fb_call_text(i);
        line(out, ind, line_text);
    }

    pub(super) fn fb_call_text(&mut self, i: usize) -> String {
        let Kind::Fb(fb) = self.pou.vars[i].kind else {
            unreachable!()
        };
        let mut args = Vec::new();
        match fb {
            Fb::Std(kind, pv) => {
                let b = |g: &mut Self, name: &str| format!("{name} := {}", g.boolean(2).text);
                match kind {
                    StdFb::Ton | StdFb::Tof | StdFb::Tp => {
                        args.push(b(self, "IN"));
                        let pt = if self.rng.pct(75) {
                            self.time_lit(true, TIME_VAR)
                        } else {
                            self.time(true, Iv::new(0, TIME_VAR), 1)
                        };
                        args.push(format!("PT := {}", pt.text));
                    }
                    StdFb::Ctu | StdFb::Ctd | StdFb::Ctud => {
                        let names: &[&str] = match kind {
                            StdFb::Ctu => &["CU", "R"],
                            StdFb::Ctd => &["CD", "LD"],
                            _ => &["CU", "CD", "R", "LD"],
                        };
                        for n in names {
                            args.push(b(self, n));
                        }
                        args.push(format!("PV := {}", self.int(Ty::Int, pv, false, 1).text));
                    }
                    StdFb::RTrig | StdFb::FTrig => args.push(b(self, "CLK")),
                    StdFb::Sr => {
                        args.push(b(self, "S1"));
                        args.push(b(self, "R"));
                    }
                    StdFb::Rs => {
                        args.push(b(self, "S"));
                        args.push(b(self, "R1"));
                    }
                }
            }
            Fb::User(u) => {
                let decl = self.fbs[u].clone();
                for p in &decl.inputs {
                    // An input left out keeps its value from the previous call.
                    if self.rng.pct(90) {
                        args.push(format!(
                            "{} := {}",
                            p.name,
                            self.value(p.sty, p.dom, 2).text
                        ));
                    }
                }
                let binds = self.pou.vars[i].binds.clone();
                for (p, v) in decl.inouts.iter().zip(binds) {
                    args.push(format!("{} := {v}", p.name));
                }
            }
        }
        if self.rng.pct(35) {
            // Never the variable of an in-out of the same call: IEC leaves the order of its
            // two writes open (docs/st.md, VAR_IN_OUT).
            let in_outs = self.pou.vars[i].binds.clone();
            if let Some(bind) = self.output_binding(fb, &in_outs) {
                args.push(bind);
            }
        }
        format!("{}({});", self.pou.vars[i].name, args.join(", "))
    }

    /// `Q => v` for an output of instance `i` and a variable whose domain holds it, other than
    /// the variables the call binds to in-outs (`in_outs`).
    pub(super) fn output_binding(&mut self, fb: Fb, in_outs: &[String]) -> Option<String> {
        let outs = self.fb_outputs(fb);
        let k = self.rng.below(outs.len() as u64) as usize;
        let (sty, dom) = outs[k];
        let vars: Vec<String> = self
            .pou
            .vars
            .iter()
            .filter(|v| v.section != Section::Input && !in_outs.contains(&v.name))
            .filter(|v| matches!(v.kind, Kind::Scalar(t, d) if t == sty && dom.fits(d)))
            .map(|v| v.name.clone())
            .collect();
        if vars.is_empty() {
            return None;
        }
        Some(format!(
            "{} => {}",
            self.fb_output_name(fb, k),
            self.rng.pick(&vars)
        ))
    }
}

pub(super) fn shuffle<T>(rng: &mut Rng, xs: &mut [T]) {
    for i in (1..xs.len()).rev() {
        let j = rng.below(i as u64 + 1) as usize;
        xs.swap(i, j);
    }
}
