//! Action bodies: statements over the guard language (docs/program-format.md, *Action bodies*),
//! compiled once at load into the guard evaluator's flat code, with stores and forward jumps.
//!
//! A body is a list of lines (or `;`-separated statements): `name := expr`, `if expr then`,
//! `elif expr then`, `else`, `end`. The parser reads them with a loop and a stack of open `if`s
//! bounded by [`MAX_IF_NESTING`]; each expression goes through the guard parser, whose own depth is
//! bounded. The code only jumps forward, so running a body costs at most one step per
//! instruction, and it runs on the evaluator's fixed stack: a body never allocates and never
//! loops.

use std::fmt;

use std::sync::Arc;

use crate::guard::{
    self, Compiler, EvalCtx, EvalError, EvalErrorKind, Expr, Op, Scope, SyntaxError,
};
use crate::st::StProgram;
use crate::value::{Type, Value};

/// Most bytes in one body.
pub const MAX_BODY_BYTES: usize = 16 * 1024;
/// Most statements (assignments and `if`/`elif`/`else`/`end` lines) in one body.
pub const MAX_STATEMENTS: usize = 512;
/// Deepest nesting of `if` in one body.
pub const MAX_IF_NESTING: usize = 32;

/// An action body, compiled.
#[derive(Clone, Debug)]
pub struct Body {
    name: String,
    source: String,
    code: Vec<(Op, u32)>,
    outputs: Vec<u32>,
    vars: Vec<u32>,
    /// A POU of the program's Structured Text (`[st]`) instead of guard-language code.
    st: Option<Arc<StProgram>>,
    /// The entry of that ST this body runs (a chart's `[st.bodies]`), else its POU's body.
    entry: Option<u32>,
}

/// A body that failed while running: which, where in its text, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodyError {
    /// The body's name.
    pub body: String,
    /// 1-based line in the body text.
    pub line: u32,
    /// 1-based column in that line.
    pub column: u32,
    /// What went wrong.
    pub kind: EvalErrorKind,
}

impl fmt::Display for BodyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mismatch = "the state does not match the program's signals";
        let what = self.kind.describe(mismatch, mismatch);
        write!(
            f,
            "action body `{}` failed at line {}, column {}: {what}",
            self.body, self.line, self.column
        )
    }
}

impl std::error::Error for BodyError {}

/// A statement of a guard-language body ([`Body::statements`]): an `if` opens arms that
/// `elif`, `else` and `end` continue and close, as the lines of the text do.
#[derive(Clone, Debug, PartialEq)]
pub enum Statement {
    /// `name := expr`, on the body's 1-based `line`.
    Assign {
        /// The variable or output assigned.
        name: String,
        /// The value.
        expr: Expr,
        /// The line in the body text.
        line: u32,
    },
    /// `if cond then`
    If(Expr),
    /// `elif cond then`
    Elif(Expr),
    /// `else`
    Else,
    /// `end`
    End,
}

/// One statement line, its parts located in the body text.
enum Line<'a> {
    Assign {
        name: &'a str,
        at: usize,
        expr: &'a str,
        expr_at: usize,
    },
    If(&'a str, usize),
    Elif(&'a str, usize),
    Else(usize),
    End(usize),
}

/// An `if` whose `end` has not been read yet.
struct Open {
    /// The `JumpIfFalse` of the last arm, to point at the next arm.
    next_arm: Option<usize>,
    /// The `Jump`s that end each arm, to point past `end`.
    ends: Vec<usize>,
    has_else: bool,
    at: usize,
}

impl Body {
    /// The name the actions use.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// The body as written.
    pub fn source(&self) -> &str {
        &self.source
    }
    /// Indices of the outputs it assigns, sorted.
    pub fn outputs(&self) -> &[u32] {
        &self.outputs
    }
    /// Indices of the variables it assigns, sorted.
    pub fn variables(&self) -> &[u32] {
        &self.vars
    }
    /// Instructions of the compiled code (bounded by the text's limits).
    pub fn code_len(&self) -> usize {
        self.code.len()
    }
    /// What one run costs in units of [`crate::Work`]: the length of its code, at least 1 (for
    /// Structured Text, its straight-line cost; its loops charge more as they go round).
    #[inline]
    pub fn cost(&self) -> u64 {
        match (&self.st, self.entry) {
            (Some(st), Some(k)) => (st.unit().entries.get(k as usize)).map_or(1, |e| e.cost.max(1)),
            (Some(st), None) => st.unit().cost.max(1),
            (None, _) => (self.code.len() as u64).max(1),
        }
    }

    /// The statements of a guard-language body as written, each expression parsed (for writing
    /// the body in another language, as `cetratus export` does); a Structured Text body has
    /// none. The body compiled at load, so its text parses again.
    pub fn statements(&self) -> Result<Vec<Statement>, SyntaxError> {
        if self.st.is_some() {
            return Ok(Vec::new());
        }
        let parse = |text: &str, at: usize| {
            guard::parse(text).map_err(|e| SyntaxError::new(at + e.offset, e.message))
        };
        lines(&self.source)
            .map(|(line, at)| {
                Ok(match classify(line, at)? {
                    Line::Assign {
                        name,
                        expr,
                        expr_at,
                        ..
                    } => Statement::Assign {
                        name: name.to_string(),
                        expr: parse(expr, expr_at)?,
                        line: line_col(&self.source, at).0,
                    },
                    Line::If(c, at) => Statement::If(parse(c, at)?),
                    Line::Elif(c, at) => Statement::Elif(parse(c, at)?),
                    Line::Else(_) => Statement::Else,
                    Line::End(_) => Statement::End,
                })
            })
            .collect()
    }

    /// The program's Structured Text POU this body runs, if it is one.
    pub fn st(&self) -> Option<&StProgram> {
        self.st.as_deref()
    }

    /// The entry of the program's ST this body runs, when it is a chart's `[st.bodies]`.
    pub fn st_entry(&self) -> Option<u32> {
        self.entry
    }

    /// A body that runs the POU of the program's Structured Text, or its `entry`; `source` is
    /// the ST text.
    pub(crate) fn structured_text(
        name: &str,
        source: &str,
        st: Arc<StProgram>,
        entry: Option<u32>,
    ) -> Body {
        let mut outputs: Vec<u32> = st.driven_outputs().map(|i| i as u32).collect();
        outputs.sort_unstable();
        Body {
            name: name.to_string(),
            source: source.to_string(),
            code: Vec::new(),
            outputs,
            vars: Vec::new(),
            st: Some(st),
            entry,
        }
    }

    /// A fault of the ST this body runs, located in its text.
    pub(crate) fn st_error(&self, kind: EvalErrorKind, pos: u32) -> BodyError {
        let (line, column) = line_col(&self.source, pos as usize);
        BodyError {
            body: self.name.clone(),
            line,
            column,
            kind,
        }
    }

    /// Parses, type-checks and compiles a body; the error's offset is in `source`.
    pub(crate) fn compile(name: &str, source: &str, scope: &Scope) -> Result<Body, SyntaxError> {
        if source.len() > MAX_BODY_BYTES {
            return Err(SyntaxError::new(
                MAX_BODY_BYTES,
                format!(
                    "the body is longer than {MAX_BODY_BYTES} bytes; split it into several actions"
                ),
            ));
        }
        let mut b = Builder {
            c: Compiler {
                body: true,
                ..Compiler::new(scope)
            },
            open: Vec::new(),
            outputs: Vec::new(),
            vars: Vec::new(),
        };
        for (n, (line, at)) in lines(source).enumerate() {
            if n >= MAX_STATEMENTS {
                return Err(SyntaxError::new(
                    at,
                    format!("the body has more than {MAX_STATEMENTS} statements; split it into several actions"),
                ));
            }
            b.statement(classify(line, at)?, at)?;
        }
        b.finish(name, source)
    }

    /// Runs the body once: reads `ctx` (its `vars` are ignored) and `vars`, assigns `vars` and
    /// `outputs`. Never allocates on success. On error, the assignments before the failing
    /// statement have taken effect.
    pub fn run(
        &self,
        ctx: &EvalCtx,
        vars: &mut [Value],
        outputs: &mut [Value],
    ) -> Result<(), BodyError> {
        let mut stack = [0u64; guard::MAX_STACK];
        let store = guard::Store { vars, outputs };
        match guard::run(&self.code, ctx, Some(store), &mut stack) {
            Ok(0) => Ok(()),
            Ok(_) => Err(self.error(EvalError {
                kind: EvalErrorKind::MissingValue,
                column: 1,
            })),
            Err(e) => Err(self.error(e)),
        }
    }

    /// Where in the text an evaluation error happened (its column is a byte offset + 1).
    fn error(&self, e: EvalError) -> BodyError {
        let (line, column) = line_col(&self.source, e.column.saturating_sub(1) as usize);
        BodyError {
            body: self.name.clone(),
            line,
            column,
            kind: e.kind,
        }
    }
}

/// A body being compiled: the expression compiler, the `if`s still open, what it assigns.
struct Builder<'s, 'a> {
    c: Compiler<'s, 'a>,
    open: Vec<Open>,
    outputs: Vec<u32>,
    vars: Vec<u32>,
}

impl Builder<'_, '_> {
    /// Compiles one statement at `at`; the jumps of an `if` wait in `open` until its arms and
    /// its `end` are known.
    fn statement(&mut self, line: Line, at: usize) -> Result<(), SyntaxError> {
        match line {
            Line::Assign {
                name,
                at,
                expr,
                expr_at,
            } => self.assign(name, at, expr, expr_at),
            Line::If(cond, cond_at) => self.open_if(cond, cond_at, at),
            Line::Elif(cond, cond_at) => {
                self.next_arm(at, "elif")?;
                let j = condition(&mut self.c, cond, cond_at)?;
                self.open.last_mut().expect("checked by next_arm").next_arm = Some(j);
                Ok(())
            }
            Line::Else(at) => {
                self.next_arm(at, "else")?.has_else = true;
                Ok(())
            }
            Line::End(at) => self.end(at),
        }
    }

    /// `name := expr` stores into a variable or an output, whose type the value must have
    /// exactly: nothing converts implicitly.
    fn assign(
        &mut self,
        name: &str,
        at: usize,
        expr: &str,
        expr_at: usize,
    ) -> Result<(), SyntaxError> {
        let scope = self.c.scope;
        let (store, want) = if let Some(i) = scope.var(name) {
            self.vars.push(i as u32);
            (Op::StoreVar(i as u32, scope.vars[i].ty), scope.vars[i].ty)
        } else if let Some(i) = scope.output(name) {
            self.outputs.push(i as u32);
            (
                Op::StoreOut(i as u32, scope.outputs[i].ty),
                scope.outputs[i].ty,
            )
        } else if scope.input(name).is_some() {
            return Err(SyntaxError::new(at, format!("`{name}` is an input, which the program cannot assign; assign a variable or an output")));
        } else {
            return Err(SyntaxError::new(
                at,
                format!("`{name}` is not declared; a body assigns a variable or an output"),
            ));
        };
        let got = expression(&mut self.c, expr, expr_at)?;
        if got != want {
            return Err(SyntaxError::new(
                expr_at,
                format!("`{name}` is {want} but the value is {got}; ints and reals convert with `real(…)` and `int(…)`"),
            ));
        }
        self.c.emit(store, at, -1);
        Ok(())
    }

    /// `if cond then` opens an arm; the nesting is bounded, and with it the stack of open `if`s.
    fn open_if(&mut self, cond: &str, cond_at: usize, at: usize) -> Result<(), SyntaxError> {
        if self.open.len() >= MAX_IF_NESTING {
            return Err(SyntaxError::new(
                at,
                format!(
                    "`if` nested more than {MAX_IF_NESTING} deep; simplify the body or split it"
                ),
            ));
        }
        let j = condition(&mut self.c, cond, cond_at)?;
        self.open.push(Open {
            next_arm: Some(j),
            ends: Vec::new(),
            has_else: false,
            at,
        });
        Ok(())
    }

    /// Closes the arm before an `elif` or `else`: a jump past the `end` ends it, and the
    /// previous condition, when false, now jumps here.
    fn next_arm(&mut self, at: usize, what: &str) -> Result<&mut Open, SyntaxError> {
        let o = arm_of(&mut self.open, at, what)?;
        let jump = self.c.code.len();
        self.c.emit(Op::Jump(0), at, 0);
        o.ends.push(jump);
        let here = self.c.code.len() as u32;
        if let Some(j) = o.next_arm.take() {
            self.c.code[j].0 = Op::JumpIfFalse(here);
        }
        Ok(o)
    }

    /// `end`: the pending jumps of the innermost `if` learn where it ends.
    fn end(&mut self, at: usize) -> Result<(), SyntaxError> {
        let Some(o) = self.open.pop() else {
            return Err(SyntaxError::new(at, "`end` without an `if`; remove it"));
        };
        let here = self.c.code.len() as u32;
        if let Some(j) = o.next_arm {
            self.c.code[j].0 = Op::JumpIfFalse(here);
        }
        for j in o.ends {
            self.c.code[j].0 = Op::Jump(here);
        }
        Ok(())
    }

    /// The checks only the whole body allows: every `if` closed, the evaluator's stack enough.
    fn finish(mut self, name: &str, source: &str) -> Result<Body, SyntaxError> {
        if let Some(o) = self.open.last() {
            return Err(SyntaxError::new(
                o.at,
                "this `if` has no `end`; close it with a line `end`",
            ));
        }
        if self.c.max > guard::MAX_STACK {
            return Err(SyntaxError::new(
                0,
                format!(
                    "an expression of this body needs {} evaluation stack slots but the evaluator has {}; split it",
                    self.c.max,
                    guard::MAX_STACK
                ),
            ));
        }
        for v in [&mut self.outputs, &mut self.vars] {
            v.sort_unstable();
            v.dedup();
        }
        Ok(Body {
            name: name.to_string(),
            source: source.to_string(),
            code: self.c.code,
            outputs: self.outputs,
            vars: self.vars,
            st: None,
            entry: None,
        })
    }
}

/// 1-based line and column of a byte offset.
pub fn line_col(text: &str, offset: usize) -> (u32, u32) {
    let before = text.get(..offset.min(text.len())).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    (line as u32, col as u32)
}

/// The open `if` an `elif` or `else` belongs to.
fn arm_of<'o>(open: &'o mut [Open], at: usize, what: &str) -> Result<&'o mut Open, SyntaxError> {
    match open.last_mut() {
        None => Err(SyntaxError::new(at, format!("`{what}` without an `if`"))),
        Some(o) if o.has_else => Err(SyntaxError::new(
            at,
            format!("`{what}` after `else`; `else` is the last arm of an `if`"),
        )),
        Some(o) => Ok(o),
    }
}

/// Compiles a condition and a `JumpIfFalse` to patch; returns the jump's index.
fn condition(c: &mut Compiler, text: &str, at: usize) -> Result<usize, SyntaxError> {
    let ty = expression(c, text, at)?;
    if ty != Type::Bool {
        return Err(SyntaxError::new(
            at,
            format!("an `if` condition must be a bool, this is {ty}; compare it, e.g. `x > 0`"),
        ));
    }
    let j = c.code.len();
    c.emit(Op::JumpIfFalse(0), at, -1);
    Ok(j)
}

fn expression(c: &mut Compiler, text: &str, at: usize) -> Result<Type, SyntaxError> {
    let e = guard::parse(text).map_err(|e| SyntaxError::new(at + e.offset, e.message))?;
    c.base = at;
    c.depth = 0;
    // Compile errors are at offsets in the expression, like parse errors.
    let ty = c
        .value(&e)
        .map_err(|e| SyntaxError::new(at + e.offset, e.message));
    // Stores and jumps are placed with positions in the whole body.
    c.base = 0;
    ty
}

/// The statements of a body with their byte offsets, split at newlines and `;`, trimmed,
/// blank ones and `#` comments left out.
fn lines(source: &str) -> impl Iterator<Item = (&str, usize)> {
    let mut rest = 0usize;
    source.split_inclusive(['\n', ';']).filter_map(move |seg| {
        let start = rest;
        rest += seg.len();
        let body = seg.trim_end_matches(['\n', ';', '\r']);
        let body = body.split('#').next().unwrap_or("");
        let lead = body.len() - body.trim_start().len();
        let t = body.trim();
        (!t.is_empty()).then_some((t, start + lead))
    })
}

fn first_word(s: &str) -> &str {
    let end = s
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    &s[..end]
}

fn classify(line: &str, at: usize) -> Result<Line<'_>, SyntaxError> {
    let word = first_word(line);
    let guarded = |kw: &str| -> Result<(&str, usize), SyntaxError> {
        let rest = &line[kw.len()..];
        let Some(cond) = rest
            .strip_suffix("then")
            .filter(|c| c.ends_with(|ch: char| ch.is_whitespace() || ch == ')'))
        else {
            return Err(SyntaxError::new(
                at + line.len(),
                format!("`{kw}` needs its condition and `then` on one line: `{kw} x > 0 then`"),
            ));
        };
        let lead = cond.len() - cond.trim_start().len();
        if cond.trim().is_empty() {
            return Err(SyntaxError::new(
                at + kw.len(),
                format!("`{kw}` has no condition"),
            ));
        }
        Ok((cond.trim(), at + kw.len() + lead))
    };
    if let Some(eq) = line.find(":=") {
        let name = line[..eq].trim();
        let ok = name
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !ok {
            return Err(SyntaxError::new(
                at,
                format!(
                    "`{}` cannot be assigned; the left of `:=` is a signal name",
                    name
                ),
            ));
        }
        let expr = &line[eq + 2..];
        let lead = expr.len() - expr.trim_start().len();
        return Ok(Line::Assign {
            name,
            at,
            expr: expr.trim(),
            expr_at: at + eq + 2 + lead,
        });
    }
    match word {
        "if" if line.len() > 2 => guarded("if").map(|(c, a)| Line::If(c, a)),
        "elif" => guarded("elif").map(|(c, a)| Line::Elif(c, a)),
        "else" if line == "else" => Ok(Line::Else(at)),
        "end" if line == "end" => Ok(Line::End(at)),
        _ => Err(SyntaxError::new(
            at,
            format!(
                "`{}` is not a statement; a body has `name := expr`, `if … then`, `elif … then`, `else` and `end`",
                line.chars().take(40).collect::<String>()
            ),
        )),
    }
}
