//! Declarations: data types, variable blocks, POUs and configurations.
//!
//! ```text
//! library   := ( types | pou | config )*
//! types     := "TYPE" ( NAME ":" type_decl ";" )* "END_TYPE"     (last ";" optional)
//! type_decl := "STRUCT" ( decl ";" )* "END_STRUCT"
//!            | "(" values ")" NAME? (":=" NAME)?                  (CODESYS base type, dropped)
//!            | NAME "(" values ")" (":=" NAME)?                   (IEC base type, dropped)
//!            | NAME "(" expr ".." expr ")" (":=" init)?           (subrange)
//!            | type (":=" init)?                                  (alias)
//! values    := NAME (":=" expr)? ("," NAME (":=" expr)?)*
//! type      := NAME | "STRING" ( "[" expr "]" | "(" expr ")" )?
//!            | "ARRAY" "[" expr ".." expr ("," expr ".." expr)* "]" "OF" type
//! pou       := ("PROGRAM" NAME | "FUNCTION_BLOCK" NAME | "FUNCTION" NAME ":" type)
//!              block* body "END_…"
//! block     := ("VAR" | "VAR_INPUT" | …) ("CONSTANT" | "RETAIN" | "PERSISTENT" | "NON_RETAIN")*
//!              ( decl ";" )* "END_VAR"
//! decl      := NAME ("," NAME)* ("AT" ADDRESS)? ":" type (":=" init)?
//! init      := "[" elem ("," elem)* "]" | "(" NAME ":=" init ("," NAME ":=" init)* ")" | expr
//! elem      := INT "(" init ")" | init
//! config    := "CONFIGURATION" NAME items
//!              ("RESOURCE" NAME "ON" NAME items "END_RESOURCE" ";"?)* "END_CONFIGURATION"
//! items     := ( "VAR_GLOBAL" … "END_VAR" | task | instance )*
//! task      := "TASK" NAME "(" NAME ":=" expr ("," NAME ":=" expr)* ")" ";"
//! instance  := "PROGRAM" NAME ("WITH" NAME)? ":" NAME ";"
//! ```

use super::{lit, Parser, DATES};
use crate::ast::{
    Config, Expr, ExprKind, Ident, Init, Library, Literal, Pou, PouKind, ProgramInstance, Section,
    Task, TypeDecl, TypeDeclKind, TypeRef, VarBlock, VarDecl,
};
use crate::error::Diagnostic;
use crate::lex::{Kw, Tok};

/// The date and time-of-day types, refused where a type is expected. They are not keywords, so
/// that `dt` can name a variable, as it often does.
const DATE_TYPES: [&str; 10] = [
    "DATE",
    "LDATE",
    "TIME_OF_DAY",
    "TOD",
    "LTIME_OF_DAY",
    "LTOD",
    "DATE_AND_TIME",
    "DT",
    "LDATE_AND_TIME",
    "LDT",
];

impl Parser<'_> {
    pub(super) fn library(&mut self) -> Result<Library, Diagnostic> {
        let mut lib = Library::default();
        loop {
            match self.peek() {
                Tok::End => return Ok(lib),
                Tok::Kw(Kw::Type) => self.types(&mut lib.types)?,
                Tok::Kw(Kw::Program | Kw::FunctionBlock | Kw::Function) => {
                    lib.pous.push(self.pou()?);
                }
                Tok::Kw(Kw::Configuration) => lib.configs.push(self.configuration()?),
                Tok::Kw(Kw::VarGlobal) => {
                    return Err(Diagnostic::new(
                        self.pos(),
                        "VAR_GLOBAL outside a CONFIGURATION is not supported: declare global variables in CONFIGURATION … VAR_GLOBAL … END_VAR … END_CONFIGURATION",
                    ))
                }
                _ => {
                    return Err(
                        self.unexpected("TYPE, FUNCTION, FUNCTION_BLOCK, PROGRAM or CONFIGURATION")
                    )
                }
            }
        }
    }

    fn types(&mut self, out: &mut Vec<TypeDecl>) -> Result<(), Diagnostic> {
        self.bump();
        while !self.eat_kw(Kw::EndType) {
            out.push(self.type_decl()?);
            if !self.eat(Tok::Semi) && !self.at_kw(Kw::EndType) {
                return Err(self.unexpected("';' after the type declaration"));
            }
        }
        Ok(())
    }

    fn type_decl(&mut self) -> Result<TypeDecl, Diagnostic> {
        let name = self.name("the name of a type, or END_TYPE")?;
        self.expect(Tok::Colon, "':' after the type's name")?;
        let kind = match self.peek() {
            Tok::Kw(Kw::Struct) => {
                self.bump();
                let mut members = Vec::new();
                while !self.eat_kw(Kw::EndStruct) {
                    let decl = self.var_decl()?;
                    if let Some(at) = &decl.at {
                        return Err(Diagnostic::new(
                            at.pos,
                            "a member of a STRUCT cannot be located (AT): locate the variable of that type instead",
                        ));
                    }
                    members.push(decl);
                    self.expect(Tok::Semi, "';' after the member")?;
                }
                TypeDeclKind::Struct(members)
            }
            Tok::LParen => {
                let values = self.enum_values()?;
                if self.at(Tok::Ident) {
                    // CODESYS's base type, `(A, B) INT`: the tree has no place for it.
                    self.bump();
                }
                self.enum_rest(values)?
            }
            Tok::Ident if self.peek_at(1) == Tok::LParen => {
                let ty = self.type_ref()?;
                let values_follow = self.peek_at(1) == Tok::Ident
                    && matches!(self.peek_at(2), Tok::Assign | Tok::Comma | Tok::RParen);
                if values_follow {
                    // IEC's named values over a base type, `INT (A := 1, B := 2)`: the tree
                    // has no place for the base type.
                    let values = self.enum_values()?;
                    self.enum_rest(values)?
                } else {
                    self.subrange(ty)?
                }
            }
            _ => {
                let ty = self.type_ref()?;
                let init = self.init_opt()?;
                TypeDeclKind::Alias {
                    ty,
                    range: None,
                    init,
                }
            }
        };
        Ok(TypeDecl { name, kind })
    }

    /// `(Red, Green := 5, Blue)`.
    fn enum_values(&mut self) -> Result<Vec<(Ident, Option<Expr>)>, Diagnostic> {
        self.bump();
        let mut values = Vec::new();
        loop {
            let name = self.name("an enumeration value")?;
            let value = if self.eat(Tok::Assign) {
                Some(self.expr()?.0)
            } else {
                None
            };
            values.push((name, value));
            if !self.eat(Tok::Comma) {
                break;
            }
        }
        self.expect(Tok::RParen, "',' or ')' in the enumeration")?;
        Ok(values)
    }

    /// An enumeration's initial value, after its values.
    fn enum_rest(
        &mut self,
        values: Vec<(Ident, Option<Expr>)>,
    ) -> Result<TypeDeclKind, Diagnostic> {
        let init = if self.eat(Tok::Assign) {
            Some(self.name("the initial value, one of the enumeration's values")?)
        } else {
            None
        };
        Ok(TypeDeclKind::Enum { values, init })
    }

    /// `INT (0..100) := 5`, the type already read.
    fn subrange(&mut self, ty: TypeRef) -> Result<TypeDeclKind, Diagnostic> {
        self.bump();
        let (lo, _) = self.expr()?;
        self.expect(Tok::DotDot, "'..' between the bounds of the subrange")?;
        let (hi, _) = self.expr()?;
        self.expect(Tok::RParen, "')' after the subrange")?;
        let init = self.init_opt()?;
        Ok(TypeDeclKind::Alias {
            ty,
            range: Some((lo, hi)),
            init,
        })
    }

    /// A type in a declaration.
    pub(super) fn type_ref(&mut self) -> Result<TypeRef, Diagnostic> {
        let t = self.tok(0);
        match t.tok {
            Tok::Kw(Kw::String) => {
                self.bump();
                let close = match self.peek() {
                    Tok::LBracket => Tok::RBracket,
                    Tok::LParen => Tok::RParen,
                    _ => return Ok(TypeRef::String { len: None, pos: t.pos }),
                };
                self.bump();
                let (len, _) = self.expr()?;
                let what = if close == Tok::RBracket { "']'" } else { "')'" };
                self.expect(close, &format!("{what} after the STRING's length"))?;
                Ok(TypeRef::String {
                    len: Some(Box::new(len)),
                    pos: t.pos,
                })
            }
            Tok::Kw(Kw::Array) => self.nested(Parser::array_type),
            Tok::Ident => {
                let name = self.text_of(t);
                if DATE_TYPES.iter().any(|d| d.eq_ignore_ascii_case(name)) {
                    return Err(Diagnostic::new(t.pos, DATES));
                }
                if let Some(refused) = self.refusal() {
                    return Err(refused);
                }
                self.bump();
                Ok(TypeRef::Named(self.ident_of(t)))
            }
            Tok::LParen => Err(Diagnostic::new(
                t.pos,
                "an enumeration must be declared as a type: TYPE Color : (Red, Green); END_TYPE, then x : Color",
            )),
            _ => Err(self.unexpected("a type")),
        }
    }

    /// `ARRAY [1..3, 0..1] OF T`.
    fn array_type(&mut self) -> Result<TypeRef, Diagnostic> {
        let pos = self.bump().pos;
        self.expect(Tok::LBracket, "'[' and the bounds after ARRAY")?;
        let mut dims = Vec::new();
        loop {
            if self.at(Tok::Star) {
                return Err(Diagnostic::new(
                    self.pos(),
                    "arrays of variable length (ARRAY [*]) are not supported: give the bounds, as ARRAY [1..10] OF INT",
                ));
            }
            let (lo, _) = self.expr()?;
            self.expect(Tok::DotDot, "'..' between the bounds")?;
            let (hi, _) = self.expr()?;
            dims.push((lo, hi));
            if !self.eat(Tok::Comma) {
                break;
            }
        }
        self.expect(Tok::RBracket, "',' or ']' after the bounds")?;
        self.expect_kw(Kw::Of, "OF and the element type after the bounds")?;
        let elem = self.type_ref()?;
        Ok(TypeRef::Array {
            dims,
            elem: Box::new(elem),
            pos,
        })
    }

    /// `:= init`, if there.
    fn init_opt(&mut self) -> Result<Option<Init>, Diagnostic> {
        if self.eat(Tok::Assign) {
            Ok(Some(self.init()?))
        } else {
            Ok(None)
        }
    }

    /// An initial value: an expression, `[1, 2, 3(0)]` or `(a := 1, b := 2)`.
    fn init(&mut self) -> Result<Init, Diagnostic> {
        match self.peek() {
            Tok::LBracket => self.nested(Parser::array_init),
            Tok::LParen if self.peek_at(1) == Tok::Ident && self.peek_at(2) == Tok::Assign => {
                self.nested(Parser::struct_init)
            }
            _ => Ok(Init::Expr(self.expr()?.0)),
        }
    }

    fn array_init(&mut self) -> Result<Init, Diagnostic> {
        let pos = self.bump().pos;
        let mut elems = Vec::new();
        loop {
            if self.at(Tok::Int) && self.peek_at(1) == Tok::LParen {
                let t = self.bump();
                let count = Expr {
                    kind: ExprKind::Lit(Literal::Int {
                        value: lit::int(self.text_of(t), t.pos)?,
                        ty: None,
                    }),
                    pos: t.pos,
                };
                self.bump();
                if self.at(Tok::RParen) {
                    return Err(Diagnostic::new(
                        self.pos(),
                        "write the value to repeat inside n( ), as 3(0)",
                    ));
                }
                let value = self.init()?;
                self.expect(Tok::RParen, "')' after the repeated value")?;
                elems.push((Some(count), value));
            } else {
                elems.push((None, self.init()?));
            }
            if !self.eat(Tok::Comma) {
                break;
            }
        }
        self.expect(Tok::RBracket, "',' or ']' after the array element")?;
        Ok(Init::Array(elems, pos))
    }

    fn struct_init(&mut self) -> Result<Init, Diagnostic> {
        let pos = self.bump().pos;
        let mut members = Vec::new();
        loop {
            let name = self.name("a member name")?;
            self.expect(Tok::Assign, "':=' after the member name")?;
            members.push((name, self.init()?));
            if !self.eat(Tok::Comma) {
                break;
            }
        }
        self.expect(Tok::RParen, "',' or ')' after the member's value")?;
        Ok(Init::Struct(members, pos))
    }

    fn section(&self) -> Option<Section> {
        Some(match self.peek() {
            Tok::Kw(Kw::Var) => Section::Var,
            Tok::Kw(Kw::VarInput) => Section::Input,
            Tok::Kw(Kw::VarOutput) => Section::Output,
            Tok::Kw(Kw::VarInOut) => Section::InOut,
            Tok::Kw(Kw::VarTemp) => Section::Temp,
            Tok::Kw(Kw::VarExternal) => Section::External,
            Tok::Kw(Kw::VarGlobal) => Section::Global,
            _ => return None,
        })
    }

    /// `VAR … END_VAR`, at its keyword.
    fn var_block(&mut self, section: Section) -> Result<VarBlock, Diagnostic> {
        let pos = self.bump().pos;
        let (mut constant, mut retain, mut non_retain) = (false, false, false);
        loop {
            match self.peek() {
                Tok::Kw(Kw::Constant) => constant = true,
                Tok::Kw(Kw::Retain | Kw::Persistent) => retain = true,
                Tok::Kw(Kw::NonRetain) => non_retain = true,
                _ => break,
            }
            self.bump();
        }
        if retain && non_retain {
            return Err(Diagnostic::new(
                pos,
                format!(
                    "a {} block is RETAIN or NON_RETAIN, not both",
                    section.keyword()
                ),
            ));
        }
        let mut decls = Vec::new();
        while !self.eat_kw(Kw::EndVar) {
            decls.push(self.var_decl()?);
            self.expect(Tok::Semi, "';' after the declaration")?;
        }
        Ok(VarBlock {
            section,
            constant,
            retain,
            decls,
            pos,
        })
    }

    /// `a, b AT %IX0.0 : T := init`.
    fn var_decl(&mut self) -> Result<VarDecl, Diagnostic> {
        if self.at_kw(Kw::At) {
            return Err(Diagnostic::new(
                self.pos(),
                "a located variable needs a name: write x AT %IX0.0 : BOOL",
            ));
        }
        let mut names = vec![self.name("a variable name, or END_VAR")?];
        while self.eat(Tok::Comma) {
            names.push(self.name("a variable name after ','")?);
        }
        let at = if self.eat_kw(Kw::At) {
            let t = self.expect(Tok::Address, "an address such as %IX0.0 after AT")?;
            Some(self.ident_of(t))
        } else {
            None
        };
        self.expect(Tok::Colon, "':' and a type after the variable's name")?;
        let ty = self.type_ref()?;
        if self.at(Tok::LParen) {
            return Err(Diagnostic::new(
                self.pos(),
                "a subrange (INT (0..100)) or arguments to a function block are not supported in a variable's declaration: declare a subrange as a type (TYPE Level : INT (0..100); END_TYPE), and give a function block's inputs as an initial value, t : TON := (PT := T#1s)",
            ));
        }
        if self.at_word(0, "R_EDGE") || self.at_word(0, "F_EDGE") {
            return Err(Diagnostic::new(
                self.pos(),
                "R_EDGE and F_EDGE inputs are not supported: declare a BOOL input and detect its edge with an R_TRIG or F_TRIG instance",
            ));
        }
        let init = self.init_opt()?;
        Ok(VarDecl {
            names,
            at,
            ty,
            init,
        })
    }

    /// A PROGRAM, FUNCTION_BLOCK or FUNCTION.
    fn pou(&mut self) -> Result<Pou, Diagnostic> {
        let start = self.bump();
        let (what, end) = match start.tok {
            Tok::Kw(Kw::Program) => ("PROGRAM", Kw::EndProgram),
            Tok::Kw(Kw::FunctionBlock) => ("FUNCTION_BLOCK", Kw::EndFunctionBlock),
            _ => ("FUNCTION", Kw::EndFunction),
        };
        let name = self.name(&format!("the name of the {what}"))?;
        let kind = match start.tok {
            Tok::Kw(Kw::Program) => PouKind::Program,
            Tok::Kw(Kw::FunctionBlock) => PouKind::FunctionBlock,
            _ => {
                self.expect(
                    Tok::Colon,
                    "':' and the return type after the FUNCTION's name",
                )?;
                PouKind::Function(self.type_ref()?)
            }
        };
        let mut vars = Vec::new();
        while let Some(section) = self.section() {
            vars.push(self.var_block(section)?);
        }
        let body = self.body()?;
        self.expect_kw(
            end,
            &format!("{} to close {what} {}", end.text(), name.text),
        )?;
        Ok(Pou {
            kind,
            name,
            vars,
            body,
            pos: start.pos,
        })
    }

    fn configuration(&mut self) -> Result<Config, Diagnostic> {
        self.bump();
        let mut config = Config {
            name: self.name("the name of the CONFIGURATION")?,
            tasks: Vec::new(),
            programs: Vec::new(),
            globals: Vec::new(),
        };
        self.resource_items(&mut config)?;
        while self.eat_kw(Kw::Resource) {
            self.name("the name of the RESOURCE")?;
            if !self.at_word(0, "ON") {
                return Err(self.unexpected("ON and the resource type after the RESOURCE's name"));
            }
            self.bump();
            self.name("the resource type after ON")?;
            self.resource_items(&mut config)?;
            self.expect_kw(Kw::EndResource, "VAR_GLOBAL, TASK, PROGRAM or END_RESOURCE")?;
            self.eat(Tok::Semi);
        }
        self.expect_kw(
            Kw::EndConfiguration,
            "VAR_GLOBAL, TASK, PROGRAM, RESOURCE or END_CONFIGURATION",
        )?;
        Ok(config)
    }

    /// The global variables, tasks and program instances of a configuration or a resource.
    fn resource_items(&mut self, config: &mut Config) -> Result<(), Diagnostic> {
        loop {
            match self.peek() {
                Tok::Kw(Kw::VarGlobal) => config.globals.push(self.var_block(Section::Global)?),
                Tok::Kw(Kw::Program) => config.programs.push(self.program_instance()?),
                Tok::Ident if self.at_word(0, "TASK") => config.tasks.push(self.task()?),
                _ => return Ok(()),
            }
        }
    }

    /// `TASK t (INTERVAL := T#20ms, PRIORITY := 1);`
    fn task(&mut self) -> Result<Task, Diagnostic> {
        self.bump();
        let name = self.name("the name of the TASK")?;
        self.expect(Tok::LParen, "'(' and the task's INTERVAL and PRIORITY")?;
        let mut interval = None;
        if !self.at(Tok::RParen) {
            loop {
                let key = self.name("INTERVAL or PRIORITY")?;
                self.expect(Tok::Assign, &format!("':=' after {}", key.text))?;
                let (value, _) = self.expr()?;
                match key.key().as_str() {
                    "INTERVAL" if interval.is_none() => interval = Some(value),
                    "PRIORITY" => {}
                    "SINGLE" => {
                        return Err(Diagnostic::new(
                            key.pos,
                            "event tasks (SINGLE) are not supported: give the task an INTERVAL",
                        ))
                    }
                    "INTERVAL" => {
                        return Err(Diagnostic::new(
                            key.pos,
                            "the task's INTERVAL is given twice",
                        ))
                    }
                    _ => {
                        return Err(Diagnostic::new(
                            key.pos,
                            format!("a TASK takes INTERVAL and PRIORITY, not {}", key.text),
                        ))
                    }
                }
                if !self.eat(Tok::Comma) {
                    break;
                }
            }
        }
        self.expect(Tok::RParen, "',' or ')' after the task's parameter")?;
        self.expect(Tok::Semi, "';' after the TASK")?;
        Ok(Task { name, interval })
    }

    /// `PROGRAM inst WITH task : Type;`
    fn program_instance(&mut self) -> Result<ProgramInstance, Diagnostic> {
        self.bump();
        let name = self.name("the name of the program instance")?;
        let task = if self.at_word(0, "WITH") {
            self.bump();
            Some(self.name("the task after WITH")?)
        } else {
            None
        };
        self.expect(Tok::Colon, "WITH and a task, or ':' and the PROGRAM type")?;
        let program = self.name("the PROGRAM type of the instance")?;
        if self.at(Tok::LParen) {
            return Err(Diagnostic::new(
                self.pos(),
                "connecting a program instance's variables in the configuration is not supported: share them through VAR_GLOBAL and VAR_EXTERNAL",
            ));
        }
        self.expect(Tok::Semi, "';' after the program instance")?;
        Ok(ProgramInstance {
            name,
            task,
            program,
        })
    }
}
