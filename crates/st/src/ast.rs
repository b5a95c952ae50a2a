//! The syntax tree of a Structured Text file, as the parser reads it: names as written, every
//! node with the byte offset where it starts. Nothing here is checked yet; `check` resolves
//! names and types.
//!
//! The parser bounds how deep any tree is ([`crate::parse::MAX_NESTING`] levels of statements,
//! initial values and types, each expression at most [`crate::parse::MAX_DEPTH`] deep), so the
//! walks over it that recurse (type checking, compiling, `Drop`) recurse a bounded number of
//! times.

/// A byte offset into the source text; [`crate::Source::locate`] turns it into line:column.
pub type Pos = u32;

/// A name as written, with where it is. Names compare case-insensitively (IEC 61131-3 §6.1.2).
#[derive(Clone, Debug)]
pub struct Ident {
    /// The text as written.
    pub text: String,
    /// Where it starts.
    pub pos: Pos,
}

impl Ident {
    /// The name in upper case, the form used for comparisons.
    pub fn key(&self) -> String {
        self.text.to_ascii_uppercase()
    }
}

/// Everything one file declares.
#[derive(Clone, Debug, Default)]
pub struct Library {
    /// `TYPE … END_TYPE` declarations.
    pub types: Vec<TypeDecl>,
    /// FUNCTIONs, FUNCTION_BLOCKs and PROGRAMs.
    pub pous: Vec<Pou>,
    /// `CONFIGURATION`s: only their tasks are read (a program's scan period).
    pub configs: Vec<Config>,
}

/// A declared data type.
#[derive(Clone, Debug)]
pub struct TypeDecl {
    /// Its name.
    pub name: Ident,
    /// What it is.
    pub kind: TypeDeclKind,
}

/// The kinds of data type declaration.
// A file has a handful of type declarations: boxing the alias's fields would save nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum TypeDeclKind {
    /// `STRUCT a : INT; … END_STRUCT`.
    Struct(Vec<VarDecl>),
    /// `(Red, Green := 5, Blue)`, optionally with a base type and a default value.
    Enum {
        /// The values, with an explicit integer where one is given.
        values: Vec<(Ident, Option<Expr>)>,
        /// The initial value, if declared (`:= Green`).
        init: Option<Ident>,
    },
    /// Another name for a type, with an optional initial value (`TYPE Speed : INT := 10; END_TYPE`)
    /// or a subrange (`INT (0..100)`).
    Alias {
        /// The type named.
        ty: TypeRef,
        /// A subrange, if declared.
        range: Option<(Expr, Expr)>,
        /// The initial value, if declared.
        init: Option<Init>,
    },
}

/// A reference to a type in a declaration.
#[derive(Clone, Debug)]
pub enum TypeRef {
    /// An elementary, declared, or function block type by name.
    Named(Ident),
    /// `STRING` or `STRING[n]` / `STRING(n)`.
    String {
        /// The declared capacity, if any.
        len: Option<Box<Expr>>,
        /// Where `STRING` is.
        pos: Pos,
    },
    /// `ARRAY [lo..hi, …] OF T`.
    Array {
        /// The bounds of each dimension.
        dims: Vec<(Expr, Expr)>,
        /// The element type.
        elem: Box<TypeRef>,
        /// Where `ARRAY` is.
        pos: Pos,
    },
}

impl TypeRef {
    /// Where the reference starts.
    pub fn pos(&self) -> Pos {
        match self {
            TypeRef::Named(id) => id.pos,
            TypeRef::String { pos, .. } | TypeRef::Array { pos, .. } => *pos,
        }
    }
}

/// The kinds of POU.
#[derive(Clone, Debug)]
pub enum PouKind {
    /// `PROGRAM`.
    Program,
    /// `FUNCTION_BLOCK`.
    FunctionBlock,
    /// `FUNCTION name : T`.
    Function(TypeRef),
}

/// A program organisation unit.
#[derive(Clone, Debug)]
pub struct Pou {
    /// Program, function block or function.
    pub kind: PouKind,
    /// Its name.
    pub name: Ident,
    /// Its variable blocks, in order.
    pub vars: Vec<VarBlock>,
    /// Its body.
    pub body: Vec<Stmt>,
    /// Where `PROGRAM` (or `FUNCTION…`) is.
    pub pos: Pos,
}

/// The sections of variable declarations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Section {
    /// `VAR`.
    Var,
    /// `VAR_INPUT`.
    Input,
    /// `VAR_OUTPUT`.
    Output,
    /// `VAR_IN_OUT`.
    InOut,
    /// `VAR_TEMP`.
    Temp,
    /// `VAR_EXTERNAL`.
    External,
    /// `VAR_GLOBAL`.
    Global,
}

impl Section {
    /// The keyword, for messages.
    pub fn keyword(self) -> &'static str {
        match self {
            Section::Var => "VAR",
            Section::Input => "VAR_INPUT",
            Section::Output => "VAR_OUTPUT",
            Section::InOut => "VAR_IN_OUT",
            Section::Temp => "VAR_TEMP",
            Section::External => "VAR_EXTERNAL",
            Section::Global => "VAR_GLOBAL",
        }
    }
}

/// One `VAR… END_VAR` block.
#[derive(Clone, Debug)]
pub struct VarBlock {
    /// Which section.
    pub section: Section,
    /// `CONSTANT`.
    pub constant: bool,
    /// `RETAIN` (or `PERSISTENT`).
    pub retain: bool,
    /// Its declarations.
    pub decls: Vec<VarDecl>,
    /// Where the keyword is.
    pub pos: Pos,
}

/// `a, b AT %IX0.0 : T := init;`
#[derive(Clone, Debug)]
pub struct VarDecl {
    /// The names declared.
    pub names: Vec<Ident>,
    /// A located address (`%IX0.0`), as written.
    pub at: Option<Ident>,
    /// The type.
    pub ty: TypeRef,
    /// The initial value.
    pub init: Option<Init>,
}

/// An initial value.
#[derive(Clone, Debug)]
pub enum Init {
    /// A single expression (constant).
    Expr(Expr),
    /// `[1, 2, 3(0)]`: array elements, `n(x)` repeating x n times.
    Array(Vec<(Option<Expr>, Init)>, Pos),
    /// `(a := 1, b := 2)`: structure members, or the inputs of an FB instance.
    Struct(Vec<(Ident, Init)>, Pos),
}

impl Init {
    /// Where the value starts.
    pub fn pos(&self) -> Pos {
        match self {
            Init::Expr(e) => e.pos,
            Init::Array(_, pos) | Init::Struct(_, pos) => *pos,
        }
    }
}

/// A `CONFIGURATION`: the tasks, which program each runs, and the global variables.
#[derive(Clone, Debug)]
pub struct Config {
    /// Its name.
    pub name: Ident,
    /// `TASK name (INTERVAL := T#…, PRIORITY := n)`.
    pub tasks: Vec<Task>,
    /// `PROGRAM inst WITH task : Type`.
    pub programs: Vec<ProgramInstance>,
    /// The `VAR_GLOBAL` blocks of the configuration and of its resources, in order.
    pub globals: Vec<VarBlock>,
}

/// A task of a resource.
#[derive(Clone, Debug)]
pub struct Task {
    /// Its name.
    pub name: Ident,
    /// `INTERVAL`, if given (a literal TIME).
    pub interval: Option<Expr>,
}

/// A program instance of a resource.
#[derive(Clone, Debug)]
pub struct ProgramInstance {
    /// The instance name.
    pub name: Ident,
    /// `WITH task`, if given.
    pub task: Option<Ident>,
    /// The PROGRAM type.
    pub program: Ident,
}

/// A statement.
#[derive(Clone, Debug)]
pub struct Stmt {
    /// What it is.
    pub kind: StmtKind,
    /// Where it starts.
    pub pos: Pos,
}

/// The statements of ST (IEC 61131-3 §7.3.3).
#[derive(Clone, Debug)]
pub enum StmtKind {
    /// `target := value`.
    Assign {
        /// A variable, member or element.
        target: Expr,
        /// The value.
        value: Expr,
    },
    /// A call as a statement: `inst(IN := x, Q => y)` or `F(x)`.
    Call(Call),
    /// `IF c THEN … ELSIF c THEN … ELSE … END_IF`.
    If {
        /// Each condition with its statements.
        arms: Vec<(Expr, Vec<Stmt>)>,
        /// The `ELSE` statements.
        otherwise: Vec<Stmt>,
    },
    /// `CASE sel OF 1, 2..5: … ELSE … END_CASE`.
    Case {
        /// The selector.
        selector: Expr,
        /// Each list of labels with its statements.
        arms: Vec<(Vec<CaseLabel>, Vec<Stmt>)>,
        /// The `ELSE` statements.
        otherwise: Vec<Stmt>,
    },
    /// `FOR v := a TO b BY c DO … END_FOR`.
    For {
        /// The control variable.
        var: Ident,
        /// Its first value.
        from: Expr,
        /// Its last value.
        to: Expr,
        /// The step, 1 if absent.
        by: Option<Expr>,
        /// The statements.
        body: Vec<Stmt>,
    },
    /// `WHILE c DO … END_WHILE`.
    While {
        /// The condition, tested before each iteration.
        cond: Expr,
        /// The statements.
        body: Vec<Stmt>,
    },
    /// `REPEAT … UNTIL c END_REPEAT`.
    Repeat {
        /// The statements.
        body: Vec<Stmt>,
        /// The condition, tested after each iteration.
        until: Expr,
    },
    /// `EXIT`.
    Exit,
    /// `RETURN`.
    Return,
    /// `;` alone.
    Empty,
}

/// A label of a CASE arm.
#[derive(Clone, Debug)]
pub enum CaseLabel {
    /// One value.
    Value(Expr),
    /// `lo..hi`.
    Range(Expr, Expr),
}

/// A call of a function or of a function block instance.
#[derive(Clone, Debug)]
pub struct Call {
    /// The function, or the instance (a variable, possibly a member or element).
    pub callee: Expr,
    /// The arguments.
    pub args: Vec<Arg>,
    /// Where the call starts.
    pub pos: Pos,
}

/// One argument of a call.
#[derive(Clone, Debug)]
pub enum Arg {
    /// Positional: `F(x, y)`.
    Positional(Expr),
    /// Formal input: `IN := x`.
    Input(Ident, Expr),
    /// Formal output: `Q => y`, or `NOT Q => y` when `negated`.
    Output {
        /// The output's name.
        name: Ident,
        /// Where it goes.
        target: Expr,
        /// `NOT Q => y`.
        negated: bool,
    },
}

/// An expression.
#[derive(Clone, Debug)]
pub struct Expr {
    /// What it is.
    pub kind: ExprKind,
    /// Where it starts (for a binary operation, where its operator is).
    pub pos: Pos,
}

/// The expressions of ST (IEC 61131-3 §7.3.2).
#[derive(Clone, Debug)]
pub enum ExprKind {
    /// A literal.
    Lit(Literal),
    /// A variable or enumeration value.
    Name(Ident),
    /// `a.b`: a structure member, an FB instance's input or output, or `Enum.Value`.
    Member(Box<Expr>, Ident),
    /// `a[i, j]`.
    Index(Box<Expr>, Vec<Expr>),
    /// `F(…)`.
    Call(Box<Call>),
    /// `-a`, `NOT a`.
    Unary(UnOp, Box<Expr>),
    /// `a + b`, …
    Binary(BinOp, Box<Expr>, Box<Expr>),
}

/// Unary operators.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnOp {
    /// `-`.
    Neg,
    /// `NOT`.
    Not,
}

/// Binary operators, in IEC 61131-3 Table 71's order of precedence (last binds weakest).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinOp {
    /// `**`.
    Pow,
    /// `*`.
    Mul,
    /// `/`.
    Div,
    /// `MOD`.
    Mod,
    /// `+`.
    Add,
    /// `-`.
    Sub,
    /// A comparison: `<`, `>`, `<=`, `>=`, `=`, `<>`.
    Cmp(Rel),
    /// `AND`, `&`.
    And,
    /// `XOR`.
    Xor,
    /// `OR`.
    Or,
}

impl BinOp {
    /// The operator as written, for messages.
    pub fn symbol(self) -> &'static str {
        match self {
            BinOp::Pow => "**",
            BinOp::Mul => "*",
            BinOp::Div => "/",
            BinOp::Mod => "MOD",
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Cmp(rel) => rel.symbol(),
            BinOp::And => "AND",
            BinOp::Xor => "XOR",
            BinOp::Or => "OR",
        }
    }
}

/// Comparisons.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rel {
    /// `<`.
    Lt,
    /// `>`.
    Gt,
    /// `<=`.
    Le,
    /// `>=`.
    Ge,
    /// `=`.
    Eq,
    /// `<>`.
    Ne,
}

impl Rel {
    /// The comparison as written, for messages.
    pub fn symbol(self) -> &'static str {
        match self {
            Rel::Lt => "<",
            Rel::Gt => ">",
            Rel::Le => "<=",
            Rel::Ge => ">=",
            Rel::Eq => "=",
            Rel::Ne => "<>",
        }
    }

    /// Whether an ordering satisfies the comparison.
    #[inline]
    pub fn holds(self, o: std::cmp::Ordering) -> bool {
        use std::cmp::Ordering::*;
        match self {
            Rel::Lt => o == Less,
            Rel::Gt => o == Greater,
            Rel::Le => o != Greater,
            Rel::Ge => o != Less,
            Rel::Eq => o == Equal,
            Rel::Ne => o != Equal,
        }
    }

    /// Whether two values whose order is `o` satisfy the comparison; `None`, values that do not
    /// compare (a NaN), satisfy only `<>`, as in C.
    #[inline]
    pub fn holds_partial(self, o: Option<std::cmp::Ordering>) -> bool {
        o.map_or(self == Rel::Ne, |o| self.holds(o))
    }
}

/// A literal, with the type prefix it was written with (`INT#5`), if any.
#[derive(Clone, Debug)]
pub enum Literal {
    /// An integer: `5`, `16#FF`, `INT#-5`. The sign is part of the literal when a type prefix
    /// is written (`INT#-5`); otherwise `-5` is a negation of `5`.
    Int {
        /// The value.
        value: i128,
        /// The type prefix.
        ty: Option<Ident>,
    },
    /// A real: `1.5`, `1.0E-3`, `REAL#2.5`.
    Real {
        /// The value, as f64; a REAL literal is rounded to f32 when typed.
        value: f64,
        /// The type prefix.
        ty: Option<Ident>,
    },
    /// `TRUE`, `FALSE`, `BOOL#1`.
    Bool(bool),
    /// `T#1s500ms`, in nanoseconds.
    Time(i64),
    /// `'text'`, after `$` escapes.
    String(Vec<u8>),
    /// `Color#Red`.
    Enum {
        /// The enumeration type.
        ty: Ident,
        /// The value.
        value: Ident,
    },
}
