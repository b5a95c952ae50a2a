//! The step contract every twin keeps alike: time never runs back (a step at an earlier time is
//! reported once and ignored), a wrong-sized output image is reported once, and the events
//! before a step happen each at its own time before the step's outputs are taken. A twin gives
//! its physics ([`Physics`]); [`Plant`] is implemented once over it.

use crate::{Counters, Fault, FaultKind, FaultLog, Plant, TwinError};

/// What every twin keeps alike: its clock, its fault log, and whether it has reported a
/// wrong-sized output image yet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Books {
    /// The virtual time of the last step, in microseconds.
    pub(crate) now: u64,
    /// Every physical fault seen so far.
    pub(crate) faults: FaultLog,
    /// Whether a wrong-sized output image has been reported.
    pub(crate) image_size_reported: bool,
}

impl Books {
    /// At time 0, with no fault.
    pub(crate) fn new() -> Self {
        Self {
            now: 0,
            faults: FaultLog::new(),
            image_size_reported: false,
        }
    }
}

/// What a twin supplies: its names, where it keeps its clock, how its events happen, how it
/// takes an output image and what its inputs read. [`Plant`] is implemented once on top of it
/// for every twin, so that all keep the step contract alike.
pub(crate) trait Physics: Clone + Send + 'static {
    /// The twin's name, as [`crate::TwinKind`] spells it.
    const NAME: &'static str;
    /// The input image's names, in image order.
    const INPUT_NAMES: &'static [&'static str];
    /// The output image's names, in image order.
    const OUTPUT_NAMES: &'static [&'static str];
    /// The operator buttons, in input order: none by default.
    const BUTTONS: &'static [&'static str] = &[];
    /// The presses an operator gives the twin to start it: none by default.
    const START_PRESSES: &'static [(&'static str, u64)] = &[];

    /// The twin's clock and fault log.
    fn books(&self) -> &Books;
    /// The twin's clock and fault log, to keep.
    fn books_mut(&mut self) -> &mut Books;
    /// Lets every event due at or before `now` happen, at its own time, in time order.
    fn run_events_until(&mut self, now: u64);
    /// Takes the output image at `now`.
    fn apply(&mut self, now: u64, outputs: &[bool]);
    /// Writes the input image at the current time (see [`Plant::inputs`]).
    fn read_inputs(&self, buf: &mut [bool]);
    /// The twin's production counters.
    fn tally(&self) -> Counters;
    /// Holds button `index` of [`Physics::BUTTONS`] from `at_us`; twins without buttons never
    /// get a call.
    fn press_index(&mut self, index: usize, at_us: u64) {
        let _ = (index, at_us);
    }
}

impl<P: Physics> Plant for P {
    fn name(&self) -> &'static str {
        P::NAME
    }

    fn input_names(&self) -> &[&'static str] {
        P::INPUT_NAMES
    }

    fn output_names(&self) -> &[&'static str] {
        P::OUTPUT_NAMES
    }

    fn step(&mut self, now_us: u64, outputs: &[bool]) {
        let books = self.books_mut();
        let now = monotonic(&mut books.faults, books.now, now_us);
        let want = P::OUTPUT_NAMES.len();
        check_image(
            &mut books.faults,
            &mut books.image_size_reported,
            now,
            outputs.len(),
            want,
        );
        self.run_events_until(now);
        // Only now: the events before happened each at its own time, not at `now`.
        self.books_mut().now = now;
        self.apply(now, outputs);
        // Zero-length strokes and durations (a parameter of 0) complete at once.
        self.run_events_until(now);
    }

    fn inputs(&self, buf: &mut [bool]) {
        self.read_inputs(buf);
    }

    fn now_us(&self) -> u64 {
        self.books().now
    }

    fn faults(&self) -> &[Fault] {
        self.books().faults.as_slice()
    }

    fn faults_dropped(&self) -> u64 {
        self.books().faults.dropped()
    }

    fn counters(&self) -> Counters {
        self.tally()
    }

    fn buttons(&self) -> &[&'static str] {
        P::BUTTONS
    }

    fn start_presses(&self) -> &'static [(&'static str, u64)] {
        P::START_PRESSES
    }

    fn press(&mut self, button: &str, at_us: u64) -> Result<(), TwinError> {
        match P::BUTTONS
            .iter()
            .position(|b| b.eq_ignore_ascii_case(button))
        {
            Some(i) => {
                self.press_index(i, at_us);
                Ok(())
            }
            None => Err(TwinError::UnknownButton {
                twin: P::NAME,
                button: button.to_owned(),
                known: P::BUTTONS.join(", "),
            }),
        }
    }

    fn fork(&self) -> Box<dyn Plant> {
        Box::new(self.clone())
    }
}

/// Checks the image length once per twin, so that a wrong-sized image is reported without flooding.
fn check_image(log: &mut FaultLog, reported: &mut bool, now_us: u64, got: usize, want: usize) {
    if got != want && !*reported {
        *reported = true;
        log.push(
            FaultKind::ImageSize,
            now_us,
            "output image length differs from the twin's output list; missing outputs count as off",
        );
    }
}

/// Clamps a requested time to the twin's clock, reporting a regression once per occurrence.
fn monotonic(log: &mut FaultLog, current_us: u64, now_us: u64) -> u64 {
    if now_us < current_us {
        log.push(
            FaultKind::ClockRegression,
            current_us,
            "step called with a time earlier than the previous step; the earlier time was ignored",
        );
        current_us
    } else {
        now_us
    }
}
