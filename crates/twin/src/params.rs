//! Parameters of a twin changed from their defaults, by name (`cetratus run --twin-param
//! m2_machining=24s`): a plant that is not quite the model, to run a PLC against while its
//! updates are validated on the model itself (docs/operations.md, *The digital twins*).

use crate::{FestoParams, TwinError, VernadatParams};

/// A parameter's value: a duration in µs, for a parameter that is one, or a count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamValue {
    /// A duration, µs.
    Micros(u64),
    /// A count.
    Count(u64),
}

/// One parameter changed from its default.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TwinParam {
    /// The parameter's name, without its unit (`m2_machining`, `buffer_capacity`).
    pub name: String,
    /// Its value.
    pub value: ParamValue,
}

/// Where a value goes: a duration field, or a count field.
enum Field<'a> {
    Micros(&'a mut u64),
    Count(&'a mut u32),
}

/// Sets `field` to `value`, or says why it cannot be.
fn put(twin: &'static str, p: &TwinParam, field: Field<'_>) -> Result<(), TwinError> {
    let bad = |reason: String| TwinError::UnknownParameter {
        twin,
        name: p.name.clone(),
        reason,
    };
    match (field, p.value) {
        (Field::Micros(f), ParamValue::Micros(us)) => *f = us,
        (Field::Count(f), ParamValue::Count(n)) => {
            *f = u32::try_from(n).map_err(|_| bad(format!("{n} is too large a count")))?
        }
        (Field::Micros(_), ParamValue::Count(n)) => {
            return Err(bad(format!(
                "it is a duration; give one with its unit, e.g. {n}s or {n}ms"
            )))
        }
        (Field::Count(_), ParamValue::Micros(_)) => {
            return Err(bad("it is a count; give a whole number".into()))
        }
    }
    Ok(())
}

impl VernadatParams {
    /// The parameters `--twin-param` may change, for messages.
    pub const NAMES: &'static str = "infeed_interval, move, m1_machining, m2_machining, lubrication, jitter (durations); buffer_capacity, buffer_initial (counts)";

    /// Changes one parameter, by name.
    pub fn set(&mut self, p: &TwinParam) -> Result<(), TwinError> {
        let field = match p.name.as_str() {
            "infeed_interval" => Field::Micros(&mut self.infeed_interval_us),
            "move" => Field::Micros(&mut self.move_us),
            "m1_machining" => Field::Micros(&mut self.m1_machining_us),
            "m2_machining" => Field::Micros(&mut self.m2_machining_us),
            "lubrication" => Field::Micros(&mut self.lubrication_us),
            "jitter" => Field::Micros(&mut self.jitter_us),
            "buffer_capacity" => Field::Count(&mut self.buffer_capacity),
            "buffer_initial" => Field::Count(&mut self.buffer_initial),
            _ => return Err(unknown(crate::vernadat::NAME, p, Self::NAMES)),
        };
        put(crate::vernadat::NAME, p, field)
    }
}

impl FestoParams {
    /// The parameters `--twin-param` may change, for messages (the defect rate has its own
    /// option, `--defect-rate`).
    pub const NAMES: &'static str = "index, in_position_window, test, clamp, drill_down, drill_up, eject, reject, arrival_interval, press, jitter (durations)";

    /// Changes one parameter, by name.
    pub fn set(&mut self, p: &TwinParam) -> Result<(), TwinError> {
        let field = match p.name.as_str() {
            "index" => &mut self.index_us,
            "in_position_window" => &mut self.in_position_window_us,
            "test" => &mut self.test_us,
            "clamp" => &mut self.clamp_us,
            "drill_down" => &mut self.drill_down_us,
            "drill_up" => &mut self.drill_up_us,
            "eject" => &mut self.eject_us,
            "reject" => &mut self.reject_us,
            "arrival_interval" => &mut self.arrival_interval_us,
            "press" => &mut self.press_us,
            "jitter" => &mut self.jitter_us,
            _ => return Err(unknown(crate::festo::NAME, p, Self::NAMES)),
        };
        put(crate::festo::NAME, p, Field::Micros(field))
    }
}

fn unknown(twin: &'static str, p: &TwinParam, names: &str) -> TwinError {
    TwinError::UnknownParameter {
        twin,
        name: p.name.clone(),
        reason: format!("it has no such parameter; it has {names}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(name: &str, value: ParamValue) -> TwinParam {
        TwinParam {
            name: name.into(),
            value,
        }
    }

    #[test]
    fn parameters_are_set_by_name_and_a_wrong_name_or_unit_says_what_to_give() {
        let mut v = VernadatParams::default();
        v.set(&p("m2_machining", ParamValue::Micros(24_000_000)))
            .expect("a duration");
        v.set(&p("buffer_capacity", ParamValue::Count(7)))
            .expect("a count");
        assert_eq!((v.m2_machining_us, v.buffer_capacity), (24_000_000, 7));
        let e = v
            .set(&p("m3_machining", ParamValue::Micros(1)))
            .unwrap_err();
        assert!(e.to_string().contains("m2_machining"), "{e}");
        let e = v.set(&p("move", ParamValue::Count(3))).unwrap_err();
        assert!(e.to_string().contains("3s"), "{e}");
        let mut f = FestoParams::default();
        f.set(&p("drill_down", ParamValue::Micros(5)))
            .expect("a duration");
        assert_eq!(f.drill_down_us, 5);
        assert!(f.set(&p("buffer_capacity", ParamValue::Count(1))).is_err());
    }
}
