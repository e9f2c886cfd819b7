//! Progress on standard error: a line per stage, an indicatif bar with ETA for each stage
//! whose work can be counted (visibility per vertex, transport per observation, rotation per
//! normal-grid cell, outer iterations, held-out photos, renders), a spinner with elapsed time
//! for the others (the pilot fit), one line per outer iteration of the solver, and a table
//! of time and memory per stage at the end. With `--quiet` only warnings (and errors and the
//! final summary, printed by the caller) appear; hidden bars cost nothing.
//!
//! Kernels deep in the library report counted work through [`tick`], which advances the
//! bar of the stage running now ([`Progress::stage_bar`]) and does nothing otherwise (a
//! relaxed atomic load), so the kernels stay free of progress parameters.

use crate::stages::StageRecord;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::fmt::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::RwLock;
use std::time::{Duration, Instant};

/// The bar [`tick`] advances, if any.
static ACTIVE: RwLock<Option<ProgressBar>> = RwLock::new(None);
static HAS_ACTIVE: AtomicBool = AtomicBool::new(false);

/// Advance the running stage's bar by `n` units of work (no-op when there is none).
pub fn tick(n: u64) {
    if HAS_ACTIVE.load(Ordering::Relaxed) {
        if let Ok(g) = ACTIVE.read() {
            if let Some(b) = g.as_ref() {
                b.inc(n);
            }
        }
    }
}

fn set_active(bar: Option<ProgressBar>) {
    if let Ok(mut g) = ACTIVE.write() {
        HAS_ACTIVE.store(bar.is_some(), Ordering::Relaxed);
        *g = bar;
    }
}

/// Stage lines and bars, or (quiet) warnings only.
pub struct Progress {
    enabled: bool,
    start: Instant,
}

/// A stage's bar: while it lives, [`tick`] advances it; dropping it clears it.
pub struct StageBar {
    bar: ProgressBar,
}

impl StageBar {
    /// The underlying bar (to set a message or advance it directly).
    pub fn bar(&self) -> &ProgressBar {
        &self.bar
    }
}

impl Drop for StageBar {
    fn drop(&mut self) {
        set_active(None);
        self.bar.finish_and_clear();
    }
}

const BAR_TEMPLATE: &str =
    "          {prefix:<18} [{bar:30}] {pos}/{len} {elapsed_precise} ETA {eta} {msg}";
const SPIN_TEMPLATE: &str = "          {prefix:<18} {spinner} {elapsed_precise} {msg}";

impl Progress {
    /// Progress output when `enabled` (otherwise warnings only).
    pub fn new(enabled: bool) -> Self {
        Progress {
            enabled,
            start: Instant::now(),
        }
    }

    /// Whether stage output is shown.
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    fn stamp(&self) -> String {
        format!("[{:7.1}s]", self.start.elapsed().as_secs_f64())
    }

    /// Announce a stage.
    pub fn stage(&self, name: &str) {
        if self.enabled {
            eprintln!("{} {name}", self.stamp());
        }
    }

    /// A warning: shown even with `--quiet`.
    pub fn warn(&self, msg: &str) {
        eprintln!("warning: {msg}");
    }

    /// One line of information (one per solver iteration, skipped photos, ...), printed
    /// above any bar; nothing with `--quiet`.
    pub fn line(&self, msg: &str) {
        if !self.enabled {
            return;
        }
        let active = ACTIVE.read().ok().and_then(|g| g.clone());
        match active {
            Some(b) if !b.is_hidden() => b.println(format!("          {msg}")),
            _ => eprintln!("          {msg}"),
        }
    }

    fn styled(&self, bar: ProgressBar, template: &str, what: &str) -> ProgressBar {
        if let Ok(style) = ProgressStyle::with_template(template) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_prefix(what.to_string());
        bar
    }

    /// A bar of `len` steps with ETA (hidden when disabled).
    pub fn bar(&self, len: u64, what: &str) -> ProgressBar {
        if !self.enabled {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
        self.styled(bar, BAR_TEMPLATE, what)
    }

    /// A line of information worth a user's attention (a default chosen for them).
    pub fn note(&self, msg: &str) {
        if self.enabled {
            eprintln!("{} {msg}", self.stamp());
        }
    }

    /// A bar of `len` steps that the library's kernels advance through [`tick`] until the
    /// returned guard is dropped.
    pub fn stage_bar(&self, len: u64, what: &str) -> StageBar {
        let bar = self.bar(len, what);
        if self.enabled {
            set_active(Some(bar.clone()));
        }
        StageBar { bar }
    }

    /// A spinner with elapsed time for work that cannot be counted ahead.
    pub fn spinner(&self, what: &str) -> StageBar {
        if !self.enabled {
            return StageBar {
                bar: ProgressBar::hidden(),
            };
        }
        let bar = self.styled(
            ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr()),
            SPIN_TEMPLATE,
            what,
        );
        bar.enable_steady_tick(Duration::from_millis(200));
        StageBar { bar }
    }

    /// The final line and the table of time and memory per stage.
    pub fn finish(&self, msg: &str, stages: &[StageRecord]) {
        if self.enabled {
            eprint!("{}", stage_table(stages));
            eprintln!("{} done: {msg}", self.stamp());
        }
    }
}

/// A plain-text table: stage | wall s | CPU s | peak memory MiB, and a total row.
pub fn stage_table(stages: &[StageRecord]) -> String {
    let width = stages
        .iter()
        .map(|s| s.name.chars().count())
        .max()
        .unwrap_or(5)
        .max(5);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "  {:<width$}  {:>9}  {:>9}  {:>12}",
        "stage", "wall s", "CPU s", "peak MiB"
    );
    let (mut wall, mut cpu, mut peak) = (0.0, 0.0, 0u64);
    for st in stages {
        let _ = writeln!(
            s,
            "  {:<width$}  {:>9.2}  {:>9.2}  {:>12.1}",
            st.name,
            st.seconds,
            st.cpu_seconds,
            st.peak_memory_bytes as f64 / (1u64 << 20) as f64
        );
        wall += st.seconds;
        cpu += st.cpu_seconds;
        peak = peak.max(st.peak_memory_bytes);
    }
    let _ = writeln!(
        s,
        "  {:<width$}  {:>9.2}  {:>9.2}  {:>12.1}",
        "total",
        wall,
        cpu,
        peak as f64 / (1u64 << 20) as f64
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table lists every stage once with its figures, and the total row sums the wall
    /// and CPU seconds and takes the largest peak.
    #[test]
    fn stage_table_rows_and_totals() {
        let rec = |name: &str, s: f64, c: f64, m: u64| StageRecord {
            name: name.into(),
            seconds: s,
            cpu_seconds: c,
            peak_memory_bytes: m << 20,
            memory_exact: true,
        };
        let t = stage_table(&[
            rec("import", 1.5, 2.0, 10),
            rec("visibility", 3.25, 6.0, 40),
        ]);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), 4);
        assert!(lines[1].contains("import") && lines[1].contains("1.50"));
        let total: Vec<&str> = lines[3].split_whitespace().collect();
        assert_eq!(total, ["total", "4.75", "8.00", "40.0"]);
    }

    /// `tick` advances the stage bar while it lives and nothing after it is dropped (other
    /// tests' kernels may tick concurrently, hence `>=` while the bar is live).
    #[test]
    fn tick_advances_only_the_live_stage_bar() {
        let p = Progress::new(true);
        let sb = p.stage_bar(10, "test");
        tick(3);
        let bar = sb.bar().clone();
        assert!(bar.position() >= 3);
        drop(sb);
        let after = bar.position();
        tick(4);
        assert_eq!(bar.position(), after);
    }
}
