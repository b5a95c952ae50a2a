//! Expressions, variables and calls.
//!
//! ```text
//! expr     := power ( binop power )*     (by precedence climbing, Table 71 below)
//! binop    := "OR" | "XOR" | "AND" | "&" | "=" | "<>" | "<" | ">" | "<=" | ">="
//!           | "+" | "-" | "*" | "/" | "MOD"
//! power    := unary ( "**" unary )*
//! unary    := ("-" | "+" | "NOT") unary | primary
//! primary  := literal | "(" expr ")" | variable
//! variable := NAME ( "." NAME | "[" expr ("," expr)* "]" | "(" args ")" )*
//! args     := ( arg ("," arg)* )?
//! arg      := NAME ":=" expr | "NOT"? NAME "=>" variable | expr
//! ```
//!
//! | precedence | operators |
//! |---|---|
//! | 7 | `*`, `/`, `MOD` |
//! | 6 | `+`, `-` |
//! | 5 | `<`, `>`, `<=`, `>=` |
//! | 4 | `=`, `<>` |
//! | 3 | `AND`, `&` |
//! | 2 | `XOR` |
//! | 1 | `OR` |

use super::{lit, Parsed, Parser};
use crate::ast::{Arg, BinOp, Call, Expr, ExprKind, Ident, Literal, Pos, Rel, UnOp};
use crate::error::Diagnostic;
use crate::lex::{Kw, Tok};

impl Parser<'_> {
    /// An expression.
    pub(super) fn expr(&mut self) -> Result<Parsed, Diagnostic> {
        self.binary(0)
    }

    /// Binary operators by precedence climbing: a loop over the operators that bind at least
    /// as strongly as `min`, each right operand parsed one level stronger so that the chain is
    /// left-associative. The recursion for a right operand is at most one call per precedence
    /// level (seven), and every node's depth is checked.
    fn binary(&mut self, min: u8) -> Result<Parsed, Diagnostic> {
        let mut left = self.power()?;
        while let Some((op, precedence)) = binary_op(self.peek()) {
            if precedence < min {
                break;
            }
            let pos = self.bump().pos;
            let right = self.binary(precedence + 1)?;
            left = self.binary_node(op, left, right, pos)?;
        }
        Ok(left)
    }

    /// `left op right` at `pos`, a level deeper than the deeper operand.
    fn binary_node(
        &self,
        op: BinOp,
        left: Parsed,
        right: Parsed,
        pos: Pos,
    ) -> Result<Parsed, Diagnostic> {
        let below = left.1.max(right.1);
        let kind = ExprKind::Binary(op, Box::new(left.0), Box::new(right.0));
        self.node(kind, pos, below)
    }

    /// `**` chains, refusing the operand with a unary operator that the standard reads two ways
    /// (the module doc).
    fn power(&mut self) -> Result<Parsed, Diagnostic> {
        let mut signed = self.at_unary().then(|| self.pos());
        let mut left = self.unary()?;
        while self.at(Tok::Power) {
            if let Some(at) = signed {
                return Err(Diagnostic::new(
                    at,
                    "a unary operator before an operand of '**' is ambiguous: IEC 61131-3 Table 71 reads -a ** b as -(a ** b), its grammar and MATIEC as (-a) ** b; write the one you mean with parentheses",
                ));
            }
            let pos = self.bump().pos;
            signed = self.at_unary().then(|| self.pos());
            let right = self.unary()?;
            left = self.binary_node(BinOp::Pow, left, right, pos)?;
        }
        Ok(left)
    }

    fn at_unary(&self) -> bool {
        matches!(self.peek(), Tok::Minus | Tok::Plus | Tok::Kw(Kw::Not))
    }

    fn unary(&mut self) -> Result<Parsed, Diagnostic> {
        let op = match self.peek() {
            Tok::Minus => Some(UnOp::Neg),
            Tok::Kw(Kw::Not) => Some(UnOp::Not),
            Tok::Plus => None,
            _ => return self.primary(),
        };
        self.nested(|p| {
            let pos = p.bump().pos;
            let (operand, below) = p.unary()?;
            match op {
                Some(op) => p.node(ExprKind::Unary(op, Box::new(operand)), pos, below),
                // Unary plus leaves no trace in the tree.
                None => Ok((operand, below)),
            }
        })
    }

    fn primary(&mut self) -> Result<Parsed, Diagnostic> {
        let t = self.tok(0);
        let text = self.text_of(t);
        let lit = match t.tok {
            Tok::Int => Literal::Int {
                value: lit::int(text, t.pos)?,
                ty: None,
            },
            Tok::Real => Literal::Real {
                value: lit::real(text, t.pos)?,
                ty: None,
            },
            Tok::Time => Literal::Time(lit::time(text, t.pos)?),
            Tok::Str => Literal::String(lit::string(text)),
            Tok::Typed => lit::typed(text, t.pos)?,
            Tok::Kw(Kw::True) => Literal::Bool(true),
            Tok::Kw(Kw::False) => Literal::Bool(false),
            Tok::Kw(Kw::And | Kw::Or | Kw::Xor | Kw::Mod) if self.tok(1).tok == Tok::LParen => {
                return self.operator_call();
            }
            Tok::Ident => {
                if let Some(refused) = self.refusal() {
                    return Err(refused);
                }
                return self.variable("a variable");
            }
            Tok::LParen => {
                return self.nested(|p| {
                    p.bump();
                    let e = p.expr()?;
                    p.expect(Tok::RParen, "')' to close the parenthesis")?;
                    // Parentheses leave no trace in the tree.
                    Ok(e)
                })
            }
            Tok::Address => {
                return Err(Diagnostic::new(
                    t.pos,
                    "a direct address cannot be used in a statement: declare a variable at it (x AT %IX0.0 : BOOL) and use its name",
                ))
            }
            _ => return Err(self.unexpected("an expression")),
        };
        self.bump();
        Ok((
            Expr {
                kind: ExprKind::Lit(lit),
                pos: t.pos,
            },
            1,
        ))
    }

    /// A name and its members, indices and call: what can be assigned to, called, or read.
    pub(super) fn variable(&mut self, what: &str) -> Result<Parsed, Diagnostic> {
        let name = self.name(what)?;
        self.variable_from(name)
    }

    /// An operator called as the function IEC 61131-3 also makes it (`AND(a, b, c)`,
    /// `MOD(a, b)`): its keyword read as the function's name.
    fn operator_call(&mut self) -> Result<Parsed, Diagnostic> {
        let t = self.bump();
        let name = self.ident_of(t);
        self.variable_from(name)
    }

    /// [`Parser::variable`] once its name is read.
    fn variable_from(&mut self, name: Ident) -> Result<Parsed, Diagnostic> {
        let pos = name.pos;
        let mut e = (
            Expr {
                kind: ExprKind::Name(name),
                pos,
            },
            1,
        );
        loop {
            let called = matches!(e.0.kind, ExprKind::Call(_));
            match self.peek() {
                Tok::Dot | Tok::LBracket | Tok::LParen if called => {
                    return Err(Diagnostic::new(
                        self.pos(),
                        "a call's result cannot be followed by '.', '[' or '(': call the function block first, then read its outputs (inst(…); x := inst.Q;)",
                    ))
                }
                Tok::Dot => {
                    self.bump();
                    if self.at(Tok::Int) {
                        return Err(Diagnostic::new(
                            self.pos(),
                            "bit access (x.3) is not supported: test the bit with a mask, as (x AND 16#08) <> 0",
                        ));
                    }
                    let member = self.name("a member name after '.'")?;
                    e = self.node(ExprKind::Member(Box::new(e.0), member), pos, e.1)?;
                }
                Tok::LBracket => {
                    let (indices, below) = self.nested(Parser::indices)?;
                    e = self.node(
                        ExprKind::Index(Box::new(e.0), indices),
                        pos,
                        e.1.max(below),
                    )?;
                }
                Tok::LParen => {
                    let (args, below) = self.nested(Parser::args)?;
                    let call = Call {
                        callee: e.0,
                        args,
                        pos,
                    };
                    e = self.node(ExprKind::Call(Box::new(call)), pos, e.1.max(below))?;
                }
                _ => return Ok(e),
            }
        }
    }

    /// `[i, j]`, with the depth of the deepest index.
    fn indices(&mut self) -> Result<(Vec<Expr>, usize), Diagnostic> {
        self.bump();
        let mut indices = Vec::new();
        let mut depth = 0;
        loop {
            let (e, d) = self.expr()?;
            indices.push(e);
            depth = depth.max(d);
            if !self.eat(Tok::Comma) {
                break;
            }
        }
        self.expect(Tok::RBracket, "',' or ']' after the index")?;
        Ok((indices, depth))
    }

    /// `(…)` of a call, with the depth of the deepest argument.
    fn args(&mut self) -> Result<(Vec<Arg>, usize), Diagnostic> {
        self.bump();
        let mut args = Vec::new();
        let mut depth = 0;
        let mut formal: Option<bool> = None;
        if self.eat(Tok::RParen) {
            return Ok((args, depth));
        }
        loop {
            let pos = self.pos();
            let (arg, d) = self.arg()?;
            let is_formal = !matches!(arg, Arg::Positional(_));
            if formal.is_some_and(|f| f != is_formal) {
                return Err(Diagnostic::new(
                    pos,
                    "a call takes either positional arguments, F(a, b), or formal ones, F(IN1 := a, IN2 := b), not both",
                ));
            }
            formal = Some(is_formal);
            args.push(arg);
            depth = depth.max(d);
            if !self.eat(Tok::Comma) {
                break;
            }
        }
        self.expect(Tok::RParen, "',' or ')' after the argument")?;
        Ok((args, depth))
    }

    fn arg(&mut self) -> Result<(Arg, usize), Diagnostic> {
        let negated =
            self.at_kw(Kw::Not) && self.peek_at(1) == Tok::Ident && self.peek_at(2) == Tok::Arrow;
        if negated {
            self.bump();
        }
        if self.at(Tok::Ident) && matches!(self.peek_at(1), Tok::Assign | Tok::Arrow) {
            let t = self.bump();
            let name = self.ident_of(t);
            if self.eat(Tok::Assign) {
                let (value, d) = self.expr()?;
                return Ok((Arg::Input(name, value), d));
            }
            self.bump();
            let what = format!("the variable that receives {} after '=>'", name.text);
            let (target, d) = self.variable(&what)?;
            if matches!(target.kind, ExprKind::Call(_)) {
                return Err(Diagnostic::new(
                    target.pos,
                    format!(
                        "the output {} must go to a variable, not to a call",
                        name.text
                    ),
                ));
            }
            return Ok((
                Arg::Output {
                    name,
                    target,
                    negated,
                },
                d,
            ));
        }
        let (value, d) = self.expr()?;
        Ok((Arg::Positional(value), d))
    }
}

/// The binary operator a token is (`**` aside), with its precedence: higher binds stronger
/// (IEC 61131-3 Table 71).
fn binary_op(t: Tok) -> Option<(BinOp, u8)> {
    Some(match t {
        Tok::Kw(Kw::Or) => (BinOp::Or, 1),
        Tok::Kw(Kw::Xor) => (BinOp::Xor, 2),
        Tok::Kw(Kw::And) | Tok::Amp => (BinOp::And, 3),
        // Equality binds weaker than order (Table 71).
        Tok::Rel(rel @ (Rel::Eq | Rel::Ne)) => (BinOp::Cmp(rel), 4),
        Tok::Rel(rel) => (BinOp::Cmp(rel), 5),
        Tok::Plus => (BinOp::Add, 6),
        Tok::Minus => (BinOp::Sub, 6),
        Tok::Star => (BinOp::Mul, 7),
        Tok::Slash => (BinOp::Div, 7),
        Tok::Kw(Kw::Mod) => (BinOp::Mod, 7),
        _ => return None,
    })
}
