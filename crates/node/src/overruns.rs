//! The primary's overruns with a candidate in quarantine, against their level before the load.
//!
//! A candidate's scan runs in the same cycle as the primary's, after the outputs are written. Its
//! work budget bounds one scan ([`cetratus_runtime::Limits::candidate_instruction_budget`]), but
//! a candidate within its budget can still take enough of each cycle that the next one starts
//! late. The runtime does not see that (virtual time has no overruns); the real-time loop does.
//!
//! The rule (docs/live-update.md, *Timing isolation*):
//! * the level before the load is the share of the last [`BEFORE_CYCLES`] cycles that overran;
//! * in quarantine, once [`WINDOW`] cycles have run, the share of the last [`WINDOW`] cycles
//!   that overran is compared with it at every cycle;
//! * an overrun counts against the candidate only when the candidate's scan in the cycle before
//!   took at least [`CANDIDATE_SHARE`] of the period: a machine that is busy with something else
//!   makes the primary overrun whatever the candidate does, and must not abort an update whose
//!   candidate takes a few microseconds;
//! * the candidate is faulted when at least [`MIN_OVERRUNS`] of those cycles overran and their
//!   share is over twice the level before plus [`MARGIN`] (2.5 % before: over 7 % in quarantine).
//!
//! The margin, the least count and the candidate's share keep a machine's ordinary jitter, and
//! its load, from aborting an update; a candidate that makes the primary overrun one cycle in ten
//! or more is caught within a second at a 1 ms period.

/// Cycles before the load whose overruns set the level.
pub const BEFORE_CYCLES: usize = 1024;

/// Cycles in quarantine over which the overruns are counted.
pub const WINDOW: usize = 256;

/// Overruns in [`WINDOW`] below which the candidate is never blamed.
pub const MIN_OVERRUNS: usize = 10;

/// Share of cycles, over twice the level before the load, that the overruns may add.
pub const MARGIN: f64 = 0.02;

/// The least part of the period the candidate's scan must take for an overrun to count
/// against it. The default instruction budget keeps a candidate under about 7 % of the period,
/// so the rule matters for a budget raised, or a slower machine.
pub const CANDIDATE_SHARE: f64 = 0.1;

/// The last `N` cycles, one bit each: overran or not.
struct Bits<const W: usize> {
    words: [u64; W],
    next: usize,
    filled: usize,
}

impl<const W: usize> Bits<W> {
    const LEN: usize = W * 64;

    fn new() -> Self {
        Bits {
            words: [0; W],
            next: 0,
            filled: 0,
        }
    }

    fn push(&mut self, overran: bool) {
        let (w, b) = (self.next / 64, self.next % 64);
        self.words[w] = (self.words[w] & !(1 << b)) | (u64::from(overran) << b);
        self.next = (self.next + 1) % Self::LEN;
        self.filled = (self.filled + 1).min(Self::LEN);
    }

    fn count(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }

    fn share(&self) -> f64 {
        if self.filled == 0 {
            0.0
        } else {
            self.count() as f64 / self.filled as f64
        }
    }
}

/// Watches the primary's overruns; see the module's rule.
pub struct OverrunWatch {
    before: Bits<{ BEFORE_CYCLES / 64 }>,
    during: Bits<{ WINDOW / 64 }>,
    /// The level before the load, while a candidate is in quarantine.
    level: Option<f64>,
    seen: u64,
}

impl Default for OverrunWatch {
    fn default() -> Self {
        OverrunWatch {
            before: Bits::new(),
            during: Bits::new(),
            level: None,
            seen: 0,
        }
    }
}

impl OverrunWatch {
    /// Takes one cycle: `overruns` is the loop's count so far; `candidate`, while a candidate is
    /// in quarantine, the part of the period its last scan took. Returns why the candidate is to
    /// be faulted, when it is.
    pub fn cycle(&mut self, overruns: u64, candidate: Option<f64>) -> Option<String> {
        let overran = overruns > self.seen;
        self.seen = overruns;
        let Some(share) = candidate else {
            self.level = None;
            self.before.push(overran);
            return None;
        };
        let overran = overran && share >= CANDIDATE_SHARE;
        let level = *self.level.get_or_insert_with(|| {
            self.during = Bits::new();
            self.before.share()
        });
        self.during.push(overran);
        let n = self.during.count();
        let share = self.during.share();
        let full = self.during.filled == WINDOW;
        (full && n >= MIN_OVERRUNS && share > 2.0 * level + MARGIN).then(|| {
            format!(
                "with the candidate in quarantine the primary overran {n} of its last {WINDOW} \
                 cycles ({:.1} %), against {:.1} % of the {BEFORE_CYCLES} cycles before the \
                 load: the candidate takes the primary's time",
                share * 100.0,
                level * 100.0
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds `n` cycles in which every `every`-th overran (none when 0), with a candidate whose
    /// scans take half the period when `q`.
    fn feed(w: &mut OverrunWatch, total: &mut u64, n: usize, every: usize, q: bool) -> Vec<String> {
        feed_with(w, total, n, every, q.then_some(0.5))
    }

    fn feed_with(
        w: &mut OverrunWatch,
        total: &mut u64,
        n: usize,
        every: usize,
        candidate: Option<f64>,
    ) -> Vec<String> {
        (1..=n)
            .filter_map(|k| {
                if every > 0 && k % every == 0 {
                    *total += 1;
                }
                w.cycle(*total, candidate)
            })
            .collect()
    }

    #[test]
    fn overruns_of_a_busy_machine_are_not_blamed_on_a_candidate_that_takes_a_few_microseconds() {
        let (mut w, mut total) = (OverrunWatch::default(), 0);
        feed(&mut w, &mut total, 2000, 0, false);
        // Every cycle overruns, but the candidate's scans take 1 % of the period.
        assert!(feed_with(&mut w, &mut total, 2000, 1, Some(0.01)).is_empty());
    }

    #[test]
    fn overruns_at_their_level_before_the_load_do_not_blame_the_candidate() {
        let (mut w, mut total) = (OverrunWatch::default(), 0);
        feed(&mut w, &mut total, 2000, 40, false);
        assert!(feed(&mut w, &mut total, 5000, 40, true).is_empty());
        // Jitter: a few more, still under the margin.
        assert!(feed(&mut w, &mut total, 5000, 20, true).is_empty());
    }

    #[test]
    fn a_candidate_that_makes_the_primary_overrun_one_cycle_in_three_is_blamed_within_the_window() {
        let (mut w, mut total) = (OverrunWatch::default(), 0);
        feed(&mut w, &mut total, 2000, 40, false);
        let why = feed(&mut w, &mut total, WINDOW, 3, true);
        assert_eq!(why.len(), 1, "judged once the window is full: {why:?}");
        assert!(why[0].contains("85 of its last 256 cycles"), "{}", why[0]);
        assert!(why[0].contains("against 2.5 %"), "{}", why[0]);
    }

    #[test]
    fn a_new_quarantine_starts_a_new_window_against_the_cycles_before_it() {
        let (mut w, mut total) = (OverrunWatch::default(), 0);
        feed(&mut w, &mut total, 2000, 0, false);
        assert!(!feed(&mut w, &mut total, 300, 3, true).is_empty());
        // After the candidate left, the overruns it caused are part of the level no more than
        // the cycles that follow make them.
        feed(&mut w, &mut total, 2000, 0, false);
        assert!(feed(&mut w, &mut total, WINDOW - 1, 3, true).is_empty());
    }
}
