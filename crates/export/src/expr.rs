//! A guard-language expression (docs/program-format.md, *Guards*) as Structured Text.
//!
//! Every operation is parenthesised, so that IEC's precedence (where the comparisons bind more
//! loosely than in the guard language) never changes a meaning; literals carry their type
//! (`LINT#3`, `LREAL#1.5`, `T#3s`), so that no dialect infers another. The guard parser bounds
//! a tree's depth (128 levels), and with it this printer's recursion.

use std::collections::HashMap;
use std::fmt::Write as _;

use cetratus_program::guard::{BinOp, Expr, ExprKind, Func, UnOp};

/// What a guard's names are in the export.
pub(crate) struct Symbols {
    /// Signals (inputs, outputs, variables): program name → ST name.
    pub(crate) signals: HashMap<String, String>,
    /// Places by id: their 1-based index in the marking.
    pub(crate) places: HashMap<String, usize>,
    /// Places whose time a guard or a timed action reads: id → the TON that keeps it.
    pub(crate) timers: HashMap<String, String>,
    /// Places whose dwell a guard reads: id → the TIME variable that keeps it.
    pub(crate) dwells: HashMap<String, String>,
    /// Inputs whose edges a guard reads: program name → the copy of the previous scan's value.
    pub(crate) previous: HashMap<String, String>,
    /// The marking array's name.
    pub(crate) marking: String,
    /// The dialect's words for `&&` and `||`.
    pub(crate) and_or: (&'static str, &'static str),
}

impl Symbols {
    fn name(&self, n: &str) -> String {
        if let Some(s) = self.signals.get(n) {
            return s.clone();
        }
        match self.places.get(n) {
            Some(i) => format!("DINT_TO_LINT({}[{i}])", self.marking),
            None => n.to_string(),
        }
    }

    fn lookup(map: &HashMap<String, String>, n: &str) -> String {
        map.get(n).cloned().unwrap_or_else(|| n.to_string())
    }
}

/// `e` in Structured Text.
pub(crate) fn st(e: &Expr, sym: &Symbols) -> String {
    let mut s = String::new();
    write(&mut s, e, sym);
    if s.starts_with('(') && s.ends_with(')') && balanced_inside(&s) {
        s = s[1..s.len() - 1].to_string();
    }
    s
}

/// Whether the outer parentheses of `s` enclose all of it.
fn balanced_inside(s: &str) -> bool {
    let mut depth = 0i32;
    for (i, c) in s.char_indices() {
        match c {
            '(' => depth += 1,
            ')' => depth -= 1,
            _ => {}
        }
        if depth == 0 && i + 1 < s.len() {
            return false;
        }
    }
    true
}

fn write(s: &mut String, e: &Expr, sym: &Symbols) {
    match &e.kind {
        ExprKind::Bool(b) => s.push_str(if *b { "TRUE" } else { "FALSE" }),
        ExprKind::Int(i) => {
            let _ = write!(s, "LINT#{i}");
        }
        ExprKind::Real(r) => {
            let _ = write!(s, "LREAL#{}", real_literal(*r));
        }
        ExprKind::Duration(us) => s.push_str(&time_literal(*us)),
        ExprKind::Name(n) => s.push_str(&sym.name(n)),
        ExprKind::Timer(p) => {
            let _ = write!(s, "{}.ET", Symbols::lookup(&sym.timers, p));
        }
        ExprKind::Dwell(p) => s.push_str(&Symbols::lookup(&sym.dwells, p)),
        ExprKind::Rise(x) | ExprKind::Fall(x) => {
            let (now, before) = (sym.name(x), Symbols::lookup(&sym.previous, x));
            let _ = match e.kind {
                ExprKind::Rise(_) => write!(s, "({now} AND NOT {before})"),
                _ => write!(s, "(NOT {now} AND {before})"),
            };
        }
        ExprKind::Call(f, a) => {
            s.push_str(match f {
                Func::Real => "LINT_TO_LREAL(",
                Func::Int => "TRUNC(",
            });
            write(s, a, sym);
            s.push(')');
        }
        ExprKind::Unary(op, a) => {
            s.push_str(match op {
                UnOp::Not => "NOT ",
                UnOp::Neg => "-",
            });
            let atom = !matches!(a.kind, ExprKind::Binary(..) | ExprKind::Unary(..));
            if !atom {
                s.push('(');
            }
            write(s, a, sym);
            if !atom {
                s.push(')');
            }
        }
        ExprKind::Binary(op, l, r) => {
            s.push('(');
            write(s, l, sym);
            let word = match op {
                BinOp::And => sym.and_or.0,
                BinOp::Or => sym.and_or.1,
                _ => operator(*op),
            };
            let _ = write!(s, " {word} ");
            write(s, r, sym);
            s.push(')');
        }
    }
}

/// IEC's spelling of an operator where it differs from the guard language's.
fn operator(op: BinOp) -> &'static str {
    match op {
        BinOp::Or => "OR",
        BinOp::And => "AND",
        BinOp::Eq => "=",
        BinOp::Ne => "<>",
        _ => op.symbol(),
    }
}

/// A real as IEC writes one: digits, a point, digits, and an exponent when it needs one.
pub(crate) fn real_literal(r: f64) -> String {
    let plain = format!("{r:?}");
    if !plain.contains('e') {
        return plain;
    }
    let sci = format!("{r:e}");
    match sci.split_once('e') {
        Some((m, x)) if !m.contains('.') => format!("{m}.0e{x}"),
        _ => sci,
    }
}

/// A duration in microseconds as an IEC TIME literal: whole seconds as `T#3s`, else
/// milliseconds, with a fraction below them.
pub(crate) fn time_literal(us: u64) -> String {
    if us.is_multiple_of(1_000_000) {
        format!("T#{}s", us / 1_000_000)
    } else if us.is_multiple_of(1000) {
        format!("T#{}ms", us / 1000)
    } else {
        let frac = format!("{:03}", us % 1000);
        format!("T#{}.{}ms", us / 1000, frac.trim_end_matches('0'))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn literals_are_written_as_iec_types_them() {
        assert_eq!(real_literal(1.5), "1.5");
        assert_eq!(real_literal(2e3), "2000.0");
        assert_eq!(real_literal(1e-7), "1.0e-7");
        assert_eq!(time_literal(3_000_000), "T#3s");
        assert_eq!(time_literal(10_000), "T#10ms");
        assert_eq!(time_literal(1_500), "T#1.5ms");
        assert_eq!(time_literal(0), "T#0s");
    }
}
