//! Progress bars and warnings on stderr: the binary's side of [`bake_job::Events`].

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;

/// Progress bars on a terminal (none with --quiet or when stderr is not a terminal).
pub struct Bars {
    enabled: bool,
    quiet: bool,
    bar: Mutex<Option<ProgressBar>>,
}

/// A bar still open when the bake stops early (an error return) is cleared, so the error
/// line stands alone.
impl Drop for Bars {
    fn drop(&mut self) {
        bake_job::Progress::finish(self);
    }
}

impl Bars {
    pub fn new(quiet: bool) -> Bars {
        Bars {
            enabled: !quiet && std::io::stderr().is_terminal(),
            quiet,
            bar: Mutex::new(None),
        }
    }
}

impl bake_job::Progress for Bars {
    fn start(&self, stage: &str, total: u64) {
        if !self.enabled {
            return;
        }
        let bar = if total == 0 {
            // Open-ended (an iterative solve): a count, no bar or time left.
            let bar = ProgressBar::new_spinner();
            if let Ok(style) = ProgressStyle::with_template("{msg:>13} {spinner} {elapsed}") {
                bar.set_style(style);
            }
            bar.enable_steady_tick(std::time::Duration::from_millis(120));
            bar
        } else {
            let bar = ProgressBar::new(total);
            if let Ok(style) =
                ProgressStyle::with_template("{msg:>13} [{bar:40}] {pos}/{len}, {eta} left")
            {
                bar.set_style(style.progress_chars("=> "));
            }
            bar
        };
        bar.set_message(stage.to_string());
        if let Ok(mut slot) = self.bar.lock() {
            *slot = Some(bar);
        }
    }

    fn advance(&self, steps: u64) {
        if let Ok(slot) = self.bar.lock() {
            if let Some(bar) = slot.as_ref() {
                bar.inc(steps);
            }
        }
    }

    fn finish(&self) {
        if let Ok(mut slot) = self.bar.lock() {
            if let Some(bar) = slot.take() {
                bar.finish_and_clear();
            }
        }
    }
}

impl bake_job::Events for Bars {
    fn warn(&self, line: &str) {
        if !self.quiet {
            eprintln!("bake: warning: {line}");
        }
    }
}
