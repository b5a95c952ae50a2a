//! Values as MATIEC's library prints them (`*_TO_STRING`), and TIME scaled by a number as its
//! `__time_mul` and `__time_div` compute it; into fixed buffers, so the scan never allocates.

use std::fmt::Write as _;

use crate::types::Elem;

const NS_PER_S: i64 = 1_000_000_000;

/// A writer into a fixed buffer; what does not fit is dropped.
struct Buf<'a> {
    bytes: &'a mut [u8],
    len: usize,
}

impl std::fmt::Write for Buf<'_> {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        let n = s.len().min(self.bytes.len() - self.len);
        self.bytes[self.len..self.len + n].copy_from_slice(&s.as_bytes()[..n]);
        self.len += n;
        Ok(())
    }
}

/// Writes `<e>_TO_STRING` of the slot `v` into `out`; the length written.
pub fn iec_text(e: Elem, v: u64, out: &mut [u8]) -> usize {
    let mut b = Buf { bytes: out, len: 0 };
    let _ = match e {
        Elem::Bool => b.write_str(if v != 0 { "TRUE" } else { "FALSE" }),
        Elem::Real => g(f64::from(f32::from_bits(v as u32)), 10, &mut b),
        Elem::Lreal => g(f64::from_bits(v), 10, &mut b),
        Elem::Time => time_text(v as i64, &mut b),
        e if e.is_bits() => write!(b, "16#{v:x}"),
        e if e.is_signed() => write!(b, "{}", v as i64),
        _ => write!(b, "{v}"),
    };
    b.len
}

/// MATIEC's TIME_TO_STRING: `T#<d>d`, `T#<d>d<h>h`, `T#<d>d<h>h<m>m`, `T#<d>d<h>h<m>m<s>s` or
/// `T#<d>d<h>h<m>m<s>s<ms>ms`, the shortest that holds the value, each part C's truncating
/// division of the seconds (so a negative TIME has negative parts), the milliseconds as `%g`.
fn time_text(ns: i64, b: &mut Buf<'_>) -> std::fmt::Result {
    let (sec, nsec) = (ns / NS_PER_S, ns % NS_PER_S);
    // C's `div` on an `int`: the seconds as MATIEC passes them.
    let sec = sec as i32;
    let (days, rem) = (sec / 86_400, sec % 86_400);
    let (hours, rem) = (rem / 3_600, rem % 3_600);
    let (minutes, seconds) = (rem / 60, rem % 60);
    write!(b, "T#{days}d")?;
    if rem == 0 && hours == 0 && minutes == 0 && seconds == 0 && nsec == 0 {
        return Ok(());
    }
    write!(b, "{hours}h")?;
    if minutes == 0 && seconds == 0 && nsec == 0 {
        return Ok(());
    }
    write!(b, "{minutes}m")?;
    if seconds == 0 && nsec == 0 {
        return Ok(());
    }
    write!(b, "{seconds}s")?;
    if nsec == 0 {
        return Ok(());
    }
    g(nsec as f64 / 1e6, 6, b)?;
    b.write_str("ms")
}

/// C's `%.<digits>g`: that many significant digits (at most 10), in exponent form when the
/// exponent is below -4 or at least `digits`, trailing zeros removed.
fn g(x: f64, precision: usize, b: &mut Buf<'_>) -> std::fmt::Result {
    if x.is_nan() {
        return b.write_str(if x.is_sign_negative() { "-nan" } else { "nan" });
    }
    if x.is_infinite() {
        return b.write_str(if x < 0.0 { "-inf" } else { "inf" });
    }
    if x == 0.0 {
        return b.write_str(if x.is_sign_negative() { "-0" } else { "0" });
    }
    let mut sci = [0u8; 32];
    let mut s = Buf {
        bytes: &mut sci,
        len: 0,
    };
    write!(s, "{:.*e}", precision - 1, x.abs())?;
    let len = s.len;
    let text = std::str::from_utf8(&sci[..len]).unwrap_or("0e0");
    let (mantissa, exp) = text.split_once('e').unwrap_or((text, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let mut d = [0u8; 10];
    let mut n = 0;
    for c in mantissa.bytes().filter(u8::is_ascii_digit) {
        if n < precision.min(10) {
            d[n] = c;
            n += 1;
        }
    }
    let mut last = n;
    while last > 1 && d[last - 1] == b'0' {
        last -= 1;
    }
    if x < 0.0 {
        b.write_str("-")?;
    }
    let digits = std::str::from_utf8(&d[..last]).unwrap_or("0");
    if !(-4..precision as i32).contains(&exp) {
        let (first, rest) = digits.split_at(1);
        b.write_str(first)?;
        if !rest.is_empty() {
            write!(b, ".{rest}")?;
        }
        let sign = if exp < 0 { '-' } else { '+' };
        return write!(b, "e{sign}{:02}", exp.abs());
    }
    if exp < 0 {
        b.write_str("0.")?;
        for _ in 0..(-exp - 1) {
            b.write_str("0")?;
        }
        return b.write_str(digits);
    }
    let int_len = (exp + 1) as usize;
    if digits.len() <= int_len {
        b.write_str(digits)?;
        for _ in digits.len()..int_len {
            b.write_str("0")?;
        }
        return Ok(());
    }
    let (int, frac) = digits.split_at(int_len);
    write!(b, "{int}.{frac}")
}

/// `STRING_TO_<e>` of `text`, as MATIEC's library reads it (`__string_to_bool`,
/// `__pstring_to_sint`, `__string_to_real`), within the string's length; TIME as IEC writes a
/// duration (`T#1m30s`), or a bare number of seconds as MATIEC reads it (docs/st.md, *Where
/// Cetratus and MATIEC differ*).
pub fn from_text(e: Elem, text: &[u8]) -> u64 {
    match e {
        Elem::Bool => {
            u64::from(text == b"1" || (text.len() == 4 && text.eq_ignore_ascii_case(b"TRUE")))
        }
        Elem::Real | Elem::Lreal => {
            let x = match text.iter().rposition(|&c| c == b'.') {
                Some(l) if l != 0 => strtod_prefix(text),
                _ => integer_text(text) as f64,
            };
            match e {
                Elem::Real => u64::from((x as f32).to_bits()),
                _ => x.to_bits(),
            }
        }
        Elem::Time => duration_text(text) as u64,
        e => crate::types::wrap(e, integer_text(text) as u64),
    }
}

/// MATIEC's `__pstring_to_sint`: `2#`, `8#` and `16#` read their digits from the right and skip
/// anything else (underscores); otherwise up to 20 decimal digits from the right, a character
/// from `.` up that is not a digit starting the number again, and a leading `-` negating it.
fn integer_text(text: &[u8]) -> i64 {
    let based = |skip: usize, radix: u32, bits: u32| {
        let mut res = 0u64;
        let mut shift = 0u32;
        for &c in text[skip..].iter().rev() {
            if shift >= 64 {
                break;
            }
            if let Some(d) = (c as char).to_digit(radix) {
                res |= u64::from(d).checked_shl(shift).unwrap_or(0);
                shift += bits;
            }
        }
        res as i64
    };
    match text {
        [] => 0,
        [b'2', b'#', ..] => based(2, 2, 1),
        [b'8', b'#', ..] => based(2, 8, 3),
        [b'1', b'6', b'#', ..] => based(3, 16, 4),
        _ => {
            let sign: i64 = if text[0] == b'-' { -1 } else { 1 };
            let (mut res, mut fac, mut shift) = (0i64, sign, 0);
            for &c in text.iter().rev() {
                if shift >= 20 {
                    break;
                }
                if c.is_ascii_digit() {
                    res = res.wrapping_add(i64::from(c - b'0').wrapping_mul(fac));
                    fac = fac.wrapping_mul(10);
                    shift += 1;
                } else if (b'.'..0x80).contains(&c) {
                    // MATIEC compares a C `char`, signed where it runs here (x86-64): a byte of
                    // 0x80 or more is below `.`, and skipped.
                    (res, fac, shift) = (0, sign, 0);
                }
            }
            res
        }
    }
}

/// C's `atof` on the text: leading white space, a sign, digits with one `.`, an exponent;
/// what follows is ignored, and no number at all is 0.
fn strtod_prefix(text: &[u8]) -> f64 {
    let start = text
        .iter()
        .position(|c| !c.is_ascii_whitespace())
        .unwrap_or(text.len());
    let t = &text[start..];
    let mut end = usize::from(matches!(t.first(), Some(b'+' | b'-')));
    let digits = |from: usize| t[from..].iter().take_while(|c| c.is_ascii_digit()).count();
    let int = digits(end);
    end += int;
    let mut frac = 0;
    if t.get(end) == Some(&b'.') {
        frac = digits(end + 1);
        end += 1 + frac;
    }
    if int + frac == 0 {
        return 0.0;
    }
    if matches!(t.get(end), Some(b'e' | b'E')) {
        let sign = usize::from(matches!(t.get(end + 1), Some(b'+' | b'-')));
        let exp = digits(end + 1 + sign);
        if exp > 0 {
            end += 1 + sign + exp;
        }
    }
    std::str::from_utf8(&t[..end])
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.0)
}

/// A duration: `T#`/`TIME#` and its parts (`1d2h3m4s5ms`, `us`, `ns`, fractions, underscores,
/// a leading `-`), or a bare number of seconds; anything else is 0.
fn duration_text(text: &[u8]) -> i64 {
    let upper: Vec<u8> = text.iter().map(u8::to_ascii_uppercase).collect();
    let body = upper
        .strip_prefix(b"TIME#")
        .or_else(|| upper.strip_prefix(b"T#"));
    let Some(body) = body else {
        let s = strtod_prefix(text);
        return (s * NS_PER_S as f64) as i64;
    };
    let (neg, mut rest) = match body {
        [b'-', r @ ..] => (true, r),
        r => (false, r),
    };
    let mut total = 0f64;
    while !rest.is_empty() {
        let n = rest
            .iter()
            .take_while(|c| c.is_ascii_digit() || **c == b'.' || **c == b'_')
            .count();
        let number: String = rest[..n]
            .iter()
            .filter(|c| **c != b'_')
            .map(|&c| c as char)
            .collect();
        let Ok(value) = number.parse::<f64>() else {
            return 0;
        };
        rest = &rest[n..];
        let units: [(&[u8], f64); 7] = [
            (b"MS", 1e6),
            (b"US", 1e3),
            (b"NS", 1.0),
            (b"D", 86_400e9),
            (b"H", 3_600e9),
            (b"M", 60e9),
            (b"S", 1e9),
        ];
        let Some((unit, scale)) = units.iter().find(|(u, _)| rest.starts_with(u)) else {
            return 0;
        };
        total += value * scale;
        rest = &rest[unit.len()..];
        while rest.first() == Some(&b'_') {
            rest = &rest[1..];
        }
    }
    let ns = total.round() as i64;
    if neg {
        -ns
    } else {
        ns
    }
}

/// A TIME (nanoseconds) times or divided by `f`, as MATIEC's `__time_mul`/`__time_div` compute
/// it on (seconds, nanoseconds): each part scaled in double and truncated.
pub fn time_scale(div: bool, ns: i64, f: f64) -> i64 {
    let (sec, nsec) = (ns / NS_PER_S, ns % NS_PER_S);
    let (s, n) = if div {
        let s_f = sec as f64 / f;
        let s = s_f as i64;
        (s, (nsec as f64 / f + (s_f - s as f64) * 1e9) as i64)
    } else {
        let s_f = sec as f64 * f;
        let s = s_f as i64;
        let prod = (nsec as f64 * f) as i32;
        let (q, r) = (prod / 1_000_000_000, prod % 1_000_000_000);
        (
            s + i64::from(q),
            (f64::from(r) + (s_f - s as f64) * 1e9) as i64,
        )
    };
    s.wrapping_mul(NS_PER_S).wrapping_add(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(e: Elem, v: u64) -> String {
        let mut buf = [0u8; 48];
        let n = iec_text(e, v, &mut buf);
        String::from_utf8_lossy(&buf[..n]).into_owned()
    }

    #[test]
    fn values_print_as_matiec_s_library_prints_them() {
        assert_eq!(text(Elem::Bool, 1), "TRUE");
        assert_eq!(text(Elem::Int, (-42i64) as u64), "-42");
        assert_eq!(text(Elem::Byte, 255), "16#ff");
        assert_eq!(text(Elem::Lreal, 1.5f64.to_bits()), "1.5");
        assert_eq!(text(Elem::Lreal, 100.0f64.to_bits()), "100");
        assert_eq!(
            text(Elem::Real, u64::from(0.1f32.to_bits())),
            "0.1000000015"
        );
        assert_eq!(
            text(Elem::Real, u64::from(1.0e20f32.to_bits())),
            "1.00000002e+20"
        );
        assert_eq!(
            text(Elem::Real, u64::from(1.0e-5f32.to_bits())),
            "9.999999747e-06"
        );
        assert_eq!(text(Elem::Lreal, (1.0f64 / 3.0).to_bits()), "0.3333333333");
        assert_eq!(text(Elem::Lreal, (-0.0f64).to_bits()), "-0");
    }

    #[test]
    fn times_scale_as_matiec_scales_them() {
        assert_eq!(time_scale(false, 1_500_000_000, 2.0), 3_000_000_000);
        assert_eq!(time_scale(true, 1_000_000_000, 3.0), 333_333_333);
        assert_eq!(time_scale(false, 10_000_000_000, 0.1), 1_000_000_000);
    }

    /// STRING_TO_TIME reads what IEC 61131-3 writes, where MATIEC reads seconds only (docs/st.md).
    #[test]
    fn durations_read_as_iec_writes_them_and_bare_numbers_as_seconds() {
        let t = |s: &str| from_text(Elem::Time, s.as_bytes()) as i64;
        assert_eq!(t("T#1m30s"), 90 * NS_PER_S);
        assert_eq!(t("time#-1.5s"), -1_500_000_000);
        assert_eq!(t("T#1d_2h"), 26 * 3_600 * NS_PER_S);
        assert_eq!(t("T#250us3ns"), 250_003);
        assert_eq!(t("90"), 90 * NS_PER_S);
        assert_eq!(t("1.5"), 1_500_000_000);
        assert_eq!((t("T#5x"), t("T#"), t("abc")), (0, 0, 0));
    }

    /// A decimal text read from the right as MATIEC reads it on x86-64: a character from `.` up
    /// starts the number again, anything below `.` (a byte of 0x80 or more among them, C's
    /// `char` being signed there) is skipped.
    #[test]
    fn integers_read_from_the_right_skip_what_is_below_a_dot() {
        let i = |s: &[u8]| from_text(Elem::Dint, s) as i64;
        assert_eq!(i(b"+42"), 42);
        assert_eq!(i(b"1_000"), 1);
        assert_eq!(i(b"abc"), 0);
        assert_eq!(i(b"-12"), -12);
        assert_eq!(i(b"\xb8,2#fOT0E!"), 2);
        assert_eq!(i(b"3\xb87"), 37);
        assert_eq!(i(b"3x7"), 3);
    }
}
