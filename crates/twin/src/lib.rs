//! Digital twins of the plants Cetratus controls, for virtual commissioning and for validating an
//! update candidate before it drives the real cell.
//!
//! A twin is a [`Plant`]: the PLC hands it the output image, the twin answers with the input image.
//! Every twin is
//!
//! * **driven by virtual time.** Time is an argument (`now_us`, microseconds since the twin was built),
//!   never read from a clock, so a twin runs a virtual hour in milliseconds and a test is repeatable;
//! * **deterministic.** The only randomness is optional jitter on durations and the Festo station's
//!   defective parts, drawn from the crate's own [`rng::SplitMix64`] so that a seed gives the same
//!   stream forever, whatever a dependency does. With the default parameters there is neither jitter
//!   nor a defective part, and the seed has no effect;
//! * **forkable.** Twins are `Clone`: a fork taken mid-run and driven like the original stays identical
//!   to it, which is how a candidate program can be tried from the live plant's state;
//! * **honest about physics.** Misuse of the machine (two robot moves at once, a part pushed into a full
//!   buffer, a table turned while the drill is down) is recorded as a [`Fault`], never a panic, and the
//!   twin carries on so that a validation run can report every fault it saw;
//! * **allocation-free while running.** [`Plant::step`] and [`Plant::inputs`] never touch the heap: the
//!   fault log reserves its space up front (see [`FAULT_LOG_CAPACITY`]).
//!
//! # The step contract
//!
//! `step(now_us, outputs)` first advances the physics from the previous call up to `now_us` under the
//! previous output image (events due at or before `now_us` happen at their own time, in time order),
//! then applies `outputs` at `now_us`. [`Plant::inputs`] then describes the plant at `now_us`. A PLC
//! loop therefore reads: `step(now, &outputs)`, `inputs(&mut image)`, scan, repeat with a later `now`.
//! Output and input images are ordered as [`Plant::output_names`] and [`Plant::input_names`]. An image
//! of the wrong length is a [`FaultKind::ImageSize`] fault: missing outputs count as off, extra ones are
//! ignored. A `now_us` earlier than the previous one is a [`FaultKind::ClockRegression`] fault and is
//! treated as the previous time.
//!
//! # The Vernadat cell ([`vernadat::VernadatCell`], name `vernadat`)
//!
//! Two machines share a buffer; one robot loads and unloads them (docs/design.md §6). Inputs, in order:
//!
//! | input | true while |
//! |---|---|
//! | `PE`   | a raw part waits at the infeed; the next one arrives `infeed_interval_us` (1 s) after the robot picked the last one |
//! | `FCM1` | the CM1 move (infeed → M1) is complete and CM1 is still commanded |
//! | `FPM1` | M1 holds a finished part: from the end of machining until the robot picks it (start of DM1) |
//! | `EB`   | M1 holds a finished part with its clamp open (PM1 withdrawn) |
//! | `SB`   | the DM1 move (M1 → buffer) is complete and DM1 is still commanded |
//! | `FCM2` | the CM2 move (buffer → M2) is complete and CM2 is still commanded |
//! | `FPM2` | M2 holds a finished part: from the end of machining until the robot picks it (start of DM2) |
//! | `PS`   | the DM2 move (M2 → outfeed) is complete and DM2 is still commanded |
//!
//! Outputs, in order: `CM1`, `PM1`, `DM1`, `CM2`, `PM2`, `DM2`, `LM1`, `LM2`.
//!
//! * A move command (CM1, DM1, CM2, DM2) starts a robot move of `move_us` (1 s) when the robot is idle
//!   and it is the only move commanded. The robot grips the part at the start of the move, so the
//!   source's signals drop at once, and puts it down at the end. The acknowledgement stays true until the
//!   command is withdrawn; withdrawing it frees the robot.
//! * PM1/PM2 close the clamp and machine the loaded raw part: M1 takes `m1_machining_us` (3 s), M2
//!   `m2_machining_us` (6 s). Withdrawing PM opens the clamp. The machine runs whenever PM is on and a
//!   raw part is in it.
//! * LM1/LM2 lubricate. Keeping one on for `lubrication_us` (3 s, U.2's timers) counts one lubrication
//!   of that machine; a longer pulse still counts once.
//! * The buffer holds at most `buffer_capacity` (9) parts physically and starts with `buffer_initial` (3).
//! * DM2 delivers to the outfeed, which counts finished parts.
//!
//! Faults: [`FaultKind::Collision`] (two move commands at once; the robot keeps its current move and
//! starts none of the new ones), [`FaultKind::BufferOverflow`], [`FaultKind::MachineBusy`] (loading a
//! machine that holds a part), [`FaultKind::EmptySource`] (a move from an empty infeed, machine or
//! buffer: the robot moves empty-handed and still acknowledges), [`FaultKind::PartNotReady`] (unloading
//! a part that is unfinished or still clamped; it stays), [`FaultKind::MoveAborted`] (a command
//! withdrawn mid-move; the gripped part is dropped), [`FaultKind::MachiningInterrupted`] (PM withdrawn
//! before machining ended; the part must be machined again). A dropped or misplaced part is scrapped.
//!
//! Counters: `parts_finished`, `parts_in_buffer`, `lubrications_m1`, `lubrications_m2`,
//! `parts_machined_m1`, `parts_machined_m2`, `parts_scrapped`.
//!
//! Driven by the program net of docs/design.md §6 scanned every 10 ms, the cell makes 446 parts in a virtual
//! hour with no fault (the bound is 450: machine 2 needs 8 s per part); with U.2's 3 s lubrication
//! stages it makes 325 (`tests/vernadat_program.rs`).
//!
//! # The Festo processing station ([`festo::FestoStation`], name `festo`)
//!
//! A rotary indexing table with six nests carries parts past four stations: position 0 input, 1 hole
//! tester, 2 drill, 3 ejector (positions 4 and 5 are transit). Inputs, in order:
//!
//! | input | true while |
//! |---|---|
//! | `START`, `STOP`, `RESET` | the button is held; [`Plant::press`] holds it for `press_us` (200 ms) |
//! | `PART_AT_INPUT` | the table is in position and the nest at the input holds a part |
//! | `TABLE_IN_POS`  | the table's position cam is made: within `in_position_window_us` (100 ms of travel) after reaching a position |
//! | `PART_AT_TEST`  | the table is in position and the nest under the tester holds a part |
//! | `TESTER_DOWN`   | the tester's probe has reached its lower end (the part's hole is there): `test_us` (0.5 s) after the solenoid was energised |
//! | `PART_AT_DRILL` | the table is in position and the nest under the drill holds a part |
//! | `CLAMPED`       | the clamp is closed: `clamp_us` (0.2 s) after CLAMP came on |
//! | `DRILL_UP`      | the drill feed is at its upper end |
//! | `DRILL_DOWN`    | the drill feed is at its lower end, `drill_down_us` (2 s) of feed below the top |
//! | `PART_AT_EJECT` | the table is in position and the nest at the ejector holds a part |
//! | `EJECTOR_OUT`   | the ejector is fully out, `eject_us` (0.5 s) after EJECTOR came on; the part has left |
//! | `TEST_OK`       | the test result: the table is in position and the part under the tester passed the hole test (from the moment the probe reached the bottom of its hole until the part leaves) |
//! | `REJECTOR_OUT`  | the rejector is fully out, `reject_us` (0.5 s) after REJECTOR came on; the part under the tester has gone into the reject bin |
//!
//! Outputs, in order:
//!
//! | output | effect |
//! |---|---|
//! | `TABLE_MOTOR`     | turns the table; one index (60°) takes `index_us` (1 s); it keeps turning while on |
//! | `TESTER_SOLENOID` | lowers the probe; off lets the spring lift it at once |
//! | `CLAMP`           | closes the clamp on the part under the drill; off opens it at once |
//! | `DRILL_MOTOR`     | spins the drill |
//! | `DRILL_FEED_DOWN` | feeds the drill down; off feeds it up, in `drill_up_us` (0.5 s) for the whole travel |
//! | `EJECTOR`         | pushes the part at the ejector off the table; off retracts it at once |
//! | `REJECTOR`        | pushes the part under the tester into the reject bin; off retracts it at once |
//! | `REJECT_BIN_FULL` | a lamp asking the operator to empty the reject bin; the twin has no use for it |
//!
//! A part arrives upstream every `arrival_interval_us` (5 s, the first at time 0). The upstream station
//! puts it into the input nest when that nest is empty and the table stands in position with its motor
//! off; until then it waits. A part is tested when the probe reaches down on it, drilled when the feed
//! reaches its lower end on it while it is clamped and the drill spins, ejected when the ejector is fully
//! out, rejected when the rejector is fully out while the probe is up.
//!
//! A part is defective with probability `defect_ppm` parts per million (0 by default; 50 000 is 5 %),
//! drawn when it is put into the input nest from a stream of its own, so that the seed alone decides
//! which parts are defective. A defective part lies upside down: the probe stops on its closed
//! bottom, so `TESTER_DOWN` and `TEST_OK` never come, and a program finds out by a timeout. A
//! hand-coded program that tests (rejecting on a 1 s timeout), drills and ejects in parallel and then
//! indexes ejects 718 parts in a virtual hour without defects (`tests/festo_program.rs`).
//!
//! Faults: [`FaultKind::TableTurnWhileEngaged`] (the motor runs while the tester is down, the
//! clamp closed, the drill below its top, the ejector or the rejector out), [`FaultKind::EngagedOutOfPosition`]
//! (a module engaged while the table stands between positions), [`FaultKind::DrillWithoutClamp`] (the
//! drill reaches an unclamped part, or the clamp opens with the drill in the part),
//! [`FaultKind::DrillMotorOff`] (the drill is fed into a part with the spindle stopped),
//! [`FaultKind::RejectUnderProbe`] (the rejector pushes while the probe is down; the part stays).
//!
//! Counters: `parts_supplied`, `parts_defective` (of those supplied), `parts_tested`,
//! `parts_rejected`, `parts_rejected_good` (good parts thrown into the reject bin), `parts_drilled`,
//! `parts_good` (ejected good, tested and drilled), `parts_ejected`, `parts_ejected_incomplete`
//! (ejected without having been both tested and drilled), `parts_ejected_defective` (defective
//! parts that went downstream), `parts_waiting`.
//!
//! # Choosing a twin by name
//!
//! [`TwinKind`] parses `vernadat` and `festo`; [`TwinKind::build`] makes a [`Twin`] with default
//! parameters, [`TwinKind::boxed`] a `Box<dyn Plant>`.

#![warn(missing_docs)]

pub mod festo;
mod params;
mod physics;
pub mod rng;
pub mod vernadat;

use std::fmt;
use std::str::FromStr;

use serde::{Serialize, Serializer};

pub use festo::{FestoParams, FestoStation, PPM};
pub use params::{ParamValue, TwinParam};
pub(crate) use physics::{Books, Physics};
pub use vernadat::{VernadatCell, VernadatParams};

/// One second of virtual time, in the microseconds every twin counts in.
pub const SECOND_US: u64 = 1_000_000;

/// How many faults a twin records before it only counts further ones (see [`Plant::faults_dropped`]).
pub const FAULT_LOG_CAPACITY: usize = 1024;

/// The most counters a twin reports.
pub const MAX_COUNTERS: usize = 12;

/// A simulated plant that a PLC program drives through its I/O images.
pub trait Plant: Send {
    /// The twin's name, as [`TwinKind`] spells it.
    fn name(&self) -> &'static str;
    /// Names of the plant's inputs (the PLC's input image), in image order.
    fn input_names(&self) -> &[&'static str];
    /// Names of the plant's outputs (the PLC's output image), in image order.
    fn output_names(&self) -> &[&'static str];
    /// Advances the physics up to `now_us` under the previous outputs, then applies `outputs` at `now_us`.
    fn step(&mut self, now_us: u64, outputs: &[bool]);
    /// Writes the input image at the current time into `buf` (order of [`Plant::input_names`]).
    fn inputs(&self, buf: &mut [bool]);
    /// The virtual time of the last [`Plant::step`], in microseconds.
    fn now_us(&self) -> u64;
    /// Every physical fault seen so far, oldest first.
    fn faults(&self) -> &[Fault];
    /// Faults not kept because the log was full.
    fn faults_dropped(&self) -> u64;
    /// The plant's production counters.
    fn counters(&self) -> Counters;
    /// Names of the operator buttons [`Plant::press`] accepts.
    fn buttons(&self) -> &[&'static str];
    /// The presses an operator gives the plant to start it (button, virtual time in µs), when
    /// no others are asked for.
    fn start_presses(&self) -> &'static [(&'static str, u64)];
    /// Schedules an operator's press of `button` at virtual time `at_us`; a button the plant
    /// does not have is refused with the ones it has.
    fn press(&mut self, button: &str, at_us: u64) -> Result<(), TwinError>;
    /// A copy of the twin in its current state, which evolves independently from now on.
    fn fork(&self) -> Box<dyn Plant>;
}

/// What kind of physical misuse a [`Fault`] records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// Two robot moves were commanded at once.
    Collision,
    /// A part was put into a full buffer.
    BufferOverflow,
    /// A part was loaded into a machine that already held one.
    MachineBusy,
    /// A move started from a place with no part in it.
    EmptySource,
    /// A part was to be unloaded before it was finished and unclamped.
    PartNotReady,
    /// A move command was withdrawn before the move was complete.
    MoveAborted,
    /// A machining command was withdrawn before machining was complete.
    MachiningInterrupted,
    /// The rotary table turned while a module was engaged.
    TableTurnWhileEngaged,
    /// A module engaged while the table stood between two positions.
    EngagedOutOfPosition,
    /// The drill met a part that was not clamped.
    DrillWithoutClamp,
    /// The drill was fed into a part with its spindle stopped.
    DrillMotorOff,
    /// The rejector pushed a part while the tester's probe was down on it.
    RejectUnderProbe,
    /// An output image had the wrong length.
    ImageSize,
    /// Virtual time went backwards.
    ClockRegression,
}

impl FaultKind {
    /// The kind's stable snake_case name, for reports and topics.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Collision => "collision",
            Self::BufferOverflow => "buffer_overflow",
            Self::MachineBusy => "machine_busy",
            Self::EmptySource => "empty_source",
            Self::PartNotReady => "part_not_ready",
            Self::MoveAborted => "move_aborted",
            Self::MachiningInterrupted => "machining_interrupted",
            Self::TableTurnWhileEngaged => "table_turn_while_engaged",
            Self::EngagedOutOfPosition => "engaged_out_of_position",
            Self::DrillWithoutClamp => "drill_without_clamp",
            Self::DrillMotorOff => "drill_motor_off",
            Self::RejectUnderProbe => "reject_under_probe",
            Self::ImageSize => "image_size",
            Self::ClockRegression => "clock_regression",
        }
    }
}

impl fmt::Display for FaultKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A physical fault the twin saw: what, when, and a sentence for the operator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Fault {
    /// What went wrong.
    pub kind: FaultKind,
    /// Virtual time of the fault, in microseconds.
    pub at_us: u64,
    /// What happened, in words.
    pub message: &'static str,
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} at {}.{:06} s: {}",
            self.kind,
            self.at_us / SECOND_US,
            self.at_us % SECOND_US,
            self.message
        )
    }
}

/// The fault log: bounded, so that recording a fault in `step` never allocates.
#[derive(Debug, PartialEq, Eq)]
pub(crate) struct FaultLog {
    items: Vec<Fault>,
    dropped: u64,
}

impl FaultLog {
    pub(crate) fn new() -> Self {
        Self {
            items: Vec::with_capacity(FAULT_LOG_CAPACITY),
            dropped: 0,
        }
    }

    pub(crate) fn push(&mut self, kind: FaultKind, at_us: u64, message: &'static str) {
        if self.items.len() < FAULT_LOG_CAPACITY {
            self.items.push(Fault {
                kind,
                at_us,
                message,
            });
        } else {
            self.dropped += 1;
        }
    }

    pub(crate) fn as_slice(&self) -> &[Fault] {
        &self.items
    }

    pub(crate) fn dropped(&self) -> u64 {
        self.dropped
    }
}

impl Clone for FaultLog {
    // The derived clone would shrink the capacity to the length, and the fork's first fault would
    // then allocate inside `step`.
    fn clone(&self) -> Self {
        let mut items = Vec::with_capacity(FAULT_LOG_CAPACITY);
        items.extend_from_slice(&self.items);
        Self {
            items,
            dropped: self.dropped,
        }
    }
}

/// One named production counter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Counter {
    /// The counter's name, e.g. `parts_finished`.
    pub name: &'static str,
    /// Its value.
    pub value: u64,
}

/// A plant's counters, by name, in a fixed order; a value type so that reading them never allocates.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Counters {
    items: [Counter; MAX_COUNTERS],
    len: usize,
}

impl Counters {
    pub(crate) fn from_pairs(pairs: &[(&'static str, u64)]) -> Self {
        let mut items = [Counter { name: "", value: 0 }; MAX_COUNTERS];
        let len = pairs.len().min(MAX_COUNTERS);
        for (slot, &(name, value)) in items.iter_mut().zip(pairs) {
            *slot = Counter { name, value };
        }
        Self { items, len }
    }

    /// The counters as a slice, in the twin's order.
    pub fn as_slice(&self) -> &[Counter] {
        &self.items[..self.len]
    }

    /// The value of the counter called `name`, if the twin has one.
    pub fn get(&self, name: &str) -> Option<u64> {
        self.as_slice()
            .iter()
            .find(|c| c.name == name)
            .map(|c| c.value)
    }

    /// Iterates over the counters in the twin's order.
    pub fn iter(&self) -> std::slice::Iter<'_, Counter> {
        self.as_slice().iter()
    }
}

impl fmt::Debug for Counters {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_map()
            .entries(self.iter().map(|c| (c.name, c.value)))
            .finish()
    }
}

impl Serialize for Counters {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_map(self.iter().map(|c| (c.name, c.value)))
    }
}

/// Everything that can go wrong when choosing, building or operating a twin.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TwinError {
    /// No twin has that name.
    #[error("unknown twin `{name}`; choose one of: vernadat, festo")]
    UnknownTwin {
        /// The name asked for.
        name: String,
    },
    /// The twin has no such button.
    #[error("twin `{twin}` has no button `{button}`; its buttons are: [{known}]")]
    UnknownButton {
        /// The twin.
        twin: &'static str,
        /// The button asked for.
        button: String,
        /// The buttons it has, comma-separated.
        known: String,
    },
    /// A defect rate that is not a share between 0 and 1.
    #[error("invalid defect rate `{text}`: {reason}; write a percentage (`5%`), a fraction (`0.05`) or parts per million (`50000ppm`)")]
    InvalidDefectRate {
        /// The text given.
        text: String,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The twin has no such setting.
    #[error("twin `{twin}` has no setting `{setting}`: {reason}")]
    UnsupportedSetting {
        /// The twin.
        twin: &'static str,
        /// The setting.
        setting: &'static str,
        /// Why, and what to do.
        reason: &'static str,
    },
    /// A parameter given by name does not exist, or its value is of the wrong kind.
    #[error("twin `{twin}` cannot take the parameter `{name}`: {reason}")]
    UnknownParameter {
        /// The twin.
        twin: &'static str,
        /// The parameter as given.
        name: String,
        /// Why, and what it has.
        reason: String,
    },
    /// A parameter is out of range.
    #[error("invalid parameter `{name}` of twin `{twin}`: {reason}")]
    InvalidParameter {
        /// The twin.
        twin: &'static str,
        /// The parameter.
        name: &'static str,
        /// Why it is rejected and what would be accepted.
        reason: String,
    },
}

/// The twins this crate provides, chosen by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TwinKind {
    /// The Vernadat cell of docs/design.md §6.
    Vernadat,
    /// The Festo processing station.
    Festo,
}

impl TwinKind {
    /// Every kind, in a stable order.
    pub const ALL: [TwinKind; 2] = [TwinKind::Vernadat, TwinKind::Festo];

    /// The kind's name: `vernadat` or `festo`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Vernadat => vernadat::NAME,
            Self::Festo => festo::NAME,
        }
    }

    /// A twin of this kind with default parameters and the given jitter seed.
    pub fn build(self, seed: u64) -> Twin {
        match self {
            Self::Vernadat => Twin::Vernadat(VernadatCell::with_defaults(seed)),
            Self::Festo => Twin::Festo(FestoStation::with_defaults(seed)),
        }
    }

    /// Like [`TwinKind::build`], behind the [`Plant`] trait object.
    pub fn boxed(self, seed: u64) -> Box<dyn Plant> {
        Box::new(self.build(seed))
    }

    /// A twin of this kind with default parameters changed by `settings`; refuses a setting the
    /// twin does not have (the Vernadat cell makes no defective parts).
    pub fn configure(self, settings: &TwinSettings) -> Result<Twin, TwinError> {
        match self {
            Self::Vernadat if settings.defect_ppm > 0 => Err(TwinError::UnsupportedSetting {
                twin: vernadat::NAME,
                setting: "defect rate",
                reason: "the Vernadat cell makes no defective parts; leave the defect rate out",
            }),
            Self::Vernadat => {
                let mut params = VernadatParams::default();
                for p in &settings.params {
                    params.set(p)?;
                }
                Ok(Twin::Vernadat(VernadatCell::new(params, settings.seed)?))
            }
            Self::Festo => {
                let mut params = FestoParams {
                    defect_ppm: settings.defect_ppm,
                    ..FestoParams::default()
                };
                for p in &settings.params {
                    params.set(p)?;
                }
                Ok(Twin::Festo(FestoStation::new(params, settings.seed)?))
            }
        }
    }
}

/// What a twin chosen by name can be given from outside (`cetratus run --seed --defect-rate
/// --twin-param`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TwinSettings {
    /// The seed of the twin's randomness (jitter, defective parts).
    pub seed: u64,
    /// Defective parts per million supplied (Festo station only).
    pub defect_ppm: u32,
    /// Parameters changed from their defaults, in order.
    pub params: Vec<TwinParam>,
}

/// Parses a defect rate into parts per million: `5%`, `0.05` or `50000ppm`, between 0 and 1.
pub fn parse_defect_rate(text: &str) -> Result<u32, TwinError> {
    let bad = |reason| TwinError::InvalidDefectRate {
        text: text.to_owned(),
        reason,
    };
    let t = text.trim();
    let (number, per) = if let Some(n) = t.strip_suffix('%') {
        (n, 100.0)
    } else if let Some(n) = t.strip_suffix("ppm") {
        (n, f64::from(festo::PPM))
    } else {
        (t, 1.0)
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| bad("it is not a number"))?;
    if !value.is_finite() || value < 0.0 || value > per {
        return Err(bad("a defect rate lies between 0 and 1 (0 % and 100 %)"));
    }
    // In range by the check above, so the cast neither wraps nor saturates.
    Ok((value / per * f64::from(festo::PPM)).round() as u32)
}

impl FromStr for TwinKind {
    type Err = TwinError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| TwinError::UnknownTwin { name: s.to_owned() })
    }
}

impl fmt::Display for TwinKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Any twin of this crate, as one value type: `Clone`, comparable, and a [`Plant`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Twin {
    /// A Vernadat cell.
    Vernadat(VernadatCell),
    /// A Festo processing station.
    Festo(FestoStation),
}

impl Twin {
    /// A twin chosen by name (`vernadat`, `festo`) with default parameters.
    pub fn by_name(name: &str, seed: u64) -> Result<Self, TwinError> {
        Ok(name.parse::<TwinKind>()?.build(seed))
    }

    /// The counter that measures the plant's production, for throughput: finished parts of the
    /// Vernadat cell, good parts of the Festo station.
    pub fn production_counter(&self) -> &'static str {
        match self {
            Self::Vernadat(_) => "parts_finished",
            Self::Festo(_) => "parts_good",
        }
    }

    /// Which kind of twin this is.
    pub fn kind(&self) -> TwinKind {
        match self {
            Self::Vernadat(_) => TwinKind::Vernadat,
            Self::Festo(_) => TwinKind::Festo,
        }
    }

    fn plant(&self) -> &dyn Plant {
        match self {
            Self::Vernadat(t) => t,
            Self::Festo(t) => t,
        }
    }

    fn plant_mut(&mut self) -> &mut dyn Plant {
        match self {
            Self::Vernadat(t) => t,
            Self::Festo(t) => t,
        }
    }
}

impl Plant for Twin {
    fn name(&self) -> &'static str {
        self.plant().name()
    }
    fn input_names(&self) -> &[&'static str] {
        self.plant().input_names()
    }
    fn output_names(&self) -> &[&'static str] {
        self.plant().output_names()
    }
    fn step(&mut self, now_us: u64, outputs: &[bool]) {
        self.plant_mut().step(now_us, outputs);
    }
    fn inputs(&self, buf: &mut [bool]) {
        self.plant().inputs(buf);
    }
    fn now_us(&self) -> u64 {
        self.plant().now_us()
    }
    fn faults(&self) -> &[Fault] {
        self.plant().faults()
    }
    fn faults_dropped(&self) -> u64 {
        self.plant().faults_dropped()
    }
    fn counters(&self) -> Counters {
        self.plant().counters()
    }
    fn buttons(&self) -> &[&'static str] {
        self.plant().buttons()
    }
    fn start_presses(&self) -> &'static [(&'static str, u64)] {
        self.plant().start_presses()
    }
    fn press(&mut self, button: &str, at_us: u64) -> Result<(), TwinError> {
        self.plant_mut().press(button, at_us)
    }
    fn fork(&self) -> Box<dyn Plant> {
        Box::new(self.clone())
    }
}

/// The output at `idx`, or off when the image is too short.
pub(crate) fn out(outputs: &[bool], idx: usize) -> bool {
    outputs.get(idx).copied().unwrap_or(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn twin_kind_parses_both_names_and_rejects_others() {
        assert_eq!("vernadat".parse::<TwinKind>(), Ok(TwinKind::Vernadat));
        assert_eq!("Festo".parse::<TwinKind>(), Ok(TwinKind::Festo));
        assert!(matches!(
            "lathe".parse::<TwinKind>(),
            Err(TwinError::UnknownTwin { .. })
        ));
    }

    #[test]
    fn defect_rates_are_read_as_percentages_fractions_or_parts_per_million() {
        assert_eq!(parse_defect_rate("5%"), Ok(50_000));
        assert_eq!(parse_defect_rate("0.05"), Ok(50_000));
        assert_eq!(parse_defect_rate("50000ppm"), Ok(50_000));
        assert_eq!(parse_defect_rate("0"), Ok(0));
        assert_eq!(parse_defect_rate("100%"), Ok(PPM));
        for bad in ["", "five", "-1%", "101%", "1.5", "NaN"] {
            assert!(
                matches!(
                    parse_defect_rate(bad),
                    Err(TwinError::InvalidDefectRate { .. })
                ),
                "{bad:?} was accepted"
            );
        }
    }

    #[test]
    fn a_defect_rate_is_refused_for_the_vernadat_cell_and_given_to_the_festo_station() {
        let settings = TwinSettings {
            seed: 1,
            defect_ppm: 50_000,
            params: Vec::new(),
        };
        assert!(matches!(
            TwinKind::Vernadat.configure(&settings),
            Err(TwinError::UnsupportedSetting { .. })
        ));
        match TwinKind::Festo.configure(&settings) {
            Ok(Twin::Festo(st)) => assert_eq!(st.params().defect_ppm, 50_000),
            other => panic!("expected a Festo station, got {other:?}"),
        }
    }

    #[test]
    fn counters_are_found_by_name() {
        let c = Counters::from_pairs(&[("a", 1), ("b", 2)]);
        assert_eq!(c.get("b"), Some(2));
        assert_eq!(c.get("c"), None);
        assert_eq!(c.as_slice().len(), 2);
    }

    #[test]
    fn fault_log_keeps_its_capacity_when_cloned() {
        let mut log = FaultLog::new();
        log.push(FaultKind::Collision, 1, "x");
        let fork = log.clone();
        assert!(fork.items.capacity() >= FAULT_LOG_CAPACITY);
        assert_eq!(fork, log);
    }

    #[test]
    fn fault_log_counts_what_it_cannot_keep() {
        let mut log = FaultLog::new();
        for i in 0..FAULT_LOG_CAPACITY as u64 + 5 {
            log.push(FaultKind::Collision, i, "x");
        }
        assert_eq!(log.as_slice().len(), FAULT_LOG_CAPACITY);
        assert_eq!(log.dropped(), 5);
    }

    #[test]
    fn twins_built_by_name_have_their_signal_lists() {
        let v = Twin::by_name("vernadat", 0).expect("known twin");
        assert_eq!(v.input_names().len(), 8);
        assert_eq!(v.output_names().len(), 8);
        let f = Twin::by_name("festo", 0).expect("known twin");
        assert_eq!(f.buttons(), &["START", "STOP", "RESET"]);
    }

    #[test]
    fn pressing_a_button_the_cell_does_not_have_is_an_error() {
        let mut v = TwinKind::Vernadat.boxed(0);
        assert!(matches!(
            v.press("START", 0),
            Err(TwinError::UnknownButton { .. })
        ));
    }
}
