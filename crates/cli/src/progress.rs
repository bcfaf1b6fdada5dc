//! Terminal progress: indicatif bars on stderr when both stdout and stderr are terminals
//! and `--quiet` is off; `-v` messages on stderr.

use std::io::IsTerminal;
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressStyle};
use primfit_core::Progress;

/// A [`Progress`] that draws one bar per stage.
pub struct Bars {
    bar: Mutex<Option<ProgressBar>>,
    visible: bool,
    verbose: bool,
}

impl Bars {
    /// Bars are drawn only on an interactive terminal and when not quiet.
    pub fn new(quiet: bool, verbose: bool) -> Self {
        let visible = !quiet && std::io::stdout().is_terminal() && std::io::stderr().is_terminal();
        Bars {
            bar: Mutex::new(None),
            visible,
            verbose: verbose && !quiet,
        }
    }
}

impl Progress for Bars {
    fn start(&self, stage: &str, total: u64) {
        if !self.visible {
            return;
        }
        let bar = ProgressBar::new(total);
        let style =
            ProgressStyle::with_template("{prefix:>16} [{bar:40}] {pos}/{len} {elapsed_precise}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> ");
        bar.set_style(style);
        bar.set_prefix(stage.to_string());
        if let Ok(mut b) = self.bar.lock() {
            *b = Some(bar);
        }
    }
    fn advance(&self, n: u64) {
        if let Ok(b) = self.bar.lock()
            && let Some(bar) = b.as_ref()
        {
            bar.inc(n);
        }
    }
    fn finish(&self) {
        if let Ok(mut b) = self.bar.lock()
            && let Some(bar) = b.take()
        {
            bar.finish_and_clear();
        }
    }
    fn message(&self, text: &str) {
        if self.verbose {
            eprintln!("{text}");
        }
    }
}
