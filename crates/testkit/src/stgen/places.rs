//! Places: reading and writing variables, array elements, fields and FB outputs.

use super::*;

// ------------------------------------------------------------------------------------------
// Places: reading and writing variables, array elements, fields and FB outputs

impl ProgramGen<'_> {
    pub(super) fn fresh(&mut self, stem: &str) -> String {
        self.names += 1;
        format!("{stem}{}", self.names)
    }

    /// The places of type `sty`, with their domains; only writable ones if `write`.
    pub(super) fn places(&self, sty: Sty, write: bool) -> Vec<(Place, Val)> {
        let mut out = Vec::new();
        for (i, v) in self.pou.vars.iter().enumerate() {
            let readable = !self.pou.stable || v.section == Section::Input;
            let writable = v.section != Section::Input;
            if !readable || (write && !writable) {
                continue;
            }
            match &v.kind {
                Kind::Scalar(t, dom) if *t == sty => out.push((Place::Var(i), *dom)),
                Kind::Array(_, Elem::Scalar(t, dom)) if *t == sty => {
                    out.push((Place::Elem(i, None), *dom))
                }
                Kind::Array(_, Elem::Struct(s)) => {
                    for (f, p) in self.structs[*s].fields.iter().enumerate() {
                        if p.sty == sty {
                            out.push((Place::Elem(i, Some(f)), p.dom));
                        }
                    }
                }
                Kind::Struct(s) => {
                    for (f, p) in self.structs[*s].fields.iter().enumerate() {
                        if p.sty == sty {
                            out.push((Place::Field(i, f), p.dom));
                        }
                    }
                }
                Kind::Fb(fb) if !write => {
                    for (k, (t, dom)) in self.fb_outputs(*fb).into_iter().enumerate() {
                        if t == sty {
                            out.push((Place::FbOut(i, k), dom));
                        }
                    }
                }
                _ => {}
            }
        }
        if !write {
            for (k, l) in self.pou.live.iter().enumerate() {
                if Sty::E(l.ty) == sty {
                    out.push((Place::Live(k), Val::Int(l.range)));
                }
            }
        }
        out
    }

    /// The outputs of an FB instance, as (type, domain), in the order of their names.
    pub(super) fn fb_outputs(&self, fb: Fb) -> Vec<(Sty, Val)> {
        match fb {
            Fb::Std(kind, pv) => kind
                .outputs()
                .iter()
                .map(|&(_, t)| {
                    let dom = match t {
                        Ty::Bool => Val::Bool,
                        Ty::Time => Val::Time {
                            clean: true,
                            range: Iv::new(0, TIME_VAR),
                        },
                        _ => Val::Int(pv.join(Iv::point(0))),
                    };
                    (Sty::E(t), dom)
                })
                .collect(),
            Fb::User(u) => self.fbs[u].outputs.iter().map(|p| (p.sty, p.dom)).collect(),
        }
    }

    pub(super) fn fb_output_name(&self, fb: Fb, k: usize) -> String {
        match fb {
            Fb::Std(kind, _) => kind.outputs()[k].0.to_string(),
            Fb::User(u) => self.fbs[u].outputs[k].name.clone(),
        }
    }

    /// The text of a place (index expressions are generated anew each time).
    pub(super) fn place_text(&mut self, p: Place) -> String {
        match p {
            Place::Var(i) => self.pou.vars[i].name.clone(),
            Place::Live(k) => self.pou.live[k].name.clone(),
            Place::Field(i, f) => {
                let Kind::Struct(s) = self.pou.vars[i].kind else {
                    unreachable!()
                };
                format!(
                    "{}.{}",
                    self.pou.vars[i].name, self.structs[s].fields[f].name
                )
            }
            Place::FbOut(i, k) => {
                let Kind::Fb(fb) = self.pou.vars[i].kind else {
                    unreachable!()
                };
                format!("{}.{}", self.pou.vars[i].name, self.fb_output_name(fb, k))
            }
            Place::Elem(i, f) => {
                let Kind::Array(dims, elem) = self.pou.vars[i].kind.clone() else {
                    unreachable!()
                };
                let idx: Vec<String> = dims.iter().map(|&(lo, hi)| self.index(lo, hi)).collect();
                let mut text = format!("{}[{}]", self.pou.vars[i].name, idx.join(", "));
                if let (Some(f), Elem::Struct(s)) = (f, elem) {
                    text = format!("{text}.{}", self.structs[s].fields[f].name);
                }
                text
            }
        }
    }

    pub(super) fn read(&mut self, p: Place, dom: Val) -> Expr {
        Expr::atom(self.place_text(p), dom, true)
    }

    /// An index expression whose value is always within `lo..=hi` (rule 6).
    pub(super) fn index(&mut self, lo: i128, hi: i128) -> String {
        let bounds = Iv::new(lo, hi);
        let counters: Vec<String> = self
            .pou
            .live
            .iter()
            .filter(|l| l.range.within(bounds))
            .map(|l| l.name.clone())
            .collect();
        if !counters.is_empty() && self.rng.pct(70) {
            return self.rng.pick(&counters).clone();
        }
        let ty = if lo < 0 {
            *self.rng.pick(&[Ty::Int, Ty::Dint, Ty::Sint])
        } else {
            *self.rng.pick(&[Ty::Int, Ty::Dint, Ty::Sint, Ty::Uint])
        };
        self.in_index += 1;
        let choice = if self.in_index > 1 {
            0
        } else {
            self.rng.below(4)
        };
        let text = match choice {
            0 => self.rng.int(lo, hi).to_string(),
            1 => {
                let e = self.int(ty, ty.full(), true, 1);
                format!("LIMIT({lo}, {}, {hi})", e.text)
            }
            _ => {
                let n = hi - lo + 1;
                let e = self.int(ty, ty.full(), true, 1);
                let m = format!("{} MOD {n}", e.at(P_MUL));
                let m = if ty.signed() {
                    format!("ABS({m})")
                } else {
                    format!("({m})")
                };
                match lo {
                    0 => m,
                    lo if lo < 0 => format!("{m} - {}", -lo),
                    lo => format!("{lo} + {m}"),
                }
            }
        };
        self.in_index -= 1;
        text
    }

    /// A writable place of any scalar type: (text, type, domain).
    pub(super) fn target(&mut self) -> Option<(String, Sty, Val)> {
        let mut all = Vec::new();
        for (i, v) in self.pou.vars.iter().enumerate() {
            if v.section == Section::Input {
                continue;
            }
            match &v.kind {
                Kind::Scalar(t, dom) => all.push((Place::Var(i), *t, *dom)),
                Kind::Array(_, Elem::Scalar(t, dom)) => all.push((Place::Elem(i, None), *t, *dom)),
                Kind::Array(_, Elem::Struct(s)) => {
                    for (f, p) in self.structs[*s].fields.iter().enumerate() {
                        all.push((Place::Elem(i, Some(f)), p.sty, p.dom));
                    }
                }
                Kind::Struct(s) => {
                    for (f, p) in self.structs[*s].fields.iter().enumerate() {
                        all.push((Place::Field(i, f), p.sty, p.dom));
                    }
                }
                Kind::Fb(_) => {}
            }
        }
        if all.is_empty() {
            return None;
        }
        let (p, sty, dom) = *self.rng.pick(&all);
        Some((self.place_text(p), sty, dom))
    }
}
