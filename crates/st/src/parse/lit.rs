//! Literal values from the text of their tokens, which the lexer has already shaped: integers
//! (`1_000`, `16#FF`), reals, durations (`T#1h2m3.5s`, in nanoseconds), strings after their
//! `$` escapes, and typed literals (`INT#-5`, `BOOL#1`, `Color#Red`).
//!
//! Durations follow MATIEC and IEC 61131-3 §6.3.4 (Table 8): units `d`, `h`, `m`, `s`, `ms`,
//! `us`, `ns` in any case, from the largest to the smallest and each at most once, `_` allowed
//! between them; the first may be any size (`T#90m`), the ones after it must stay within the
//! unit above (`T#1h70m` is refused: h < 24, m and s < 60, ms, us and ns < 1000); only the last
//! may have a fraction (`T#1.5s`), and a fraction finer than a nanosecond is refused rather than
//! rounded. `$N` and `$L` are both a line feed (0x0A), `$P` a form feed, `$R` a carriage return,
//! `$T` a tab.

use std::borrow::Cow;

use crate::ast::{Ident, Literal, Pos};
use crate::error::Diagnostic;

/// An unsigned integer: `123`, `1_000`, `2#1010`, `8#17`, `16#FF`.
pub(super) fn int(text: &str, pos: Pos) -> Result<i128, Diagnostic> {
    let (base, digits) = match text.split_once('#') {
        None => (10, text),
        Some(("2", d)) => (2, d),
        Some(("8", d)) => (8, d),
        Some(("16", d)) => (16, d),
        Some((b, _)) => {
            return Err(Diagnostic::new(
                pos,
                format!("'{b}#' is not a base: IEC 61131-3 has 2#, 8# and 16#"),
            ))
        }
    };
    let mut value: i128 = 0;
    for c in digits.chars().filter(|&c| c != '_') {
        let digit = c
            .to_digit(base)
            .ok_or_else(|| Diagnostic::new(pos, format!("'{c}' is not a digit in base {base}")))?;
        value = value
            .checked_mul(i128::from(base))
            .and_then(|v| v.checked_add(i128::from(digit)))
            .ok_or_else(|| {
                Diagnostic::new(
                    pos,
                    format!("the integer {text} is too large for any integer type"),
                )
            })?;
    }
    Ok(value)
}

/// A real: `1.5`, `1.0E-3`, `1_000.5`.
pub(super) fn real(text: &str, pos: Pos) -> Result<f64, Diagnostic> {
    let cleaned: Cow<str> = if text.contains('_') {
        Cow::Owned(text.replace('_', ""))
    } else {
        Cow::Borrowed(text)
    };
    match cleaned.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(Diagnostic::new(
            pos,
            format!("the REAL literal {text} is out of range"),
        )),
    }
}

/// The units of a duration, largest first: name, nanoseconds, and the bound a unit after the
/// first must stay under.
const UNITS: [(&str, i128, i128); 7] = [
    ("D", 86_400_000_000_000, i128::MAX),
    ("H", 3_600_000_000_000, 24),
    ("M", 60_000_000_000, 60),
    ("S", 1_000_000_000, 60),
    ("MS", 1_000_000, 1000),
    ("US", 1_000, 1000),
    ("NS", 1, 1000),
];

/// A duration in nanoseconds, from its token (`T#1s500ms`, `LTIME#-5ms`).
pub(super) fn time(text: &str, pos: Pos) -> Result<i64, Diagnostic> {
    let bad = |msg: String| Diagnostic::new(pos, msg);
    let Some((_, body)) = text.split_once('#') else {
        return Err(bad(format!("'{text}' is not a duration")));
    };
    let (negative, body) = match body.as_bytes().first() {
        Some(b'-') => (true, &body[1..]),
        Some(b'+') => (false, &body[1..]),
        _ => (false, body),
    };
    let mut rest = body;
    let mut total: i128 = 0;
    let mut last_unit: Option<usize> = None;
    let mut had_fraction = false;
    while !rest.is_empty() {
        if last_unit.is_some() {
            rest = rest.strip_prefix('_').unwrap_or(rest);
        }
        let part = Part::read(&mut rest);
        let unit = part.unit(text, pos)?;
        if last_unit.is_some_and(|last| unit <= last) {
            return Err(bad(format!(
                "the units of '{text}' must go from the largest to the smallest, each once (d, h, m, s, ms, us, ns)"
            )));
        }
        if had_fraction {
            return Err(bad(format!(
                "only the last unit of '{text}' may have a fraction"
            )));
        }
        had_fraction = !part.fraction.is_empty();
        let value = part.nanoseconds(unit, last_unit.is_none(), text, pos)?;
        total = total
            .checked_add(value)
            .ok_or_else(|| bad(format!("the duration '{text}' is too long")))?;
        last_unit = Some(unit);
    }
    if last_unit.is_none() {
        return Err(bad(format!(
            "'{text}' is not a duration: write a number and a unit, as T#1s500ms"
        )));
    }
    let signed = if negative { -total } else { total };
    i64::try_from(signed).map_err(|_| {
        bad(format!(
            "the duration '{text}' is too long: a TIME holds about ±292 years in nanoseconds"
        ))
    })
}

/// One part of a duration, `1`, `.5` and `s` of `1.5s`, as written.
struct Part<'t> {
    whole: &'t str,
    fraction: &'t str,
    unit: &'t str,
}

impl<'t> Part<'t> {
    /// Reads a part from the start of `rest`, and moves `rest` past it.
    fn read(rest: &mut &'t str) -> Part<'t> {
        let take = |rest: &mut &'t str, f: fn(&u8) -> bool| {
            let n = rest.bytes().take_while(f).count();
            let (taken, left) = rest.split_at(n);
            *rest = left;
            taken
        };
        let whole = take(rest, |c| c.is_ascii_digit() || *c == b'_');
        let fraction = match rest.strip_prefix('.') {
            Some(after) => {
                *rest = after;
                take(rest, u8::is_ascii_digit)
            }
            None => "",
        };
        let unit = take(rest, u8::is_ascii_alphabetic);
        Part {
            whole,
            fraction,
            unit,
        }
    }

    /// The index of its unit in [`UNITS`].
    fn unit(&self, text: &str, pos: Pos) -> Result<usize, Diagnostic> {
        let w = self.whole;
        if w.is_empty() || w.starts_with('_') || w.ends_with('_') {
            return Err(Diagnostic::new(
                pos,
                format!("'{text}' is not a duration: write a number before each unit, as T#1h30m or T#1.5s"),
            ));
        }
        UNITS
            .iter()
            .position(|(u, _, _)| u.eq_ignore_ascii_case(self.unit))
            .ok_or_else(|| {
                Diagnostic::new(
                    pos,
                    format!(
                        "'{}' is not a unit of duration in '{text}': use d, h, m, s, ms, us or ns",
                        self.unit
                    ),
                )
            })
    }

    /// Its value in nanoseconds; only the `first` part of a duration may exceed the unit above.
    fn nanoseconds(
        &self,
        unit: usize,
        first: bool,
        text: &str,
        pos: Pos,
    ) -> Result<i128, Diagnostic> {
        let bad = |msg: String| Diagnostic::new(pos, msg);
        let (_, scale, bound) = UNITS[unit];
        let whole = int(self.whole, pos)?;
        if !first && whole >= bound {
            return Err(bad(format!(
                "'{}{}' in '{text}' must be less than {bound}: only the first unit of a duration may be any size",
                self.whole, self.unit
            )));
        }
        let too_long = || bad(format!("the duration '{text}' is too long"));
        let value = whole.checked_mul(scale).ok_or_else(too_long)?;
        if self.fraction.is_empty() {
            return Ok(value);
        }
        let digits = u32::try_from(self.fraction.len()).unwrap_or(u32::MAX);
        let places = 10_i128.checked_pow(digits).ok_or_else(too_long)?;
        let part = int(self.fraction, pos)?
            .checked_mul(scale)
            .ok_or_else(too_long)?;
        if part % places != 0 {
            return Err(bad(format!("'{text}' is finer than a nanosecond")));
        }
        value.checked_add(part / places).ok_or_else(too_long)
    }
}

/// A single-quoted string's bytes after its `$` escapes (the lexer has checked them).
pub(super) fn string(quoted: &str) -> Vec<u8> {
    let inner = quoted
        .strip_prefix('\'')
        .and_then(|s| s.strip_suffix('\''))
        .unwrap_or("");
    let b = inner.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c != b'$' || i + 1 >= b.len() {
            out.push(c);
            i += 1;
            continue;
        }
        let next = b[i + 1];
        let escaped = match next.to_ascii_uppercase() {
            b'L' | b'N' => Some(b'\n'),
            b'P' => Some(0x0c),
            b'R' => Some(b'\r'),
            b'T' => Some(b'\t'),
            b'$' | b'\'' | b'"' => Some(next),
            _ => None,
        };
        if let Some(e) = escaped {
            out.push(e);
            i += 2;
            continue;
        }
        let hex = inner
            .get(i + 1..i + 3)
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match hex {
            Some(v) => {
                out.push(v);
                i += 3;
            }
            None => {
                out.push(c);
                i += 1;
            }
        }
    }
    out
}

/// A typed literal: `INT#-5`, `WORD#16#FF`, `REAL#1.5`, `BOOL#1`, `BOOL#TRUE`, `STRING#'a'`,
/// `Color#Red`.
pub(super) fn typed(text: &str, pos: Pos) -> Result<Literal, Diagnostic> {
    let Some((prefix, value)) = text.split_once('#') else {
        return Err(Diagnostic::new(pos, format!("'{text}' is not a literal")));
    };
    let ty = Ident {
        text: prefix.to_string(),
        pos,
    };
    let value_pos = pos + prefix.len() as Pos + 1;
    let is_bool = prefix.eq_ignore_ascii_case("BOOL");
    let first = value.as_bytes().first().copied().unwrap_or(0);
    if first == b'\'' {
        if !prefix.eq_ignore_ascii_case("STRING") {
            return Err(Diagnostic::new(
                pos,
                format!("'{prefix}#' does not take a quoted text; only STRING#'…' does"),
            ));
        }
        return Ok(Literal::String(string(value)));
    }
    if first.is_ascii_alphabetic() || first == b'_' {
        return named(ty, value, value_pos);
    }
    let (negative, digits) = match first {
        b'-' => (true, &value[1..]),
        b'+' => (false, &value[1..]),
        _ => (false, value),
    };
    if is_bool {
        return match (digits, first) {
            ("0", b'0') => Ok(Literal::Bool(false)),
            ("1", b'1') => Ok(Literal::Bool(true)),
            _ => Err(Diagnostic::new(pos, "BOOL#… takes 0, 1, TRUE or FALSE")),
        };
    }
    let is_real_type = prefix.eq_ignore_ascii_case("REAL") || prefix.eq_ignore_ascii_case("LREAL");
    if digits.contains('#') {
        if negative || first == b'+' {
            return Err(Diagnostic::new(
                pos,
                format!("a based literal takes no sign: write -{prefix}#{digits} for {text}"),
            ));
        }
        return Ok(Literal::Int {
            value: int(digits, value_pos)?,
            ty: Some(ty),
        });
    }
    if digits.contains(['.', 'e', 'E']) || is_real_type {
        let v = real(digits, value_pos)?;
        return Ok(Literal::Real {
            value: if negative { -v } else { v },
            ty: Some(ty),
        });
    }
    let v = int(digits, value_pos)?;
    Ok(Literal::Int {
        value: if negative { -v } else { v },
        ty: Some(ty),
    })
}

/// A typed literal whose value is a name: `BOOL#TRUE`, or an enumeration value `Color#Red`.
fn named(ty: Ident, value: &str, value_pos: Pos) -> Result<Literal, Diagnostic> {
    let truth = if value.eq_ignore_ascii_case("TRUE") {
        Some(true)
    } else if value.eq_ignore_ascii_case("FALSE") {
        Some(false)
    } else {
        None
    };
    let is_bool = ty.text.eq_ignore_ascii_case("BOOL");
    match (truth, is_bool) {
        (Some(b), true) => Ok(Literal::Bool(b)),
        (Some(_), false) => Err(Diagnostic::new(
            ty.pos,
            format!(
                "{value} is a BOOL: write BOOL#{value} or {value}, not {}#{value}",
                ty.text
            ),
        )),
        (None, true) => Err(Diagnostic::new(ty.pos, "BOOL#… takes 0, 1, TRUE or FALSE")),
        (None, false) => Ok(Literal::Enum {
            ty,
            value: Ident {
                text: value.to_string(),
                pos: value_pos,
            },
        }),
    }
}
