//! The recursive-descent guard parser.
//!
//! Every walk over a guard's tree (the type checker and compiler, the printer, `Clone`,
//! `PartialEq`, `Drop`) recurses once per level, so the parser bounds the tree: at most
//! [`MAX_TOKENS`] tokens, and at most [`MAX_DEPTH`] levels counting every operator, since a flat
//! chain `a && b && …` parses into a left-nested tree as deep as it is long. Its own recursion is
//! bounded by [`MAX_NESTING`]: binary chains are loops, only parentheses, unary operators and
//! calls recurse.
//!
//! ```text
//! expr    := and ( "||" and )*
//! and     := cmp ( "&&" cmp )*
//! cmp     := sum ( ("=="|"!="|"<"|"<="|">"|">=") sum )?
//! sum     := product ( ("+"|"-") product )*
//! product := unary ( ("*"|"/") unary )*
//! unary   := ("!"|"-") unary | atom
//! atom    := "true" | "false" | INT | REAL | DURATION
//!          | NAME "." ("t" | "dwell") | "t" "(" NAME ")" | "rise" "(" NAME ")" | "fall" "(" NAME ")"
//!          | "real" "(" expr ")" | "int" "(" expr ")" | NAME | "(" expr ")"
//! ```

use super::ast::{BinOp, Expr, ExprKind, Func, UnOp};
use super::lexer::{lex_at_most, Tok, Token};
use super::SyntaxError;

/// Deepest nesting of parentheses, unary operators and calls the parser accepts; keeps its
/// recursion bounded whatever the input.
pub const MAX_NESTING: usize = 48;

/// Most tokens (names, numbers, operators, parentheses) a guard may have.
pub const MAX_TOKENS: usize = 1024;

/// Deepest syntax tree a guard may have ([`Expr::nesting`]): every operator counts, so a chain
/// `a && b && …` of n terms is n deep. The compiler's frame is about 5 KB in a debug build, so
/// this keeps a guard's compilation under 1 MB of stack, half of what a thread gets by default.
pub const MAX_DEPTH: usize = 128;

/// A parsed subtree and its depth ([`Expr::nesting`]), carried up so that no node is ever built
/// deeper than [`MAX_DEPTH`].
type Parsed = (Expr, usize);

/// Parses a guard.
pub fn parse(src: &str) -> Result<Expr, SyntaxError> {
    let toks = lex_at_most(src, MAX_TOKENS)?;
    let mut p = Parser {
        toks,
        i: 0,
        depth: 0,
    };
    if p.peek() == &Tok::End {
        return Err(SyntaxError::new(0, "empty guard; write a condition such as `PE` or `B > 0`, or leave the transition without a guard"));
    }
    let (e, _) = p.expr()?;
    match p.peek() {
        Tok::End => Ok(e),
        Tok::Assign => Err(p.error_here("`=` is not a comparison; use `==`")),
        other => {
            let msg = format!(
                "unexpected {}; expected an operator or the end of the guard",
                other.describe()
            );
            Err(p.error_here(msg))
        }
    }
}

struct Parser {
    toks: Vec<Token>,
    i: usize,
    depth: usize,
}

impl Parser {
    fn peek(&self) -> &Tok {
        // The lexer always ends the list with `End`, and `bump` never moves past it.
        &self.toks[self.i.min(self.toks.len() - 1)].kind
    }

    fn offset(&self) -> usize {
        self.toks[self.i.min(self.toks.len() - 1)].offset
    }

    fn bump(&mut self) -> Token {
        let t = self.toks[self.i.min(self.toks.len() - 1)].clone();
        if self.i < self.toks.len() - 1 {
            self.i += 1;
        }
        t
    }

    fn error_here(&self, msg: impl Into<String>) -> SyntaxError {
        SyntaxError::new(self.offset(), msg)
    }

    fn expect(&mut self, tok: Tok, what: &str) -> Result<(), SyntaxError> {
        if *self.peek() == tok {
            self.bump();
            Ok(())
        } else {
            let msg = format!("expected {what}, found {}", self.peek().describe());
            Err(self.error_here(msg))
        }
    }

    fn enter(&mut self) -> Result<(), SyntaxError> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            return Err(self.error_here(format!(
                "guard nested too deeply (more than {MAX_NESTING} levels); split it or simplify it"
            )));
        }
        Ok(())
    }

    /// A node over a subtree of depth `below`, refused when it would be deeper than
    /// [`MAX_DEPTH`]; `pos` is the node's operator, where the error points.
    fn node(&self, kind: ExprKind, pos: usize, below: usize) -> Result<Parsed, SyntaxError> {
        let depth = below + 1;
        if depth > MAX_DEPTH {
            return Err(SyntaxError::new(
                pos,
                format!(
                    "the expression is too deep: more than {MAX_DEPTH} levels, the limit (a chain such as `a && b && …` is one level deeper per term); group a long chain with parentheses, as in `(a && b) && (c && d)`, or spread the condition over more transitions"
                ),
            ));
        }
        Ok((Expr { kind, pos }, depth))
    }

    fn binary_level(
        &mut self,
        next: fn(&mut Parser) -> Result<Parsed, SyntaxError>,
        op_of: fn(&Tok) -> Option<BinOp>,
        chain: bool,
    ) -> Result<Parsed, SyntaxError> {
        let mut left = next(self)?;
        while let Some(op) = op_of(self.peek()) {
            let pos = self.bump().offset;
            let right = next(self)?;
            let below = left.1.max(right.1);
            let kind = ExprKind::Binary(op, Box::new(left.0), Box::new(right.0));
            left = self.node(kind, pos, below)?;
            if !chain {
                if op_of(self.peek()).is_some() {
                    return Err(self.error_here(
                        "comparisons do not chain; write `a < b && b < c` instead of `a < b < c`",
                    ));
                }
                break;
            }
        }
        Ok(left)
    }

    fn expr(&mut self) -> Result<Parsed, SyntaxError> {
        self.binary_level(
            Parser::and,
            |t| (*t == Tok::OrOr).then_some(BinOp::Or),
            true,
        )
    }

    fn and(&mut self) -> Result<Parsed, SyntaxError> {
        self.binary_level(
            Parser::cmp,
            |t| (*t == Tok::AndAnd).then_some(BinOp::And),
            true,
        )
    }

    fn cmp(&mut self) -> Result<Parsed, SyntaxError> {
        self.binary_level(
            Parser::sum,
            |t| match t {
                Tok::EqEq => Some(BinOp::Eq),
                Tok::NotEq => Some(BinOp::Ne),
                Tok::Lt => Some(BinOp::Lt),
                Tok::Le => Some(BinOp::Le),
                Tok::Gt => Some(BinOp::Gt),
                Tok::Ge => Some(BinOp::Ge),
                _ => None,
            },
            false,
        )
    }

    fn sum(&mut self) -> Result<Parsed, SyntaxError> {
        self.binary_level(
            Parser::product,
            |t| match t {
                Tok::Plus => Some(BinOp::Add),
                Tok::Minus => Some(BinOp::Sub),
                _ => None,
            },
            true,
        )
    }

    fn product(&mut self) -> Result<Parsed, SyntaxError> {
        self.binary_level(
            Parser::unary,
            |t| match t {
                Tok::Star => Some(BinOp::Mul),
                Tok::Slash => Some(BinOp::Div),
                _ => None,
            },
            true,
        )
    }

    fn unary(&mut self) -> Result<Parsed, SyntaxError> {
        let op = match self.peek() {
            Tok::Bang => UnOp::Not,
            Tok::Minus => UnOp::Neg,
            _ => return self.atom(),
        };
        self.enter()?;
        let pos = self.bump().offset;
        let (e, below) = self.unary()?;
        self.depth -= 1;
        self.node(ExprKind::Unary(op, Box::new(e)), pos, below)
    }

    fn name_arg(&mut self, func: &str) -> Result<String, SyntaxError> {
        self.expect(Tok::LParen, &format!("`(` after `{func}`"))?;
        let name = match self.peek() {
            Tok::Ident(n) => n.clone(),
            other => {
                let msg = format!(
                    "expected a name inside `{func}(…)`, found {}",
                    other.describe()
                );
                return Err(self.error_here(msg));
            }
        };
        self.bump();
        self.expect(Tok::RParen, &format!("`)` to close `{func}(`"))?;
        Ok(name)
    }

    fn atom(&mut self) -> Result<Parsed, SyntaxError> {
        let pos = self.offset();
        let tok = self.bump();
        let kind = match tok.kind {
            Tok::Int(i) => ExprKind::Int(i),
            Tok::Real(r) => ExprKind::Real(r),
            Tok::Duration(d) => ExprKind::Duration(d),
            Tok::LParen => {
                self.enter()?;
                let e = self.expr()?;
                self.depth -= 1;
                self.expect(Tok::RParen, "`)`")?;
                // Parentheses leave no trace in the tree.
                return Ok(e);
            }
            Tok::Ident(name) => {
                let call = *self.peek() == Tok::LParen;
                match name.as_str() {
                    "true" => ExprKind::Bool(true),
                    "false" => ExprKind::Bool(false),
                    "t" if call => ExprKind::Timer(self.name_arg("t")?),
                    "rise" if call => ExprKind::Rise(self.name_arg("rise")?),
                    "fall" if call => ExprKind::Fall(self.name_arg("fall")?),
                    "real" | "int" if call => {
                        let func = if name == "real" { Func::Real } else { Func::Int };
                        self.bump();
                        self.enter()?;
                        let (e, below) = self.expr()?;
                        self.depth -= 1;
                        self.expect(Tok::RParen, &format!("`)` to close `{name}(`"))?;
                        return self.node(ExprKind::Call(func, Box::new(e)), pos, below);
                    }
                    _ if call => {
                        return Err(SyntaxError::new(
                            pos,
                            format!("unknown function `{name}`; the functions are rise, fall, t, real and int"),
                        ))
                    }
                    _ if *self.peek() == Tok::Dot => {
                        self.bump();
                        match self.peek() {
                            Tok::Ident(t) if t == "t" => {
                                self.bump();
                                ExprKind::Timer(name)
                            }
                            Tok::Ident(t) if t == "dwell" => {
                                self.bump();
                                ExprKind::Dwell(name)
                            }
                            other => {
                                let msg = format!(
                                    "expected `t` or `dwell` after `{name}.` (the place timer `{name}.t`), found {}",
                                    other.describe()
                                );
                                return Err(self.error_here(msg));
                            }
                        }
                    }
                    _ => ExprKind::Name(name),
                }
            }
            other => {
                return Err(SyntaxError::new(
                    pos,
                    format!(
                        "expected a value (a name, a number, a duration, `true`, `false` or `(`), found {}",
                        other.describe()
                    ),
                ))
            }
        };
        Ok((Expr { kind, pos }, 1))
    }
}
