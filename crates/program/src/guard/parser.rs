//! The recursive-descent guard parser.
//!
//! ```text
//! expr    := and ( "||" and )*
//! and     := cmp ( "&&" cmp )*
//! cmp     := sum ( ("=="|"!="|"<"|"<="|">"|">=") sum )?
//! sum     := product ( ("+"|"-") product )*
//! product := unary ( ("*"|"/") unary )*
//! unary   := ("!"|"-") unary | atom
//! atom    := "true" | "false" | INT | REAL | DURATION
//!          | NAME "." "t" | "t" "(" NAME ")" | "rise" "(" NAME ")" | "fall" "(" NAME ")"
//!          | "real" "(" expr ")" | "int" "(" expr ")" | NAME | "(" expr ")"
//! ```

use super::ast::{BinOp, Expr, ExprKind, Func, UnOp};
use super::lexer::{lex, Tok, Token};
use super::SyntaxError;

/// Deepest nesting of parentheses, unary operators and calls the parser accepts; keeps its
/// recursion bounded whatever the input.
pub const MAX_NESTING: usize = 48;

/// Parses a guard.
pub fn parse(src: &str) -> Result<Expr, SyntaxError> {
    let toks = lex(src)?;
    let mut p = Parser {
        toks,
        i: 0,
        depth: 0,
    };
    if p.peek() == &Tok::End {
        return Err(SyntaxError::new(0, "empty guard; write a condition such as `PE` or `B > 0`, or leave the transition without a guard"));
    }
    let e = p.expr()?;
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

    fn binary_level(
        &mut self,
        next: fn(&mut Parser) -> Result<Expr, SyntaxError>,
        op_of: fn(&Tok) -> Option<BinOp>,
        chain: bool,
    ) -> Result<Expr, SyntaxError> {
        let mut left = next(self)?;
        while let Some(op) = op_of(self.peek()) {
            let pos = self.bump().offset;
            let right = next(self)?;
            left = Expr {
                kind: ExprKind::Binary(op, Box::new(left), Box::new(right)),
                pos,
            };
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

    fn expr(&mut self) -> Result<Expr, SyntaxError> {
        self.binary_level(
            Parser::and,
            |t| (*t == Tok::OrOr).then_some(BinOp::Or),
            true,
        )
    }

    fn and(&mut self) -> Result<Expr, SyntaxError> {
        self.binary_level(
            Parser::cmp,
            |t| (*t == Tok::AndAnd).then_some(BinOp::And),
            true,
        )
    }

    fn cmp(&mut self) -> Result<Expr, SyntaxError> {
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

    fn sum(&mut self) -> Result<Expr, SyntaxError> {
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

    fn product(&mut self) -> Result<Expr, SyntaxError> {
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

    fn unary(&mut self) -> Result<Expr, SyntaxError> {
        let op = match self.peek() {
            Tok::Bang => UnOp::Not,
            Tok::Minus => UnOp::Neg,
            _ => return self.atom(),
        };
        self.enter()?;
        let pos = self.bump().offset;
        let e = self.unary()?;
        self.depth -= 1;
        Ok(Expr {
            kind: ExprKind::Unary(op, Box::new(e)),
            pos,
        })
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

    fn atom(&mut self) -> Result<Expr, SyntaxError> {
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
                        let e = self.expr()?;
                        self.depth -= 1;
                        self.expect(Tok::RParen, &format!("`)` to close `{name}(`"))?;
                        ExprKind::Call(func, Box::new(e))
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
                            other => {
                                let msg = format!(
                                    "expected `t` after `{name}.` (the place timer `{name}.t`), found {}",
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
        Ok(Expr { kind, pos })
    }
}
