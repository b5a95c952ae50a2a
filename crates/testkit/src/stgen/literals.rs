//! Literals of every type, and the text they are written in.

use super::*;

// ------------------------------------------------------------------------------------------
// Literals

/// TIME literals MATIEC converts exactly (rule 8), with their value in nanoseconds; the first
/// `PT_LITERALS` are the timer presets (tens of milliseconds, the tick being 10 ms).
pub(super) const TIME_LITERALS: [(&str, i64); 28] = [
    ("T#10ms", 10_000_000),
    ("T#20ms", 20_000_000),
    ("TIME#20ms", 20_000_000),
    ("T#30ms", 30_000_000),
    ("T#40ms", 40_000_000),
    ("t#50ms", 50_000_000),
    ("T#60ms", 60_000_000),
    ("T#70ms", 70_000_000),
    ("T#80ms", 80_000_000),
    ("TIME#100ms", 100_000_000),
    ("T#120ms", 120_000_000),
    ("T#0ms", 0),
    ("T#150ms", 150_000_000),
    ("T#200ms", 200_000_000),
    ("T#250ms", 250_000_000),
    ("T#300ms", 300_000_000),
    ("T#500ms", 500_000_000),
    ("T#750ms", 750_000_000),
    ("T#1s", 1_000_000_000),
    ("T#2s", 2_000_000_000),
    ("T#1s500ms", 1_500_000_000),
    ("T#1s_500ms", 1_500_000_000),
    ("T#2s250ms", 2_250_000_000),
    ("T#1.5s", 1_500_000_000),
    ("T#0.25s", 250_000_000),
    ("t#1m", 60_000_000_000),
    ("T#1m30s", 90_000_000_000),
    ("TIME#1h", 3_600_000_000_000),
];
pub(super) const PT_LITERALS: usize = 11;

/// Characters of string literals that need no escape and no care (rule 9): no `{` (MATIEC's
/// lexer, looking for the first `;` of a body, takes it for a pragma and scans for the `}`).
pub(super) const STR_CHARS: &[u8] =
    b"abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 _-+.,:;!#%&=<>@[]^|~\"\\/";
/// Of those, the ones that may follow `$N` or `$hh`: not a hex digit.
pub(super) const STR_CHARS_NOT_HEX: &[u8] = b"ghijklmnopqrstuvwxyzGHIJKLMNOPQRSTUVWXYZ _-+.,:;!";

pub(super) fn based(rng: &mut Rng, v: i128) -> String {
    debug_assert!(v >= 0);
    let (base, digits) = match rng.below(6) {
        0 if v < 1 << 16 => (2, format!("{v:b}")),
        1 if v < 1 << 24 => (8, format!("{v:o}")),
        _ => (16, format!("{v:X}")),
    };
    let digits = if digits.len() > 4 && rng.pct(40) {
        group(&digits, 4)
    } else {
        digits
    };
    format!("{base}#{digits}")
}

/// `digits` with an underscore every `n` digits from the right: `1_000_000`.
pub(super) fn group(digits: &str, n: usize) -> String {
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(n) {
            out.push('_');
        }
        out.push(c);
    }
    out
}

impl ProgramGen<'_> {
    /// A value for an integer literal in `b`: small, at the budget's edges, or anywhere.
    pub(super) fn pick_int(&mut self, ty: Ty, b: Iv) -> i128 {
        let v = match self.rng.below(10) {
            0..=3 => self.rng.int(b.lo.max(-10), b.hi.min(10)),
            4 => {
                if self.rng.pct(50) {
                    b.lo
                } else {
                    b.hi
                }
            }
            5 => {
                let k = self.rng.int(0, 3);
                if self.rng.pct(50) {
                    (b.lo + k).min(b.hi)
                } else {
                    (b.hi - k).max(b.lo)
                }
            }
            _ => self.rng.int(b.lo, b.hi),
        };
        // `-9223372036854775808` is not a C literal of type long (its magnitude is unsigned).
        if ty == Ty::Lint && v == ty.full().lo {
            v + 1
        } else {
            v
        }
    }

    /// An integer literal of type `ty` (typed as `INT#…` if `typed`, and now and then anyway).
    pub(super) fn int_lit(&mut self, ty: Ty, v: i128, typed: bool) -> Expr {
        let typed = typed || self.rng.pct(12);
        // Untyped decimals above the C type of the context change the C arithmetic (rule 1).
        let wide = (ty.width() == 32 && v > i128::from(i32::MAX))
            || (ty.width() == 64 && v > i128::from(i64::MAX));
        let style = self.rng.below(10);
        let body = if v >= 0 && (style < 3 || (wide && (!typed || ty.width() == 64))) {
            based(self.rng, v)
        } else if v.abs() >= 10_000 && style < 5 {
            let digits = group(&v.abs().to_string(), 3);
            if v < 0 {
                format!("-{digits}")
            } else {
                digits
            }
        } else {
            v.to_string()
        };
        let text = if typed {
            format!("{}#{body}", ty.name())
        } else {
            body
        };
        Expr::lit(text, Val::Int(Iv::point(v)), typed)
    }

    pub(super) fn bits_lit(&mut self, ty: Ty, typed: bool) -> Expr {
        let max = ty.full().hi;
        let v = match self.rng.below(8) {
            0 => 0,
            1 => max,
            2 => 1i128 << (ty.width() - 1),
            3 => *self.rng.pick(&[1, 3, 15, 255, 0x0F0F, 0xAAAA]) & max,
            _ => self.rng.int(0, max),
        };
        let typed = typed || self.rng.pct(25);
        let wide = v > i128::from(i32::MAX);
        let body = if !wide && self.rng.pct(20) {
            v.to_string()
        } else {
            based(self.rng, v)
        };
        let text = if typed {
            format!("{}#{body}", ty.name())
        } else {
            body
        };
        Expr::lit(text, Val::Bits { dirty: false }, typed)
    }

    /// A REAL/LREAL literal in `b` (which holds 0); REAL literals are always typed (rule 7).
    pub(super) fn real_lit(&mut self, ty: Ty, b: Rv, typed: bool) -> Expr {
        let (v, body) = self.real_value(ty, b);
        let typed = typed || ty == Ty::Real || self.rng.pct(40);
        let text = if typed {
            format!("{}#{body}", ty.name())
        } else {
            body
        };
        Expr::lit(text, Val::Real(Rv::new(v, v)), typed)
    }

    /// A "nice" value in `b` and its text: a decimal, dyadic fraction or exponent form.
    pub(super) fn real_value(&mut self, ty: Ty, b: Rv) -> (f64, String) {
        for _ in 0..8 {
            let text = match self.rng.below(10) {
                0 => {
                    let m = self.rng.int(4, 39) as f64 / 4.0;
                    let e = self.rng.int(-2, 3);
                    let m = if self.rng.pct(30) { -m } else { m };
                    let exp = if self.rng.pct(20) { 'e' } else { 'E' };
                    format!("{}{exp}{e}", real_text(m))
                }
                1..=5 => {
                    let g = *self.rng.pick(&[1.0, 0.5, 0.25, 0.125]);
                    let s = *self.rng.pick(&[4.0, 16.0, 100.0, 1000.0, 1e4, 1e6]);
                    let lo = (b.lo.max(-s) / g).ceil() as i128;
                    let hi = (b.hi.min(s) / g).floor() as i128;
                    real_text(self.rng.int(lo, hi) as f64 * g)
                }
                _ => {
                    let d = self.rng.int(1, 2) as u32;
                    let k = 10f64.powi(d as i32);
                    let s = *self.rng.pick(&[10.0, 100.0, 1000.0]);
                    let lo = (b.lo.max(-s) * k).ceil() as i128;
                    let hi = (b.hi.min(s) * k).floor() as i128;
                    let v = self.rng.int(lo, hi);
                    let frac = format!("{:0width$}", v.abs() % k as i128, width = d as usize);
                    let sign = if v < 0 { "-" } else { "" };
                    format!("{sign}{}.{frac}", v.abs() / k as i128)
                }
            };
            let text = if text.contains('E') || text.contains('e') || self.rng.pct(80) {
                text
            } else {
                underscore_real(&text)
            };
            let plain = text.replace('_', "");
            let (Ok(v64), Ok(v32)) = (plain.parse::<f64>(), plain.parse::<f32>()) else {
                continue;
            };
            let v = if ty == Ty::Real {
                // decimal→f64→f32 must be decimal→f32 (MATIEC writes the decimal into C).
                if v64 as f32 != v32 {
                    continue;
                }
                f64::from(v32)
            } else {
                v64
            };
            if b.lo <= v && v <= b.hi {
                return (v, text);
            }
        }
        (0.0, "0.0".to_string())
    }

    /// A TIME literal of at most `max` ns (a timer preset if `preset`).
    pub(super) fn time_lit(&mut self, preset: bool, max: i128) -> Expr {
        let n = if preset {
            PT_LITERALS
        } else {
            TIME_LITERALS.len()
        };
        let fit: Vec<&(&str, i64)> = TIME_LITERALS[..n]
            .iter()
            .filter(|l| i128::from(l.1) <= max)
            .collect();
        let (text, ns) = if fit.is_empty() {
            ("T#0s", 0)
        } else {
            **self.rng.pick(&fit)
        };
        let range = Iv::point(ns.into());
        Expr::lit(text.to_string(), Val::Time { clean: true, range }, true)
    }

    /// A string literal of `min..=max` characters (rule 9 says which escapes are safe).
    pub(super) fn str_lit(&mut self, min: u32, max: u32) -> Expr {
        let n = self.rng.int(i128::from(min), i128::from(max)) as u32;
        let mut text = String::from("'");
        let mut after_hex_escape = false;
        for _ in 0..n {
            let r = self.rng.below(100);
            if after_hex_escape {
                text.push(*self.rng.pick(STR_CHARS_NOT_HEX) as char);
                after_hex_escape = false;
            } else if r < 88 {
                text.push(*self.rng.pick(STR_CHARS) as char);
            } else if r < 91 {
                text.push_str(if self.rng.pct(50) { "$$" } else { "$'" });
            } else if r < 95 {
                let esc = *self.rng.pick(&["$N", "$T", "$R", "$P"]);
                after_hex_escape = esc == "$N";
                text.push_str(esc);
            } else {
                let byte = if self.rng.pct(80) {
                    self.rng.int(0x20, 0x7e)
                } else {
                    self.rng.int(0x80, 0xff)
                };
                text.push_str(&format!("${byte:02X}"));
                after_hex_escape = true;
            }
        }
        text.push('\'');
        Expr::lit(text, Val::Str { min: n, max: n }, true)
    }
}

/// A real's text with a decimal point (`3.0`, `-0.125`), as ST wants.
pub(super) fn real_text(v: f64) -> String {
    let t = format!("{v}");
    if t.contains('.') {
        t
    } else {
        format!("{t}.0")
    }
}

/// `1234.5` as `1_234.5`.
pub(super) fn underscore_real(text: &str) -> String {
    let (sign, rest) = match text.strip_prefix('-') {
        Some(r) => ("-", r),
        None => ("", text),
    };
    match rest.split_once('.') {
        Some((int, frac)) if int.len() > 3 => format!("{sign}{}.{frac}", group(int, 3)),
        _ => text.to_string(),
    }
}
