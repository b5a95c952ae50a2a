//! The lexer of the ST subset: tokens with their byte offsets, comments skipped, time literals
//! read into microseconds with checked arithmetic.

use super::{StError, MAX_TOKENS};

#[derive(Clone, Debug, PartialEq)]
pub(super) enum Tok {
    Ident(String),
    Int(i64),
    Real(f64),
    Time(u64),
    Sym(&'static str),
    End,
}

pub(super) const KEYWORDS_OUTSIDE: [&str; 12] = [
    "CASE", "FOR", "WHILE", "REPEAT", "RETURN", "EXIT", "CONTINUE", "JMP", "OF", "DO", "TO", "BY",
];

pub(super) fn lex(src: &str) -> Result<Vec<(Tok, usize)>, StError> {
    let b = src.as_bytes();
    let mut i = 0;
    let mut out = Vec::new();
    while i < b.len() {
        let c = b[i];
        if c.is_ascii_whitespace() {
            i += 1;
            continue;
        }
        if out.len() >= MAX_TOKENS {
            return Err(StError::new(
                i,
                format!("more than {MAX_TOKENS} tokens; split the expression or the body"),
            ));
        }
        let start = i;
        if src[i..].starts_with("(*") {
            let Some(end) = src[i + 2..].find("*)") else {
                return Err(StError::new(i, "a comment `(*` is never closed; add `*)`"));
            };
            i += 2 + end + 2;
            continue;
        }
        if src[i..].starts_with("//") {
            i = src[i..].find('\n').map_or(b.len(), |n| i + n);
            continue;
        }
        if c.is_ascii_alphabetic() || c == b'_' {
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            let word = &src[start..i];
            if i < b.len() && b[i] == b'#' {
                if word.eq_ignore_ascii_case("T") || word.eq_ignore_ascii_case("TIME") {
                    let (us, end) = time_literal(src, i + 1)?;
                    out.push((Tok::Time(us), start));
                    i = end;
                    continue;
                }
                return Err(StError::unsupported(
                    start,
                    format!("the typed literal `{word}#…`"),
                    "the subset has untyped literals and T#… durations only",
                ));
            }
            out.push((Tok::Ident(word.to_string()), start));
            continue;
        }
        if c.is_ascii_digit() {
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'_') {
                i += 1;
            }
            let mut real = false;
            if i + 1 < b.len() && b[i] == b'.' && b[i + 1].is_ascii_digit() {
                real = true;
                i += 1;
                while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'_') {
                    i += 1;
                }
            }
            if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
                real = true;
                i += 1;
                if i < b.len() && (b[i] == b'+' || b[i] == b'-') {
                    i += 1;
                }
                while i < b.len() && b[i].is_ascii_digit() {
                    i += 1;
                }
            }
            if i < b.len() && b[i] == b'#' {
                return Err(StError::unsupported(
                    start,
                    "a based literal (`16#FF`)",
                    "write the number in decimal",
                ));
            }
            let text: String = src[start..i].chars().filter(|&c| c != '_').collect();
            let tok = if real {
                match text.parse::<f64>() {
                    Ok(r) if r.is_finite() => Tok::Real(r),
                    _ => {
                        return Err(StError::new(
                            start,
                            format!("`{text}` is not a finite REAL"),
                        ))
                    }
                }
            } else {
                match text.parse::<i64>() {
                    Ok(n) => Tok::Int(n),
                    Err(_) => {
                        return Err(StError::new(
                            start,
                            format!("`{text}` does not fit a 64-bit integer"),
                        ))
                    }
                }
            };
            out.push((tok, start));
            continue;
        }
        let two = src.get(i..i + 2).unwrap_or("");
        let sym: &'static str = match two {
            ":=" => ":=",
            "<=" => "<=",
            ">=" => ">=",
            "<>" => "<>",
            "**" => "**",
            "=>" => "=>",
            _ => match c {
                b'=' => "=",
                b'<' => "<",
                b'>' => ">",
                b'+' => "+",
                b'-' => "-",
                b'*' => "*",
                b'/' => "/",
                b'(' => "(",
                b')' => ")",
                b';' => ";",
                b'.' => ".",
                b',' => ",",
                b'&' => "&",
                b'[' => "[",
                b'^' => "^",
                b':' => ":",
                _ => {
                    let ch = src[i..].chars().next().unwrap_or('?');
                    return Err(StError::new(i, format!("unexpected character `{ch}`")));
                }
            },
        };
        i += sym.len();
        out.push((Tok::Sym(sym), start));
    }
    out.push((Tok::End, src.len()));
    Ok(out)
}

/// Reads the part of a time literal after `T#`: `1h2m3s4ms5us`, `1.5s`, with `_` allowed.
pub(super) fn time_literal(src: &str, from: usize) -> Result<(u64, usize), StError> {
    let b = src.as_bytes();
    let mut i = from;
    let mut total: u64 = 0;
    let mut parts = 0;
    let overflow = || StError::new(from, "the duration does not fit 64 bits of microseconds");
    loop {
        let start = i;
        while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.' || b[i] == b'_') {
            i += 1;
        }
        if i == start {
            break;
        }
        let number: String = src[start..i].chars().filter(|&c| c != '_').collect();
        let unit_start = i;
        while i < b.len() && b[i].is_ascii_alphabetic() {
            i += 1;
        }
        let unit = src[unit_start..i].to_ascii_lowercase();
        let scale: u64 = match unit.as_str() {
            "d" => 86_400_000_000,
            "h" => 3_600_000_000,
            "m" => 60_000_000,
            "s" => 1_000_000,
            "ms" => 1_000,
            "us" => 1,
            _ => {
                return Err(StError::new(
                    unit_start,
                    format!("`{unit}` is not a time unit of the subset; use d, h, m, s, ms or us"),
                ))
            }
        };
        let value = match number.split_once('.') {
            None => number
                .parse::<u64>()
                .ok()
                .and_then(|n| n.checked_mul(scale))
                .ok_or_else(overflow)?,
            Some((whole, frac)) => {
                let whole = whole.parse::<u64>().unwrap_or(0);
                let mut v = whole.checked_mul(scale).ok_or_else(overflow)?;
                let mut place = scale;
                for d in frac.bytes() {
                    if !d.is_ascii_digit() {
                        return Err(StError::new(start, "a malformed number in the duration"));
                    }
                    if !place.is_multiple_of(10) {
                        return Err(StError::new(
                            start,
                            "the duration is finer than a microsecond",
                        ));
                    }
                    place /= 10;
                    v = v
                        .checked_add(u64::from(d - b'0') * place)
                        .ok_or_else(overflow)?;
                }
                v
            }
        };
        total = total.checked_add(value).ok_or_else(overflow)?;
        parts += 1;
    }
    if parts == 0 {
        return Err(StError::new(
            from,
            "a time literal needs a value and a unit, such as T#3s or T#1m30s",
        ));
    }
    Ok((total, i))
}
