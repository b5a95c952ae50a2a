//! From a parsed file to a [`Unit`]: names resolved, types checked, and the PROGRAM's body
//! compiled to register-machine code (`crate::code`), with every call of a function or function
//! block expanded where it is made.
//!
//! Expanding calls keeps the machine simple and fast (absolute operands, no frames, no call
//! stack), and is possible because IEC 61131-3 forbids recursion (§6.1.4: "recursive calls of
//! … POUs are not allowed"), which the compiler checks. Its cost is code size, which is bounded
//! ([`MAX_OPS`]); a call chain deeper than [`MAX_CALL_DEPTH`] is refused, which also bounds the
//! compiler's own recursion.
//!
//! Typing is strict, as MATIEC's is and as the 3rd edition's: the two operands of an operator
//! have the same type, and a value is converted with an explicit `*_TO_*`. A literal without a
//! type prefix takes the type its context needs (`x + 1` with `x : INT` is INT).

mod call;
mod decl;
mod entry;
mod expr;
mod konst;
mod operator;
mod stdfn;
mod stdstr;
mod stmt;

use std::collections::HashMap;

use crate::ast::{Expr, Library, Pos, Pou, PouKind, Section};
use crate::code::{Code, Op, Piece, Slot, TextAt};
use crate::error::Diagnostic;
use crate::stdfb::StdFb;
use crate::types::{Elem, FbId, Field, Size, Ty, Types};
use crate::vm::State;
use expr::Val;

pub use decl::Var;
use entry::ParsedEntry;
pub use entry::{assigned_name, EntryText};

/// Most instructions in one compiled program, after expanding calls: its body and its entries
/// together.
pub const MAX_OPS: usize = 1 << 22;
/// Deepest chain of calls of user functions and function blocks.
pub const MAX_CALL_DEPTH: usize = 32;
/// Most slots in one program's state (8 MiB).
pub const MAX_SLOTS: u32 = 1 << 20;
/// Most bytes of text in one program's state.
pub const MAX_TEXT: u32 = 1 << 22;

/// A function block type: standard, or declared in the file.
#[derive(Clone, Debug)]
pub(crate) enum FbKind<'a> {
    /// One of the standard blocks, run natively.
    Std(StdFb),
    /// A FUNCTION_BLOCK of the file, expanded where it is called.
    User(&'a Pou),
}

/// A function block type with its instance layout.
#[derive(Clone, Debug)]
pub(crate) struct FbDef<'a> {
    /// Its name as declared.
    pub name: String,
    /// What runs it.
    pub kind: FbKind<'a>,
    /// Its members at their offsets, with their sections.
    pub fields: Vec<(Field, Section)>,
    /// The size of an instance.
    pub size: Size,
}

/// Where a value is: at a fixed place, or at a place computed at run time (an array element
/// indexed by a variable), whose slot and text offsets are held in two slots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Loc {
    /// At `at`.
    Static(Size),
    /// At `slots[slot_addr] + off.slots` and `slots[text_addr] + off.text`.
    Dynamic {
        /// The slot that holds the slot offset.
        slot_addr: Slot,
        /// The slot that holds the text offset.
        text_addr: Slot,
        /// Added to both.
        off: Size,
    },
}

impl Loc {
    /// The place `off` further on.
    pub fn offset(self, by: Size) -> Loc {
        match self {
            Loc::Static(at) => Loc::Static(Size {
                slots: at.slots + by.slots,
                text: at.text + by.text,
            }),
            Loc::Dynamic {
                slot_addr,
                text_addr,
                off,
            } => Loc::Dynamic {
                slot_addr,
                text_addr,
                off: Size {
                    slots: off.slots + by.slots,
                    text: off.text + by.text,
                },
            },
        }
    }
}

/// A variable as a body sees it.
#[derive(Clone, Debug)]
pub(crate) struct VarRef {
    /// Its type.
    pub ty: Ty,
    /// Where it is.
    pub loc: Loc,
    /// `CONSTANT`: not assignable.
    pub constant: bool,
}

/// The names a body can see: its POU's variables.
#[derive(Clone, Debug, Default)]
pub(crate) struct Scope {
    /// By upper-case name.
    pub vars: HashMap<String, VarRef>,
    /// The POU, upper case, for messages and recursion checks.
    pub pou: String,
}

/// A loop being compiled: the jumps its `EXIT`s make, to point past its end.
#[derive(Debug, Default)]
pub(crate) struct LoopCtx {
    pub exits: Vec<usize>,
}

/// The compiler's state while it works on one file.
pub(crate) struct Compiler<'a> {
    /// The file.
    pub lib: &'a Library,
    /// The types declared so far.
    pub types: Types,
    /// Declared types by upper-case name, resolved.
    pub named: HashMap<String, decl::Named>,
    /// Types being resolved, to refuse a type that contains itself.
    pub resolving: Vec<String>,
    /// FUNCTIONs by upper-case name.
    pub functions: HashMap<String, &'a Pou>,
    /// Function block types, by [`FbId`].
    pub fbs: Vec<FbDef<'a>>,
    /// FB ids by upper-case name.
    pub fb_by_key: HashMap<String, FbId>,
    /// The code so far.
    pub code: Code,
    /// The state's initial values so far; its length is where the next allocation goes.
    pub init: State,
    /// The innermost scope is the body being compiled.
    pub scopes: Vec<Scope>,
    /// The enclosing loops of the statement being compiled (of the innermost body).
    pub loops: Vec<LoopCtx>,
    /// For each body being compiled, the jumps of its `RETURN`s.
    pub returns: Vec<Vec<usize>>,
    /// Slots holding constants, by their bits.
    pub consts: HashMap<u64, Slot>,
    /// Instructions already compiled into other code of the unit (the body, earlier entries):
    /// [`MAX_OPS`] bounds them all together.
    pub emitted: usize,
    /// Temporaries: slots that hold one operation's result for one reader, in the order they
    /// were made, which is their order (slots are allocated upwards).
    pub temps: Vec<Slot>,
    /// The configuration's `VAR_GLOBAL`s, by upper-case name, for `VAR_EXTERNAL`.
    pub globals: HashMap<String, VarRef>,
}

/// A compiled PROGRAM: its code, its state's layout and initial values, and its variables.
#[derive(Clone, Debug)]
pub struct Unit {
    /// The PROGRAM's name.
    pub name: String,
    /// The code of one scan.
    pub code: Code,
    /// What running the straight-line code once costs, in units of work.
    pub cost: u64,
    /// The state before the first scan.
    pub init: State,
    /// The declared types.
    pub types: Types,
    /// The PROGRAM's own variables, in declaration order, then the configuration's global
    /// variables (section [`Section::Global`]).
    pub vars: Vec<Var>,
    /// Each variable's index in `vars` by its name in upper case (the first of a name).
    var_index: HashMap<String, usize>,
    /// The interval of the TASK that runs the program, if the file has one (nanoseconds).
    pub interval: Option<i64>,
    /// The names of the function block types, by id.
    pub fb_names: Vec<String>,
    /// The members of the function block types, by id.
    pub fb_fields: Vec<Vec<Field>>,
    /// Code that runs on the same state besides the body: a chart's action bodies and
    /// transition conditions ([`compile_with_entries`]), in the order they were given.
    pub entries: Vec<Entry>,
    /// The body and the entries in machine code (`crate::jit`), once
    /// [`Unit::prepare_machine_code`] has made them; until then, and where this machine has no
    /// code generator, the interpreter runs them. Clones share it.
    #[cfg(feature = "jit")]
    machine: std::sync::Arc<std::sync::OnceLock<Option<crate::jit::Machine>>>,
}

/// An entry, compiled.
#[derive(Clone, Debug)]
pub struct Entry {
    /// Its name, as given.
    pub name: String,
    /// Its code.
    pub code: Code,
    /// What running its straight-line code once costs, in units of work.
    pub cost: u64,
    /// For a condition, the slot that holds its value after a run.
    pub result: Option<Slot>,
}

/// An error in the POU or in one of the entries of [`compile_with_entries`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EntryError {
    /// The entry whose text it is in, by position; `None` for the POU's own source.
    pub entry: Option<usize>,
    /// What is wrong, at an offset of that text.
    pub diagnostic: Diagnostic,
}

impl Unit {
    /// A new state, as before the first scan.
    pub fn new_state(&self) -> State {
        self.init.clone()
    }

    /// Runs one scan at time `now` (nanoseconds), within `work`.
    #[inline]
    pub fn run(
        &self,
        state: &mut State,
        now: i64,
        work: &mut crate::Work,
    ) -> Result<(), crate::vm::Fault> {
        let piece = Piece {
            index: 0,
            code: &self.code,
            cost: self.cost,
        };
        self.run_piece(piece, state, now, work)
    }

    /// Runs `piece`: in machine code once it is there, else on the interpreter.
    #[inline]
    fn run_piece(
        &self,
        piece: Piece<'_>,
        state: &mut State,
        now: i64,
        work: &mut crate::Work,
    ) -> Result<(), crate::vm::Fault> {
        #[cfg(feature = "jit")]
        if let Some(done) = (self.machine.get().and_then(Option::as_ref))
            .and_then(|m| m.run(piece, state, now, work))
        {
            return done;
        }
        crate::vm::run(piece.code, piece.cost, state, now, work)
    }

    /// Translates the body and the entries into machine code, once: later calls, and calls on
    /// clones, return at once. It takes about 7 µs an instruction (docs/st.md, *Machine
    /// code*), so it is called where a program is made ready to run, off the scan thread, never
    /// by [`Unit::run`], which interprets until it is done. Whether the body is now in machine
    /// code.
    pub fn prepare_machine_code(&self) -> bool {
        #[cfg(feature = "jit")]
        {
            let machine = self.machine.get_or_init(|| {
                let pieces: Vec<&Code> = std::iter::once(&self.code)
                    .chain(self.entries.iter().map(|e| &e.code))
                    .collect();
                crate::jit::Machine::compile(&pieces)
            });
            machine.as_ref().is_some_and(|m| m.is_native(0))
        }
        #[cfg(not(feature = "jit"))]
        false
    }

    /// [`Unit::run`] on the interpreter, whether or not the unit is in machine code: the
    /// reference the machine code is tested against, and the bench's second figure.
    pub fn run_interpreted(
        &self,
        state: &mut State,
        now: i64,
        work: &mut crate::Work,
    ) -> Result<(), crate::vm::Fault> {
        crate::vm::run(&self.code, self.cost, state, now, work)
    }

    /// Whether the body runs in machine code (after [`Unit::prepare_machine_code`]).
    pub fn in_machine_code(&self) -> bool {
        #[cfg(feature = "jit")]
        if let Some(Some(m)) = self.machine.get() {
            return m.is_native(0);
        }
        false
    }

    /// Runs entry `k` ([`Unit::entries`]) once at time `now`, within `work`; for a condition,
    /// its value. An entry that does not exist runs nothing and is false.
    pub fn run_entry(
        &self,
        k: usize,
        state: &mut State,
        now: i64,
        work: &mut crate::Work,
    ) -> Result<bool, crate::vm::Fault> {
        let Some(e) = self.entries.get(k) else {
            return Ok(false);
        };
        let piece = Piece {
            index: k + 1,
            code: &e.code,
            cost: e.cost,
        };
        self.run_piece(piece, state, now, work)?;
        Ok(e.result
            .and_then(|r| state.slots.get(r as usize))
            .is_some_and(|&v| v != 0))
    }

    /// The position of the entry named `name` (case-insensitive).
    pub fn entry(&self, name: &str) -> Option<usize> {
        self.entries
            .iter()
            .position(|e| e.name.eq_ignore_ascii_case(name))
    }

    /// The PROGRAM's variable named `name` (case-insensitive).
    pub fn var(&self, name: &str) -> Option<&Var> {
        let i = *self.var_index.get(&name.to_ascii_uppercase())?;
        self.vars.get(i)
    }

    /// The part of `state` that holds `v`: its slots and its bytes of text.
    pub fn image<'s>(&self, state: &'s State, v: &Var) -> (&'s [u64], &'s [u8]) {
        let (s, t) = (v.at.slots as usize, v.at.text as usize);
        (
            state.slots.get(s..s + v.size.slots as usize).unwrap_or(&[]),
            state.text.get(t..t + v.size.text as usize).unwrap_or(&[]),
        )
    }

    /// Writes an image taken by [`Unit::image`] back into `v`'s part of `state`; false, and
    /// nothing written, when it is not the size of `v` or a string of it says it holds more
    /// characters than its capacity (an image from outside, a saved state, is checked before the
    /// scan reads it).
    pub fn restore(&self, state: &mut State, v: &Var, slots: &[u64], text: &[u8]) -> bool {
        if !self.strings_fit(v.ty, text) {
            return false;
        }
        let (s, t) = (v.at.slots as usize, v.at.text as usize);
        let (Some(to_slots), Some(to_text)) = (
            state.slots.get_mut(s..s + v.size.slots as usize),
            state.text.get_mut(t..t + v.size.text as usize),
        ) else {
            return false;
        };
        if to_slots.len() != slots.len() || to_text.len() != text.len() {
            return false;
        }
        to_slots.copy_from_slice(slots);
        to_text.copy_from_slice(text);
        true
    }

    /// Whether every string in `text`, the bytes of a value of type `ty`, holds no more
    /// characters than its capacity. A walk with a stack of its own; an array of strings is
    /// visited element by element.
    pub fn strings_fit(&self, ty: Ty, text: &[u8]) -> bool {
        let mut todo = vec![(ty, 0usize)];
        while let Some((ty, at)) = todo.pop() {
            match ty {
                Ty::String(cap) => match text.get(at..at + 2) {
                    Some(&[lo, hi]) if u16::from_le_bytes([lo, hi]) <= cap => {}
                    _ => return false,
                },
                Ty::Array(id) => {
                    let Some(a) = self.types.arrays.get(id as usize) else {
                        return false;
                    };
                    let step = a.elem_size.text as usize;
                    if step > 0 {
                        todo.extend((0..a.count() as usize).map(|i| (a.elem, at + i * step)));
                    }
                }
                Ty::Struct(id) => {
                    let Some(s) = self.types.structs.get(id as usize) else {
                        return false;
                    };
                    todo.extend(s.fields.iter().map(|f| (f.ty, at + f.at.text as usize)));
                }
                Ty::Fb(id) => {
                    let Some(fields) = self.fb_fields.get(id as usize) else {
                        return false;
                    };
                    todo.extend(fields.iter().map(|f| (f.ty, at + f.at.text as usize)));
                }
                Ty::Elem(_) | Ty::Enum(_) => {}
            }
        }
        true
    }

    /// The layout of `ty`, spelled out: two variables whose layouts are equal hold their values
    /// in the same slots and bytes the same way, so one's state can be copied into the other's
    /// (an online change, docs/st.md). Names, member types and array bounds all count; an
    /// instance of a function block whose members changed has another layout. Its recursion is
    /// bounded by the compiler's limit on nested types.
    pub fn layout(&self, ty: Ty) -> String {
        let members = |name: &str, fields: &[Field]| {
            let inner: Vec<String> = fields
                .iter()
                .map(|f| format!("{}:{}", f.key, self.layout(f.ty)))
                .collect();
            format!("{name}{{{}}}", inner.join(";"))
        };
        match ty {
            Ty::Struct(id) => {
                let s = &self.types.structs[id as usize];
                members(&s.name, &s.fields)
            }
            Ty::Fb(id) => members(&self.fb_names[id as usize], &self.fb_fields[id as usize]),
            Ty::Array(id) => {
                let a = &self.types.arrays[id as usize];
                let dims: Vec<String> = a.dims.iter().map(|(l, h)| format!("{l}..{h}")).collect();
                format!("ARRAY[{}]OF {}", dims.join(","), self.layout(a.elem))
            }
            Ty::Enum(id) => {
                let e = &self.types.enums[id as usize];
                let values: Vec<String> =
                    e.values.iter().map(|(n, v)| format!("{n}={v}")).collect();
                format!("{}({})", e.name, values.join(","))
            }
            Ty::Elem(_) | Ty::String(_) => self.describe(ty),
        }
    }

    /// The name of a type, for messages.
    pub fn describe(&self, ty: Ty) -> String {
        self.types
            .describe(ty, &|id| self.fb_names[id as usize].clone())
    }
}

/// Compiles the PROGRAM (or FUNCTION_BLOCK) named `pou` of `lib`, or the file's only PROGRAM
/// when `pou` is `None`.
pub fn compile(lib: &Library, pou: Option<&str>) -> Result<Unit, Diagnostic> {
    compile_with_entries(lib, pou, &[]).map_err(|e| e.diagnostic)
}

/// [`compile`], and `entries` compiled in the scope of the POU, on its state: each sees the
/// POU's variables (VAR_INPUTs may be assigned, as in the POU's own body) and the file's
/// functions and types.
pub fn compile_with_entries(
    lib: &Library,
    pou: Option<&str>,
    entries: &[(String, EntryText<'_>)],
) -> Result<Unit, EntryError> {
    let in_pou = |diagnostic| EntryError {
        entry: None,
        diagnostic,
    };
    let (mut c, main, vars) = compile_pou(lib, pou).map_err(in_pou)?;
    let body = std::mem::take(&mut c.code);
    c.emitted = body.ops.len();
    let mut compiled = Vec::with_capacity(entries.len());
    for (k, (name, text)) in entries.iter().enumerate() {
        let entry = c.entry(name, *text).map_err(|diagnostic| EntryError {
            entry: Some(k),
            diagnostic,
        })?;
        compiled.push(entry);
    }
    c.code = body;
    let mut unit = c.finish(main, vars).map_err(in_pou)?;
    unit.entries = compiled;
    Ok(unit)
}

/// [`compile_with_entries`] of entries given as text: `(name, text, body)`, each text parsed as
/// statements when `body`, else as a condition. A parse error is an [`EntryError`] of its entry,
/// as a compile error is.
pub fn compile_entry_texts(
    lib: &Library,
    pou: Option<&str>,
    texts: &[(&str, &str, bool)],
) -> Result<Unit, EntryError> {
    let mut parsed = Vec::with_capacity(texts.len());
    for (k, &(_, text, body)) in texts.iter().enumerate() {
        parsed.push(
            ParsedEntry::parse(text, body).map_err(|diagnostic| EntryError {
                entry: Some(k),
                diagnostic,
            })?,
        );
    }
    let entries: Vec<(String, EntryText<'_>)> = (texts.iter().zip(&parsed))
        .map(|(&(name, _, _), p)| (name.to_string(), p.text()))
        .collect();
    compile_with_entries(lib, pou, &entries)
}

/// The compiler after the POU's body, with the POU and its variables.
fn compile_pou<'a>(
    lib: &'a Library,
    pou: Option<&str>,
) -> Result<(Compiler<'a>, &'a Pou, Vec<Var>), Diagnostic> {
    let main = pick(lib, pou)?;
    let mut c = Compiler::new(lib)?;
    let globals = c.global_vars()?;
    let mut vars = c.program_vars(main)?;
    for g in globals {
        if let Some(v) = vars.iter().find(|v| v.name.eq_ignore_ascii_case(&g.name)) {
            if v.section != Section::External {
                return Err(Diagnostic::new(
                    main.name.pos,
                    format!("`{}` of `{}` has the name of a VAR_GLOBAL of the configuration; rename one, or declare it VAR_EXTERNAL to use the global", v.name, main.name.text),
                ));
            }
        }
        vars.push(g);
    }
    vars.retain(|v| v.section != Section::External);
    c.body(&main.body)?;
    Ok((c, main, vars))
}

/// The POU to compile.
fn pick<'a>(lib: &'a Library, pou: Option<&str>) -> Result<&'a Pou, Diagnostic> {
    let runnable = |p: &&Pou| matches!(p.kind, PouKind::Program | PouKind::FunctionBlock);
    match pou {
        Some(name) => lib
            .pous
            .iter()
            .find(|p| p.name.text.eq_ignore_ascii_case(name))
            .filter(runnable)
            .ok_or_else(|| {
                let names: Vec<&str> = lib
                    .pous
                    .iter()
                    .filter(runnable)
                    .map(|p| p.name.text.as_str())
                    .collect();
                Diagnostic::new(
                    0,
                    format!(
                        "no PROGRAM or FUNCTION_BLOCK named `{name}` in the file; it has: {}",
                        names.join(", ")
                    ),
                )
            }),
        None => {
            let programs: Vec<&Pou> = lib
                .pous
                .iter()
                .filter(|p| matches!(p.kind, PouKind::Program))
                .collect();
            match programs.as_slice() {
                [one] => Ok(one),
                [] => Err(Diagnostic::new(
                    0,
                    "the file has no PROGRAM; name the POU to run",
                )),
                many => Err(Diagnostic::new(
                    many[1].pos,
                    format!(
                        "the file has {} PROGRAMs ({}); name the one to run",
                        many.len(),
                        many.iter()
                            .map(|p| p.name.text.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )),
            }
        }
    }
}

impl<'a> Compiler<'a> {
    fn new(lib: &'a Library) -> Result<Self, Diagnostic> {
        let mut c = Compiler {
            lib,
            types: Types::default(),
            named: HashMap::new(),
            resolving: Vec::new(),
            functions: HashMap::new(),
            fbs: Vec::new(),
            fb_by_key: HashMap::new(),
            code: Code::default(),
            init: State {
                slots: Vec::new(),
                text: Vec::new(),
            },
            scopes: vec![Scope::default()],
            loops: Vec::new(),
            returns: Vec::new(),
            consts: HashMap::new(),
            emitted: 0,
            temps: Vec::new(),
            globals: HashMap::new(),
        };
        c.index_pous()?;
        Ok(c)
    }

    /// Records the file's functions, and refuses two POUs of one name.
    fn index_pous(&mut self) -> Result<(), Diagnostic> {
        let mut seen: HashMap<String, Pos> = HashMap::new();
        for pou in &self.lib.pous {
            let key = pou.name.key();
            if seen.insert(key.clone(), pou.pos).is_some() {
                return Err(Diagnostic::new(
                    pou.name.pos,
                    format!("`{}` is declared twice", pou.name.text),
                ));
            }
            if crate::stdfb::StdFb::from_name(&key).is_some() || stdfn::is_standard(&key) {
                return Err(Diagnostic::new(
                    pou.name.pos,
                    format!(
                        "`{}` is the name of a standard function or function block; rename the POU",
                        pou.name.text
                    ),
                ));
            }
            if let PouKind::Function(_) = pou.kind {
                self.functions.insert(key, pou);
            }
        }
        Ok(())
    }

    /// The unit, once the body is compiled.
    fn finish(mut self, main: &Pou, vars: Vec<Var>) -> Result<Unit, Diagnostic> {
        let interval = self.task_interval(main)?;
        self.code.temps = std::mem::take(&mut self.temps);
        let cost = self.code.ops.iter().map(|op| op.cost(&self.code)).sum();
        let mut var_index = HashMap::new();
        for (i, v) in vars.iter().enumerate() {
            var_index.entry(v.name.to_ascii_uppercase()).or_insert(i);
        }
        Ok(Unit {
            name: main.name.text.clone(),
            code: self.code,
            cost,
            init: self.init,
            types: self.types,
            vars,
            var_index,
            interval,
            fb_names: self.fbs.iter().map(|f| f.name.clone()).collect(),
            fb_fields: self
                .fbs
                .iter()
                .map(|f| f.fields.iter().map(|(field, _)| field.clone()).collect())
                .collect(),
            entries: Vec::new(),
            #[cfg(feature = "jit")]
            machine: Default::default(),
        })
    }

    /// One entry compiled into code of its own, in the POU's scope.
    fn entry(&mut self, name: &str, text: EntryText<'_>) -> Result<Entry, Diagnostic> {
        self.code = Code::default();
        let first = self.temps.len();
        let result = match text {
            EntryText::Body(stmts) => {
                self.body(stmts)?;
                None
            }
            EntryText::Condition(e) => match self.expr(e, Some(Ty::Elem(Elem::Bool)))? {
                Val::Scalar(Ty::Elem(Elem::Bool), slot) => Some(slot),
                v => {
                    return Err(Diagnostic::new(
                        e.pos,
                        format!(
                            "a transition's condition is BOOL, and this is {}; compare it (x > 0)",
                            self.describe(v.ty())
                        ),
                    ))
                }
            },
            EntryText::Assigned(stmts) => Some(self.assigned(name, stmts)?),
        };
        let mut code = std::mem::take(&mut self.code);
        // This code's temporaries are the ones made since it began, but the result, which the
        // caller reads.
        code.temps = (self.temps[first..].iter().copied())
            .filter(|&t| Some(t) != result)
            .collect();
        self.emitted += code.ops.len();
        let cost = code.ops.iter().map(|op| op.cost(&code)).sum();
        Ok(Entry {
            name: name.to_string(),
            code,
            cost,
            result,
        })
    }

    /// A condition as statements that assign its value to `name` ([`EntryText::Assigned`]): a
    /// BOOL slot of its own, FALSE at the start of each run, which the statements see by that
    /// name; its slot. A nested chart's transition `A__T5` (no IEC name) is `T5` in its chart,
    /// and its statements assign `T5`.
    fn assigned(&mut self, name: &str, stmts: &[crate::ast::Stmt]) -> Result<Slot, Diagnostic> {
        let name = assigned_name(name);
        let key = name.to_ascii_uppercase();
        let pos = stmts.first().map_or(0, |s| s.pos);
        if self.scope().vars.contains_key(&key) {
            return Err(Diagnostic::new(
                pos,
                format!("the condition is statements that assign its value to `{name}`, and `{name}` is a variable of the POU; rename one"),
            ));
        }
        let slot = self.alloc(Size { slots: 1, text: 0 }, pos)?.slots;
        self.emit(Op::Const { dst: slot, bits: 0 }, pos)?;
        let last = self.scopes.len() - 1;
        let var = VarRef {
            ty: Ty::Elem(Elem::Bool),
            loc: Loc::Static(Size {
                slots: slot,
                text: 0,
            }),
            constant: false,
        };
        self.scopes[last].vars.insert(key.clone(), var);
        let compiled = self.body(stmts);
        self.scopes[last].vars.remove(&key);
        compiled.map(|_| slot)
    }

    /// The INTERVAL of the task that runs `main` in the file's configuration, if any.
    fn task_interval(&self, main: &Pou) -> Result<Option<i64>, Diagnostic> {
        for config in &self.lib.configs {
            for inst in &config.programs {
                if !inst.program.text.eq_ignore_ascii_case(&main.name.text) {
                    continue;
                }
                let task = inst.task.as_ref().and_then(|t| {
                    config
                        .tasks
                        .iter()
                        .find(|task| task.name.text.eq_ignore_ascii_case(&t.text))
                });
                if let Some(interval) = task.and_then(|t| t.interval.as_ref()) {
                    return self.const_time(interval).map(Some);
                }
            }
        }
        Ok(None)
    }

    /// Appends an instruction compiled from the text at `pos`; its index.
    pub fn emit(&mut self, op: Op, pos: Pos) -> Result<usize, Diagnostic> {
        if self.emitted + self.code.ops.len() >= MAX_OPS {
            return Err(Diagnostic::new(
                pos,
                format!("the program is too large: more than {MAX_OPS} instructions once its calls are expanded; split it, or call fewer function blocks from inside other function blocks"),
            ));
        }
        self.code.ops.push(op);
        self.code.pos.push(pos);
        Ok(self.code.ops.len() - 1)
    }

    /// The index of the next instruction.
    pub fn here(&self) -> u32 {
        self.code.ops.len() as u32
    }

    /// Points the jump at `at` to `to`.
    pub fn patch(&mut self, at: usize, to: u32) {
        match &mut self.code.ops[at] {
            Op::Jump { to: t } | Op::JumpIf { to: t, .. } | Op::JumpUnless { to: t, .. } => *t = to,
            _ => {}
        }
    }

    /// Room for a value of `size`, zeroed; where it starts.
    pub fn alloc(&mut self, size: Size, pos: Pos) -> Result<Size, Diagnostic> {
        let at = Size {
            slots: self.init.slots.len() as u32,
            text: self.init.text.len() as u32,
        };
        let end = at
            .plus(size)
            .filter(|e| e.slots <= MAX_SLOTS && e.text <= MAX_TEXT);
        let Some(end) = end else {
            return Err(Diagnostic::new(
                pos,
                format!("the program's variables are too large: at most {MAX_SLOTS} values and {MAX_TEXT} bytes of strings in all"),
            ));
        };
        self.init.slots.resize(end.slots as usize, 0);
        self.init.text.resize(end.text as usize, 0);
        Ok(at)
    }

    /// A fresh temporary slot.
    pub fn temp(&mut self, pos: Pos) -> Result<Slot, Diagnostic> {
        let slot = self.alloc(Size { slots: 1, text: 0 }, pos)?.slots;
        self.temps.push(slot);
        Ok(slot)
    }

    /// Room for a string temporary of capacity `cap`; where its text starts.
    pub fn string_temp(&mut self, cap: u16, pos: Pos) -> Result<TextAt, Diagnostic> {
        Ok(self.alloc(self.size_of(Ty::String(cap)), pos)?.text)
    }

    /// `e` compiled as an integer (of any integer type, a literal a DINT): its type and slot;
    /// `what` names it in the error (`"an array index"`).
    pub fn integer(&mut self, e: &Expr, what: &str) -> Result<(Elem, Slot), Diagnostic> {
        match self.expr(e, Some(Ty::Elem(Elem::Dint)))? {
            Val::Scalar(Ty::Elem(t), slot) if t.is_int() => Ok((t, slot)),
            v => Err(Diagnostic::new(
                e.pos,
                format!("{what} is an integer, found {}", self.describe(v.ty())),
            )),
        }
    }

    /// The scope of the body being compiled.
    pub fn scope(&self) -> &Scope {
        // The root scope is never popped, so there is always a last one.
        &self.scopes[self.scopes.len() - 1]
    }

    /// The name of a type, for messages.
    pub fn describe(&self, ty: Ty) -> String {
        self.types
            .describe(ty, &|id| self.fbs[id as usize].name.clone())
    }
}
