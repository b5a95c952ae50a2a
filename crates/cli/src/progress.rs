//! A terminal progress display for long explorations (indicatif, on stderr), drawn from the
//! analysis's progress callback: the analysis reports, the command line draws.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use cetratus_analysis::{Progress, ProgressFn};

/// Runs shorter than this show nothing.
const QUIET_FOR: Duration = Duration::from_secs(1);

/// A line on stderr showing states, states per second, memory and, against the budgets, the
/// time left at most; it appears once a run has taken a second, and is invisible when stderr is
/// not a terminal. The CLI does not create one in `--json` mode.
#[derive(Clone, Debug)]
pub struct TerminalProgress {
    bar: indicatif::ProgressBar,
    max_states: u64,
    timeout: Duration,
    /// The last reading: (time since the start, states), for the rate.
    last: Arc<Mutex<Option<(Duration, u64)>>>,
}

impl TerminalProgress {
    /// A new display for a run whose budgets are `max_states` and `timeout`; nothing is shown yet.
    pub fn new(max_states: u64, timeout: Duration) -> Self {
        let bar = indicatif::ProgressBar::new_spinner();
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {elapsed_precise} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        TerminalProgress {
            bar,
            max_states,
            timeout,
            last: Arc::new(Mutex::new(None)),
        }
    }

    /// The callback to put in [`cetratus_analysis::CheckOptions::progress`].
    pub fn callback(&self) -> ProgressFn {
        let me = self.clone();
        Arc::new(move |p: Progress| me.show(p))
    }

    fn show(&self, p: Progress) {
        // indicatif's own clock (the analysis reads none): time since the display was made.
        let now = self.bar.elapsed();
        let elapsed = now;
        if elapsed < QUIET_FOR {
            return;
        }
        let Ok(mut last) = self.last.lock() else {
            return;
        };
        let rate = match *last {
            Some((t, s)) if now > t => {
                (p.states.saturating_sub(s)) as f64 / (now - t).as_secs_f64()
            }
            _ => p.states as f64 / elapsed.as_secs_f64().max(1e-3),
        };
        if last.is_none() {
            self.bar.enable_steady_tick(Duration::from_millis(200));
        }
        *last = Some((now, p.states));
        // The run ends at the latest at the state budget (at this rate) or at the timeout.
        let to_states =
            (rate > 0.0).then(|| self.max_states.saturating_sub(p.states) as f64 / rate);
        let to_timeout = self.timeout.saturating_sub(elapsed).as_secs_f64();
        let eta = to_states.map_or(to_timeout, |s| s.min(to_timeout));
        self.bar.set_message(format!(
            "{} states, {:.2} M states/s, {:.1} MiB, {} to expand, at most {} left \
             (budgets; Ctrl-C stops with a partial report)",
            p.states,
            rate / 1e6,
            p.bytes as f64 / (1024.0 * 1024.0),
            p.states.saturating_sub(p.expanded),
            human(eta)
        ));
    }

    /// Removes the display.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

fn human(secs: f64) -> String {
    if secs >= 3600.0 {
        format!("{:.1} h", secs / 3600.0)
    } else if secs >= 60.0 {
        format!("{:.0} min", secs / 60.0)
    } else {
        format!("{secs:.0} s")
    }
}
