//! The I/O map of an export: each input and output of the program at a located address
//! (`%IX0.0`, `%QW2`), its own when it declares one, the next free one of its area and size
//! otherwise, written beside the export as `<program>.io.csv`.

use std::fmt::Write as _;

use cetratus_program::{Signal, Type};

use crate::ExportError;

/// One signal of the map.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IoRow {
    /// The signal's name in the program.
    pub signal: String,
    /// Its name in the export (different when the naming rule changed it).
    pub name: String,
    /// `input` or `output`.
    pub direction: &'static str,
    /// The located address, e.g. `%IX0.0`.
    pub address: String,
    /// The IEC type of the located variable: BOOL, INT, DINT, LINT, REAL or LREAL.
    pub iec_type: &'static str,
    /// Whether the address was assigned by the export (the program declared none).
    pub assigned: bool,
}

/// An address split into its parts: area letter, size letter, number (a bit's is `8·byte + bit`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Located {
    area: char,
    size: char,
    number: u64,
}

fn parse(address: &str) -> Option<Located> {
    let rest = address.strip_prefix('%')?;
    let mut chars = rest.chars();
    let area = chars.next()?.to_ascii_uppercase();
    let size = chars.next()?.to_ascii_uppercase();
    let digits = chars.as_str();
    if !matches!(area, 'I' | 'Q' | 'M') || !matches!(size, 'X' | 'W' | 'D' | 'L') {
        return None;
    }
    // Numbers are 32-bit at most, so that every address arithmetic below fits in a u64.
    let number = match (size, digits.split_once('.')) {
        ('X', Some((byte, bit))) => {
            let (byte, bit) = (byte.parse::<u32>().ok()?, bit.parse::<u8>().ok()?);
            (bit < 8).then_some(u64::from(byte) * 8 + u64::from(bit))?
        }
        (_, None) => u64::from(digits.parse::<u32>().ok()?),
        _ => return None,
    };
    Some(Located { area, size, number })
}

fn text(l: Located) -> String {
    match l.size {
        'X' => format!("%{}X{}.{}", l.area, l.number / 8, l.number % 8),
        s => format!("%{}{s}{}", l.area, l.number),
    }
}

/// The IEC type a located variable of this size holds a signal of this type as.
fn iec_type(ty: Type, size: char) -> Option<&'static str> {
    match (ty, size) {
        (Type::Bool, 'X') => Some("BOOL"),
        (Type::Int, 'W') => Some("INT"),
        (Type::Int, 'D') => Some("DINT"),
        (Type::Int, 'L') => Some("LINT"),
        (Type::Real, 'D') => Some("REAL"),
        (Type::Real, 'L') => Some("LREAL"),
        _ => None,
    }
}

/// The map of the program's inputs and outputs, `names` their names in the export.
pub(crate) fn map(
    inputs: &[Signal],
    outputs: &[Signal],
    name: impl Fn(&str) -> String,
) -> Result<Vec<IoRow>, ExportError> {
    let all = || {
        inputs
            .iter()
            .map(|s| (s, "input", 'I'))
            .chain(outputs.iter().map(|s| (s, "output", 'Q')))
    };
    // Every declared address checked first, so that an assigned one never overlaps it.
    let mut declared = Vec::new();
    for (s, direction, _) in all() {
        declared.push(
            s.address
                .as_ref()
                .map(|a| located(s, direction, a))
                .transpose()?,
        );
    }
    let mut used: Vec<Located> = declared.iter().flatten().copied().collect();
    let mut rows = Vec::new();
    for ((s, direction, area), declared) in all().zip(declared) {
        let (l, assigned) = match declared {
            Some(l) => (l, false),
            None => {
                let size = match s.ty {
                    Type::Bool => 'X',
                    Type::Int => 'W',
                    Type::Real => 'D',
                };
                let l = next_free(&used, area, size);
                used.push(l);
                (l, true)
            }
        };
        rows.push(IoRow {
            signal: s.name.clone(),
            name: name(&s.name),
            direction,
            address: text(l),
            iec_type: iec_type(s.ty, l.size)
                .expect("declared addresses are checked, and assigned ones fit"),
            assigned,
        });
    }
    Ok(rows)
}

/// A signal's declared address, if it is a direct address of a size that holds its type.
fn located(s: &Signal, direction: &str, a: &str) -> Result<Located, ExportError> {
    let refuse = |why: String| ExportError::Address {
        signal: s.name.clone(),
        address: a.to_string(),
        why,
    };
    let l = parse(a).ok_or_else(|| {
        refuse(
            "it is not an IEC 61131-3 direct address such as %IX0.0, %IW3 or %QD1 \
             (numbers below 2^32, bits 0 to 7)"
                .into(),
        )
    })?;
    iec_type(s.ty, l.size).ok_or_else(|| {
        refuse(format!(
            "the {direction} is {} and this size holds none; give it {}",
            s.ty,
            wanted(s.ty)
        ))
    })?;
    Ok(l)
}

fn wanted(ty: Type) -> &'static str {
    match ty {
        Type::Bool => "a bit address (%IX…, %QX…)",
        Type::Int => "a word, double or long address (%IW…, %QD…, %IL…)",
        Type::Real => "a double or long address (%ID…, %QL…)",
    }
}

/// The first address of `area` and `size` after every one used: a bit after the last bit, a
/// word (two bytes), double (four) or long (eight) after the last byte of any, so that no
/// assigned address overlaps a declared one.
fn next_free(used: &[Located], area: char, size: char) -> Located {
    let bits = |s: char| match s {
        'X' => 1,
        'W' => 16,
        'D' => 32,
        _ => 64,
    };
    let end = used
        .iter()
        .filter(|l| l.area == area)
        .map(|l| (l.number + 1) * bits(l.size))
        .max()
        .unwrap_or(0);
    Located {
        area,
        size,
        number: end.div_ceil(bits(size)),
    }
}

/// The map as CSV: `signal,address,type,direction,name`.
pub(crate) fn csv(rows: &[IoRow]) -> String {
    let mut s = String::from("signal,address,type,direction,name\n");
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{}",
            r.signal, r.address, r.iec_type, r.direction, r.name
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_parse_and_free_ones_follow_the_declared() {
        let l = parse("%IX1.3").unwrap();
        assert_eq!((l.area, l.size, l.number), ('I', 'X', 11));
        assert_eq!(text(l), "%IX1.3");
        assert!(parse("%IX0.8").is_none());
        assert!(parse("IX0.0").is_none());
        assert!(parse("%IW18446744073709551615").is_none());
        assert!(parse("%IX4294967296.0").is_none());
        let top = parse("%IW4294967295").unwrap();
        assert_eq!(text(next_free(&[top], 'I', 'W')), "%IW4294967296");
        let used = [l, parse("%IW2").unwrap()];
        assert_eq!(text(next_free(&used, 'I', 'X')), "%IX6.0");
        assert_eq!(text(next_free(&[l], 'I', 'X')), "%IX1.4");
        assert_eq!(text(next_free(&used, 'I', 'W')), "%IW3");
        assert_eq!(text(next_free(&used, 'I', 'D')), "%ID2");
        assert_eq!(text(next_free(&used, 'Q', 'X')), "%QX0.0");
    }
}
