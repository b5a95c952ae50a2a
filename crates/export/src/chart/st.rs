//! A chart's conditions and action bodies in the Structured Text that the SFC importer reads
//! (docs/sfc.md, *The Structured Text subset*): a step's activity as `Step.X`, its time as
//! `Step.T`, and only the parentheses that IEC's precedence needs, so that a long chain of
//! `AND` stays one level deep for the importer's nesting limit. Recursion follows the guard
//! tree, whose depth the guard parser bounds (128 levels).

use std::collections::HashMap;
use std::fmt::Write as _;

use cetratus_program::guard::{BinOp, Expr, ExprKind, UnOp};
use cetratus_program::Statement;

/// The steps, by place id, with the name a condition reads them by (a nested chart's own steps
/// by their name in it): a name among them reads the step.
pub(crate) struct Steps<'p>(pub(crate) HashMap<&'p str, String>);

impl Steps<'_> {
    /// The step whose activity `P > 0` reads, which the importer reads from `P.X`.
    fn active(&self, op: BinOp, l: &Expr, r: &Expr) -> Option<&str> {
        match (op, &l.kind, &r.kind) {
            (BinOp::Gt, ExprKind::Name(p), ExprKind::Int(0)) => {
                self.0.get(p.as_str()).map(|s| s.as_str())
            }
            _ => None,
        }
    }

    /// IEC binding strength, loosest first, as the importer's parser reads it.
    fn precedence(&self, e: &Expr) -> u8 {
        match &e.kind {
            ExprKind::Binary(op, l, r) if self.active(*op, l, r).is_some() => 8,
            ExprKind::Binary(op, ..) => binary_precedence(*op),
            ExprKind::Unary(..) => 7,
            _ => 8,
        }
    }
}

fn binary_precedence(op: BinOp) -> u8 {
    match op {
        BinOp::Or => 0,
        BinOp::And => 2,
        BinOp::Eq | BinOp::Ne => 3,
        BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => 4,
        BinOp::Add | BinOp::Sub => 5,
        BinOp::Mul | BinOp::Div => 6,
    }
}

impl Steps<'_> {
    /// A condition or a value in the importer's ST; an error names what the subset lacks.
    pub(crate) fn expr(&self, e: &Expr) -> Result<String, String> {
        let mut s = String::new();
        self.write(&mut s, e)?;
        Ok(s)
    }

    fn write(&self, s: &mut String, e: &Expr) -> Result<(), String> {
        match &e.kind {
            ExprKind::Bool(b) => s.push_str(if *b { "TRUE" } else { "FALSE" }),
            ExprKind::Int(i) => {
                let _ = write!(s, "{i}");
            }
            ExprKind::Real(r) => s.push_str(&crate::expr::real_literal(*r)),
            ExprKind::Duration(us) => s.push_str(&crate::expr::time_literal(*us)),
            ExprKind::Name(n) if self.0.contains_key(n.as_str()) => {
                return Err(format!(
                    "the token count of step `{n}` (a chart reads `{n}.X`)"
                ))
            }
            ExprKind::Name(n) => s.push_str(n),
            ExprKind::Dwell(p) if self.0.contains_key(p.as_str()) => {
                let _ = write!(s, "{}.T", self.0[p.as_str()]);
            }
            ExprKind::Binary(op, l, r) => {
                if let Some(p) = self.active(*op, l, r) {
                    let _ = write!(s, "{p}.X");
                    return Ok(());
                }
                let word = match op {
                    BinOp::Or => "OR",
                    BinOp::And => "AND",
                    BinOp::Eq => "=",
                    BinOp::Ne => "<>",
                    other => other.symbol(),
                };
                let own = self.precedence(e);
                self.operand(s, l, self.precedence(l) < own)?;
                let _ = write!(s, " {word} ");
                self.operand(s, r, self.precedence(r) <= own)?;
            }
            ExprKind::Unary(op, x) => {
                s.push_str(match op {
                    UnOp::Not => "NOT ",
                    UnOp::Neg => "-",
                });
                self.operand(s, x, self.precedence(x) <= 7)?;
            }
            ExprKind::Timer(_) | ExprKind::Dwell(_) => {
                return Err(format!("`{e}` (a chart reads a step's time as `Step.T`)"))
            }
            ExprKind::Rise(_) | ExprKind::Fall(_) | ExprKind::Call(..) => {
                return Err(format!("`{e}`, which the chart's ST subset does not have"))
            }
        }
        Ok(())
    }

    fn operand(&self, s: &mut String, e: &Expr, parens: bool) -> Result<(), String> {
        if parens {
            s.push('(');
        }
        self.write(s, e)?;
        if parens {
            s.push(')');
        }
        Ok(())
    }

    /// An action body's statements as ST, indented by their nesting.
    pub(crate) fn body(&self, statements: &[Statement]) -> Result<String, String> {
        let mut out = String::new();
        let mut depth = 0usize;
        for st in statements {
            let (line, inner) = match st {
                Statement::Assign { name, expr, .. } => {
                    (format!("{name} := {};", self.expr(expr)?), depth)
                }
                Statement::If(c) => {
                    depth += 1;
                    (format!("IF {} THEN", self.expr(c)?), depth - 1)
                }
                Statement::Elif(c) => (
                    format!("ELSIF {} THEN", self.expr(c)?),
                    depth.saturating_sub(1),
                ),
                Statement::Else => ("ELSE".into(), depth.saturating_sub(1)),
                Statement::End => {
                    depth = depth.saturating_sub(1);
                    ("END_IF;".into(), depth)
                }
            };
            let _ = writeln!(out, "{:w$}{line}", "", w = inner * 2);
        }
        Ok(out)
    }
}
