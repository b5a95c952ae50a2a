//! Durations on the command line: `500ms`, `3s`, `1.5s`, `2min`, `1h`, `250us`.

use anyhow::bail;

/// Parses a duration into microseconds.
pub fn parse_duration_us(text: &str) -> anyhow::Result<u64> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let value: f64 = match num.parse() {
        Ok(v) => v,
        Err(_) => {
            bail!("`{text}` is not a duration; write a number and a unit, e.g. 500ms, 3s, 2min, 1h")
        }
    };
    let scale = match unit {
        "us" | "µs" => 1.0,
        "ms" => 1e3,
        "s" | "" => 1e6,
        "min" | "m" => 60e6,
        "h" => 3600e6,
        other => bail!("unknown unit `{other}` in `{text}`; use us, ms, s, min or h"),
    };
    let us = value * scale;
    if !us.is_finite() || !(0.0..=1e18).contains(&us) {
        bail!("`{text}` is out of range");
    }
    Ok(us.round() as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_scale_to_microseconds() {
        assert_eq!(parse_duration_us("500ms").unwrap(), 500_000);
        assert_eq!(parse_duration_us("1.5s").unwrap(), 1_500_000);
        assert_eq!(parse_duration_us("2min").unwrap(), 120_000_000);
        assert_eq!(parse_duration_us("1h").unwrap(), 3_600_000_000);
        assert!(parse_duration_us("soon").is_err());
        assert!(parse_duration_us("3 weeks").is_err());
    }
}
