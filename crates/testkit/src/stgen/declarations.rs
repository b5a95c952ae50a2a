//! Declarations and POUs: types, functions, function blocks.

use super::*;

// ------------------------------------------------------------------------------------------
// Declarations and POUs

/// Who a domain is for: inputs get the whole type (and "nice" REALs), the rest may be narrower.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Role {
    Input,
    Other,
}

/// The types of inputs, outputs and variables, BOOL (the trigger of timers) more often.
pub(super) fn pick_type(rng: &mut Rng) -> Ty {
    if rng.pct(15) {
        Ty::Bool
    } else {
        *rng.pick(&ALL_TYPES)
    }
}

impl<'r> ProgramGen<'r> {
    pub(super) fn new(rng: &'r mut Rng, index: usize) -> ProgramGen<'r> {
        ProgramGen {
            rng,
            prefix: format!("P{index}"),
            enums: Vec::new(),
            structs: Vec::new(),
            funcs: Vec::new(),
            fbs: Vec::new(),
            decls: String::new(),
            pou: Pou::default(),
            names: 0,
            in_index: 0,
            groups: Vec::new(),
        }
    }

    pub(super) fn dom(&mut self, ty: Ty, role: Role) -> Val {
        match ty {
            Ty::Bool => Val::Bool,
            Ty::Real | Ty::Lreal => {
                let b = match (ty, role) {
                    (Ty::Real, Role::Input) => REAL_INPUT,
                    (Ty::Real, _) => REAL_VAR,
                    (_, Role::Input) => LREAL_INPUT,
                    _ => LREAL_VAR,
                };
                Val::Real(Rv::new(-b, b))
            }
            Ty::Time => Val::Time {
                clean: role == Role::Input || self.rng.pct(70),
                range: if role == Role::Input {
                    Iv::new(0, TIME_INPUT)
                } else {
                    Iv::new(-TIME_VAR, TIME_VAR)
                },
            },
            Ty::String => Val::Str {
                min: 0,
                max: if role == Role::Input {
                    STR_INPUT
                } else {
                    *self.rng.pick(&[20, 40, 80, 80])
                },
            },
            t if t.is_int() => {
                if role == Role::Input || self.rng.pct(55) {
                    Val::Int(t.full())
                } else {
                    let k = *self.rng.pick(&[10, 100, 1000]);
                    let lo = if t.signed() { -k } else { 0 };
                    Val::Int(Iv::new(lo, k).meet(t.full()))
                }
            }
            _ => Val::Bits { dirty: false },
        }
    }

    /// An initial value in `dom`, near the type's limits now and then (state that will wrap).
    pub(super) fn init(&mut self, sty: Sty, dom: Val) -> Option<String> {
        if self.rng.pct(55) {
            None
        } else {
            self.init_value(sty, dom)
        }
    }

    /// A literal of `sty` in `dom` for a declaration's initial value.
    pub(super) fn init_value(&mut self, sty: Sty, dom: Val) -> Option<String> {
        let text = match (sty, dom) {
            (Sty::Enum(e), _) => self.rng.pick(&self.enums[e].values).clone(),
            (_, Val::Bool) => if self.rng.pct(50) { "TRUE" } else { "FALSE" }.to_string(),
            (Sty::E(t), Val::Int(iv)) => {
                let v = if iv == t.full() && self.rng.pct(50) {
                    let k = self.rng.int(0, 5);
                    if t.signed() && self.rng.pct(40) {
                        iv.lo + k
                    } else {
                        iv.hi - k
                    }
                } else {
                    self.pick_int(t, iv)
                };
                let v = if t == Ty::Lint && v == iv.lo {
                    v + 1
                } else {
                    v
                };
                self.int_lit(t, v, false).text
            }
            (Sty::E(t), Val::Bits { .. }) => self.bits_lit(t, false).text,
            (Sty::E(t), Val::Real(rv)) => self.real_lit(t, rv, false).text,
            (_, Val::Time { range, .. }) => self.time_lit(false, range.hi).text,
            (_, Val::Str { max, .. }) => self.str_lit(0, max.min(10)).text,
            _ => return None,
        };
        Some(text)
    }

    pub(super) fn scalar(&mut self, name: String, sty: Sty, section: Section, role: Role) -> Var {
        let dom = match sty {
            Sty::E(t) => self.dom(t, role),
            Sty::Enum(e) => Val::Enum(e),
        };
        let init = if section == Section::Var {
            self.init(sty, dom)
        } else {
            None
        };
        Var {
            name,
            kind: Kind::Scalar(sty, dom),
            section,
            init,
            binds: Vec::new(),
        }
    }

    pub(super) fn type_name(&self, sty: Sty) -> String {
        match sty {
            Sty::E(t) => t.name().to_string(),
            Sty::Enum(e) => self.enums[e].name.clone(),
        }
    }

    pub(super) fn decl_text(&self, v: &Var) -> String {
        let ty = match &v.kind {
            Kind::Scalar(sty, _) => self.type_name(*sty),
            Kind::Struct(s) => self.structs[*s].name.clone(),
            Kind::Fb(Fb::Std(kind, _)) => kind.name().to_string(),
            Kind::Fb(Fb::User(u)) => self.fbs[*u].name.clone(),
            Kind::Array(dims, elem) => {
                let dims: Vec<String> = dims.iter().map(|(lo, hi)| format!("{lo}..{hi}")).collect();
                let elem = match elem {
                    Elem::Scalar(sty, _) => self.type_name(*sty),
                    Elem::Struct(s) => self.structs[*s].name.clone(),
                };
                format!("ARRAY[{}] OF {elem}", dims.join(", "))
            }
        };
        match &v.init {
            Some(init) => format!("{} : {ty} := {init};", v.name),
            None => format!("{} : {ty};", v.name),
        }
    }

    /// The declarations of the current POU's variables of `sections`, as `VAR…END_VAR` blocks.
    pub(super) fn var_blocks(&self, out: &mut Vec<String>) {
        for (section, kw) in [
            (Section::Input, "VAR_INPUT"),
            (Section::Output, "VAR_OUTPUT"),
            (Section::InOut, "VAR_IN_OUT"),
            (Section::Var, "VAR"),
        ] {
            let mut decls: Vec<String> = self
                .pou
                .vars
                .iter()
                .filter(|v| v.section == section)
                .map(|v| self.decl_text(v))
                .collect();
            if section == Section::Var {
                decls.extend(
                    self.pou
                        .counters
                        .iter()
                        .map(|(n, t)| format!("{n} : {};", t.name())),
                );
            }
            if !decls.is_empty() {
                line(out, 1, kw);
                // One declaration a line, or a few, as people write them.
                let mut rest = &decls[..];
                while !rest.is_empty() {
                    let n = self.groups[out.len() % self.groups.len()].min(rest.len());
                    line(out, 2, rest[..n].join(" "));
                    rest = &rest[n..];
                }
                line(out, 1, "END_VAR");
            }
        }
    }

    // --------------------------------------------------------------------------------------
    // TYPE … END_TYPE

    pub(super) fn gen_types(&mut self) {
        let mut lines = Vec::new();
        let n_enums = self.rng.weighted(&[(55, 0), (35, 1), (10, 2)]);
        for k in 0..n_enums {
            let name = format!("{}_E{}", self.prefix, k + 1);
            let n = self.rng.range(2, 5);
            let values: Vec<String> = ["A", "B", "C", "D", "E"][..n]
                .iter()
                .map(|v| format!("{name}_{v}"))
                .collect();
            lines.push(format!("  {name} : ({});", values.join(", ")));
            self.enums.push(EnumDecl { name, values });
        }
        if self.rng.pct(35) {
            let name = format!("{}_S1", self.prefix);
            lines.push(format!("  {name} : STRUCT"));
            let mut fields = Vec::new();
            for f in 0..self.rng.range(2, 4) {
                let sty = if !self.enums.is_empty() && self.rng.pct(25) {
                    Sty::Enum(self.rng.range(0, self.enums.len() - 1))
                } else {
                    Sty::E(pick_type(self.rng))
                };
                let dom = match sty {
                    Sty::E(t) => self.dom(t, Role::Other),
                    Sty::Enum(e) => Val::Enum(e),
                };
                let fname = format!("f{}", f + 1);
                lines.push(format!("    {fname} : {};", self.type_name(sty)));
                fields.push(Param {
                    name: fname,
                    sty,
                    dom,
                });
            }
            lines.push("  END_STRUCT;".to_string());
            self.structs.push(StructDecl { name, fields });
        }
        if !lines.is_empty() {
            self.decls.push_str("TYPE\n");
            for l in lines {
                self.decls.push_str(&l);
                self.decls.push('\n');
            }
            self.decls.push_str("END_TYPE\n\n");
        }
    }

    pub(super) fn params(&mut self, stem: &str, n: usize, role: Role) -> Vec<Param> {
        (0..n)
            .map(|k| {
                let ty = pick_type(self.rng);
                Param {
                    name: format!("{stem}{}", k + 1),
                    sty: Sty::E(ty),
                    dom: self.dom(ty, role),
                }
            })
            .collect()
    }

    pub(super) fn param_var(p: &Param, section: Section) -> Var {
        Var {
            name: p.name.clone(),
            kind: Kind::Scalar(p.sty, p.dom),
            section,
            init: None,
            binds: Vec::new(),
        }
    }

    /// Local state of a POU: scalars, and in FBs sometimes a standard FB instance.
    pub(super) fn locals(&mut self, n: usize, fb_allowed: bool) {
        for _ in 0..n {
            let name = self.fresh("v");
            let ty = pick_type(self.rng);
            let v = self.scalar(name, Sty::E(ty), Section::Var, Role::Other);
            self.pou.vars.push(v);
        }
        if fb_allowed && self.rng.pct(30) {
            let kind = *self.rng.pick(&STD_FBS);
            let name = self.fresh(kind.stem());
            self.pou.vars.push(Var {
                name,
                kind: Kind::Fb(Fb::Std(kind, Iv::new(0, 10))),
                section: Section::Var,
                init: None,
                binds: Vec::new(),
            });
        }
    }

    // --------------------------------------------------------------------------------------
    // FUNCTION

    pub(super) fn gen_function(&mut self) {
        let name = format!("{}_F{}", self.prefix, self.funcs.len() + 1);
        let ret = pick_type(self.rng);
        let dom = self.dom(ret, Role::Other);
        let n = self.rng.range(1, 3);
        let params = self.params("a", n, Role::Other);
        self.pou = Pou {
            callable: self.funcs.len(),
            ..Pou::default()
        };
        self.pou
            .vars
            .extend(params.iter().map(|p| Self::param_var(p, Section::Input)));
        let n = self.rng.range(0, 2);
        self.locals(n, false);
        // The result, written as the function's name; declared by the FUNCTION line.
        self.pou.vars.push(Var {
            name: name.clone(),
            kind: Kind::Scalar(Sty::E(ret), dom),
            section: Section::Result,
            init: None,
            binds: Vec::new(),
        });
        let mut body = Vec::new();
        let first = self.rhs(Sty::E(ret), dom, &name);
        line(&mut body, 1, format!("{name} := {};", first.text));
        if self.rng.pct(50) {
            let c = self.boolean(2);
            line(&mut body, 1, format!("IF {} THEN", c.text));
            let e = self.rhs(Sty::E(ret), dom, &name);
            line(&mut body, 2, format!("{name} := {};", e.text));
            line(&mut body, 2, "RETURN;");
            line(&mut body, 1, "END_IF;");
        }
        let n = self.rng.range(1, 2);
        self.block(&mut body, 1, n, 1);
        if self.rng.pct(60) {
            let e = self.rhs(Sty::E(ret), dom, &name);
            line(&mut body, 1, format!("{name} := {};", e.text));
        }
        let mut out = vec![format!("FUNCTION {name} : {}", ret.name())];
        self.var_blocks(&mut out);
        out.extend(body);
        out.push("END_FUNCTION".to_string());
        self.push_decl(&out);
        self.funcs.push(FnDecl {
            name,
            ret,
            dom,
            params,
        });
    }

    pub(super) fn push_decl(&mut self, lines: &[String]) {
        for l in lines {
            self.decls.push_str(l);
            self.decls.push('\n');
        }
        self.decls.push('\n');
    }

    // --------------------------------------------------------------------------------------
    // FUNCTION_BLOCK

    pub(super) fn gen_fb(&mut self) {
        let name = format!("{}_B{}", self.prefix, self.fbs.len() + 1);
        let n = self.rng.range(1, 3);
        let inputs = self.params("x", n, Role::Other);
        let n = self.rng.range(1, 2);
        let outputs = self.params("y", n, Role::Other);
        let n = self.rng.weighted(&[(1, 0), (1, 1)]);
        // VAR_IN_OUT: a domain the caller's variable shares exactly (a whole type, or 80 chars).
        let inouts: Vec<Param> = (0..n)
            .map(|k| {
                let ty = pick_type(self.rng);
                let dom = match ty {
                    t if t.is_int() => Val::Int(t.full()),
                    Ty::String => Val::Str {
                        min: 0,
                        max: STR_CAP,
                    },
                    Ty::Time => Val::Time {
                        clean: false,
                        range: Iv::new(-TIME_VAR, TIME_VAR),
                    },
                    t => self.dom(t, Role::Other),
                };
                Param {
                    name: format!("z{}", k + 1),
                    sty: Sty::E(ty),
                    dom,
                }
            })
            .collect();
        self.pou = Pou {
            callable: self.funcs.len(),
            ..Pou::default()
        };
        self.pou
            .vars
            .extend(inputs.iter().map(|p| Self::param_var(p, Section::Input)));
        self.pou
            .vars
            .extend(outputs.iter().map(|p| Self::param_var(p, Section::Output)));
        self.pou
            .vars
            .extend(inouts.iter().map(|p| Self::param_var(p, Section::InOut)));
        let n = self.rng.range(1, 2);
        self.locals(n, true);
        let mut body = Vec::new();
        let n = self.rng.range(1, 3);
        self.block(&mut body, 1, n, 1);
        for p in &outputs {
            self.store(&mut body, 1, &p.name, p.sty, p.dom);
        }
        let mut out = vec![format!("FUNCTION_BLOCK {name}")];
        self.var_blocks(&mut out);
        out.extend(body);
        out.push("END_FUNCTION_BLOCK".to_string());
        self.push_decl(&out);
        self.fbs.push(FbDecl {
            name,
            inputs,
            outputs,
            inouts,
        });
    }
}
