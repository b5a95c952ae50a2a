//! The stall watchdog of the primary: a place that stays marked longer than its `[[watchdog]]`
//! maximum, or no firing for `[stall] no_firing` while a watched place is marked, or after a
//! warm start whatever is marked (the saved state may not match the plant). It raises
//! `stall_alarm` once per episode, and during probation it is a cause to revert.
//!
//! It complements the deadlock alarm: a deadlock is a marking in which no transition is enabled
//! at all, whatever the plant does; a stall is a program that could go on but waits for the plant
//! longer than the machine's own timing allows (a sensor that never comes, a guard that never
//! holds). Checked after each primary scan, in O(watched places), without allocating.

use crate::Container;

/// Why the primary stalls.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Stall {
    /// Watchdog `index` of the program: its place has been marked for `dwell_us`.
    Dwell { index: usize, dwell_us: u64 },
    /// Nothing fired for `idle_us` while watched place `index` was marked.
    NoFiring { index: usize, idle_us: u64 },
    /// Nothing fired for `idle_us` since a warm start, with no watched place marked.
    AfterWarmStart { idle_us: u64 },
}

impl Stall {
    /// How long the program waited: the dwell, or the time without a firing.
    pub fn waited_us(self) -> u64 {
        match self {
            Stall::Dwell { dwell_us, .. } => dwell_us,
            Stall::NoFiring { idle_us, .. } | Stall::AfterWarmStart { idle_us } => idle_us,
        }
    }
}

/// The watchdog's memory: when the primary last fired, and whether the current episode has
/// already been reported.
pub(crate) struct StallWatch {
    last_firing_us: u64,
    alarmed: bool,
    // A warm start resumed a saved marking and nothing has fired since.
    after_warm_start: bool,
}

impl StallWatch {
    /// A watch that starts counting at `now_us`.
    pub fn new(now_us: u64) -> Self {
        StallWatch {
            last_firing_us: now_us,
            alarmed: false,
            after_warm_start: false,
        }
    }

    /// The primary resumed a saved state: until it fires, `[stall] no_firing` counts whatever
    /// is marked, for a plant that was restarted meanwhile may not be where the state says.
    pub fn warm_started(&mut self) {
        self.after_warm_start = true;
    }

    /// Starts again at `now_us`: another program became primary.
    pub fn restart(&mut self, now_us: u64) {
        *self = StallWatch::new(now_us);
    }

    /// Whether the current episode of a stall goes on.
    pub fn stalled(&self) -> bool {
        self.alarmed
    }

    /// Checks the primary after its scan at `now_us`. Returns a stall only when it begins an
    /// episode; an episode ends when no watchdog condition holds.
    pub fn check(&mut self, primary: &Container, now_us: u64) -> Option<Stall> {
        let program = primary.program();
        let watchdogs = program.watchdogs();
        if watchdogs.is_empty() && program.no_firing_us().is_none() {
            return None;
        }
        if !primary.fired().is_empty() {
            self.last_firing_us = now_us;
            self.after_warm_start = false;
        }
        let marking = primary.marking();
        let since = primary.place_since_us();
        let mut stall = None;
        let mut marked = None;
        for (index, w) in watchdogs.iter().enumerate() {
            let p = w.place.index();
            if marking[p] == 0 {
                continue;
            }
            marked.get_or_insert(index);
            let dwell_us = since[p].map_or(0, |t| now_us.saturating_sub(t));
            if dwell_us > w.max_us {
                stall = Some(Stall::Dwell { index, dwell_us });
                break;
            }
        }
        if stall.is_none() {
            let idle_us = now_us.saturating_sub(self.last_firing_us);
            if program.no_firing_us().is_some_and(|limit| idle_us > limit) {
                stall = match marked {
                    Some(index) => Some(Stall::NoFiring { index, idle_us }),
                    None if self.after_warm_start => Some(Stall::AfterWarmStart { idle_us }),
                    None => None,
                };
            }
        }
        match stall {
            None => {
                self.alarmed = false;
                None
            }
            Some(_) if self.alarmed => None,
            Some(s) => {
                self.alarmed = true;
                Some(s)
            }
        }
    }

    /// The stall in words, with the place's id; after a warm start with no firing since, with
    /// what that may mean.
    pub fn describe(&self, stall: Stall, primary: &Container) -> String {
        let what = Self::what(stall, primary);
        if self.after_warm_start && !matches!(stall, Stall::AfterWarmStart { .. }) {
            format!("{what}; nothing has fired since the warm start: the saved state may not match the plant (was it restarted?); start with --cold to begin from the initial marking")
        } else {
            what
        }
    }

    fn what(stall: Stall, primary: &Container) -> String {
        let program = primary.program();
        let net = program.net();
        let secs = |us: u64| us as f64 / 1e6;
        match stall {
            Stall::Dwell { index, dwell_us } => {
                let w = program.watchdogs()[index];
                format!(
                    "place {} has been marked for {:.1} s, longer than its watchdog of {:.1} s",
                    net.place(w.place).id,
                    secs(dwell_us),
                    secs(w.max_us)
                )
            }
            Stall::NoFiring { index, idle_us } => {
                let w = program.watchdogs()[index];
                format!(
                    "nothing has fired for {:.1} s while {} is marked, longer than [stall] no_firing of {:.1} s",
                    secs(idle_us),
                    net.place(w.place).id,
                    secs(program.no_firing_us().unwrap_or(0))
                )
            }
            Stall::AfterWarmStart { idle_us } => format!(
                "nothing has fired for {:.1} s since the warm start, longer than [stall] no_firing of {:.1} s: the saved state may not match the plant (was it restarted?); start with --cold to begin from the initial marking",
                secs(idle_us),
                secs(program.no_firing_us().unwrap_or(0))
            ),
        }
    }
}
