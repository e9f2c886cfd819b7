//! Progress on standard error: one line per stage and indicatif bars for long loops;
//! silent with `--quiet` (hidden bars cost nothing).

use indicatif::{ProgressBar, ProgressStyle};
use std::time::Instant;

/// Stage lines and bars, or nothing.
pub struct Progress {
    enabled: bool,
    start: Instant,
}

impl Progress {
    /// Progress output when `enabled`.
    pub fn new(enabled: bool) -> Self {
        Progress {
            enabled,
            start: Instant::now(),
        }
    }

    /// Announce a stage.
    pub fn stage(&self, name: &str) {
        if self.enabled {
            eprintln!("[{:7.1}s] {name}", self.start.elapsed().as_secs_f64());
        }
    }

    /// A bar of `len` steps (hidden when disabled).
    pub fn bar(&self, len: u64, what: &str) -> ProgressBar {
        if !self.enabled {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::new(len);
        if let Ok(style) = ProgressStyle::with_template(
            "          {prefix} [{bar:30}] {pos}/{len} {elapsed_precise} {msg}",
        ) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_prefix(what.to_string());
        bar
    }

    /// A line of information worth a user's attention (a default chosen for them).
    pub fn note(&self, msg: &str) {
        if self.enabled {
            eprintln!("[{:7.1}s] {msg}", self.start.elapsed().as_secs_f64());
        }
    }

    /// The final line.
    pub fn finish(&self, msg: &str) {
        if self.enabled {
            eprintln!("[{:7.1}s] done: {msg}", self.start.elapsed().as_secs_f64());
        }
    }
}
