//! Declarations: data types, function block layouts, variables and their initial values.

use crate::ast::{Init, Pos, Pou, PouKind, Section, TypeDecl, TypeDeclKind, TypeRef, VarDecl};
use crate::error::Diagnostic;
use crate::stdfb::{Access, StdFb};
use crate::types::{
    ArrayTy, Elem, EnumTy, FbId, Field, Size, StructTy, Ty, DEFAULT_STRING, MAX_STRING,
};

use super::{Compiler, FbDef, FbKind, Loc, Scope, VarRef};

/// Deepest nesting of declared types (a structure in an array in a structure …).
pub const MAX_TYPE_DEPTH: usize = 32;

/// A declared type, resolved, with the initial value its declaration gives.
#[derive(Clone, Debug)]
pub struct Named {
    /// The type.
    pub ty: Ty,
    /// `TYPE T : INT := 5; END_TYPE`, `(A, B) := B`.
    pub init: Option<Init>,
}

/// A variable of the compiled PROGRAM, as the outside sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct Var {
    /// Its name as declared.
    pub name: String,
    /// Its section.
    pub section: Section,
    /// Its type.
    pub ty: Ty,
    /// Where it is in the state.
    pub at: Size,
    /// How much of the state it takes, from `at`.
    pub size: Size,
    /// RETAIN.
    pub retain: bool,
    /// CONSTANT.
    pub constant: bool,
    /// `AT %IX0.0`, as written.
    pub address: Option<String>,
}

/// A member of a user function block with what initialises it.
pub(crate) struct Member<'a> {
    pub decl: &'a VarDecl,
    pub section: Section,
    pub constant: bool,
    pub retain: bool,
}

/// The members a POU declares, in order.
pub(crate) fn members(pou: &Pou) -> Vec<(crate::ast::Ident, Member<'_>)> {
    let mut out = Vec::new();
    for block in &pou.vars {
        for decl in &block.decls {
            for name in &decl.names {
                let member = Member {
                    decl,
                    section: block.section,
                    constant: block.constant,
                    retain: block.retain,
                };
                out.push((name.clone(), member));
            }
        }
    }
    out
}

impl<'a> Compiler<'a> {
    /// The type a reference names.
    pub fn resolve_type(&mut self, t: &TypeRef) -> Result<Ty, Diagnostic> {
        match t {
            TypeRef::String { len, pos } => {
                let cap = match len {
                    None => DEFAULT_STRING,
                    Some(e) => {
                        let n = self.const_int(e)?;
                        u16::try_from(n)
                            .ok()
                            .filter(|n| (1..=MAX_STRING).contains(n))
                            .ok_or_else(|| {
                                Diagnostic::new(
                                    *pos,
                                    format!("a STRING holds 1 to {MAX_STRING} characters, not {n}"),
                                )
                            })?
                    }
                };
                Ok(Ty::String(cap))
            }
            TypeRef::Array { dims, elem, pos } => self.array_type(dims, elem, *pos),
            TypeRef::Named(id) => {
                let key = id.key();
                if let Some(e) = Elem::from_name(&key) {
                    return Ok(Ty::Elem(e));
                }
                if key == "STRING" {
                    return Ok(Ty::String(DEFAULT_STRING));
                }
                if let Some(named) = self.named_type(&key, id.pos)? {
                    return Ok(named.ty);
                }
                if let Some(fb) = self.fb_type(&key, id.pos)? {
                    return Ok(Ty::Fb(fb));
                }
                Err(Diagnostic::new(id.pos, unknown_type(&id.text)))
            }
        }
    }

    fn array_type(
        &mut self,
        dims: &[(crate::ast::Expr, crate::ast::Expr)],
        elem: &TypeRef,
        pos: Pos,
    ) -> Result<Ty, Diagnostic> {
        let elem = self.resolve_type(elem)?;
        let mut bounds = Vec::new();
        for (lo, hi) in dims {
            let (l, h) = (self.const_int(lo)?, self.const_int(hi)?);
            if l > h || l < i128::from(i32::MIN) || h > i128::from(i32::MAX) {
                return Err(Diagnostic::new(lo.pos, format!("array bounds {l}..{h}: the lower bound must not pass the upper, and both must fit in a DINT")));
            }
            bounds.push((l as i64, h as i64));
        }
        let elem_size = self.size_of(elem);
        let array = ArrayTy {
            dims: bounds,
            elem,
            elem_size,
        };
        if elem_size
            .times(array.count())
            .is_none_or(|s| s.slots > super::MAX_SLOTS || s.text > super::MAX_TEXT)
        {
            return Err(Diagnostic::new(
                pos,
                "the array is too large for a program's state",
            ));
        }
        self.types.arrays.push(array);
        Ok(Ty::Array(self.types.arrays.len() as u32 - 1))
    }

    /// The declared type named `key`, resolving it on first use.
    fn named_type(&mut self, key: &str, pos: Pos) -> Result<Option<Named>, Diagnostic> {
        if let Some(n) = self.named.get(key) {
            return Ok(Some(n.clone()));
        }
        let Some(decl) = self.lib.types.iter().find(|t| t.name.key() == key) else {
            return Ok(None);
        };
        if self.resolving.iter().any(|k| k == key) {
            return Err(Diagnostic::new(
                pos,
                format!("the type `{}` contains itself", decl.name.text),
            ));
        }
        if self.resolving.len() >= MAX_TYPE_DEPTH {
            return Err(Diagnostic::new(
                pos,
                format!("types nested more than {MAX_TYPE_DEPTH} deep"),
            ));
        }
        self.resolving.push(key.to_string());
        let named = self.declare_type(decl);
        self.resolving.pop();
        let named = named?;
        self.named.insert(key.to_string(), named.clone());
        Ok(Some(named))
    }

    fn declare_type(&mut self, decl: &TypeDecl) -> Result<Named, Diagnostic> {
        match &decl.kind {
            TypeDeclKind::Alias { ty, init, .. } => Ok(Named {
                ty: self.resolve_type(ty)?,
                init: init.clone(),
            }),
            TypeDeclKind::Enum { values, init } => {
                let mut out: Vec<(String, i64)> = Vec::new();
                let mut next = 0i64;
                for (name, value) in values {
                    if let Some(v) = value {
                        next = self.const_int(v)? as i64;
                    }
                    if out.iter().any(|(k, _)| *k == name.key()) {
                        return Err(Diagnostic::new(
                            name.pos,
                            format!("`{}` is declared twice in the enumeration", name.text),
                        ));
                    }
                    out.push((name.key(), next));
                    next += 1;
                }
                self.types.enums.push(EnumTy {
                    name: decl.name.text.clone(),
                    values: out,
                });
                let ty = Ty::Enum(self.types.enums.len() as u32 - 1);
                let init = init.as_ref().map(|v| {
                    Init::Expr(crate::ast::Expr {
                        kind: crate::ast::ExprKind::Name(v.clone()),
                        pos: v.pos,
                    })
                });
                Ok(Named { ty, init })
            }
            TypeDeclKind::Struct(fields) => self.struct_type(decl, fields),
        }
    }

    fn struct_type(&mut self, decl: &TypeDecl, fields: &[VarDecl]) -> Result<Named, Diagnostic> {
        let mut out: Vec<Field> = Vec::new();
        let mut size = Size::default();
        for field in fields {
            let ty = self.resolve_type(&field.ty)?;
            for name in &field.names {
                if out.iter().any(|f| f.key == name.key()) {
                    return Err(Diagnostic::new(
                        name.pos,
                        format!("`{}` is declared twice in the structure", name.text),
                    ));
                }
                out.push(Field {
                    key: name.key(),
                    name: name.text.clone(),
                    ty,
                    at: size,
                });
                size = size
                    .plus(self.size_of(ty))
                    .ok_or_else(|| Diagnostic::new(name.pos, "the structure is too large"))?;
            }
        }
        self.types.structs.push(StructTy {
            name: decl.name.text.clone(),
            fields: out,
            size,
        });
        Ok(Named {
            ty: Ty::Struct(self.types.structs.len() as u32 - 1),
            init: None,
        })
    }

    /// The function block type named `key`, laying it out on first use.
    pub fn fb_type(&mut self, key: &str, pos: Pos) -> Result<Option<FbId>, Diagnostic> {
        if let Some(&id) = self.fb_by_key.get(key) {
            return Ok(Some(id));
        }
        let def = if let Some(std) = StdFb::from_name(key) {
            std_def(std)
        } else if let Some(pou) = self
            .lib
            .pous
            .iter()
            .find(|p| p.name.key() == key && matches!(p.kind, PouKind::FunctionBlock))
        {
            if self.resolving.iter().any(|k| k == key) {
                return Err(Diagnostic::new(
                    pos,
                    format!(
                        "the function block `{}` contains an instance of itself",
                        pou.name.text
                    ),
                ));
            }
            if self.resolving.len() >= MAX_TYPE_DEPTH {
                return Err(Diagnostic::new(
                    pos,
                    format!("function blocks nested more than {MAX_TYPE_DEPTH} deep"),
                ));
            }
            self.resolving.push(key.to_string());
            let def = self.user_def(pou);
            self.resolving.pop();
            def?
        } else {
            return Ok(None);
        };
        self.fbs.push(def);
        let id = self.fbs.len() as FbId - 1;
        self.fb_by_key.insert(key.to_string(), id);
        Ok(Some(id))
    }

    fn user_def(&mut self, pou: &'a Pou) -> Result<FbDef<'a>, Diagnostic> {
        let mut fields = Vec::new();
        let mut size = Size::default();
        for (name, m) in members(pou) {
            // A VAR_EXTERNAL is the global itself, reached when the body is compiled.
            if m.section == Section::External {
                continue;
            }
            let ty = self.resolve_type(&m.decl.ty)?;
            if fields
                .iter()
                .any(|(f, _): &(Field, Section)| f.key == name.key())
            {
                return Err(Diagnostic::new(
                    name.pos,
                    format!("`{}` is declared twice in `{}`", name.text, pou.name.text),
                ));
            }
            fields.push((
                Field {
                    key: name.key(),
                    name: name.text.clone(),
                    ty,
                    at: size,
                },
                m.section,
            ));
            size = size
                .plus(self.size_of(ty))
                .ok_or_else(|| Diagnostic::new(name.pos, "the function block is too large"))?;
        }
        Ok(FbDef {
            name: pou.name.text.clone(),
            kind: FbKind::User(pou),
            fields,
            size,
        })
    }

    /// The state a value of `ty` takes.
    pub fn size_of(&self, ty: Ty) -> Size {
        match ty {
            Ty::Elem(_) | Ty::Enum(_) => Size { slots: 1, text: 0 },
            Ty::String(cap) => Size {
                slots: 0,
                text: u32::from(cap) + 2,
            },
            Ty::Array(id) => {
                let a = &self.types.arrays[id as usize];
                a.elem_size.times(a.count()).unwrap_or_default()
            }
            Ty::Struct(id) => self.types.structs[id as usize].size,
            Ty::Fb(id) => self.fbs[id as usize].size,
        }
    }

    /// Allocates and initialises the PROGRAM's variables, and makes them its body's scope.
    pub fn program_vars(&mut self, main: &'a Pou) -> Result<Vec<Var>, Diagnostic> {
        let mut scope = Scope {
            pou: main.name.key(),
            ..Scope::default()
        };
        let mut vars = Vec::new();
        for (name, m) in members(main) {
            if m.section == Section::External {
                let global = self.external(&name, &m)?;
                let Loc::Static(at) = global.loc else {
                    return Err(Diagnostic::new(
                        name.pos,
                        "a global variable at a computed place",
                    ));
                };
                vars.push(Var {
                    name: name.text.clone(),
                    section: m.section,
                    ty: global.ty,
                    at,
                    size: self.size_of(global.ty),
                    retain: false,
                    constant: global.constant,
                    address: None,
                });
                scope.vars.insert(name.key(), global);
                continue;
            }
            let ty = self.resolve_type(&m.decl.ty)?;
            let size = self.size_of(ty);
            let at = self.alloc(size, name.pos)?;
            self.init_var(ty, at, m.decl.init.as_ref())?;
            if scope.vars.contains_key(&name.key()) {
                return Err(Diagnostic::new(
                    name.pos,
                    format!("`{}` is declared twice in `{}`", name.text, main.name.text),
                ));
            }
            scope.vars.insert(
                name.key(),
                VarRef {
                    ty,
                    loc: Loc::Static(at),
                    constant: m.constant,
                },
            );
            vars.push(Var {
                name: name.text.clone(),
                section: m.section,
                ty,
                at,
                size,
                retain: m.retain,
                constant: m.constant,
                address: m.decl.at.as_ref().map(|a| a.text.clone()),
            });
        }
        self.scopes.push(scope);
        Ok(vars)
    }

    /// Allocates and initialises the `VAR_GLOBAL`s of the file's configurations, which
    /// `VAR_EXTERNAL` declarations reach by name.
    pub fn global_vars(&mut self) -> Result<Vec<Var>, Diagnostic> {
        let mut vars = Vec::new();
        let lib = self.lib;
        for block in lib.configs.iter().flat_map(|c| &c.globals) {
            for decl in &block.decls {
                for name in &decl.names {
                    if self.globals.contains_key(&name.key()) {
                        return Err(Diagnostic::new(
                            name.pos,
                            format!("the global variable `{}` is declared twice", name.text),
                        ));
                    }
                    let ty = self.resolve_type(&decl.ty)?;
                    let size = self.size_of(ty);
                    let at = self.alloc(size, name.pos)?;
                    self.init_var(ty, at, decl.init.as_ref())?;
                    let global = VarRef {
                        ty,
                        loc: Loc::Static(at),
                        constant: block.constant,
                    };
                    self.globals.insert(name.key(), global);
                    vars.push(Var {
                        name: name.text.clone(),
                        section: Section::Global,
                        ty,
                        at,
                        size,
                        retain: block.retain,
                        constant: block.constant,
                        address: decl.at.as_ref().map(|a| a.text.clone()),
                    });
                }
            }
        }
        Ok(vars)
    }

    /// The global variable that `VAR_EXTERNAL name : T` names, of the same type; constant if
    /// either declaration says so.
    pub fn external(&mut self, name: &crate::ast::Ident, m: &Member) -> Result<VarRef, Diagnostic> {
        let Some(global) = self.globals.get(&name.key()).cloned() else {
            return Err(Diagnostic::new(
                name.pos,
                format!("VAR_EXTERNAL `{}` names no VAR_GLOBAL of the file's CONFIGURATION; declare it there", name.text),
            ));
        };
        let ty = self.resolve_type(&m.decl.ty)?;
        if ty != global.ty {
            return Err(Diagnostic::new(
                name.pos,
                format!(
                    "VAR_EXTERNAL `{}` is declared {} but the global is {}; declare both with one type",
                    name.text,
                    self.describe(ty),
                    self.describe(global.ty)
                ),
            ));
        }
        Ok(VarRef {
            constant: global.constant || m.constant,
            ..global
        })
    }

    /// Writes the initial value of a variable of `ty` at `at`: `init` if given, else its type's.
    pub fn init_var(&mut self, ty: Ty, at: Size, init: Option<&Init>) -> Result<(), Diagnostic> {
        match init {
            Some(init) => self.init_value(ty, at, init),
            None => self.init_default(ty, at),
        }
    }

    /// The initial value of a type: zero, an empty string, an enumeration's first value, or
    /// what its declaration says, member by member.
    pub fn init_default(&mut self, ty: Ty, at: Size) -> Result<(), Diagnostic> {
        match ty {
            Ty::Elem(_) | Ty::String(_) => Ok(()),
            Ty::Enum(id) => {
                self.init.slots[at.slots as usize] = self.types.enums[id as usize]
                    .values
                    .first()
                    .map_or(0, |v| v.1) as u64;
                self.init_named_default(ty, at)
            }
            Ty::Array(id) => {
                let a = self.types.arrays[id as usize].clone();
                if !needs_init(&a.elem) {
                    return Ok(());
                }
                for i in 0..a.count() {
                    let el = Size {
                        slots: at.slots + a.elem_size.slots * i as u32,
                        text: at.text + a.elem_size.text * i as u32,
                    };
                    self.init_default(a.elem, el)?;
                }
                Ok(())
            }
            Ty::Struct(id) => {
                let fields = self.types.structs[id as usize].fields.clone();
                for f in fields {
                    self.init_default(f.ty, offset(at, f.at))?;
                }
                self.init_struct_decl(id, at)
            }
            Ty::Fb(id) => self.init_fb(id, at),
        }
    }

    /// The initial values a TYPE declaration gives (an alias or enumeration with `:= v`).
    fn init_named_default(&mut self, ty: Ty, at: Size) -> Result<(), Diagnostic> {
        let init = self
            .named
            .values()
            .find(|n| n.ty == ty)
            .and_then(|n| n.init.clone());
        match init {
            Some(init) => self.init_value(ty, at, &init),
            None => Ok(()),
        }
    }

    /// The members' initial values written in a STRUCT declaration.
    fn init_struct_decl(&mut self, id: u32, at: Size) -> Result<(), Diagnostic> {
        let name = self.types.structs[id as usize].name.to_ascii_uppercase();
        let lib = self.lib;
        let Some(TypeDeclKind::Struct(decls)) = lib
            .types
            .iter()
            .find(|t| t.name.key() == name)
            .map(|t| &t.kind)
        else {
            return Ok(());
        };
        for decl in decls {
            let Some(init) = &decl.init else { continue };
            for n in &decl.names {
                let f = self.types.structs[id as usize]
                    .fields
                    .iter()
                    .find(|f| f.key == n.key())
                    .cloned();
                if let Some(f) = f {
                    self.init_value(f.ty, offset(at, f.at), init)?;
                }
            }
        }
        Ok(())
    }

    fn init_fb(&mut self, id: FbId, at: Size) -> Result<(), Diagnostic> {
        let FbKind::User(pou) = self.fbs[id as usize].kind else {
            return Ok(());
        };
        let fields = self.fbs[id as usize].fields.clone();
        for ((_, m), (f, _)) in members(pou).into_iter().zip(fields) {
            self.init_var(f.ty, offset(at, f.at), m.decl.init.as_ref())?;
        }
        Ok(())
    }
}

/// Whether a type's initial value is anything but zero bytes.
fn needs_init(ty: &Ty) -> bool {
    !matches!(ty, Ty::Elem(_) | Ty::String(_))
}

/// `at` moved by `by`.
pub(crate) fn offset(at: Size, by: Size) -> Size {
    Size {
        slots: at.slots + by.slots,
        text: at.text + by.text,
    }
}

fn unknown_type(name: &str) -> String {
    format!(
        "unknown type `{name}`: not an elementary type, a TYPE of the file, or a function block"
    )
}

/// A standard FB's layout.
fn std_def(std: StdFb) -> FbDef<'static> {
    let fields = std
        .fields()
        .into_iter()
        .enumerate()
        .map(|(i, f)| {
            let section = match f.access {
                Access::Input => Section::Input,
                Access::Output => Section::Output,
                Access::Hidden => Section::Var,
            };
            let field = Field {
                key: f.name.to_string(),
                name: f.name.to_string(),
                ty: Ty::Elem(f.elem),
                at: Size {
                    slots: i as u32,
                    text: 0,
                },
            };
            (field, section)
        })
        .collect::<Vec<_>>();
    let size = Size {
        slots: fields.len() as u32,
        text: 0,
    };
    FbDef {
        name: std.name(),
        kind: FbKind::Std(std),
        fields,
        size,
    }
}
