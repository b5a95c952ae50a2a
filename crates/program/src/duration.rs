//! Durations, written the same way everywhere: in guards (`P30.t >= 3s`), in program and
//! configuration files (`period = "10ms"`), and on the command line (`--for 1h`).
//!
//! A duration is a decimal number and a unit: `250us` (or `250µs`), `500ms`, `3s`, `1.5s`,
//! `2min` (or `2m`), `1h`. It must come to a whole number of microseconds; the arithmetic is
//! exact. Where a caller allows it ([`Bare::Seconds`], the command line), a bare number means
//! seconds.

/// Units in microseconds, longest first: printing picks the largest that divides a duration.
pub const UNITS: [(&str, u64); 5] = [
    ("h", 3_600_000_000),
    ("min", 60_000_000),
    ("s", 1_000_000),
    ("ms", 1_000),
    ("us", 1),
];

/// Other spellings that are read but never printed.
const ALIASES: [(&str, u64); 2] = [("m", 60_000_000), ("µs", 1)];

/// What a number without a unit means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bare {
    /// Refused: a unit is required.
    Refused,
    /// Seconds (the command line).
    Seconds,
}

/// Why a text is not a duration.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DurationError {
    /// Not a number and a unit.
    #[error("`{0}` is not a duration; write a number and a unit, e.g. 500ms, 3s, 2min, 1h")]
    NotADuration(String),
    /// The unit is unknown.
    #[error("unknown duration unit `{0}`; expected one of us, ms, s, min, h (e.g. `500ms`)")]
    UnknownUnit(String),
    /// The number needs a unit.
    #[error("`{0}` needs a unit, e.g. `{0}ms` or `{0}s`")]
    NoUnit(String),
    /// Not a whole number of microseconds.
    #[error("a duration must be a whole number of microseconds")]
    Fraction,
    /// Longer than the runtime can count.
    #[error("duration too long; the longest is about 292 000 years")]
    TooLong,
}

/// The length of `unit` in microseconds.
pub fn unit_us(unit: &str) -> Option<u64> {
    UNITS
        .iter()
        .chain(ALIASES.iter())
        .find(|(u, _)| *u == unit)
        .map(|&(_, s)| s)
}

/// Exact microseconds of `whole.frac` `unit`, where `whole` and `frac` are ASCII digits.
pub fn micros(whole: &str, frac: &str, unit: &str) -> Result<u64, DurationError> {
    let scale = unit_us(unit).ok_or_else(|| DurationError::UnknownUnit(unit.to_string()))?;
    let whole: u64 = if whole.is_empty() {
        0
    } else {
        whole.parse().map_err(|_| DurationError::TooLong)?
    };
    let mut us = whole.checked_mul(scale).ok_or(DurationError::TooLong)?;
    if !frac.is_empty() {
        let (mut num, mut den) = (0u64, 1u64);
        for d in frac.bytes() {
            num = num
                .checked_mul(10)
                .and_then(|n| n.checked_add(u64::from(d - b'0')))
                .ok_or(DurationError::TooLong)?;
            den = den.checked_mul(10).ok_or(DurationError::TooLong)?;
        }
        let scaled = u128::from(num) * u128::from(scale);
        if scaled % u128::from(den) != 0 {
            return Err(DurationError::Fraction);
        }
        let extra = u64::try_from(scaled / u128::from(den)).map_err(|_| DurationError::TooLong)?;
        us = us.checked_add(extra).ok_or(DurationError::TooLong)?;
    }
    if us > i64::MAX as u64 {
        return Err(DurationError::TooLong);
    }
    Ok(us)
}

/// Parses a whole text as a duration in microseconds.
pub fn parse_us(text: &str, bare: Bare) -> Result<u64, DurationError> {
    let t = text.trim();
    let not = || DurationError::NotADuration(text.to_string());
    let int_end = t.find(|c: char| !c.is_ascii_digit()).unwrap_or(t.len());
    let (whole, rest) = t.split_at(int_end);
    let (frac, unit) = match rest.strip_prefix('.') {
        Some(r) => {
            let f_end = r.find(|c: char| !c.is_ascii_digit()).unwrap_or(r.len());
            r.split_at(f_end)
        }
        None => ("", rest),
    };
    if whole.is_empty() && frac.is_empty() {
        return Err(not());
    }
    if unit.is_empty() {
        return match bare {
            Bare::Seconds => micros(whole, frac, "s"),
            Bare::Refused => Err(DurationError::NoUnit(t.to_string())),
        };
    }
    if unit_us(unit).is_none() {
        // `3 weeks`, `soon`: name the whole text, not only the unit.
        return Err(if unit.chars().all(|c| c.is_alphabetic()) {
            DurationError::UnknownUnit(unit.to_string())
        } else {
            not()
        });
    }
    micros(whole, frac, unit)
}

/// Writes `us` with the largest unit that divides it (`90s`, `1500ms`, `2min`).
pub fn format_us(us: u64) -> String {
    for (unit, scale) in UNITS {
        if us != 0 && us.is_multiple_of(scale) {
            return format!("{}{unit}", us / scale);
        }
    }
    format!("{us}us")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_documented_form_scales_to_microseconds() {
        for (text, us) in [
            ("250us", 250),
            ("250µs", 250),
            ("500ms", 500_000),
            ("3s", 3_000_000),
            ("1.5s", 1_500_000),
            ("2min", 120_000_000),
            ("2m", 120_000_000),
            ("1h", 3_600_000_000),
            (" 90s ", 90_000_000),
        ] {
            assert_eq!(parse_us(text, Bare::Refused), Ok(us), "{text}");
        }
    }

    #[test]
    fn a_bare_number_is_seconds_only_where_allowed() {
        assert_eq!(parse_us("2", Bare::Seconds), Ok(2_000_000));
        assert_eq!(parse_us("0.5", Bare::Seconds), Ok(500_000));
        assert_eq!(
            parse_us("2", Bare::Refused),
            Err(DurationError::NoUnit("2".into()))
        );
    }

    #[test]
    fn bad_durations_say_what_to_write() {
        assert!(matches!(
            parse_us("soon", Bare::Seconds),
            Err(DurationError::NotADuration(_))
        ));
        assert!(parse_us("3 weeks", Bare::Seconds).is_err());
        assert_eq!(
            parse_us("3weeks", Bare::Seconds),
            Err(DurationError::UnknownUnit("weeks".into()))
        );
        assert_eq!(
            parse_us("0.5us", Bare::Seconds),
            Err(DurationError::Fraction)
        );
        assert_eq!(
            parse_us("99999999999999999999h", Bare::Seconds),
            Err(DurationError::TooLong)
        );
    }

    #[test]
    fn format_then_parse_is_identity() {
        for us in [1, 999, 1_000, 1_500_000, 60_000_000, 7_200_000_000, 0] {
            assert_eq!(parse_us(&format_us(us), Bare::Refused), Ok(us));
        }
    }
}
