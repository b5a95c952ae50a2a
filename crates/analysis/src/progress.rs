//! A terminal progress display for long explorations (indicatif, on stderr).

use std::sync::Arc;
use std::time::Duration;

use crate::{Progress, ProgressFn};

/// A spinner on stderr showing states, edges and the BFS frontier; invisible when stderr is not a
/// terminal, so scripts reading `--json` see nothing of it.
#[derive(Clone, Debug)]
pub struct TerminalProgress {
    bar: indicatif::ProgressBar,
}

impl TerminalProgress {
    /// A new spinner, not yet showing anything.
    pub fn new() -> Self {
        let bar = indicatif::ProgressBar::new_spinner();
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {elapsed_precise} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        bar.enable_steady_tick(Duration::from_millis(200));
        TerminalProgress { bar }
    }

    /// The callback to put in [`crate::CheckOptions::progress`].
    pub fn callback(&self) -> ProgressFn {
        let bar = self.bar.clone();
        Arc::new(move |p: Progress| {
            bar.set_message(format!(
                "{} states, {} edges, {} to expand (Ctrl-C stops with a partial report)",
                p.states,
                p.edges,
                p.states.saturating_sub(p.expanded)
            ));
        })
    }

    /// Removes the spinner.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

impl Default for TerminalProgress {
    fn default() -> Self {
        Self::new()
    }
}
