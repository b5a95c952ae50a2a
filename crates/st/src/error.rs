//! The crate's one error: a fault in the program text, located, or a fault while it runs.

use std::fmt;

use crate::ast::Pos;

/// A problem found in the text at `pos` (a byte offset), before anything runs: a syntax error,
/// an unknown name, a type mismatch, a construct outside what is supported.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Diagnostic {
    /// Where it is.
    pub pos: Pos,
    /// What is wrong, naming the construct, and what to do.
    pub message: String,
}

impl Diagnostic {
    /// A problem at `pos`.
    pub fn new(pos: Pos, message: impl Into<String>) -> Self {
        Diagnostic {
            pos,
            message: message.into(),
        }
    }
}

/// A problem in a named source, at a line and column: what a user sees.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct StError {
    /// The file (or POU) the text came from.
    pub origin: String,
    /// 1-based line.
    pub line: u32,
    /// 1-based column, in characters.
    pub column: u32,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for StError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: {}",
            self.origin, self.line, self.column, self.message
        )
    }
}

/// A source text with its name, to turn byte offsets into line:column.
#[derive(Clone, Copy, Debug)]
pub struct Source<'a> {
    /// The file name (or POU), as messages show it.
    pub origin: &'a str,
    /// The text.
    pub text: &'a str,
}

impl Source<'_> {
    /// The 1-based line and column (in characters) of byte offset `pos`.
    pub fn locate(&self, pos: Pos) -> (u32, u32) {
        let pos = (pos as usize).min(self.text.len());
        let before = &self.text.as_bytes()[..pos];
        let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
        let start = before
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |i| i + 1);
        let column = String::from_utf8_lossy(&before[start..]).chars().count() + 1;
        (line as u32, column as u32)
    }

    /// The diagnostic as a located error.
    pub fn error(&self, d: Diagnostic) -> StError {
        let (line, column) = self.locate(d.pos);
        StError {
            origin: self.origin.to_string(),
            line,
            column,
            message: d.message,
        }
    }
}
