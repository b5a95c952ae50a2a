//! The Festo processing station: rotary indexing table, hole tester, drill with clamp, ejector.
//!
//! The signal semantics are described in the crate documentation.
//!
//! A part is defective with probability `defect_ppm` parts per million, drawn when the upstream
//! station hands it over, from a stream of its own: the seed decides which parts are defective, and
//! jitter (drawn from another stream) does not change that choice. A defective part lies upside
//! down: the tester's probe stops on its closed bottom, never reaches its lower end and never
//! reports the test passed.

use serde::{Deserialize, Serialize};

use crate::rng::SplitMix64;
use crate::{out, Books, Counters, FaultKind, Physics, TwinError, SECOND_US};

/// The twin's name.
pub const NAME: &str = "festo";

/// Mixed into the seed for the stream that decides which parts are defective.
const DEFECT_STREAM: u64 = 0xD3FE_C7D3_FEC7_0001;

/// Input names, in image order.
pub const INPUT_NAMES: [&str; 15] = [
    "START",
    "STOP",
    "RESET",
    "PART_AT_INPUT",
    "TABLE_IN_POS",
    "PART_AT_TEST",
    "TESTER_DOWN",
    "PART_AT_DRILL",
    "CLAMPED",
    "DRILL_UP",
    "DRILL_DOWN",
    "PART_AT_EJECT",
    "EJECTOR_OUT",
    "TEST_OK",
    "REJECTOR_OUT",
];

/// Output names, in image order.
pub const OUTPUT_NAMES: [&str; 8] = [
    "TABLE_MOTOR",
    "TESTER_SOLENOID",
    "CLAMP",
    "DRILL_MOTOR",
    "DRILL_FEED_DOWN",
    "EJECTOR",
    "REJECTOR",
    "REJECT_BIN_FULL",
];

/// The operator buttons, in input order.
pub const BUTTONS: [&str; 3] = ["START", "STOP", "RESET"];

/// Number of nests on the rotary table.
pub const NESTS: usize = 6;

/// Table positions of the stations (nest under each station after an index).
pub mod position {
    /// Where the upstream station puts parts.
    pub const INPUT: usize = 0;
    /// Under the hole tester.
    pub const TEST: usize = 1;
    /// Under the drill.
    pub const DRILL: usize = 2;
    /// In front of the ejector.
    pub const EJECT: usize = 3;
}

/// Indices of the inputs in the input image.
pub mod input {
    /// Start button held.
    pub const START: usize = 0;
    /// Stop button held.
    pub const STOP: usize = 1;
    /// Reset button held.
    pub const RESET: usize = 2;
    /// A part sits in the input nest.
    pub const PART_AT_INPUT: usize = 3;
    /// The table stands (or passes) at an indexing position.
    pub const TABLE_IN_POS: usize = 4;
    /// A part sits under the tester.
    pub const PART_AT_TEST: usize = 5;
    /// The tester's probe is down: the part's hole is there.
    pub const TESTER_DOWN: usize = 6;
    /// A part sits under the drill.
    pub const PART_AT_DRILL: usize = 7;
    /// The clamp is closed.
    pub const CLAMPED: usize = 8;
    /// The drill feed is at its top.
    pub const DRILL_UP: usize = 9;
    /// The drill feed is at its bottom.
    pub const DRILL_DOWN: usize = 10;
    /// A part sits in front of the ejector.
    pub const PART_AT_EJECT: usize = 11;
    /// The ejector is fully out.
    pub const EJECTOR_OUT: usize = 12;
    /// The test result: the part under the tester passed the hole test.
    pub const TEST_OK: usize = 13;
    /// The rejector is fully out: the part under the tester went into the reject bin.
    pub const REJECTOR_OUT: usize = 14;
}

/// Indices of the outputs in the output image.
pub mod output {
    /// Turn the table.
    pub const TABLE_MOTOR: usize = 0;
    /// Lower the tester's probe.
    pub const TESTER_SOLENOID: usize = 1;
    /// Close the clamp.
    pub const CLAMP: usize = 2;
    /// Spin the drill.
    pub const DRILL_MOTOR: usize = 3;
    /// Feed the drill down (off: up).
    pub const DRILL_FEED_DOWN: usize = 4;
    /// Push the part off the table.
    pub const EJECTOR: usize = 5;
    /// Push the part under the tester into the reject bin.
    pub const REJECTOR: usize = 6;
    /// The lamp that asks the operator to empty the reject bin.
    pub const REJECT_BIN_FULL: usize = 7;
}

/// Physical parameters of the station; every duration is in microseconds of virtual time.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FestoParams {
    /// Travel time of one table index (one nest further).
    pub index_us: u64,
    /// Travel after a position during which the position cam stays made.
    pub in_position_window_us: u64,
    /// Time for the tester's probe to reach down.
    pub test_us: u64,
    /// Time for the clamp to close.
    pub clamp_us: u64,
    /// Time for the drill feed to travel from top to bottom (the drilling).
    pub drill_down_us: u64,
    /// Time for the drill feed to travel from bottom to top.
    pub drill_up_us: u64,
    /// Time for the ejector to push fully out.
    pub eject_us: u64,
    /// Time for the rejector to push fully out.
    pub reject_us: u64,
    /// How many parts in a million arrive defective (0: none; 50 000 is 5 %).
    pub defect_ppm: u32,
    /// Period of part arrivals upstream; the first arrives at time 0.
    pub arrival_interval_us: u64,
    /// How long [`Plant::press`] holds a button.
    pub press_us: u64,
    /// Largest random extra added to each actuator stroke and arrival (0: none).
    pub jitter_us: u64,
}

impl Default for FestoParams {
    fn default() -> Self {
        Self {
            index_us: SECOND_US,
            in_position_window_us: 100_000,
            test_us: 500_000,
            clamp_us: 200_000,
            drill_down_us: 2 * SECOND_US,
            drill_up_us: 500_000,
            eject_us: 500_000,
            reject_us: 500_000,
            defect_ppm: 0,
            arrival_interval_us: 5 * SECOND_US,
            press_us: 200_000,
            jitter_us: 0,
        }
    }
}

impl FestoParams {
    fn validate(&self) -> Result<(), TwinError> {
        let bad = |name: &'static str, reason: &str| {
            Err(TwinError::InvalidParameter {
                twin: NAME,
                name,
                reason: reason.to_owned(),
            })
        };
        if self.in_position_window_us == 0 || self.in_position_window_us >= self.index_us {
            return bad(
                "in_position_window_us",
                "must be positive and shorter than index_us, or the cam is never or always made",
            );
        }
        if self.drill_down_us == 0 || self.drill_up_us == 0 {
            return bad(
                "drill_down_us",
                "drill_down_us and drill_up_us must be positive: the feed has a travel",
            );
        }
        if self.arrival_interval_us == 0 {
            return bad("arrival_interval_us", "must be positive");
        }
        if self.defect_ppm > PPM {
            return bad(
                "defect_ppm",
                "is a share in parts per million: at most 1 000 000 (every part defective)",
            );
        }
        Ok(())
    }
}

/// One million: the unit of [`FestoParams::defect_ppm`].
pub const PPM: u32 = 1_000_000;

/// A part on the table, with what has been done to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Part {
    defective: bool,
    tested: bool,
    passed: bool,
    drilled: bool,
}

/// A single-acting actuator: extends in a set time while commanded, springs back at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stroke {
    Retracted,
    Extending {
        done_at: u64,
    },
    Extended,
    /// Stopped short of its end by an obstacle (the probe on a defective part).
    Blocked,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Actuator {
    cmd: bool,
    stroke: Stroke,
}

impl Actuator {
    const fn new() -> Self {
        Self {
            cmd: false,
            stroke: Stroke::Retracted,
        }
    }

    fn set(&mut self, now: u64, on: bool, stroke_us: u64, rng: &mut SplitMix64, jitter: u64) {
        if on && !self.cmd {
            self.stroke = Stroke::Extending {
                done_at: now.saturating_add(rng.jitter(stroke_us, jitter)),
            };
        } else if !on {
            self.stroke = Stroke::Retracted;
        }
        self.cmd = on;
    }

    fn due(&self) -> Option<u64> {
        match self.stroke {
            Stroke::Extending { done_at } => Some(done_at),
            _ => None,
        }
    }

    fn engaged(&self) -> bool {
        self.stroke != Stroke::Retracted
    }

    fn extended(&self) -> bool {
        self.stroke == Stroke::Extended
    }
}

/// The drill feed: a position in microseconds of downward travel, `0` at the top.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Feed {
    down: bool,
    pos: u64,
    at: u64,
}

impl Feed {
    fn pos_at(&self, t: u64, p: &FestoParams) -> u64 {
        let dt = t.saturating_sub(self.at);
        if self.down {
            self.pos.saturating_add(dt).min(p.drill_down_us)
        } else {
            // Upward speed is drill_down_us / drill_up_us travel per microsecond.
            let up = u128::from(dt) * u128::from(p.drill_down_us) / u128::from(p.drill_up_us);
            self.pos
                .saturating_sub(u64::try_from(up).unwrap_or(u64::MAX))
        }
    }

    fn sync(&mut self, t: u64, p: &FestoParams) {
        self.pos = self.pos_at(t, p);
        self.at = t;
    }

    fn due(&self, p: &FestoParams) -> Option<u64> {
        if self.down && self.pos < p.drill_down_us {
            Some(self.at.saturating_add(p.drill_down_us - self.pos))
        } else if !self.down && self.pos > 0 {
            // Rounded up so that at the event time the feed is surely at the top.
            let num = u128::from(self.pos) * u128::from(p.drill_up_us);
            let den = u128::from(p.drill_down_us);
            let dt = u64::try_from(num.div_ceil(den)).unwrap_or(u64::MAX);
            Some(self.at.saturating_add(dt))
        } else {
            None
        }
    }
}

/// The rotary table: travel since the last position, in microseconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Table {
    motor: bool,
    progress: u64,
    at: u64,
}

impl Table {
    fn progress_at(&self, t: u64, p: &FestoParams) -> u64 {
        if self.motor {
            self.progress
                .saturating_add(t.saturating_sub(self.at))
                .min(p.index_us)
        } else {
            self.progress
        }
    }

    fn sync(&mut self, t: u64, p: &FestoParams) {
        self.progress = self.progress_at(t, p);
        self.at = t;
    }

    fn in_position(&self, t: u64, p: &FestoParams) -> bool {
        self.progress_at(t, p) < p.in_position_window_us
    }

    fn due(&self, p: &FestoParams) -> Option<u64> {
        self.motor
            .then(|| self.at.saturating_add(p.index_us - self.progress))
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Event {
    Arrival,
    Table,
    Tester,
    Clamp,
    Feed,
    Ejector,
    Rejector,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
struct Tally {
    supplied: u64,
    defective: u64,
    tested: u64,
    rejected: u64,
    rejected_good: u64,
    drilled: u64,
    good: u64,
    ejected: u64,
    ejected_incomplete: u64,
    ejected_defective: u64,
}

/// The Festo processing station's digital twin.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FestoStation {
    params: FestoParams,
    rng: SplitMix64,
    defects: SplitMix64,
    books: Books,
    nests: [Option<Part>; NESTS],
    table: Table,
    tester: Actuator,
    clamp: Actuator,
    drill_motor: bool,
    feed: Feed,
    ejector: Actuator,
    rejector: Actuator,
    waiting: u64,
    next_arrival: u64,
    /// Per button, the interval `[from, until)` of its scheduled press.
    presses: [Option<(u64, u64)>; 3],
    tally: Tally,
    turning_latched: bool,
    misaligned_latched: bool,
}

impl FestoStation {
    /// A station at time 0 with the given parameters and jitter seed.
    pub fn new(params: FestoParams, seed: u64) -> Result<Self, TwinError> {
        params.validate()?;
        Ok(Self::build(params, seed))
    }

    /// A station with the documented default times.
    pub fn with_defaults(seed: u64) -> Self {
        Self::build(FestoParams::default(), seed)
    }

    fn build(params: FestoParams, seed: u64) -> Self {
        Self {
            params,
            rng: SplitMix64::new(seed),
            // A stream of its own, so that jitter draws never shift which parts are defective.
            defects: SplitMix64::new(seed ^ DEFECT_STREAM),
            books: Books::new(),
            nests: [None; NESTS],
            table: Table {
                motor: false,
                progress: 0,
                at: 0,
            },
            tester: Actuator::new(),
            clamp: Actuator::new(),
            drill_motor: false,
            feed: Feed {
                down: false,
                pos: 0,
                at: 0,
            },
            ejector: Actuator::new(),
            rejector: Actuator::new(),
            waiting: 0,
            next_arrival: 0,
            presses: [None; 3],
            tally: Tally::default(),
            turning_latched: false,
            misaligned_latched: false,
        }
    }

    /// The parameters the station was built with.
    pub fn params(&self) -> &FestoParams {
        &self.params
    }

    fn next_event(&self) -> (u64, Event) {
        let p = &self.params;
        // The feed wins ties: handling another event first would move the feed to its end, and
        // the feed's own event, which drills the part, would then never come.
        if let Some(t) = self.feed.due(p).filter(|&t| t <= self.next_arrival) {
            let others = [
                self.table.due(p),
                self.tester.due(),
                self.clamp.due(),
                self.ejector.due(),
                self.rejector.due(),
            ];
            if others.into_iter().flatten().all(|o| t <= o) {
                return (t, Event::Feed);
            }
        }
        let mut best = (self.next_arrival, Event::Arrival);
        for (t, ev) in [
            (self.table.due(p), Event::Table),
            (self.tester.due(), Event::Tester),
            (self.clamp.due(), Event::Clamp),
            (self.feed.due(p), Event::Feed),
            (self.ejector.due(), Event::Ejector),
            (self.rejector.due(), Event::Rejector),
        ] {
            // Strictly earlier only: ties go to the event listed first, which keeps the order fixed.
            if let Some(t) = t.filter(|&t| t < best.0) {
                best = (t, ev);
            }
        }
        best
    }

    fn handle(&mut self, t: u64, ev: Event) {
        let jitter = self.params.jitter_us;
        match ev {
            Event::Arrival => {
                self.waiting += 1;
                self.next_arrival = t.saturating_add(
                    self.rng
                        .jitter(self.params.arrival_interval_us, jitter)
                        .max(1),
                );
            }
            Event::Table => {
                self.nests.rotate_right(1);
                self.table.progress = 0;
            }
            Event::Tester => self.probe_reaches_part(),
            Event::Clamp => self.clamp.stroke = Stroke::Extended,
            Event::Feed => {
                if self.feed.pos == self.params.drill_down_us && self.feed.down {
                    self.drill_reaches_bottom(t);
                }
            }
            Event::Ejector => {
                self.ejector.stroke = Stroke::Extended;
                if let Some(part) = self.nests[position::EJECT].take() {
                    let t = &mut self.tally;
                    t.ejected += 1;
                    if part.defective {
                        t.ejected_defective += 1;
                    }
                    if !(part.tested && part.drilled) {
                        t.ejected_incomplete += 1;
                    } else if !part.defective {
                        t.good += 1;
                    }
                }
            }
            Event::Rejector => self.reject(t),
        }
    }

    /// The probe's stroke ends: at its lower end in a good part's hole (or an empty nest), or on
    /// the closed bottom of a defective part, short of its end.
    fn probe_reaches_part(&mut self) {
        let defective = self.nests[position::TEST].is_some_and(|p| p.defective);
        self.tester.stroke = if defective {
            Stroke::Blocked
        } else {
            Stroke::Extended
        };
        if let Some(part) = self.nests[position::TEST].as_mut() {
            if !part.tested {
                part.tested = true;
                part.passed = !part.defective;
                self.tally.tested += 1;
            }
        }
    }

    /// The rejector is fully out: the part under the tester falls into the reject bin.
    fn reject(&mut self, t: u64) {
        self.rejector.stroke = Stroke::Extended;
        if self.tester.engaged() {
            self.books.faults.push(
                FaultKind::RejectUnderProbe,
                t,
                "the rejector pushed against the tester's probe; the part under it stays",
            );
            return;
        }
        if let Some(part) = self.nests[position::TEST].take() {
            self.tally.rejected += 1;
            if !part.defective {
                self.tally.rejected_good += 1;
            }
        }
    }

    fn drill_reaches_bottom(&mut self, t: u64) {
        let Some(part) = &mut self.nests[position::DRILL] else {
            return;
        };
        if !self.clamp.extended() {
            self.books.faults.push(
                FaultKind::DrillWithoutClamp,
                t,
                "the drill reached a part that was not clamped; the part is not drilled",
            );
        } else if !self.drill_motor {
            self.books.faults.push(
                FaultKind::DrillMotorOff,
                t,
                "the drill was fed into the part with its spindle stopped; the part is not drilled",
            );
        } else if !part.drilled {
            part.drilled = true;
            self.tally.drilled += 1;
        }
    }

    /// The upstream station hands over a part only into an empty input nest of a table at rest.
    fn place_waiting_part(&mut self, t: u64) {
        if self.waiting > 0
            && self.nests[position::INPUT].is_none()
            && !self.table.motor
            && self.table.in_position(t, &self.params)
        {
            self.waiting -= 1;
            let defective = self.defects.below(u64::from(PPM)) < u64::from(self.params.defect_ppm);
            self.nests[position::INPUT] = Some(Part {
                defective,
                tested: false,
                passed: false,
                drilled: false,
            });
            self.tally.supplied += 1;
            self.tally.defective += u64::from(defective);
        }
    }

    /// What is engaged, as the fault message to give if the table moves; `None` when all is clear.
    fn engaged_module(&self, t: u64) -> Option<&'static str> {
        if self.tester.engaged() {
            Some("the table turned while the tester was down")
        } else if self.clamp.engaged() {
            Some("the table turned while the clamp was closed")
        } else if self.feed.pos_at(t, &self.params) > 0 {
            Some("the table turned while the drill was not up")
        } else if self.ejector.engaged() {
            Some("the table turned while the ejector was out")
        } else if self.rejector.engaged() {
            Some("the table turned while the rejector was out")
        } else {
            None
        }
    }

    /// Reports each episode of a module engaged while the table turns or stands misaligned, once.
    fn check_engagement(&mut self, t: u64) {
        let engaged = self.engaged_module(t);
        let turning = self.table.motor && engaged.is_some();
        if let (true, false, Some(msg)) = (turning, self.turning_latched, engaged) {
            self.books
                .faults
                .push(FaultKind::TableTurnWhileEngaged, t, msg);
        }
        self.turning_latched = turning;
        let misaligned =
            !self.table.motor && engaged.is_some() && !self.table.in_position(t, &self.params);
        if misaligned && !self.misaligned_latched {
            self.books.faults.push(
                FaultKind::EngagedOutOfPosition,
                t,
                "a module engaged while the table stood between two positions",
            );
        }
        self.misaligned_latched = misaligned;
    }

    fn pressed(&self, index: usize) -> bool {
        matches!(self.presses[index], Some((from, until)) if from <= self.books.now && self.books.now < until)
    }
}

impl Physics for FestoStation {
    const NAME: &'static str = NAME;
    const INPUT_NAMES: &'static [&'static str] = &INPUT_NAMES;
    const OUTPUT_NAMES: &'static [&'static str] = &OUTPUT_NAMES;
    const BUTTONS: &'static [&'static str] = &BUTTONS;
    /// RESET (homing) at 100 ms and START at 500 ms, as an operator starts the station.
    const START_PRESSES: &'static [(&'static str, u64)] = &[("RESET", 100_000), ("START", 500_000)];

    fn books(&self) -> &Books {
        &self.books
    }

    fn books_mut(&mut self) -> &mut Books {
        &mut self.books
    }

    fn run_events_until(&mut self, now: u64) {
        loop {
            let (t, ev) = self.next_event();
            if t > now {
                break;
            }
            self.table.sync(t, &self.params);
            self.feed.sync(t, &self.params);
            self.handle(t, ev);
            self.place_waiting_part(t);
            self.check_engagement(t);
        }
        self.table.sync(now, &self.params);
        self.feed.sync(now, &self.params);
    }

    fn apply(&mut self, now: u64, outputs: &[bool]) {
        let p = &self.params;
        let jitter = p.jitter_us;
        self.table.sync(now, p);
        self.table.motor = out(outputs, output::TABLE_MOTOR);
        self.tester.set(
            now,
            out(outputs, output::TESTER_SOLENOID),
            p.test_us,
            &mut self.rng,
            jitter,
        );
        let clamp = out(outputs, output::CLAMP);
        if self.clamp.cmd
            && !clamp
            && self.feed.pos_at(now, p) > 0
            && self.nests[position::DRILL].is_some()
        {
            self.books.faults.push(
                FaultKind::DrillWithoutClamp,
                now,
                "the clamp opened while the drill was in the part",
            );
        }
        self.clamp
            .set(now, clamp, p.clamp_us, &mut self.rng, jitter);
        self.drill_motor = out(outputs, output::DRILL_MOTOR);
        self.feed.sync(now, p);
        self.feed.down = out(outputs, output::DRILL_FEED_DOWN);
        self.ejector.set(
            now,
            out(outputs, output::EJECTOR),
            p.eject_us,
            &mut self.rng,
            jitter,
        );
        self.rejector.set(
            now,
            out(outputs, output::REJECTOR),
            p.reject_us,
            &mut self.rng,
            jitter,
        );
        self.place_waiting_part(now);
        self.check_engagement(now);
    }

    fn read_inputs(&self, buf: &mut [bool]) {
        let p = &self.params;
        let t = self.books.now;
        let in_pos = self.table.in_position(t, p);
        let at = |pos: usize| in_pos && self.nests[pos].is_some();
        let feed = self.feed.pos_at(t, p);
        let values = [
            self.pressed(0),
            self.pressed(1),
            self.pressed(2),
            at(position::INPUT),
            in_pos,
            at(position::TEST),
            self.tester.extended(),
            at(position::DRILL),
            self.clamp.extended(),
            feed == 0,
            feed == p.drill_down_us,
            at(position::EJECT),
            self.ejector.extended(),
            in_pos && self.nests[position::TEST].is_some_and(|p| p.passed),
            self.rejector.extended(),
        ];
        for (slot, v) in buf.iter_mut().zip(values) {
            *slot = v;
        }
    }

    fn tally(&self) -> Counters {
        let t = &self.tally;
        Counters::from_pairs(&[
            ("parts_supplied", t.supplied),
            ("parts_defective", t.defective),
            ("parts_tested", t.tested),
            ("parts_rejected", t.rejected),
            ("parts_rejected_good", t.rejected_good),
            ("parts_drilled", t.drilled),
            ("parts_good", t.good),
            ("parts_ejected", t.ejected),
            ("parts_ejected_incomplete", t.ejected_incomplete),
            ("parts_ejected_defective", t.ejected_defective),
            ("parts_waiting", self.waiting),
        ])
    }

    /// Holds the button from `at_us` for `press_us`.
    fn press_index(&mut self, index: usize, at_us: u64) {
        if let Some(slot) = self.presses.get_mut(index) {
            *slot = Some((at_us, at_us.saturating_add(self.params.press_us)));
        }
    }
}

#[cfg(test)]
mod tests;
