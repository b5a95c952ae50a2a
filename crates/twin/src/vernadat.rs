//! The Vernadat cell (docs/design.md §6): infeed, machine 1, buffer, machine 2, outfeed, one robot.
//!
//! The signal semantics are described in the crate documentation.

use serde::{Deserialize, Serialize};

use crate::rng::SplitMix64;
use crate::{out, Books, Counters, FaultKind, FaultLog, Physics, TwinError, SECOND_US};

/// The twin's name.
pub const NAME: &str = "vernadat";

/// Input names, in image order.
pub const INPUT_NAMES: [&str; 8] = ["PE", "FCM1", "FPM1", "EB", "SB", "FCM2", "FPM2", "PS"];

/// Output names, in image order.
pub const OUTPUT_NAMES: [&str; 8] = ["CM1", "PM1", "DM1", "CM2", "PM2", "DM2", "LM1", "LM2"];

/// Indices of the inputs in the input image.
pub mod input {
    /// A raw part waits at the infeed.
    pub const PE: usize = 0;
    /// The CM1 move (infeed → M1) is complete.
    pub const FCM1: usize = 1;
    /// M1 holds a finished part.
    pub const FPM1: usize = 2;
    /// M1 holds a finished part with its clamp open.
    pub const EB: usize = 3;
    /// The DM1 move (M1 → buffer) is complete.
    pub const SB: usize = 4;
    /// The CM2 move (buffer → M2) is complete.
    pub const FCM2: usize = 5;
    /// M2 holds a finished part.
    pub const FPM2: usize = 6;
    /// The DM2 move (M2 → outfeed) is complete.
    pub const PS: usize = 7;
}

/// Indices of the outputs in the output image.
pub mod output {
    /// Move a raw part from the infeed into M1.
    pub const CM1: usize = 0;
    /// Clamp and machine the part in M1.
    pub const PM1: usize = 1;
    /// Move M1's finished part into the buffer.
    pub const DM1: usize = 2;
    /// Move a part from the buffer into M2.
    pub const CM2: usize = 3;
    /// Clamp and machine the part in M2.
    pub const PM2: usize = 4;
    /// Move M2's finished part to the outfeed.
    pub const DM2: usize = 5;
    /// Lubricate M1.
    pub const LM1: usize = 6;
    /// Lubricate M2.
    pub const LM2: usize = 7;
}

/// Physical parameters of the cell; every duration is in microseconds of virtual time.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VernadatParams {
    /// Delay from the robot picking a raw part at the infeed to the next one arriving.
    pub infeed_interval_us: u64,
    /// Duration of each robot move.
    pub move_us: u64,
    /// Machining time of M1.
    pub m1_machining_us: u64,
    /// Machining time of M2.
    pub m2_machining_us: u64,
    /// How many parts the buffer holds physically.
    pub buffer_capacity: u32,
    /// Parts in the buffer at start.
    pub buffer_initial: u32,
    /// How long LM1/LM2 must stay on to count one lubrication.
    pub lubrication_us: u64,
    /// Largest random extra added to each move, machining and arrival time (0: none).
    pub jitter_us: u64,
}

impl Default for VernadatParams {
    fn default() -> Self {
        Self {
            infeed_interval_us: SECOND_US,
            move_us: SECOND_US,
            m1_machining_us: 3 * SECOND_US,
            m2_machining_us: 6 * SECOND_US,
            buffer_capacity: 9,
            buffer_initial: 3,
            lubrication_us: 3 * SECOND_US,
            jitter_us: 0,
        }
    }
}

impl VernadatParams {
    fn validate(&self) -> Result<(), TwinError> {
        if self.buffer_initial > self.buffer_capacity {
            return Err(TwinError::InvalidParameter {
                twin: NAME,
                name: "buffer_initial",
                reason: format!(
                    "{} parts do not fit a buffer of capacity {}; use at most the capacity",
                    self.buffer_initial, self.buffer_capacity
                ),
            });
        }
        if self.lubrication_us == 0 {
            return Err(TwinError::InvalidParameter {
                twin: NAME,
                name: "lubrication_us",
                reason: "must be positive, or every glitch of LM1/LM2 would count".to_owned(),
            });
        }
        Ok(())
    }
}

/// The four robot moves, in output order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Move {
    Cm1,
    Dm1,
    Cm2,
    Dm2,
}

impl Move {
    const ALL: [Move; 4] = [Move::Cm1, Move::Dm1, Move::Cm2, Move::Dm2];

    fn output(self) -> usize {
        match self {
            Move::Cm1 => output::CM1,
            Move::Dm1 => output::DM1,
            Move::Cm2 => output::CM2,
            Move::Dm2 => output::DM2,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Robot {
    Idle,
    Moving {
        mv: Move,
        done_at: u64,
        carrying: bool,
    },
    /// The move is complete and acknowledged until its command is withdrawn.
    Done(Move),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Work {
    Empty,
    Raw,
    Machining { done_at: u64 },
    Finished,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Lubricator {
    on_since: Option<u64>,
    counted: bool,
    count: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Machine {
    work: Work,
    /// PM's level: the clamp is closed while it is on.
    pm: bool,
    machining_us: u64,
    machined: u64,
    lube: Lubricator,
}

impl Machine {
    fn new(machining_us: u64) -> Self {
        Self {
            work: Work::Empty,
            pm: false,
            machining_us,
            machined: 0,
            lube: Lubricator {
                on_since: None,
                counted: false,
                count: 0,
            },
        }
    }

    fn start_if_ready(&mut self, now: u64, rng: &mut SplitMix64, jitter: u64) {
        if self.pm && self.work == Work::Raw {
            self.work = Work::Machining {
                done_at: now.saturating_add(rng.jitter(self.machining_us, jitter)),
            };
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Event {
    Robot,
    Machine1,
    Machine2,
    Infeed,
    Lube1,
    Lube2,
}

/// The Vernadat cell's digital twin.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VernadatCell {
    params: VernadatParams,
    rng: SplitMix64,
    books: Books,
    infeed: bool,
    infeed_next: Option<u64>,
    robot: Robot,
    m1: Machine,
    m2: Machine,
    buffer: u32,
    finished: u64,
    scrapped: u64,
    collision_latched: bool,
}

impl VernadatCell {
    /// A cell at time 0 with the given parameters and jitter seed.
    pub fn new(params: VernadatParams, seed: u64) -> Result<Self, TwinError> {
        params.validate()?;
        Ok(Self::build(params, seed))
    }

    /// A cell with the default parameters of docs/design.md §6.
    pub fn with_defaults(seed: u64) -> Self {
        Self::build(VernadatParams::default(), seed)
    }

    fn build(params: VernadatParams, seed: u64) -> Self {
        Self {
            rng: SplitMix64::new(seed),
            books: Books::new(),
            // A raw part is waiting when the cell starts, as the program's first transition expects.
            infeed: true,
            infeed_next: None,
            robot: Robot::Idle,
            m1: Machine::new(params.m1_machining_us),
            m2: Machine::new(params.m2_machining_us),
            buffer: params.buffer_initial,
            finished: 0,
            scrapped: 0,
            collision_latched: false,
            params,
        }
    }

    /// The parameters the cell was built with.
    pub fn params(&self) -> &VernadatParams {
        &self.params
    }

    /// Parts delivered to the outfeed.
    pub fn parts_finished(&self) -> u64 {
        self.finished
    }

    /// Parts now in the buffer.
    pub fn parts_in_buffer(&self) -> u32 {
        self.buffer
    }

    /// Lubrications counted for machine 1 and machine 2.
    pub fn lubrications(&self) -> (u64, u64) {
        (self.m1.lube.count, self.m2.lube.count)
    }

    fn next_event(&self) -> Option<(u64, Event)> {
        let mut best: Option<(u64, Event)> = None;
        let mut consider = |t: Option<u64>, ev: Event| {
            if let Some(t) = t {
                // Strictly earlier only: ties go to the event listed first, which keeps the order fixed.
                let earlier = match best {
                    None => true,
                    Some((b, _)) => t < b,
                };
                if earlier {
                    best = Some((t, ev));
                }
            }
        };
        consider(
            match self.robot {
                Robot::Moving { done_at, .. } => Some(done_at),
                _ => None,
            },
            Event::Robot,
        );
        for (m, ev) in [(&self.m1, Event::Machine1), (&self.m2, Event::Machine2)] {
            consider(
                match m.work {
                    Work::Machining { done_at } => Some(done_at),
                    _ => None,
                },
                ev,
            );
        }
        consider(self.infeed_next, Event::Infeed);
        for (m, ev) in [(&self.m1, Event::Lube1), (&self.m2, Event::Lube2)] {
            consider(
                match m.lube {
                    Lubricator {
                        on_since: Some(since),
                        counted: false,
                        ..
                    } => Some(since.saturating_add(self.params.lubrication_us)),
                    _ => None,
                },
                ev,
            );
        }
        best
    }

    fn handle(&mut self, t: u64, ev: Event) {
        match ev {
            Event::Robot => {
                if let Robot::Moving { mv, carrying, .. } = self.robot {
                    self.robot = Robot::Done(mv);
                    if carrying {
                        self.put_down(t, mv);
                    }
                }
            }
            Event::Machine1 => {
                self.m1.work = Work::Finished;
                self.m1.machined += 1;
            }
            Event::Machine2 => {
                self.m2.work = Work::Finished;
                self.m2.machined += 1;
            }
            Event::Infeed => {
                self.infeed = true;
                self.infeed_next = None;
            }
            Event::Lube1 => {
                self.m1.lube.counted = true;
                self.m1.lube.count += 1;
            }
            Event::Lube2 => {
                self.m2.lube.counted = true;
                self.m2.lube.count += 1;
            }
        }
    }

    /// The robot grips the part at the move's source; returns whether it holds one.
    fn pick_up(&mut self, now: u64, mv: Move) -> bool {
        match mv {
            Move::Cm1 => {
                if self.infeed {
                    self.infeed = false;
                    self.infeed_next = Some(
                        now.saturating_add(
                            self.rng
                                .jitter(self.params.infeed_interval_us, self.params.jitter_us),
                        ),
                    );
                    true
                } else {
                    self.books.faults.push(
                        FaultKind::EmptySource,
                        now,
                        "CM1 commanded with no raw part at the infeed",
                    );
                    false
                }
            }
            Move::Dm1 => pick_from_machine(
                &mut self.m1,
                &mut self.books.faults,
                now,
                "DM1 commanded with machine 1 empty",
                "DM1 commanded while machine 1's part is unfinished or clamped (PM1 on)",
            ),
            Move::Cm2 => {
                if self.buffer > 0 {
                    self.buffer -= 1;
                    true
                } else {
                    self.books.faults.push(
                        FaultKind::EmptySource,
                        now,
                        "CM2 commanded with the buffer empty",
                    );
                    false
                }
            }
            Move::Dm2 => pick_from_machine(
                &mut self.m2,
                &mut self.books.faults,
                now,
                "DM2 commanded with machine 2 empty",
                "DM2 commanded while machine 2's part is unfinished or clamped (PM2 on)",
            ),
        }
    }

    fn put_down(&mut self, t: u64, mv: Move) {
        let jitter = self.params.jitter_us;
        match mv {
            Move::Cm1 => {
                if self.m1.work == Work::Empty {
                    self.m1.work = Work::Raw;
                    self.m1.start_if_ready(t, &mut self.rng, jitter);
                } else {
                    self.scrapped += 1;
                    self.books.faults.push(
                        FaultKind::MachineBusy,
                        t,
                        "CM1 loaded a part into machine 1 while it held one; the new part is scrapped",
                    );
                }
            }
            Move::Dm1 => {
                if self.buffer < self.params.buffer_capacity {
                    self.buffer += 1;
                } else {
                    self.scrapped += 1;
                    self.books.faults.push(
                        FaultKind::BufferOverflow,
                        t,
                        "DM1 put a part into a full buffer; the part is scrapped",
                    );
                }
            }
            Move::Cm2 => {
                if self.m2.work == Work::Empty {
                    self.m2.work = Work::Raw;
                    self.m2.start_if_ready(t, &mut self.rng, jitter);
                } else {
                    self.scrapped += 1;
                    self.books.faults.push(
                        FaultKind::MachineBusy,
                        t,
                        "CM2 loaded a part into machine 2 while it held one; the new part is scrapped",
                    );
                }
            }
            Move::Dm2 => self.finished += 1,
        }
    }
}

fn pick_from_machine(
    m: &mut Machine,
    faults: &mut FaultLog,
    now: u64,
    empty: &'static str,
    not_ready: &'static str,
) -> bool {
    match m.work {
        Work::Finished if !m.pm => {
            m.work = Work::Empty;
            true
        }
        Work::Empty => {
            faults.push(FaultKind::EmptySource, now, empty);
            false
        }
        _ => {
            faults.push(FaultKind::PartNotReady, now, not_ready);
            false
        }
    }
}

impl Physics for VernadatCell {
    const NAME: &'static str = NAME;
    const INPUT_NAMES: &'static [&'static str] = &INPUT_NAMES;
    const OUTPUT_NAMES: &'static [&'static str] = &OUTPUT_NAMES;

    fn books(&self) -> &Books {
        &self.books
    }

    fn books_mut(&mut self) -> &mut Books {
        &mut self.books
    }

    fn run_events_until(&mut self, now: u64) {
        while let Some((t, ev)) = self.next_event() {
            if t > now {
                break;
            }
            self.handle(t, ev);
        }
    }

    fn apply(&mut self, now: u64, outputs: &[bool]) {
        // Withdrawals first, so that one image may end a move and command the next.
        match self.robot {
            Robot::Moving { mv, carrying, .. } if !out(outputs, mv.output()) => {
                if carrying {
                    self.scrapped += 1;
                }
                self.books.faults.push(
                    FaultKind::MoveAborted,
                    now,
                    "a robot move command was withdrawn before the move was complete; the part is dropped",
                );
                self.robot = Robot::Idle;
            }
            Robot::Done(mv) if !out(outputs, mv.output()) => self.robot = Robot::Idle,
            _ => {}
        }

        let mut commanded = Move::ALL.into_iter().filter(|m| out(outputs, m.output()));
        let first = commanded.next();
        let several = commanded.next().is_some();
        if several {
            // Reported when it begins, not on every step it lasts.
            if !self.collision_latched {
                self.books.faults.push(
                    FaultKind::Collision,
                    now,
                    "two robot moves were commanded at once; the robot starts neither",
                );
            }
            self.collision_latched = true;
        } else {
            self.collision_latched = false;
            if let (Some(mv), Robot::Idle) = (first, self.robot) {
                let carrying = self.pick_up(now, mv);
                let done_at =
                    now.saturating_add(self.rng.jitter(self.params.move_us, self.params.jitter_us));
                self.robot = Robot::Moving {
                    mv,
                    done_at,
                    carrying,
                };
            }
        }

        let jitter = self.params.jitter_us;
        for (m, pm, lm, what) in [
            (
                &mut self.m1,
                out(outputs, output::PM1),
                out(outputs, output::LM1),
                "PM1 was withdrawn before machining in machine 1 was complete; the part must be machined again",
            ),
            (
                &mut self.m2,
                out(outputs, output::PM2),
                out(outputs, output::LM2),
                "PM2 was withdrawn before machining in machine 2 was complete; the part must be machined again",
            ),
        ] {
            if m.pm && !pm {
                if let Work::Machining { .. } = m.work {
                    m.work = Work::Raw;
                    self.books.faults
                        .push(FaultKind::MachiningInterrupted, now, what);
                }
            }
            m.pm = pm;
            m.start_if_ready(now, &mut self.rng, jitter);
            match (m.lube.on_since, lm) {
                (None, true) => {
                    m.lube.on_since = Some(now);
                    m.lube.counted = false;
                }
                (Some(_), false) => m.lube.on_since = None,
                _ => {}
            }
        }
    }

    fn read_inputs(&self, buf: &mut [bool]) {
        let values = [
            self.infeed,
            self.robot == Robot::Done(Move::Cm1),
            self.m1.work == Work::Finished,
            self.m1.work == Work::Finished && !self.m1.pm,
            self.robot == Robot::Done(Move::Dm1),
            self.robot == Robot::Done(Move::Cm2),
            self.m2.work == Work::Finished,
            self.robot == Robot::Done(Move::Dm2),
        ];
        for (slot, v) in buf.iter_mut().zip(values) {
            *slot = v;
        }
    }

    fn tally(&self) -> Counters {
        Counters::from_pairs(&[
            ("parts_finished", self.finished),
            ("parts_in_buffer", u64::from(self.buffer)),
            ("lubrications_m1", self.m1.lube.count),
            ("lubrications_m2", self.m2.lube.count),
            ("parts_machined_m1", self.m1.machined),
            ("parts_machined_m2", self.m2.machined),
            ("parts_scrapped", self.scrapped),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::input::*;
    use super::output::*;
    use super::*;
    use crate::Plant;

    const S: u64 = SECOND_US;

    /// Drives the cell: steps to `t` seconds with the listed outputs on, returns the input image.
    fn drive(cell: &mut VernadatCell, t_ms: u64, on: &[usize]) -> [bool; 8] {
        let mut outs = [false; 8];
        for &o in on {
            outs[o] = true;
        }
        cell.step(t_ms * 1_000, &outs);
        let mut ins = [false; 8];
        cell.inputs(&mut ins);
        ins
    }

    fn kinds(cell: &VernadatCell) -> Vec<FaultKind> {
        cell.faults().iter().map(|f| f.kind).collect()
    }

    /// Runs M1's cycle by hand up to the part waiting, unclamped, in M1.
    fn machine_one_part(cell: &mut VernadatCell) {
        assert!(drive(cell, 0, &[])[PE]);
        let i = drive(cell, 10, &[CM1]);
        assert!(!i[PE], "the robot picked the raw part");
        assert!(drive(cell, 1_010, &[CM1])[FCM1]);
        let i = drive(cell, 1_020, &[PM1]);
        assert!(!i[FCM1] && !i[FPM1]);
        assert!(!drive(cell, 4_010, &[PM1])[FPM1]);
        let i = drive(cell, 4_020, &[PM1]);
        assert!(i[FPM1] && !i[EB], "finished but still clamped");
        let i = drive(cell, 4_030, &[]);
        assert!(i[FPM1] && i[EB], "clamp open");
    }

    #[test]
    fn a_raw_part_is_waiting_at_start_and_the_next_arrives_a_second_after_pickup() {
        let mut c = VernadatCell::with_defaults(0);
        assert!(drive(&mut c, 0, &[])[PE]);
        assert!(!drive(&mut c, 100, &[CM1])[PE]);
        assert!(!drive(&mut c, 1_099, &[CM1])[PE]);
        assert!(drive(&mut c, 1_100, &[CM1])[PE]);
    }

    #[test]
    fn m1_cycle_follows_the_program_net_signals() {
        let mut c = VernadatCell::with_defaults(0);
        machine_one_part(&mut c);
        let i = drive(&mut c, 4_040, &[DM1]);
        assert!(!i[FPM1] && !i[EB], "the robot took the part");
        assert!(drive(&mut c, 5_040, &[DM1])[SB]);
        assert!(!drive(&mut c, 5_050, &[])[SB], "SB drops with DM1");
        assert_eq!(c.parts_in_buffer(), 4);
        assert!(c.faults().is_empty(), "{:?}", c.faults());
    }

    #[test]
    fn two_moves_at_once_are_a_collision() {
        let mut c = VernadatCell::with_defaults(0);
        drive(&mut c, 0, &[CM1, CM2]);
        drive(&mut c, 10, &[CM1, CM2]);
        assert_eq!(kinds(&c), vec![FaultKind::Collision]);
    }

    #[test]
    fn a_move_commanded_while_another_runs_is_a_collision() {
        let mut c = VernadatCell::with_defaults(0);
        drive(&mut c, 0, &[CM1]);
        drive(&mut c, 500, &[CM1, CM2]);
        assert_eq!(kinds(&c), vec![FaultKind::Collision]);
        // The first move still completes.
        assert!(drive(&mut c, 1_000, &[CM1])[FCM1]);
    }

    #[test]
    fn a_part_put_into_a_full_buffer_overflows() {
        let params = VernadatParams {
            buffer_initial: 9,
            ..VernadatParams::default()
        };
        let mut c = VernadatCell::new(params, 0).expect("valid parameters");
        machine_one_part(&mut c);
        drive(&mut c, 4_040, &[DM1]);
        drive(&mut c, 5_040, &[DM1]);
        assert_eq!(kinds(&c), vec![FaultKind::BufferOverflow]);
        assert_eq!(c.parts_in_buffer(), 9);
        assert_eq!(c.counters().get("parts_scrapped"), Some(1));
    }

    #[test]
    fn loading_a_busy_machine_is_a_fault() {
        let mut c = VernadatCell::with_defaults(0);
        drive(&mut c, 0, &[CM1]);
        drive(&mut c, 1_000, &[CM1]);
        drive(&mut c, 1_010, &[]);
        drive(&mut c, 2_010, &[CM1]);
        drive(&mut c, 3_010, &[CM1]);
        assert_eq!(kinds(&c), vec![FaultKind::MachineBusy]);
    }

    #[test]
    fn unloading_from_empty_places_is_a_fault() {
        let params = VernadatParams {
            buffer_initial: 0,
            ..VernadatParams::default()
        };
        let mut c = VernadatCell::new(params, 0).expect("valid parameters");
        drive(&mut c, 0, &[CM2]);
        assert!(
            drive(&mut c, 1_000, &[CM2])[FCM2],
            "the empty move is still acknowledged"
        );
        drive(&mut c, 1_010, &[]);
        drive(&mut c, 1_020, &[DM1]);
        assert_eq!(
            kinds(&c),
            vec![FaultKind::EmptySource, FaultKind::EmptySource]
        );
    }

    #[test]
    fn unloading_a_clamped_part_is_a_fault_and_leaves_it() {
        let mut c = VernadatCell::with_defaults(0);
        drive(&mut c, 0, &[CM1]);
        drive(&mut c, 1_000, &[CM1]);
        drive(&mut c, 1_010, &[PM1]);
        drive(&mut c, 4_010, &[PM1]);
        let i = drive(&mut c, 4_020, &[PM1, DM1]);
        assert_eq!(kinds(&c), vec![FaultKind::PartNotReady]);
        assert!(i[FPM1]);
    }

    #[test]
    fn withdrawing_a_move_early_drops_the_part() {
        let mut c = VernadatCell::with_defaults(0);
        drive(&mut c, 0, &[CM1]);
        drive(&mut c, 500, &[]);
        assert_eq!(kinds(&c), vec![FaultKind::MoveAborted]);
        assert_eq!(c.counters().get("parts_scrapped"), Some(1));
    }

    #[test]
    fn withdrawing_pm_early_interrupts_machining() {
        let mut c = VernadatCell::with_defaults(0);
        drive(&mut c, 0, &[CM1]);
        drive(&mut c, 1_000, &[CM1]);
        drive(&mut c, 1_010, &[PM1]);
        drive(&mut c, 2_000, &[]);
        assert_eq!(kinds(&c), vec![FaultKind::MachiningInterrupted]);
        // Machining again from the start takes the full three seconds.
        drive(&mut c, 2_010, &[PM1]);
        assert!(!drive(&mut c, 5_000, &[PM1])[FPM1]);
        assert!(drive(&mut c, 5_010, &[PM1])[FPM1]);
    }

    #[test]
    fn lubrication_counts_once_per_pulse_of_at_least_the_lubrication_time() {
        let mut c = VernadatCell::with_defaults(0);
        drive(&mut c, 0, &[LM1]);
        drive(&mut c, 2_990, &[LM1]);
        assert_eq!(c.lubrications(), (0, 0));
        drive(&mut c, 3_000, &[LM1]);
        drive(&mut c, 9_000, &[LM1, LM2]);
        assert_eq!(c.lubrications(), (1, 0));
        drive(&mut c, 9_500, &[]);
        drive(&mut c, 20_000, &[]);
        assert_eq!(c.lubrications(), (1, 0), "a short LM2 pulse does not count");
        assert!(c.faults().is_empty());
    }

    #[test]
    fn time_going_backwards_is_a_fault_not_a_panic() {
        let mut c = VernadatCell::with_defaults(0);
        drive(&mut c, 1_000, &[]);
        drive(&mut c, 500, &[]);
        assert_eq!(kinds(&c), vec![FaultKind::ClockRegression]);
        assert_eq!(c.now_us(), S);
    }

    #[test]
    fn a_short_output_image_is_reported_once() {
        let mut c = VernadatCell::with_defaults(0);
        c.step(0, &[false]);
        c.step(10, &[false]);
        assert_eq!(kinds(&c), vec![FaultKind::ImageSize]);
        // A short input buffer gets the first inputs only, without a panic.
        let mut short = [false; 3];
        c.inputs(&mut short);
        assert!(short[PE]);
    }

    #[test]
    fn invalid_parameters_are_rejected_with_the_parameter_named() {
        let params = VernadatParams {
            buffer_initial: 10,
            ..VernadatParams::default()
        };
        match VernadatCell::new(params, 0) {
            Err(TwinError::InvalidParameter { name, .. }) => assert_eq!(name, "buffer_initial"),
            other => panic!("expected an invalid parameter, got {other:?}"),
        }
    }
}
