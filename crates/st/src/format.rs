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
        Elem::Real => g10(f64::from(f32::from_bits(v as u32)), &mut b),
        Elem::Lreal => g10(f64::from_bits(v), &mut b),
        e if e.is_bits() => write!(b, "16#{v:x}"),
        e if e.is_signed() || e == Elem::Time => write!(b, "{}", v as i64),
        _ => write!(b, "{v}"),
    };
    b.len
}

/// C's `%.10g`: ten significant digits, in exponent form when the exponent is below -4 or at
/// least 10, trailing zeros removed.
fn g10(x: f64, b: &mut Buf<'_>) -> std::fmt::Result {
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
    write!(s, "{:.9e}", x.abs())?;
    let len = s.len;
    let text = std::str::from_utf8(&sci[..len]).unwrap_or("0e0");
    let (mantissa, exp) = text.split_once('e').unwrap_or((text, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let mut d = [0u8; 10];
    let mut n = 0;
    for c in mantissa.bytes().filter(u8::is_ascii_digit) {
        if n < 10 {
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
    if !(-4..10).contains(&exp) {
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
}
