//! The PROGRAM of a case and its interface.

use super::*;

// ------------------------------------------------------------------------------------------
// PROGRAM

impl ProgramGen<'_> {
    pub(super) fn generate(mut self) -> Program {
        self.groups = (0..7).map(|_| *self.rng.pick(&[1, 1, 2, 2, 3])).collect();
        self.gen_types();
        for _ in 0..self.rng.weighted(&[(50, 0), (40, 1), (10, 2)]) {
            self.gen_function();
        }
        for _ in 0..self.rng.weighted(&[(70, 0), (30, 1)]) {
            self.gen_fb();
        }
        self.pou = Pou {
            callable: self.funcs.len(),
            ..Pou::default()
        };
        self.interface();
        self.state();
        let mut body = Vec::new();
        let mut calls: Vec<usize> = self.fb_vars().into_iter().filter(|_| true).collect();
        calls.retain(|_| self.rng.pct(85));
        let n = self.rng.range(3, 5);
        let depth = if self.rng.pct(85) { 2 } else { 3 };
        for _ in 0..n {
            if !calls.is_empty() && self.rng.pct(40) {
                let text = self.fb_call_text(calls.remove(0));
                line(&mut body, 1, text);
            }
            self.stmt(&mut body, 1, depth);
        }
        for i in calls {
            let text = self.fb_call_text(i);
            line(&mut body, 1, text);
        }
        for f in 0..self.funcs.len() {
            self.fn_call_stmt(&mut body, f);
        }
        // Every output is assigned in every scan.
        let outputs: Vec<(String, Sty, Val)> = self
            .pou
            .vars
            .iter()
            .filter(|v| v.section == Section::Output)
            .map(|v| match v.kind {
                Kind::Scalar(sty, dom) => (v.name.clone(), sty, dom),
                _ => unreachable!("outputs are scalars"),
            })
            .collect();
        for (name, sty, dom) in outputs {
            self.store(&mut body, 1, &name, sty, dom);
        }
        let mut out = vec![format!("PROGRAM {}", self.prefix)];
        self.var_blocks(&mut out);
        out.extend(body);
        out.push("END_PROGRAM".to_string());
        let interface = |section| -> Vec<(String, Ty)> {
            self.pou
                .vars
                .iter()
                .filter(|v| v.section == section)
                .map(|v| match v.kind {
                    Kind::Scalar(Sty::E(t), _) => (v.name.clone(), t),
                    _ => unreachable!("inputs and outputs are elementary"),
                })
                .collect()
        };
        Program {
            text: format!(
                "(* ---- {} ---- *)\n{}{}\n\n",
                self.prefix,
                self.decls,
                out.join("\n")
            ),
            inputs: interface(Section::Input),
            outputs: interface(Section::Output),
        }
    }

    /// `v := P0_F1(…);` into a variable of the function's type whose domain holds the result
    /// (after LIMIT and the like for numbers), if there is one.
    pub(super) fn fn_call_stmt(&mut self, body: &mut Vec<String>, f: usize) {
        let (ret, fdom) = (self.funcs[f].ret, self.funcs[f].dom);
        let targets: Vec<(String, Val)> = self
            .pou
            .vars
            .iter()
            .filter(|v| v.section != Section::Input)
            .filter_map(|v| match v.kind {
                Kind::Scalar(Sty::E(t), dom) if t == ret => Some((v.name.clone(), dom)),
                _ => None,
            })
            .collect();
        if targets.is_empty() || self.rng.pct(15) {
            return;
        }
        let (lv, dom) = self.rng.pick(&targets).clone();
        let e = self.call_fn(f, 2);
        let e = match dom {
            Val::Int(iv) => self.fit_int(e, ret, iv, false),
            Val::Real(rv) => self.fit_real(e, ret, rv, false),
            Val::Time { clean, range } => self.fit_time(e, range, clean),
            Val::Str { max, .. } if fdom.strlen().1 > max => return,
            _ => e,
        };
        line(body, 1, format!("{lv} := {};", e.text));
    }

    pub(super) fn interface(&mut self) {
        for k in 0..self.rng.range(2, 6) {
            let ty = if k == 0 && self.rng.pct(80) {
                Ty::Bool
            } else {
                pick_type(self.rng)
            };
            let v = self.scalar(
                format!("in{}", k + 1),
                Sty::E(ty),
                Section::Input,
                Role::Input,
            );
            self.pou.vars.push(v);
        }
        for k in 0..self.rng.range(2, 6) {
            let ty = pick_type(self.rng);
            let v = self.scalar(
                format!("out{}", k + 1),
                Sty::E(ty),
                Section::Output,
                Role::Other,
            );
            self.pou.vars.push(v);
        }
    }

    /// The program's VARs: scalars, enumerations, structures, arrays, FB instances.
    pub(super) fn state(&mut self) {
        for _ in 0..self.rng.range(2, 4) {
            let name = self.fresh("st");
            let ty = pick_type(self.rng);
            let v = self.scalar(name, Sty::E(ty), Section::Var, Role::Other);
            self.pou.vars.push(v);
        }
        for e in 0..self.enums.len() {
            for _ in 0..self.rng.range(1, 2) {
                let name = self.fresh("mode");
                let v = self.scalar(name, Sty::Enum(e), Section::Var, Role::Other);
                self.pou.vars.push(v);
            }
        }
        if !self.structs.is_empty() {
            let name = self.fresh("rec");
            let init = if self.rng.pct(30) {
                self.struct_init(0)
            } else {
                None
            };
            self.pou.vars.push(Var {
                name,
                kind: Kind::Struct(0),
                section: Section::Var,
                init,
                binds: Vec::new(),
            });
        }
        for _ in 0..self.rng.weighted(&[(45, 0), (40, 1), (15, 2)]) {
            self.array();
        }
        for _ in 0..self.rng.weighted(&[(25, 0), (35, 1), (25, 2), (15, 3)]) {
            let kind = *self.rng.pick(&STD_FBS);
            let name = self.fresh(kind.stem());
            let pv = if self.rng.pct(80) {
                Iv::new(0, 10)
            } else {
                Iv::new(-3, 20)
            };
            self.pou.vars.push(Var {
                name,
                kind: Kind::Fb(Fb::Std(kind, pv)),
                section: Section::Var,
                init: None,
                binds: Vec::new(),
            });
        }
        for u in 0..self.fbs.len() {
            for _ in 0..self.rng.range(1, 2) {
                let mut binds = Vec::new();
                for p in self.fbs[u].inouts.clone() {
                    let name = self.fresh("io");
                    let init = self.init(p.sty, p.dom);
                    self.pou.vars.push(Var {
                        name: name.clone(),
                        kind: Kind::Scalar(p.sty, p.dom),
                        section: Section::Var,
                        init,
                        binds: Vec::new(),
                    });
                    binds.push(name);
                }
                let name = self.fresh("fb");
                self.pou.vars.push(Var {
                    name,
                    kind: Kind::Fb(Fb::User(u)),
                    section: Section::Var,
                    init: None,
                    binds,
                });
            }
        }
    }

    /// An array of 2-6 elements (2x2 to 3x3 in two dimensions), bounds not always from 0.
    pub(super) fn array(&mut self) {
        let dim = |g: &mut Self, max: i128| {
            let lo = *g.rng.pick(&[0, 1, 1, -2, 5, -1]);
            (lo, lo + g.rng.int(1, max - 1))
        };
        let dims = if self.rng.pct(25) {
            vec![dim(self, 3), dim(self, 3)]
        } else {
            vec![dim(self, 6)]
        };
        let elem = if !self.structs.is_empty() && self.rng.pct(25) {
            Elem::Struct(0)
        } else {
            let sty = if !self.enums.is_empty() && self.rng.pct(10) {
                Sty::Enum(0)
            } else {
                Sty::E(pick_type(self.rng))
            };
            let dom = match sty {
                Sty::E(t) => self.dom(t, Role::Other),
                Sty::Enum(e) => Val::Enum(e),
            };
            Elem::Scalar(sty, dom)
        };
        let size: i128 = dims.iter().map(|(lo, hi)| hi - lo + 1).product();
        let init = match elem {
            Elem::Scalar(sty @ Sty::E(_), dom) if self.rng.pct(35) => {
                if self.rng.pct(30) {
                    self.init_value(sty, dom).map(|v| format!("[{size}({v})]"))
                } else {
                    let vs: Option<Vec<String>> =
                        (0..size).map(|_| self.init_value(sty, dom)).collect();
                    vs.map(|vs| format!("[{}]", vs.join(", ")))
                }
            }
            _ => None,
        };
        let name = self.fresh("arr");
        self.pou.vars.push(Var {
            name,
            kind: Kind::Array(dims, elem),
            section: Section::Var,
            init,
            binds: Vec::new(),
        });
    }

    /// `(f1 := …, f3 := …)` for some of the fields of structure `s`.
    pub(super) fn struct_init(&mut self, s: usize) -> Option<String> {
        let fields = self.structs[s].fields.clone();
        let mut parts = Vec::new();
        for f in &fields {
            // An enumeration value in a structure's initialiser crashes MATIEC
            // (enum_declaration_check.cc:145).
            if self.rng.pct(60) && matches!(f.sty, Sty::E(_)) {
                if let Some(v) = self.init_value(f.sty, f.dom) {
                    parts.push(format!("{} := {v}", f.name));
                }
            }
        }
        if parts.is_empty() {
            None
        } else {
            Some(format!("({})", parts.join(", ")))
        }
    }
}
