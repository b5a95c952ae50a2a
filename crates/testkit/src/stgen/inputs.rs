//! Input sequences: per scan, a value of each input in canonical text.

use super::*;

/// Per scan, the value of each input in canonical text.
pub(super) fn sequence(rng: &mut Rng, inputs: &[(String, Ty)], scans: usize) -> Vec<Vec<String>> {
    let mut signals: Vec<Signal> = inputs.iter().map(|(_, t)| Signal::new(rng, *t)).collect();
    (0..scans)
        .map(|k| signals.iter_mut().map(|s| s.next(rng, k)).collect())
        .collect()
}

/// How an input changes from scan to scan.
enum Shape {
    /// A BOOL square wave: period, time high, phase.
    Square(usize, usize, usize),
    /// A BOOL that is random in every scan.
    Random,
    /// A value held for a few scans, then another.
    Hold,
    /// An integer that counts up by one in every scan (towards and over its limit).
    Ramp,
}

struct Signal {
    ty: Ty,
    shape: Shape,
    held: usize,
    value: String,
    ramp: i128,
}

impl Signal {
    pub(super) fn new(rng: &mut Rng, ty: Ty) -> Signal {
        let shape = match ty {
            Ty::Bool => match rng.below(10) {
                0..=4 => {
                    let p = rng.range(2, 10);
                    Shape::Square(p, rng.range(1, p - 1), rng.range(0, p - 1))
                }
                5..=7 => Shape::Random,
                _ => Shape::Hold,
            },
            t if t.is_int() && rng.pct(15) => Shape::Ramp,
            _ => Shape::Hold,
        };
        let full = ty.full();
        Signal {
            ty,
            shape,
            held: 0,
            value: String::new(),
            ramp: full.hi - rng.int(0, 10).min(full.hi),
        }
    }

    pub(super) fn next(&mut self, rng: &mut Rng, scan: usize) -> String {
        match self.shape {
            Shape::Square(p, high, phase) => bool_text((scan + phase) % p < high),
            Shape::Random => bool_text(rng.pct(50)),
            Shape::Ramp => {
                let full = self.ty.full();
                let v = self.ramp;
                self.ramp = if v == full.hi { full.lo } else { v + 1 };
                v.to_string()
            }
            Shape::Hold => {
                if self.held == 0 {
                    self.value = value(rng, self.ty);
                    self.held = if self.ty == Ty::Bool {
                        rng.range(1, 12)
                    } else {
                        rng.range(1, 8)
                    };
                }
                self.held -= 1;
                self.value.clone()
            }
        }
    }
}

pub(super) fn bool_text(b: bool) -> String {
    if b { "TRUE" } else { "FALSE" }.to_string()
}

/// A random value of `ty` in canonical text.
pub(super) fn value(rng: &mut Rng, ty: Ty) -> String {
    match ty {
        Ty::Bool => bool_text(rng.pct(50)),
        Ty::Real => format!("r{:08x}", (real(rng, 1e3) as f32).to_bits()),
        Ty::Lreal => format!("l{:016x}", real(rng, 1e5).to_bits()),
        Ty::Time => {
            let ms = if rng.pct(70) {
                10 * rng.int(0, 30)
            } else {
                rng.int(0, 10_000)
            };
            format!("t{}", ms * 1_000_000)
        }
        Ty::String => string(rng),
        t => {
            let full = t.full();
            let v = match rng.below(20) {
                0..=4 => *rng.pick(&[full.lo, full.lo + 1, full.hi, full.hi - 1, 0, 1]),
                5..=11 => rng.int((-20).max(full.lo), 20),
                12 if t.is_bits() => 1 << (t.width() - 1),
                _ => rng.int(full.lo, full.hi),
            };
            v.to_string()
        }
    }
}

/// A "nice" real within ±`max`: quarters, tenths (rounded to f32 by the caller), integers.
pub(super) fn real(rng: &mut Rng, max: f64) -> f64 {
    let m = max as i128;
    match rng.below(10) {
        0..=3 => rng.int(-400, 400) as f64 / 4.0,
        4..=6 => rng.int(-10 * m, 10 * m) as f64 / 10.0,
        7..=8 => rng.int(-m, m) as f64,
        _ => 0.0,
    }
}

/// Printable ASCII of at most 20 characters, quoted as canonical text.
pub(super) fn string(rng: &mut Rng) -> String {
    let n = rng.range(0, 20);
    let bytes: Vec<u8> = match rng.below(10) {
        0..=3 => (0..n).map(|_| rng.int(0x20, 0x7e) as u8).collect(),
        4..=7 => (0..n).map(|_| *rng.pick(b"aabbcxyzAB 01")).collect(),
        _ => rng
            .pick(&[
                "",
                "a",
                "abc",
                "Hello",
                "xyz123",
                "it's",
                "$5",
                "ab ab",
                "ABCDEFGHIJKLMNOPQRST",
            ])
            .bytes()
            .collect(),
    };
    let mut out = String::from("'");
    for b in bytes {
        match b {
            b'$' => out.push_str("$$"),
            b'\'' => out.push_str("$'"),
            0x20..=0x7e => out.push(b as char),
            _ => out.push_str(&format!("${b:02X}")),
        }
    }
    out.push('\'');
    out
}
