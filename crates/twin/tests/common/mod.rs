//! Hand-coded controllers shared by the behaviour tests: stand-ins for the PLC programs the runtime
//! will interpret, written plainly so that a failing test points at the twin, not at a program.

// Each test crate uses a different part of this module.
#![allow(dead_code)]

use cetratus_twin::festo::{input as fi, output as fo};
use cetratus_twin::vernadat::{input as vi, output as vo};
use cetratus_twin::{Plant, SECOND_US};

/// The PLC scan period the tests use.
pub const SCAN_US: u64 = 10_000;

/// One virtual hour.
pub const HOUR_US: u64 = 3_600 * SECOND_US;

/// A controller scanned like a PLC program: inputs in, outputs out, time passed in.
pub trait Controller: Clone {
    /// One scan at `now_us`.
    fn scan(&mut self, now_us: u64, inputs: &[bool], outputs: &mut [bool]);
}

/// Drives `plant` with `ctl` from `from_us` (inclusive) to `to_us` (exclusive), one scan per period.
/// Returns a digest of every input image seen, so that two runs can be compared cheaply.
pub fn run<C: Controller, P: Plant + ?Sized>(
    plant: &mut P,
    ctl: &mut C,
    outputs: &mut [bool],
    from_us: u64,
    to_us: u64,
) -> u64 {
    let mut inputs = vec![false; plant.input_names().len()];
    let mut digest: u64 = 0xCBF2_9CE4_8422_2325;
    let mut now = from_us;
    while now < to_us {
        plant.step(now, outputs);
        plant.inputs(&mut inputs);
        for &b in &inputs {
            // FNV-1a over the input bits.
            digest = (digest ^ u64::from(b)).wrapping_mul(0x0100_0000_01B3);
        }
        ctl.scan(now, &inputs, outputs);
        now += SCAN_US;
    }
    digest
}

// ---------------------------------------------------------------------------------------------
// The Vernadat program net of docs/design.md §6, interpreted with the default step policy of docs/design.md §3.

/// A transition's guard.
#[derive(Clone, Copy, Debug)]
pub enum Guard {
    /// No condition.
    Always,
    /// An input is true.
    Input(usize),
    /// A place has been marked for at least this long (`P.t >= d`).
    Dwell(usize, u64),
}

/// A transition: guard, input places, output places (weights 1).
#[derive(Clone, Copy, Debug)]
pub struct Tr {
    pub guard: Guard,
    pub pre: &'static [usize],
    pub post: &'static [usize],
}

pub const H: usize = 0;
pub const B: usize = 1;
pub const R: usize = 2;
pub const P10: usize = 3;
pub const P11: usize = 4;
pub const P12: usize = 5;
pub const P13: usize = 6;
pub const P14: usize = 7;
pub const P20: usize = 8;
pub const P21: usize = 9;
pub const P22: usize = 10;
pub const P23: usize = 11;
pub const P24: usize = 12;
pub const P30: usize = 13;
pub const P31: usize = 14;

const PLACES: usize = 15;

/// The initial program: T10, T11, T12, T13, T20, T14, T21, T22, T24, T23.
pub const INITIAL: [Tr; 10] = [
    Tr {
        guard: Guard::Input(vi::PE),
        pre: &[P10, R],
        post: &[P11],
    },
    Tr {
        guard: Guard::Input(vi::FCM1),
        pre: &[P11],
        post: &[P12, R],
    },
    Tr {
        guard: Guard::Input(vi::FPM1),
        pre: &[P12],
        post: &[P13],
    },
    Tr {
        guard: Guard::Input(vi::EB),
        pre: &[P13, R, H],
        post: &[P14],
    },
    Tr {
        guard: Guard::Input(vi::SB),
        pre: &[P14],
        post: &[P10, R, B],
    },
    Tr {
        guard: Guard::Always,
        pre: &[P20, R, B],
        post: &[P22, H],
    },
    Tr {
        guard: Guard::Input(vi::FCM2),
        pre: &[P22],
        post: &[P21, R],
    },
    Tr {
        guard: Guard::Input(vi::FPM2),
        pre: &[P21],
        post: &[P23],
    },
    Tr {
        guard: Guard::Always,
        pre: &[P23, R],
        post: &[P24],
    },
    Tr {
        guard: Guard::Input(vi::PS),
        pre: &[P24],
        post: &[P20, R],
    },
];

/// U.2: T12 and T22 go through the lubrication places P30/P31, left by T30/T31 after 3 s.
pub const U2: [Tr; 12] = [
    INITIAL[0],
    INITIAL[1],
    Tr {
        guard: Guard::Input(vi::FPM1),
        pre: &[P12],
        post: &[P30],
    },
    INITIAL[3],
    INITIAL[4],
    INITIAL[5],
    INITIAL[6],
    Tr {
        guard: Guard::Input(vi::FPM2),
        pre: &[P21],
        post: &[P31],
    },
    INITIAL[8],
    INITIAL[9],
    Tr {
        guard: Guard::Dwell(P30, 3 * SECOND_US),
        pre: &[P30],
        post: &[P13],
    },
    Tr {
        guard: Guard::Dwell(P31, 3 * SECOND_US),
        pre: &[P31],
        post: &[P23],
    },
];

/// Place → output actions (N qualifier).
pub const ACTIONS: [(usize, usize); 8] = [
    (P11, vo::CM1),
    (P12, vo::PM1),
    (P14, vo::DM1),
    (P22, vo::CM2),
    (P21, vo::PM2),
    (P24, vo::DM2),
    (P30, vo::LM1),
    (P31, vo::LM2),
];

/// The Vernadat program net as a controller.
#[derive(Clone, Debug)]
pub struct VernadatNet {
    pub m: [u32; PLACES],
    entered: [u64; PLACES],
    transitions: &'static [Tr],
}

impl VernadatNet {
    /// The net at M0 (H=4, B=3, R=1, P10=1, P20=1) with the given transitions.
    pub fn new(transitions: &'static [Tr]) -> Self {
        let mut m = [0; PLACES];
        m[H] = 4;
        m[B] = 3;
        m[R] = 1;
        m[P10] = 1;
        m[P20] = 1;
        Self {
            m,
            entered: [0; PLACES],
            transitions,
        }
    }
}

impl Controller for VernadatNet {
    fn scan(&mut self, now: u64, inputs: &[bool], outputs: &mut [bool]) {
        // Step semantics: visit in declaration order, consume from what is left, produce afterwards.
        let mut left = self.m;
        let mut produced = [0u32; PLACES];
        for t in self.transitions {
            let guard = match t.guard {
                Guard::Always => true,
                Guard::Input(i) => inputs[i],
                Guard::Dwell(p, d) => self.m[p] > 0 && now - self.entered[p] >= d,
            };
            if guard && t.pre.iter().all(|&p| left[p] > 0) {
                for &p in t.pre {
                    left[p] -= 1;
                }
                for &p in t.post {
                    produced[p] += 1;
                }
            }
        }
        for p in 0..PLACES {
            let new = left[p] + produced[p];
            if self.m[p] == 0 && new > 0 {
                self.entered[p] = now;
            }
            self.m[p] = new;
        }
        outputs.iter_mut().for_each(|o| *o = false);
        for &(p, o) in &ACTIONS {
            if self.m[p] > 0 {
                outputs[o] = true;
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// A Festo processing-station program: index, then test, drill and eject in parallel, synchronise.

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Table at rest; decide what to do.
    Ready,
    /// Modules at work.
    Working,
    /// Motor on, waiting for the cam to open.
    Leaving,
    /// Motor on, waiting for the next position.
    Arriving,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Drill {
    Idle,
    Clamping,
    Drilling,
    Rising,
}

/// A controller for the processing station.
#[derive(Clone, Debug)]
pub struct FestoProgram {
    running: bool,
    phase: Phase,
    testing: bool,
    probe_since: u64,
    rejecting: bool,
    /// Parts pushed into the reject bin.
    pub rejects: u64,
    drill: Drill,
    ejecting: bool,
    motor: bool,
    /// Table indexes made.
    pub indexes: u64,
}

impl Default for FestoProgram {
    fn default() -> Self {
        Self {
            running: false,
            phase: Phase::Ready,
            testing: false,
            probe_since: 0,
            rejecting: false,
            rejects: 0,
            drill: Drill::Idle,
            ejecting: false,
            motor: false,
            indexes: 0,
        }
    }
}

impl Controller for FestoProgram {
    fn scan(&mut self, now: u64, i: &[bool], o: &mut [bool]) {
        if i[fi::START] {
            self.running = true;
        }
        if i[fi::STOP] {
            // Takes effect at the end of the cycle: a stop never leaves a module engaged.
            self.running = false;
        }
        match self.phase {
            Phase::Ready => {
                let any_part = i[fi::PART_AT_INPUT]
                    || i[fi::PART_AT_TEST]
                    || i[fi::PART_AT_DRILL]
                    || i[fi::PART_AT_EJECT];
                if self.running && i[fi::TABLE_IN_POS] && any_part {
                    self.testing = i[fi::PART_AT_TEST];
                    self.probe_since = now;
                    self.drill = if i[fi::PART_AT_DRILL] {
                        Drill::Clamping
                    } else {
                        Drill::Idle
                    };
                    self.ejecting = i[fi::PART_AT_EJECT];
                    self.phase = Phase::Working;
                }
            }
            Phase::Working => {
                if self.testing && i[fi::TEST_OK] {
                    self.testing = false;
                } else if self.testing && now - self.probe_since >= SECOND_US {
                    // The probe never reached the bottom of a hole: reject the part.
                    self.testing = false;
                    self.rejecting = true;
                } else if self.rejecting && i[fi::REJECTOR_OUT] {
                    self.rejecting = false;
                    self.rejects += 1;
                }
                self.drill = match self.drill {
                    Drill::Clamping if i[fi::CLAMPED] => Drill::Drilling,
                    Drill::Drilling if i[fi::DRILL_DOWN] => Drill::Rising,
                    Drill::Rising if i[fi::DRILL_UP] => Drill::Idle,
                    d => d,
                };
                if self.ejecting && i[fi::EJECTOR_OUT] {
                    self.ejecting = false;
                }
                if !self.testing && !self.rejecting && self.drill == Drill::Idle && !self.ejecting {
                    self.motor = true;
                    self.phase = Phase::Leaving;
                }
            }
            Phase::Leaving => {
                if !i[fi::TABLE_IN_POS] {
                    self.phase = Phase::Arriving;
                }
            }
            Phase::Arriving => {
                if i[fi::TABLE_IN_POS] {
                    self.motor = false;
                    self.indexes += 1;
                    self.phase = Phase::Ready;
                }
            }
        }
        o.iter_mut().for_each(|x| *x = false);
        o[fo::TABLE_MOTOR] = self.motor;
        o[fo::TESTER_SOLENOID] = self.testing;
        o[fo::CLAMP] = self.drill != Drill::Idle;
        o[fo::DRILL_MOTOR] = matches!(self.drill, Drill::Drilling | Drill::Rising);
        o[fo::DRILL_FEED_DOWN] = self.drill == Drill::Drilling;
        o[fo::EJECTOR] = self.ejecting;
        o[fo::REJECTOR] = self.rejecting;
    }
}
