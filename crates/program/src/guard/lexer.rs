//! The guard lexer, written by hand so that every token knows its byte offset in the guard.

use super::SyntaxError;

/// One token and where it starts (byte offset in the guard text).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Token {
    pub kind: Tok,
    pub offset: usize,
}

/// Token kinds.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Tok {
    Ident(String),
    Int(i64),
    Real(f64),
    /// A duration literal, in microseconds.
    Duration(u64),
    AndAnd,
    OrOr,
    Bang,
    EqEq,
    NotEq,
    Lt,
    Le,
    Gt,
    Ge,
    /// A single `=`: not part of the guard language, but the invariant syntax uses it.
    Assign,
    Plus,
    Minus,
    Star,
    Slash,
    LParen,
    RParen,
    Dot,
    Comma,
    End,
}

impl Tok {
    /// How the token is spelled in an error message.
    pub(crate) fn describe(&self) -> String {
        match self {
            Tok::Ident(s) => format!("`{s}`"),
            Tok::Int(i) => format!("`{i}`"),
            Tok::Real(r) => format!("`{r:?}`"),
            Tok::Duration(_) => "a duration".to_string(),
            Tok::AndAnd => "`&&`".into(),
            Tok::OrOr => "`||`".into(),
            Tok::Bang => "`!`".into(),
            Tok::EqEq => "`==`".into(),
            Tok::NotEq => "`!=`".into(),
            Tok::Lt => "`<`".into(),
            Tok::Le => "`<=`".into(),
            Tok::Gt => "`>`".into(),
            Tok::Ge => "`>=`".into(),
            Tok::Assign => "`=`".into(),
            Tok::Plus => "`+`".into(),
            Tok::Minus => "`-`".into(),
            Tok::Star => "`*`".into(),
            Tok::Slash => "`/`".into(),
            Tok::LParen => "`(`".into(),
            Tok::RParen => "`)`".into(),
            Tok::Dot => "`.`".into(),
            Tok::Comma => "`,`".into(),
            Tok::End => "the end of the expression".into(),
        }
    }
}

/// Splits a guard into tokens; the last one is always [`Tok::End`].
pub(crate) fn lex(src: &str) -> Result<Vec<Token>, SyntaxError> {
    lex_at_most(src, usize::MAX)
}

/// [`lex`], refusing a text of more than `limit` tokens (not counting [`Tok::End`]) as soon as
/// it gets there, so a huge text costs no more than the limit.
pub(crate) fn lex_at_most(src: &str, limit: usize) -> Result<Vec<Token>, SyntaxError> {
    let bytes = src.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        let start = i;
        if c.is_ascii_whitespace() {
            i += 1;
            continue;
        }
        if out.len() == limit {
            return Err(SyntaxError::new(
                start,
                format!(
                    "the expression is too long: more than {limit} tokens, the limit (each name, number, operator and parenthesis counts one); shorten it, e.g. by spreading the condition over more transitions"
                ),
            ));
        }
        let two = |a: u8, b: u8| c == a && bytes.get(i + 1) == Some(&b);
        let (kind, len) = if two(b'&', b'&') {
            (Tok::AndAnd, 2)
        } else if two(b'|', b'|') {
            (Tok::OrOr, 2)
        } else if two(b'=', b'=') {
            (Tok::EqEq, 2)
        } else if two(b'!', b'=') {
            (Tok::NotEq, 2)
        } else if two(b'<', b'=') {
            (Tok::Le, 2)
        } else if two(b'>', b'=') {
            (Tok::Ge, 2)
        } else {
            match c {
                b'!' => (Tok::Bang, 1),
                b'<' => (Tok::Lt, 1),
                b'>' => (Tok::Gt, 1),
                b'=' => (Tok::Assign, 1),
                b'+' => (Tok::Plus, 1),
                b'-' => (Tok::Minus, 1),
                b'*' => (Tok::Star, 1),
                b'/' => (Tok::Slash, 1),
                b'(' => (Tok::LParen, 1),
                b')' => (Tok::RParen, 1),
                b'.' => (Tok::Dot, 1),
                b',' => (Tok::Comma, 1),
                b'&' | b'|' => {
                    return Err(SyntaxError::new(
                        start,
                        format!("`{}` alone is not an operator; use `{0}{0}`", c as char),
                    ))
                }
                b'0'..=b'9' => {
                    let (kind, end) = number(src, i)?;
                    out.push(Token {
                        kind,
                        offset: start,
                    });
                    i = end;
                    continue;
                }
                c if c.is_ascii_alphabetic() || c == b'_' => {
                    let mut end = i;
                    while end < bytes.len()
                        && (bytes[end].is_ascii_alphanumeric() || bytes[end] == b'_')
                    {
                        end += 1;
                    }
                    out.push(Token {
                        kind: Tok::Ident(src[i..end].to_string()),
                        offset: start,
                    });
                    i = end;
                    continue;
                }
                _ => {
                    let ch = src[i..].chars().next().unwrap_or('?');
                    return Err(SyntaxError::new(
                        start,
                        format!("unexpected character `{ch}`; expected a name, a number, an operator or a parenthesis"),
                    ));
                }
            }
        };
        out.push(Token {
            kind,
            offset: start,
        });
        i += len;
    }
    out.push(Token {
        kind: Tok::End,
        offset: src.len(),
    });
    Ok(out)
}

/// Lexes a number starting at `start`: an int, a real (`1.5`, `2e3`, `1.5e-3`) or a duration
/// (`500ms`, `1.5s`). Returns the token and the offset just after it.
fn number(src: &str, start: usize) -> Result<(Tok, usize), SyntaxError> {
    let b = src.as_bytes();
    let digits = |mut j: usize| {
        while j < b.len() && b[j].is_ascii_digit() {
            j += 1;
        }
        j
    };
    let int_end = digits(start);
    let mut end = int_end;
    let mut frac: Option<(usize, usize)> = None;
    if end + 1 < b.len() && b[end] == b'.' && b[end + 1].is_ascii_digit() {
        let f_end = digits(end + 1);
        frac = Some((end + 1, f_end));
        end = f_end;
    }
    let mut exponent = false;
    if end < b.len() && (b[end] == b'e' || b[end] == b'E') {
        let mut j = end + 1;
        if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
            j += 1;
        }
        if j < b.len() && b[j].is_ascii_digit() {
            end = digits(j);
            exponent = true;
        }
    }
    // A unit directly after the number makes it a duration.
    let mut unit_end = end;
    while unit_end < b.len() && (b[unit_end].is_ascii_alphanumeric() || b[unit_end] == b'_') {
        unit_end += 1;
    }
    if unit_end > end {
        let unit = &src[end..unit_end];
        if crate::duration::unit_us(unit).is_some() && exponent {
            return Err(SyntaxError::new(
                start,
                "a duration cannot have an exponent; write it with a smaller unit, e.g. `1500ms`",
            ));
        }
        let frac = frac.map_or("", |(fs, fe)| &src[fs..fe]);
        let micros = crate::duration::micros(&src[start..int_end], frac, unit).map_err(|e| {
            let at = match e {
                crate::duration::DurationError::UnknownUnit(_) => end,
                _ => start,
            };
            SyntaxError::new(at, e.to_string())
        })?;
        return Ok((Tok::Duration(micros), unit_end));
    }
    let text = &src[start..end];
    if frac.is_some() || exponent {
        let v: f64 = text
            .parse()
            .map_err(|_| SyntaxError::new(start, format!("`{text}` is not a number")))?;
        if !v.is_finite() {
            return Err(SyntaxError::new(
                start,
                format!("`{text}` is too large for a real"),
            ));
        }
        Ok((Tok::Real(v), end))
    } else {
        let v: i64 = text.parse().map_err(|_| {
            SyntaxError::new(
                start,
                format!(
                    "`{text}` does not fit in an int (64-bit signed, at most 9223372036854775807)"
                ),
            )
        })?;
        Ok((Tok::Int(v), end))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(s: &str) -> Vec<Tok> {
        lex(s)
            .map(|v| v.into_iter().map(|t| t.kind).collect())
            .unwrap_or_default()
    }

    #[test]
    fn durations_are_converted_to_microseconds() {
        assert_eq!(kinds("500ms")[0], Tok::Duration(500_000));
        assert_eq!(kinds("1.5s")[0], Tok::Duration(1_500_000));
        assert_eq!(kinds("2min")[0], Tok::Duration(120_000_000));
        assert_eq!(kinds("7us")[0], Tok::Duration(7));
    }

    #[test]
    fn a_fraction_of_a_microsecond_is_refused() {
        assert!(lex("0.5us").is_err());
    }

    #[test]
    fn an_unknown_unit_points_at_the_unit() {
        let e = lex("x > 3sec").err();
        assert_eq!(e.map(|e| e.offset), Some(5));
    }

    #[test]
    fn reals_accept_fractions_and_exponents() {
        assert_eq!(kinds("1.5")[0], Tok::Real(1.5));
        assert_eq!(kinds("2e3")[0], Tok::Real(2000.0));
        assert_eq!(kinds("1e-7")[0], Tok::Real(1e-7));
    }

    #[test]
    fn a_timer_lexes_as_name_dot_name() {
        assert_eq!(
            kinds("P30.t"),
            vec![
                Tok::Ident("P30".into()),
                Tok::Dot,
                Tok::Ident("t".into()),
                Tok::End
            ]
        );
    }
}
