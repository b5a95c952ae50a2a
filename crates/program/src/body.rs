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

use crate::guard::{self, Compiler, EvalCtx, EvalError, EvalErrorKind, Op, Scope, SyntaxError};
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
        let what = match self.kind {
            EvalErrorKind::DivisionByZero => "division by zero",
            EvalErrorKind::Overflow => "arithmetic overflow",
            EvalErrorKind::MissingValue | EvalErrorKind::WrongType => {
                "the state does not match the program's signals"
            }
        };
        write!(
            f,
            "action body `{}` failed at line {}, column {}: {what}",
            self.body, self.line, self.column
        )
    }
}

impl std::error::Error for BodyError {}

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
        let mut c = Compiler {
            scope,
            code: Vec::new(),
            base: 0,
            depth: 0,
            max: 0,
            inputs: Vec::new(),
            vars: Vec::new(),
            places: Vec::new(),
            timers: Vec::new(),
            body: true,
        };
        let mut open: Vec<Open> = Vec::new();
        let (mut outputs, mut vars) = (Vec::new(), Vec::new());
        let mut statements = 0usize;
        for (line, at) in lines(source) {
            statements += 1;
            if statements > MAX_STATEMENTS {
                return Err(SyntaxError::new(
                    at,
                    format!("the body has more than {MAX_STATEMENTS} statements; split it into several actions"),
                ));
            }
            match classify(line, at)? {
                Line::Assign {
                    name,
                    at,
                    expr,
                    expr_at,
                } => {
                    let store = if let Some(i) = scope.vars.iter().position(|s| s.name == name) {
                        vars.push(i as u32);
                        Op::StoreVar(i as u32, scope.vars[i].ty)
                    } else if let Some(i) = scope.outputs.iter().position(|s| s.name == name) {
                        outputs.push(i as u32);
                        Op::StoreOut(i as u32, scope.outputs[i].ty)
                    } else if scope.inputs.iter().any(|s| s.name == name) {
                        return Err(SyntaxError::new(at, format!("`{name}` is an input, which the program cannot assign; assign a variable or an output")));
                    } else {
                        return Err(SyntaxError::new(
                            at,
                            format!(
                                "`{name}` is not declared; a body assigns a variable or an output"
                            ),
                        ));
                    };
                    let (Op::StoreVar(_, want) | Op::StoreOut(_, want)) = store else {
                        unreachable!("built above")
                    };
                    let got = expression(&mut c, expr, expr_at)?;
                    if got != want {
                        return Err(SyntaxError::new(
                            expr_at,
                            format!("`{name}` is {want} but the value is {got}; ints and reals convert with `real(…)` and `int(…)`"),
                        ));
                    }
                    c.emit(store, at, -1);
                }
                Line::If(cond, cat) => {
                    if open.len() >= MAX_IF_NESTING {
                        return Err(SyntaxError::new(
                            at,
                            format!("`if` nested more than {MAX_IF_NESTING} deep; simplify the body or split it"),
                        ));
                    }
                    let j = condition(&mut c, cond, cat)?;
                    open.push(Open {
                        next_arm: Some(j),
                        ends: Vec::new(),
                        has_else: false,
                        at,
                    });
                }
                Line::Elif(cond, cat) => {
                    let o = arm_of(&mut open, at, "elif")?;
                    let jump = c.code.len();
                    c.emit(Op::Jump(0), at, 0);
                    o.ends.push(jump);
                    let here = c.code.len() as u32;
                    if let Some(j) = o.next_arm.take() {
                        c.code[j].0 = Op::JumpIfFalse(here);
                    }
                    let j = condition(&mut c, cond, cat)?;
                    open.last_mut().expect("checked by arm_of").next_arm = Some(j);
                }
                Line::Else(at) => {
                    let o = arm_of(&mut open, at, "else")?;
                    let jump = c.code.len();
                    c.emit(Op::Jump(0), at, 0);
                    o.ends.push(jump);
                    let here = c.code.len() as u32;
                    if let Some(j) = o.next_arm.take() {
                        c.code[j].0 = Op::JumpIfFalse(here);
                    }
                    open.last_mut().expect("checked by arm_of").has_else = true;
                }
                Line::End(at) => {
                    let Some(o) = open.pop() else {
                        return Err(SyntaxError::new(at, "`end` without an `if`; remove it"));
                    };
                    let here = c.code.len() as u32;
                    if let Some(j) = o.next_arm {
                        c.code[j].0 = Op::JumpIfFalse(here);
                    }
                    for j in o.ends {
                        c.code[j].0 = Op::Jump(here);
                    }
                }
            }
        }
        if let Some(o) = open.last() {
            return Err(SyntaxError::new(
                o.at,
                "this `if` has no `end`; close it with a line `end`",
            ));
        }
        if c.max > guard::MAX_STACK {
            return Err(SyntaxError::new(
                0,
                format!(
                    "an expression of this body needs {} evaluation stack slots but the evaluator has {}; split it",
                    c.max,
                    guard::MAX_STACK
                ),
            ));
        }
        for v in [&mut outputs, &mut vars] {
            v.sort_unstable();
            v.dedup();
        }
        Ok(Body {
            name: name.to_string(),
            source: source.to_string(),
            code: c.code,
            outputs,
            vars,
        })
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
