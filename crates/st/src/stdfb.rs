//! The standard function blocks of IEC 61131-3 (§6.6.3.5): bistables, edge detection, counters
//! and timers, with the semantics of MATIEC's library (`lib/C/iec_std_FB.h`) statement for
//! statement, run natively.
//!
//! An instance is a run of slots: its inputs, its outputs, then its hidden state. The timers
//! read the scan's time (`now`, nanoseconds), as every Cetratus timer does, where MATIEC reads
//! `__CURRENT_TIME`; a program that runs with the same time per scan gets the same results.

use crate::types::{wrap, Elem};

/// A standard function block type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StdFb {
    /// SR: set-dominant bistable.
    Sr,
    /// RS: reset-dominant bistable.
    Rs,
    /// R_TRIG: rising edge.
    RTrig,
    /// F_TRIG: falling edge.
    FTrig,
    /// CTU and its typed forms (CTU_DINT …): the counter's type.
    Ctu(Elem),
    /// CTD and its typed forms.
    Ctd(Elem),
    /// CTUD and its typed forms.
    Ctud(Elem),
    /// TP: pulse.
    Tp,
    /// TON: on-delay.
    Ton,
    /// TOF: off-delay.
    Tof,
}

/// Whether a member of an instance can be set by a call, read after it, or neither.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// A VAR_INPUT.
    Input,
    /// A VAR_OUTPUT.
    Output,
    /// Internal state.
    Hidden,
}

/// A member of a standard FB instance: its name, type and access; its slot is its index.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StdField {
    /// The name, upper case.
    pub name: &'static str,
    /// Its type.
    pub elem: Elem,
    /// Input, output or hidden.
    pub access: Access,
}

use Access::{Hidden, Input, Output};

/// A member's name and type.
type Member = (&'static str, Elem);

/// The members of an instance in slot order, from the block's interface as the standard declares
/// it: its VAR_INPUT, its VAR_OUTPUT, then its internal state.
fn members(inputs: &[Member], outputs: &[Member], hidden: &[Member]) -> Vec<StdField> {
    let tagged = |list: &[Member], access| {
        list.iter()
            .map(move |&(name, elem)| StdField { name, elem, access })
            .collect::<Vec<_>>()
    };
    [
        tagged(inputs, Input),
        tagged(outputs, Output),
        tagged(hidden, Hidden),
    ]
    .concat()
}

/// The counter types MATIEC's library defines.
const COUNTER_TYPES: [(&str, Elem); 5] = [
    ("", Elem::Int),
    ("_DINT", Elem::Dint),
    ("_LINT", Elem::Lint),
    ("_UDINT", Elem::Udint),
    ("_ULINT", Elem::Ulint),
];

/// A counter's members: its BOOL inputs, `PV`, its BOOL outputs, `CV`, then the hidden edge
/// memory of each counting input (`CU_T_M`, `CD_T_M`), as MATIEC lays them out.
fn counter(e: Elem, inputs: &[&'static str], outputs: &[&'static str]) -> Vec<StdField> {
    let bools = |names: &[&'static str]| names.iter().map(|&n| (n, Elem::Bool)).collect::<Vec<_>>();
    let memories: Vec<Member> = [("CU", "CU_T_M"), ("CD", "CD_T_M")]
        .into_iter()
        .filter(|(counting, _)| inputs.contains(counting))
        .map(|(_, memory)| (memory, Elem::Bool))
        .collect();
    members(
        &[bools(inputs), vec![("PV", e)]].concat(),
        &[bools(outputs), vec![("CV", e)]].concat(),
        &memories,
    )
}

impl StdFb {
    /// The standard FB named `upper` (upper case), if it is one.
    pub fn from_name(upper: &str) -> Option<StdFb> {
        let fixed = match upper {
            "SR" => Some(StdFb::Sr),
            "RS" => Some(StdFb::Rs),
            "R_TRIG" => Some(StdFb::RTrig),
            "F_TRIG" => Some(StdFb::FTrig),
            "TP" => Some(StdFb::Tp),
            "TON" => Some(StdFb::Ton),
            "TOF" => Some(StdFb::Tof),
            _ => None,
        };
        fixed.or_else(|| {
            COUNTER_TYPES.iter().find_map(|&(suffix, e)| {
                let is = |base: &str| upper.strip_prefix(base) == Some(suffix);
                if is("CTUD") {
                    Some(StdFb::Ctud(e))
                } else if is("CTU") {
                    Some(StdFb::Ctu(e))
                } else if is("CTD") {
                    Some(StdFb::Ctd(e))
                } else {
                    None
                }
            })
        })
    }

    /// The IEC name.
    pub fn name(self) -> String {
        let counter = |base: &str, e: Elem| {
            let suffix = COUNTER_TYPES.iter().find(|c| c.1 == e).map_or("", |c| c.0);
            format!("{base}{suffix}")
        };
        match self {
            StdFb::Sr => "SR".into(),
            StdFb::Rs => "RS".into(),
            StdFb::RTrig => "R_TRIG".into(),
            StdFb::FTrig => "F_TRIG".into(),
            StdFb::Ctu(e) => counter("CTU", e),
            StdFb::Ctd(e) => counter("CTD", e),
            StdFb::Ctud(e) => counter("CTUD", e),
            StdFb::Tp => "TP".into(),
            StdFb::Ton => "TON".into(),
            StdFb::Tof => "TOF".into(),
        }
    }

    /// The members of an instance, in slot order.
    pub fn fields(self) -> Vec<StdField> {
        use Elem::{Bool, Sint, Time};
        match self {
            StdFb::Sr => members(&[("S1", Bool), ("R", Bool)], &[("Q1", Bool)], &[]),
            StdFb::Rs => members(&[("S", Bool), ("R1", Bool)], &[("Q1", Bool)], &[]),
            StdFb::RTrig | StdFb::FTrig => {
                members(&[("CLK", Bool)], &[("Q", Bool)], &[("M", Bool)])
            }
            StdFb::Tp | StdFb::Ton | StdFb::Tof => members(
                &[("IN", Bool), ("PT", Time)],
                &[("Q", Bool), ("ET", Time)],
                &[("STATE", Sint), ("PREV_IN", Bool), ("START_TIME", Time)],
            ),
            StdFb::Ctu(e) => counter(e, &["CU", "R"], &["Q"]),
            StdFb::Ctd(e) => counter(e, &["CD", "LD"], &["Q"]),
            StdFb::Ctud(e) => counter(e, &["CU", "CD", "R", "LD"], &["QU", "QD"]),
        }
    }

    /// Runs one call of the block on its instance `s` (its slots) at time `now`.
    #[inline]
    pub fn step(self, s: &mut [u64], now: i64) {
        match self {
            StdFb::Sr => s[2] = (s[0] != 0 || (s[1] == 0 && s[2] != 0)) as u64,
            StdFb::Rs => s[2] = (s[1] == 0 && (s[0] != 0 || s[2] != 0)) as u64,
            StdFb::RTrig => {
                s[1] = (s[0] != 0 && s[2] == 0) as u64;
                s[2] = s[0];
            }
            StdFb::FTrig => {
                s[1] = (s[0] == 0 && s[2] == 0) as u64;
                s[2] = (s[0] == 0) as u64;
            }
            StdFb::Ctu(e) => ctu(e, s),
            StdFb::Ctd(e) => ctd(e, s),
            StdFb::Ctud(e) => ctud(e, s),
            StdFb::Tp => tp(s, now),
            StdFb::Ton => ton(s, now),
            StdFb::Tof => tof(s, now),
        }
    }
}

/// An R_TRIG on `clk` whose memory is `*m`: its Q.
#[inline]
fn rising(clk: u64, m: &mut u64) -> bool {
    let q = clk != 0 && *m == 0;
    *m = clk;
    q
}

/// `a < b` in the counter type `e`.
#[inline]
fn less(e: Elem, a: u64, b: u64) -> bool {
    if e.is_signed() {
        (a as i64) < (b as i64)
    } else {
        a < b
    }
}

/// `a > 0` in the counter type `e`.
#[inline]
fn positive(e: Elem, a: u64) -> bool {
    if e.is_signed() {
        (a as i64) > 0
    } else {
        a > 0
    }
}

fn ctu(e: Elem, s: &mut [u64]) {
    let (cu, r, pv) = (s[0], s[1], s[2]);
    let up = rising(cu, &mut s[5]);
    if r != 0 {
        s[4] = 0;
    } else if up && less(e, s[4], pv) {
        s[4] = wrap(e, s[4].wrapping_add(1));
    }
    s[3] = (!less(e, s[4], pv)) as u64;
}

fn ctd(e: Elem, s: &mut [u64]) {
    let (cd, ld, pv) = (s[0], s[1], s[2]);
    let down = rising(cd, &mut s[5]);
    if ld != 0 {
        s[4] = pv;
    } else if down && positive(e, s[4]) {
        s[4] = wrap(e, s[4].wrapping_sub(1));
    }
    s[3] = (!positive(e, s[4])) as u64;
}

fn ctud(e: Elem, s: &mut [u64]) {
    let down = rising(s[1], &mut s[9]);
    let up = rising(s[0], &mut s[8]);
    let (r, ld, pv) = (s[2], s[3], s[4]);
    if r != 0 {
        s[7] = 0;
    } else if ld != 0 {
        s[7] = pv;
    } else if !(up && down) {
        if up && less(e, s[7], pv) {
            s[7] = wrap(e, s[7].wrapping_add(1));
        } else if down && positive(e, s[7]) {
            s[7] = wrap(e, s[7].wrapping_sub(1));
        }
    }
    s[5] = (!less(e, s[7], pv)) as u64;
    s[6] = (!positive(e, s[7])) as u64;
}

/// Slots of a timer instance.
const IN: usize = 0;
const PT: usize = 1;
const Q: usize = 2;
const ET: usize = 3;
const STATE: usize = 4;
const PREV_IN: usize = 5;
const START: usize = 6;

/// Whether the time since `START` has reached `PT` at `now`.
#[inline]
fn elapsed(s: &[u64], now: i64) -> bool {
    (s[START] as i64).wrapping_add(s[PT] as i64) <= now
}

fn tp(s: &mut [u64], now: i64) {
    if s[STATE] == 0 && s[PREV_IN] == 0 && s[IN] != 0 {
        s[STATE] = 1;
        s[Q] = 1;
        s[START] = now as u64;
    } else if s[STATE] == 1 {
        if elapsed(s, now) {
            s[STATE] = 2;
            s[Q] = 0;
            s[ET] = s[PT];
        } else {
            s[ET] = now.wrapping_sub(s[START] as i64) as u64;
        }
    }
    if s[STATE] == 2 && s[IN] == 0 {
        s[ET] = 0;
        s[STATE] = 0;
    }
    s[PREV_IN] = s[IN];
}

fn ton(s: &mut [u64], now: i64) {
    if s[STATE] == 0 && s[PREV_IN] == 0 && s[IN] != 0 {
        s[STATE] = 1;
        s[Q] = 0;
        s[START] = now as u64;
    } else if s[IN] == 0 {
        s[ET] = 0;
        s[Q] = 0;
        s[STATE] = 0;
    } else if s[STATE] == 1 {
        if elapsed(s, now) {
            s[STATE] = 2;
            s[Q] = 1;
            s[ET] = s[PT];
        } else {
            s[ET] = now.wrapping_sub(s[START] as i64) as u64;
        }
    }
    s[PREV_IN] = s[IN];
}

fn tof(s: &mut [u64], now: i64) {
    if s[STATE] == 0 && s[PREV_IN] != 0 && s[IN] == 0 {
        s[STATE] = 1;
        s[START] = now as u64;
    } else if s[IN] != 0 {
        s[ET] = 0;
        s[STATE] = 0;
    } else if s[STATE] == 1 {
        if elapsed(s, now) {
            s[STATE] = 2;
            s[ET] = s[PT];
        } else {
            s[ET] = now.wrapping_sub(s[START] as i64) as u64;
        }
    }
    s[Q] = (s[IN] != 0 || s[STATE] == 1) as u64;
    s[PREV_IN] = s[IN];
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    #[test]
    fn names_read_back_to_their_block() {
        for fb in [
            StdFb::Sr,
            StdFb::Rs,
            StdFb::RTrig,
            StdFb::FTrig,
            StdFb::Ctu(Elem::Int),
            StdFb::Ctd(Elem::Dint),
            StdFb::Ctud(Elem::Ulint),
            StdFb::Tp,
            StdFb::Ton,
            StdFb::Tof,
        ] {
            assert_eq!(StdFb::from_name(&fb.name()), Some(fb));
        }
        assert_eq!(StdFb::from_name("CTU_SINT"), None);
    }

    #[test]
    fn ton_sets_q_once_pt_has_elapsed_and_clears_it_when_in_falls() {
        let mut s = [0u64; 7];
        s[PT] = (30 * MS) as u64;
        s[IN] = 1;
        let q: Vec<u64> = (0..5)
            .map(|k| {
                StdFb::Ton.step(&mut s, k * 10 * MS);
                s[Q]
            })
            .collect();
        assert_eq!(q, [0, 0, 0, 1, 1]);
        s[IN] = 0;
        StdFb::Ton.step(&mut s, 50 * MS);
        assert_eq!((s[Q], s[ET]), (0, 0));
    }

    #[test]
    fn f_trig_fires_in_the_first_scan_when_clk_starts_false_as_matiec_s_does() {
        let mut s = [0u64; 3];
        StdFb::FTrig.step(&mut s, 0);
        assert_eq!(s[1], 1);
        StdFb::FTrig.step(&mut s, 0);
        assert_eq!(s[1], 0);
    }

    #[test]
    fn ctu_counts_rising_edges_up_to_pv() {
        let mut s = [0u64; 6];
        s[2] = 2;
        for clk in [1, 0, 1, 0, 1] {
            s[0] = clk;
            StdFb::Ctu(Elem::Int).step(&mut s, 0);
        }
        assert_eq!((s[4], s[3]), (2, 1));
    }
}
