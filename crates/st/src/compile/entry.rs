//! The text of an entry, the code that runs on a POU's state besides its body (an SFC action's
//! statements, a transition's condition), as given and as parsed.

use crate::ast::Expr;
use crate::error::Diagnostic;

/// Structured Text that runs on a POU's state besides its body: the statements of an SFC
/// action, or the BOOL expression of a transition's condition.
#[derive(Clone, Copy, Debug)]
pub enum EntryText<'t> {
    /// Statements, run as a body is (RETURN ends them).
    Body(&'t [crate::ast::Stmt]),
    /// A BOOL expression, whose value a run leaves in the entry's result slot.
    Condition(&'t Expr),
    /// A condition written as statements that assign its value to the entry's own name, as
    /// IEC 61131-3 writes a named transition's body (`T1 := …;`); the name is a BOOL of this
    /// code alone, FALSE until assigned, and its slot the entry's result. The name of a nested
    /// chart's transition, `A__T5`, is `T5` here, its name in its chart.
    Assigned(&'t [crate::ast::Stmt]),
}

/// The name to which the statements of the condition `entry` ([`EntryText::Assigned`]) assign
/// its value: the entry's own, or for a nested chart's transition `A__T5`, whose name is no IEC
/// name, `T5`, its name in its chart.
pub fn assigned_name(entry: &str) -> &str {
    entry.rsplit("__").next().unwrap_or(entry)
}

/// An entry's text, parsed: what [`EntryText`] borrows.
#[derive(Clone, Debug)]
pub(super) enum ParsedEntry {
    /// Statements.
    Body(Vec<crate::ast::Stmt>),
    /// A condition.
    Condition(Expr),
    /// A condition as statements that assign the entry's name.
    Assigned(Vec<crate::ast::Stmt>),
}

impl ParsedEntry {
    /// Parses `text` as statements (`body`) or as a condition: an expression, else statements
    /// that assign the condition's name (the expression's error when it is neither).
    pub(super) fn parse(text: &str, body: bool) -> Result<ParsedEntry, Diagnostic> {
        if body {
            return crate::parse::parse_statements(text).map(ParsedEntry::Body);
        }
        crate::parse::parse_expression(text)
            .map(ParsedEntry::Condition)
            .or_else(|e| match crate::parse::parse_statements(text) {
                Ok(stmts) => Ok(ParsedEntry::Assigned(stmts)),
                Err(_) => Err(e),
            })
    }

    /// The entry to compile.
    pub(super) fn text(&self) -> EntryText<'_> {
        match self {
            ParsedEntry::Body(s) => EntryText::Body(s),
            ParsedEntry::Condition(e) => EntryText::Condition(e),
            ParsedEntry::Assigned(s) => EntryText::Assigned(s),
        }
    }
}
