//! Statements.
//!
//! ```text
//! body      := stmt*                      (up to END_…, ELSE, ELSIF, UNTIL or the end)
//! stmt      := ";"
//!            | variable ":=" expr ";"  |  variable "(" args ")" ";"
//!            | "EXIT" ";"  |  "RETURN" ";"
//!            | compound ";"?            (";" may be left out at the end of a body: module doc)
//! compound  := "IF" expr "THEN" body ("ELSIF" expr "THEN" body)* ("ELSE" body)? "END_IF"
//!            | "CASE" expr "OF" (labels ":" body)* ("ELSE" body)? "END_CASE"
//!            | "FOR" NAME ":=" expr "TO" expr ("BY" expr)? "DO" body "END_FOR"
//!            | "WHILE" expr "DO" body "END_WHILE"
//!            | "REPEAT" body "UNTIL" expr "END_REPEAT"
//! labels    := expr (".." expr)? ("," expr (".." expr)?)*
//! ```

use super::{Parser, IL, JUMPS};
use crate::ast::{CaseLabel, ExprKind, Stmt, StmtKind};
use crate::error::Diagnostic;
use crate::lex::{Kw, Tok};

/// Where a body ends, besides `END_…`, `ELSE`, `ELSIF`, `UNTIL` and the end of the text.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum BodyEnd {
    /// Nowhere else.
    Plain,
    /// Also at the next label of a CASE.
    CaseArm,
}

/// Parses a compound statement, its keyword the current token.
type Compound<'a> = fn(&mut Parser<'a>) -> Result<StmtKind, Diagnostic>;

impl<'a> Parser<'a> {
    /// A POU's body or a body alone; an Instruction List body is refused at its first
    /// instruction (or at its first label).
    pub(super) fn body(&mut self) -> Result<Vec<Stmt>, Diagnostic> {
        if self.il_at(0) || self.at(Tok::Ident) && self.peek_at(1) == Tok::Colon && self.il_at(2) {
            return Err(Diagnostic::new(self.pos(), IL));
        }
        self.statements(BodyEnd::Plain)
    }

    fn statements(&mut self, end: BodyEnd) -> Result<Vec<Stmt>, Diagnostic> {
        let mut out = Vec::new();
        while !self.at_body_end(end) {
            out.push(self.statement(end)?);
        }
        Ok(out)
    }

    /// Whether the current token ends a body (the `;` after a compound statement may be left
    /// out here).
    fn at_body_end(&self, end: BodyEnd) -> bool {
        match self.peek() {
            Tok::End => true,
            Tok::Kw(kw) if kw.is_end() || matches!(kw, Kw::Else | Kw::Elsif | Kw::Until) => true,
            _ => end == BodyEnd::CaseArm && self.at_case_label(),
        }
    }

    /// Whether the current token starts a CASE label rather than a statement: a literal or a
    /// sign (no statement starts with one), or a name followed by `:`, `,` or `..`.
    fn at_case_label(&self) -> bool {
        match self.peek() {
            Tok::Int | Tok::Typed | Tok::Minus | Tok::Plus => true,
            Tok::Ident => matches!(self.peek_at(1), Tok::Colon | Tok::Comma | Tok::DotDot),
            _ => false,
        }
    }

    fn statement(&mut self, end: BodyEnd) -> Result<Stmt, Diagnostic> {
        let pos = self.pos();
        let kind = match self.peek() {
            Tok::Semi => {
                self.bump();
                StmtKind::Empty
            }
            Tok::Kw(Kw::If) => return self.compound(end, "END_IF", Parser::if_statement),
            Tok::Kw(Kw::Case) => return self.compound(end, "END_CASE", Parser::case_statement),
            Tok::Kw(Kw::For) => return self.compound(end, "END_FOR", Parser::for_statement),
            Tok::Kw(Kw::While) => return self.compound(end, "END_WHILE", Parser::while_statement),
            Tok::Kw(Kw::Repeat) => {
                return self.compound(end, "END_REPEAT", Parser::repeat_statement)
            }
            Tok::Kw(Kw::Exit) => {
                self.bump();
                self.expect(Tok::Semi, "';' after EXIT")?;
                StmtKind::Exit
            }
            Tok::Kw(Kw::Return) => {
                self.bump();
                self.expect(Tok::Semi, "';' after RETURN")?;
                StmtKind::Return
            }
            Tok::Ident => self.assignment_or_call()?,
            _ if self.il_at(0) => return Err(Diagnostic::new(pos, IL)),
            _ => return Err(self.unexpected("a statement")),
        };
        Ok(Stmt { kind, pos })
    }

    /// A compound statement, and its `;` unless it ends its body.
    fn compound(
        &mut self,
        end: BodyEnd,
        closer: &str,
        f: Compound<'a>,
    ) -> Result<Stmt, Diagnostic> {
        let pos = self.pos();
        let kind = self.nested(f)?;
        if !self.eat(Tok::Semi) && !self.at_body_end(end) {
            return Err(self.unexpected(&format!("';' after {closer}")));
        }
        Ok(Stmt { kind, pos })
    }

    fn assignment_or_call(&mut self) -> Result<StmtKind, Diagnostic> {
        let pos = self.pos();
        if self.il_at(0) {
            return Err(Diagnostic::new(pos, IL));
        }
        if let Some(refused) = self.refusal() {
            return Err(refused);
        }
        if self.peek_at(1) == Tok::Colon {
            let message = if self.il_at(2) { IL } else { JUMPS };
            return Err(Diagnostic::new(pos, message));
        }
        let (target, _) = self.variable("a statement")?;
        if self.at(Tok::Assign) {
            if matches!(target.kind, ExprKind::Call(_)) {
                return Err(Diagnostic::new(
                    self.pos(),
                    "a call cannot be assigned to: assign to a variable, or read the call's outputs after it (inst(…); x := inst.Q;)",
                ));
            }
            self.bump();
            let (value, _) = self.expr()?;
            self.expect(Tok::Semi, "';' after the assignment")?;
            return Ok(StmtKind::Assign { target, value });
        }
        match target.kind {
            ExprKind::Call(call) => {
                self.expect(Tok::Semi, "';' after the call")?;
                Ok(StmtKind::Call(*call))
            }
            _ => {
                let written = self.text.get(pos as usize..self.prev_end() as usize);
                Err(self.unexpected(&format!(
                    "':=' (an assignment) or '(' (a call) after '{}'",
                    written.unwrap_or("")
                )))
            }
        }
    }

    fn if_statement(&mut self) -> Result<StmtKind, Diagnostic> {
        self.bump();
        let mut arms = Vec::new();
        loop {
            let (cond, _) = self.expr()?;
            self.expect_kw(Kw::Then, "THEN after the condition")?;
            let body = self.statements(BodyEnd::Plain)?;
            arms.push((cond, body));
            if !self.eat_kw(Kw::Elsif) {
                break;
            }
        }
        let otherwise = if self.eat_kw(Kw::Else) {
            self.statements(BodyEnd::Plain)?
        } else {
            Vec::new()
        };
        self.expect_kw(Kw::EndIf, "END_IF to close the IF")?;
        Ok(StmtKind::If { arms, otherwise })
    }

    fn case_statement(&mut self) -> Result<StmtKind, Diagnostic> {
        self.bump();
        let (selector, _) = self.expr()?;
        self.expect_kw(Kw::Of, "OF after the CASE selector")?;
        let mut arms = Vec::new();
        // Up to ELSE or END_CASE; any other end is reported as a missing END_CASE below.
        while !self.at_body_end(BodyEnd::Plain) {
            let labels = self.case_labels()?;
            let body = self.statements(BodyEnd::CaseArm)?;
            arms.push((labels, body));
        }
        let otherwise = if self.eat_kw(Kw::Else) {
            self.statements(BodyEnd::Plain)?
        } else {
            Vec::new()
        };
        self.expect_kw(Kw::EndCase, "END_CASE to close the CASE")?;
        Ok(StmtKind::Case {
            selector,
            arms,
            otherwise,
        })
    }

    /// `1, 2, 5..7, Red:`
    fn case_labels(&mut self) -> Result<Vec<CaseLabel>, Diagnostic> {
        let mut labels = Vec::new();
        loop {
            let (lo, _) = self.expr()?;
            if self.eat(Tok::DotDot) {
                let (hi, _) = self.expr()?;
                labels.push(CaseLabel::Range(lo, hi));
            } else {
                labels.push(CaseLabel::Value(lo));
            }
            if !self.eat(Tok::Comma) {
                break;
            }
        }
        self.expect(Tok::Colon, "',' or ':' after the CASE label")?;
        Ok(labels)
    }

    fn for_statement(&mut self) -> Result<StmtKind, Diagnostic> {
        self.bump();
        let var = self.name("the control variable after FOR")?;
        self.expect(Tok::Assign, "':=' after the control variable")?;
        let (from, _) = self.expr()?;
        self.expect_kw(Kw::To, "TO after the first value")?;
        let (to, _) = self.expr()?;
        let by = if self.eat_kw(Kw::By) {
            Some(self.expr()?.0)
        } else {
            None
        };
        self.expect_kw(Kw::Do, "DO after the FOR range")?;
        let body = self.statements(BodyEnd::Plain)?;
        self.expect_kw(Kw::EndFor, "END_FOR to close the FOR")?;
        Ok(StmtKind::For {
            var,
            from,
            to,
            by,
            body,
        })
    }

    fn while_statement(&mut self) -> Result<StmtKind, Diagnostic> {
        self.bump();
        let (cond, _) = self.expr()?;
        self.expect_kw(Kw::Do, "DO after the WHILE condition")?;
        let body = self.statements(BodyEnd::Plain)?;
        self.expect_kw(Kw::EndWhile, "END_WHILE to close the WHILE")?;
        Ok(StmtKind::While { cond, body })
    }

    fn repeat_statement(&mut self) -> Result<StmtKind, Diagnostic> {
        self.bump();
        let body = self.statements(BodyEnd::Plain)?;
        self.expect_kw(Kw::Until, "UNTIL to end the REPEAT's body")?;
        let (until, _) = self.expr()?;
        self.expect_kw(Kw::EndRepeat, "END_REPEAT to close the REPEAT")?;
        Ok(StmtKind::Repeat { body, until })
    }
}
