//! The recursive-descent parser: IEC 61131-3 Structured Text (3rd edition) into [`crate::ast`].
//!
//! Three entry points: [`parse_library`] for a whole file (TYPEs, POUs, CONFIGURATIONs),
//! [`parse_statements`] for a body alone (an SFC action) and [`parse_expression`] for a
//! condition alone. Each error is one [`Diagnostic`] at the offending token, saying what was
//! expected and what was found; [`crate::Source::locate`] turns it into line:column.
//!
//! # Expressions
//!
//! Strongest first, as IEC 61131-3 Table 71 has them but for `**` (below); binary operators are
//! left-associative:
//!
//! | operators | |
//! |---|---|
//! | `( … )`, `F(…)`, `a.b`, `a[i, j]` | primary |
//! | `-`, `+`, `NOT` | unary |
//! | `**` | power (left-associative: `2 ** 3 ** 2` is `(2 ** 3) ** 2`) |
//! | `*`, `/`, `MOD` | |
//! | `+`, `-` | |
//! | `<`, `>`, `<=`, `>=` | |
//! | `=`, `<>` | |
//! | `AND`, `&` | |
//! | `XOR` | |
//! | `OR` | |
//!
//! **`**` and the unary operators.** Table 71 ranks `**` above unary minus, so `-a ** 2` would be
//! `-(a ** 2)`; the grammar of the same standard (Annex A: `Power_Expr : Unary_Expr ( '**'
//! Unary_Expr )*`) and MATIEC (`power_expression OPER_EXP unary_expression`) read it
//! `(-a) ** 2`. The tree here follows the grammar and MATIEC: the operands of `**` are unary
//! expressions, and `**` is left-associative as both have it. Since the standard contradicts
//! itself, the one form where the readings differ is refused: an operand of `**` written with a
//! unary operator and followed by `**` (`-a ** 2`, `NOT a ** b`, `a ** -b ** c`), with a message
//! asking for parentheses. `a ** -b` means the same under both readings and is accepted.
//! MATIEC (and Annex A) allow one unary operator before a primary; `NOT NOT a` and `- -a` are
//! accepted here, as CODESYS accepts them.
//!
//! Comparisons chain as the grammar has them (`a < b < c` is `(a < b) < c`), for the type checker
//! to refuse. `a[i][j]` parses as an element of an element; that it needs an array of arrays is
//! the type checker's to say, as is whether `a.b(…)` calls a function block instance inside a
//! structure (accepted) or a method (not supported). Calls take positional arguments or formal
//! ones (`IN := x`, `Q => y`, `NOT Q => y`), not both (MATIEC's rule).
//!
//! # The vendors' forms
//!
//! IEC 61131-3 §7.3.3 ends every statement with `;` (Annex A: `Stmt_List : ( Stmt ? ';' )*`). CODESYS
//! accepts `END_IF`, `END_CASE`, `END_FOR`, `END_WHILE` and `END_REPEAT` without one, and action
//! bodies exported from it end that way; so the `;` after those five may be left out when the
//! statement is the last of its body: followed by an `END_…` keyword (the end of the enclosing
//! statement or POU), `ELSE`, `ELSIF`, `UNTIL`, the next label of a CASE, or the end of the text.
//! Likewise the `;` after a type declaration may be left out before `END_TYPE` (CODESYS writes
//! `END_STRUCT END_TYPE`). Everywhere else a missing `;` is an error.
//!
//! # Refused by name
//!
//! Instruction List bodies, SFC in text form, pointers and references (`REF_TO`, `^`, `ADR`,
//! `REF`, `POINTER TO`), the object-oriented extensions (`METHOD`, `INTERFACE`, `PROPERTY`,
//! `CLASS`, `EXTENDS`, `IMPLEMENTS`), `WSTRING`, `DATE`/`TOD`/`DT`, `JMP` and labels, `CONTINUE`,
//! `VAR_ACCESS`/`VAR_CONFIG`, `R_EDGE`/`F_EDGE`, `ARRAY[*]`: each with a message naming the
//! construct and what to write instead. The base type of an enumeration (`(A, B) INT` as CODESYS
//! writes it, `INT (A := 1, B := 2)` as IEC does) is read and not kept: the tree has no place for
//! it. `VAR_GLOBAL` blocks of a CONFIGURATION and of its RESOURCEs are kept in
//! [`crate::ast::Config::globals`].
//!
//! # Bounds
//!
//! The input cannot choose how deep the parser recurses or how deep a tree it builds:
//!
//! * The text is at most [`MAX_TEXT`] bytes and [`MAX_TOKENS`] tokens, which bounds the work
//!   and the memory: the token list, and a tree of at most a few hundred bytes per token.
//! * The parser recurses only where the grammar nests: parentheses, unary operators, call
//!   arguments, indices, compound statements (IF, CASE, FOR, WHILE, REPEAT), array and structure
//!   initial values, and array types. Each such level counts against one limit,
//!   [`MAX_NESTING`], so the call stack is at most that many levels of about a dozen frames.
//!   Lists (statements, arms, arguments, declarations) and binary chains are loops; precedence
//!   climbing recurses for a right operand at most once per precedence level (seven).
//! * A chain `a + b + …` is a loop in the parser but a left-nested tree as deep as it is long, and
//!   every walk over the tree (type checking, compiling, `Drop`) recurses once per level. So, as
//!   `cetratus_program`'s guard parser does, each subtree's depth is carried up and no expression
//!   node deeper than [`MAX_DEPTH`] is built. A statement tree is at most [`MAX_NESTING`] deep,
//!   and so is an initial value or a type, each holding expressions at most [`MAX_DEPTH`] deep.
//!
//! No `unwrap` on anything from the text; the tests feed truncated and corrupted programs to
//! all three entry points.

mod decl;
mod expr;
mod lit;
mod stmt;
#[cfg(test)]
mod tests;

use crate::ast::{Expr, ExprKind, Ident, Library, Pos, Stmt};
use crate::error::Diagnostic;
use crate::lex::{self, Kw, Tok, Token};

/// Deepest nesting of compound statements, parentheses, unary operators, call arguments,
/// indices, initial values and array types, together; bounds the parser's recursion.
pub const MAX_NESTING: usize = 64;

/// Deepest expression tree, counting every operator, member, index and call: a chain
/// `a + b + …` of n terms is n deep. Bounds the recursion of every walk over an expression.
pub const MAX_DEPTH: usize = 256;

/// Longest text, in bytes.
pub const MAX_TEXT: usize = 8 * 1024 * 1024;

/// Most tokens in a text: about 75,000 lines of typical ST. A token costs 12 bytes in the
/// parser's list and at most a few hundred bytes of tree (an empty statement, the worst, is one
/// `Stmt`), so this also bounds the memory a text can make the parser take.
pub const MAX_TOKENS: usize = 1 << 19;

/// Parses a whole file: any sequence of TYPE blocks, FUNCTIONs, FUNCTION_BLOCKs, PROGRAMs and
/// CONFIGURATIONs.
pub fn parse_library(text: &str) -> Result<Library, Diagnostic> {
    let mut p = Parser::new(text)?;
    p.library()
}

/// Parses a body alone (an SFC action's statements).
pub fn parse_statements(text: &str) -> Result<Vec<Stmt>, Diagnostic> {
    let mut p = Parser::new(text)?;
    let body = p.body()?;
    p.expect_end("a statement")?;
    Ok(body)
}

/// `text`, a statement list that parses ([`parse_statements`]), with the `;` written in that the
/// vendors' form leaves out after its last `END_IF`, `END_CASE`, `END_FOR` or `END_WHILE`
/// (docs/st.md), for a compiler that wants it: what an export writes. A text that ends in `;`
/// comes back as it is.
pub fn terminated(text: &str) -> Result<String, Diagnostic> {
    let lexed = lex::lex(text)?;
    let last = (lexed.tokens.iter().rev()).find(|t| !matches!(t.tok, Tok::End));
    Ok(match last {
        Some(t) if t.tok != Tok::Semi => {
            let end = t.end as usize;
            format!("{};{}", &text[..end], &text[end..])
        }
        _ => text.to_string(),
    })
}

/// Parses an expression alone (a transition's condition).
pub fn parse_expression(text: &str) -> Result<Expr, Diagnostic> {
    let mut p = Parser::new(text)?;
    if p.at(Tok::End) {
        return Err(Diagnostic::new(
            p.pos(),
            "the expression is empty: write a condition such as x > 5",
        ));
    }
    let (e, _) = p.expr()?;
    p.expect_end("an operator")?;
    Ok(e)
}

/// Instruction List, refused.
pub(crate) const IL: &str = "Instruction List (IL) is not supported: the 3rd edition of IEC 61131-3 deprecates it; rewrite the POU in ST";
/// SFC in text form, refused.
pub(crate) const SFC: &str = "Sequential Function Chart (SFC) in text form (INITIAL_STEP, STEP, TRANSITION, ACTION) is not supported: import the chart from PLCopen XML (cetratus import plcopen, docs/sfc.md), where its action bodies and conditions are ST";
/// Pointers and references, refused.
pub(crate) const POINTERS: &str = "pointers and references (REF_TO, ^, ADR, REF, POINTER TO) are not supported: reach data by its name, and pass a variable that a function block must change as VAR_IN_OUT";
/// Object-oriented extensions, refused.
pub(crate) const OOP: &str = "object-oriented extensions (METHOD, PROPERTY, INTERFACE, CLASS, EXTENDS, IMPLEMENTS) are not supported: write a method as a FUNCTION or a FUNCTION_BLOCK of its own and call it";
/// WSTRING, refused.
pub(crate) const WSTRING: &str =
    "WSTRING and double-quoted strings are not supported: use STRING and single quotes ('text')";
/// Dates and times of day, refused.
pub(crate) const DATES: &str = "DATE, TIME_OF_DAY (TOD) and DATE_AND_TIME (DT) are not supported: the runtime keeps no calendar time; use TIME (T#…) for durations";
/// Jumps, refused.
pub(crate) const JUMPS: &str =
    "JMP and labels are not supported: write the jump as IF, CASE or a loop with EXIT";

/// A parsed expression and the depth of its tree, carried up so that no node is ever built
/// deeper than [`MAX_DEPTH`].
type Parsed = (Expr, usize);

/// The parser's state: the tokens, where it is, and how deep it has recursed.
struct Parser<'a> {
    text: &'a str,
    toks: Vec<Token>,
    i: usize,
    nesting: usize,
    lex_error: Option<Diagnostic>,
    end: Token,
}

impl<'a> Parser<'a> {
    fn new(text: &'a str) -> Result<Self, Diagnostic> {
        if text.len() > MAX_TEXT {
            return Err(Diagnostic::new(
                0,
                format!(
                    "the text is {} bytes, more than the limit of {MAX_TEXT} bytes; split it into several files",
                    text.len()
                ),
            ));
        }
        let lexed = lex::lex(text)?;
        let len = text.len() as Pos;
        Ok(Parser {
            text,
            toks: lexed.tokens,
            i: 0,
            nesting: 0,
            lex_error: lexed.error,
            end: Token {
                tok: Tok::End,
                pos: len,
                end: len,
            },
        })
    }

    /// The token `k` ahead (`End` past the end).
    fn tok(&self, k: usize) -> Token {
        self.toks.get(self.i + k).copied().unwrap_or(self.end)
    }

    fn peek(&self) -> Tok {
        self.tok(0).tok
    }

    fn peek_at(&self, k: usize) -> Tok {
        self.tok(k).tok
    }

    fn pos(&self) -> Pos {
        self.tok(0).pos
    }

    /// Where the token before this one ends.
    fn prev_end(&self) -> Pos {
        self.i
            .checked_sub(1)
            .and_then(|i| self.toks.get(i))
            .map_or(0, |t| t.end)
    }

    /// Moves past the current token, never past `Error` or `End`.
    fn bump(&mut self) -> Token {
        let t = self.tok(0);
        if !matches!(t.tok, Tok::End | Tok::Error) {
            self.i += 1;
        }
        t
    }

    fn at(&self, tok: Tok) -> bool {
        self.peek() == tok
    }

    fn at_kw(&self, kw: Kw) -> bool {
        self.peek() == Tok::Kw(kw)
    }

    fn eat(&mut self, tok: Tok) -> bool {
        let here = self.at(tok);
        if here {
            self.bump();
        }
        here
    }

    fn eat_kw(&mut self, kw: Kw) -> bool {
        self.eat(Tok::Kw(kw))
    }

    /// The text of a token.
    fn text_of(&self, t: Token) -> &'a str {
        self.text.get(t.pos as usize..t.end as usize).unwrap_or("")
    }

    /// Whether the token `k` ahead is the (non-keyword) name `word`, in any case.
    fn at_word(&self, k: usize, word: &str) -> bool {
        let t = self.tok(k);
        t.tok == Tok::Ident && self.text_of(t).eq_ignore_ascii_case(word)
    }

    fn ident_of(&self, t: Token) -> Ident {
        Ident {
            text: self.text_of(t).to_string(),
            pos: t.pos,
        }
    }

    fn expect(&mut self, tok: Tok, what: &str) -> Result<Token, Diagnostic> {
        if self.at(tok) {
            Ok(self.bump())
        } else {
            Err(self.unexpected(what))
        }
    }

    fn expect_kw(&mut self, kw: Kw, what: &str) -> Result<Token, Diagnostic> {
        self.expect(Tok::Kw(kw), what)
    }

    fn expect_end(&mut self, what: &str) -> Result<(), Diagnostic> {
        if self.at(Tok::End) {
            Ok(())
        } else {
            Err(self.unexpected(&format!("{what} or the end of the text")))
        }
    }

    /// A name (not a keyword).
    fn name(&mut self, what: &str) -> Result<Ident, Diagnostic> {
        let t = self.expect(Tok::Ident, what)?;
        Ok(self.ident_of(t))
    }

    /// A token as a message shows it.
    fn describe(&self, t: Token) -> String {
        match t.tok {
            Tok::End => "the end of the text".to_string(),
            _ => {
                let text = self.text_of(t);
                match text.char_indices().nth(32) {
                    Some((cut, _)) => format!("'{}…'", &text[..cut]),
                    None => format!("'{text}'"),
                }
            }
        }
    }

    /// The error for the current token where `expected` was: the lexer's error if lexing stopped
    /// here, a refusal if the token starts a construct refused by name, otherwise "expected …,
    /// found …".
    fn unexpected(&self, expected: &str) -> Diagnostic {
        if self.at(Tok::Error) {
            if let Some(e) = &self.lex_error {
                return e.clone();
            }
        }
        if let Some(refused) = self.refusal() {
            return refused;
        }
        Diagnostic::new(
            self.pos(),
            format!("expected {expected}, found {}", self.describe(self.tok(0))),
        )
    }

    /// The refusal for a construct that starts at the current token, if it is one refused by
    /// name.
    fn refusal(&self) -> Option<Diagnostic> {
        let t = self.tok(0);
        let message = match t.tok {
            Tok::Caret => POINTERS,
            Tok::Kw(kw) => match kw {
                Kw::RefTo => POINTERS,
                Kw::Method
                | Kw::EndMethod
                | Kw::Interface
                | Kw::EndInterface
                | Kw::Extends
                | Kw::Implements
                | Kw::Property
                | Kw::EndProperty
                | Kw::Class
                | Kw::EndClass => OOP,
                Kw::InitialStep | Kw::EndStep | Kw::EndTransition | Kw::EndAction => SFC,
                Kw::Jmp => JUMPS,
                Kw::Continue => "CONTINUE is not supported: guard the rest of the loop's body with IF",
                Kw::Wstring => WSTRING,
                Kw::VarAccess | Kw::VarConfig => {
                    "VAR_ACCESS and VAR_CONFIG are not supported: declare the variables in VAR_GLOBAL and reach them with VAR_EXTERNAL"
                }
                _ => return None,
            },
            // The next token first: it rules out nearly every name without comparing words.
            Tok::Ident => match self.peek_at(1) {
                Tok::Kw(Kw::To) if self.at_word(0, "POINTER") => POINTERS,
                Tok::LParen if self.at_word(0, "ADR") || self.at_word(0, "REF") => POINTERS,
                Tok::LParen if self.at_word(0, "TRANSITION") => SFC,
                Tok::Ident
                    if ["STEP", "ACTION", "TRANSITION"]
                        .iter()
                        .any(|w| self.at_word(0, w)) =>
                {
                    SFC
                }
                _ => return None,
            },
            _ => return None,
        };
        Some(Diagnostic::new(t.pos, message))
    }

    /// Runs `f` one nesting level deeper, refusing past [`MAX_NESTING`].
    fn nested<T>(
        &mut self,
        f: impl FnOnce(&mut Self) -> Result<T, Diagnostic>,
    ) -> Result<T, Diagnostic> {
        if self.nesting >= MAX_NESTING {
            return Err(Diagnostic::new(
                self.pos(),
                format!(
                    "nested too deeply: more than {MAX_NESTING} levels (the limit) of statements, parentheses, unary operators, arguments, indices, initial values or array types; move the inner part into a variable or a FUNCTION"
                ),
            ));
        }
        self.nesting += 1;
        let r = f(self);
        self.nesting -= 1;
        r
    }

    /// An expression node over subtrees at most `below` deep, refused when it would be deeper
    /// than [`MAX_DEPTH`]; `pos` is where the error points.
    fn node(&self, kind: ExprKind, pos: Pos, below: usize) -> Result<Parsed, Diagnostic> {
        let depth = below + 1;
        if depth > MAX_DEPTH {
            return Err(Diagnostic::new(
                pos,
                format!(
                    "the expression is too deep: more than {MAX_DEPTH} levels, the limit (a chain such as a + b + … is one level deeper per term); group a long chain with parentheses, as in (a + b) + (c + d), or compute it in several assignments"
                ),
            ));
        }
        Ok((Expr { kind, pos }, depth))
    }

    /// Whether the token `k` ahead starts an Instruction List instruction: a mnemonic followed
    /// by an operand (no ST statement has a name followed by a name or a literal), or an
    /// operand-less one (`RET`, `NOT`) alone on its line.
    fn il_at(&self, k: usize) -> bool {
        const MNEMONICS: [&str; 31] = [
            "LD", "LDN", "ST", "STN", "S", "R", "S1", "R1", "ANDN", "ORN", "XORN", "ADD", "SUB",
            "MUL", "DIV", "GT", "GE", "EQ", "NE", "LE", "LT", "JMPC", "JMPCN", "CAL", "CALC",
            "CALCN", "RET", "RETC", "RETCN", "CLK", "PT",
        ];
        let t = self.tok(k);
        let next = self.tok(k + 1);
        let operand = matches!(
            next.tok,
            Tok::Ident
                | Tok::Int
                | Tok::Real
                | Tok::Time
                | Tok::Str
                | Tok::Typed
                | Tok::Address
                | Tok::Kw(Kw::True | Kw::False)
        );
        // The next token first: after a name, it is nearly always ':=', '(', '.' or '['.
        if operand {
            return match t.tok {
                Tok::Ident => {
                    let w = self.text_of(t);
                    MNEMONICS.iter().any(|m| m.eq_ignore_ascii_case(w))
                }
                Tok::Kw(kw) => matches!(kw, Kw::And | Kw::Or | Kw::Xor | Kw::Not | Kw::Mod),
                _ => false,
            };
        }
        let operandless = t.tok == Tok::Kw(Kw::Not)
            || t.tok == Tok::Ident
                && ["RET", "RETC", "RETCN"]
                    .iter()
                    .any(|m| m.eq_ignore_ascii_case(self.text_of(t)));
        let gap = self
            .text
            .get(t.end as usize..next.pos as usize)
            .unwrap_or("");
        operandless && (next.tok == Tok::End || gap.contains('\n'))
    }
}
