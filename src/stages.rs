//! Wall time, CPU time and peak memory per pipeline stage, and [`tick`] (batched per chunk
//! of work by [`Ticker`]): how kernels deep in the library advance the running stage's
//! progress bar (set by `run`'s progress) without a progress parameter or a dependency on
//! `run`.
//!
//! Wall time from [`std::time::Instant`]; CPU time (user + system, all threads) and the
//! resident-set high-water mark from Linux `/proc/self`. Before each stage the high-water
//! mark is reset (writing `5` to `/proc/self/clear_refs`, Linux ≥ 4.0) so that each stage's
//! peak is its own; where `/proc` is missing or read-only the figures fall back to the
//! process-wide peak, or to zero, and [`StageRecord::memory_exact`] says so.

use indicatif::ProgressBar;
use serde::Serialize;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::RwLock;
use std::time::Instant;

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

/// How many units a [`Ticker`] gathers before it passes them on.
const TICK_BATCH: u64 = 64;

/// Ticks gathered by one worker and passed to [`tick`] once per `TICK_BATCH` units (the
/// rest when dropped): one read of the active bar per chunk of work instead of one per
/// item. Give each parallel job its own (rayon's `map_init`/`for_each_init`).
#[derive(Debug, Default)]
pub struct Ticker {
    pending: u64,
}

impl Ticker {
    /// Count `n` units of work done.
    pub fn tick(&mut self, n: u64) {
        self.pending += n;
        if self.pending >= TICK_BATCH {
            tick(std::mem::take(&mut self.pending));
        }
    }
}

impl Drop for Ticker {
    fn drop(&mut self) {
        if self.pending > 0 {
            tick(self.pending);
        }
    }
}

pub(crate) fn set_active(bar: Option<ProgressBar>) {
    if let Ok(mut g) = ACTIVE.write() {
        HAS_ACTIVE.store(bar.is_some(), Ordering::Relaxed);
        *g = bar;
    }
}

/// The bar [`tick`] advances now, if any.
pub(crate) fn active_bar() -> Option<ProgressBar> {
    ACTIVE.read().ok().and_then(|g| g.clone())
}

/// One finished stage.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct StageRecord {
    /// Stage name, e.g. `import`, `visibility`, `lighting`.
    pub name: String,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// CPU seconds over all threads (user + system).
    pub cpu_seconds: f64,
    /// Peak resident memory during the stage, in bytes.
    pub peak_memory_bytes: u64,
    /// Whether the peak could be reset before the stage (otherwise it is the process peak so far).
    pub memory_exact: bool,
}

impl StageRecord {
    /// The stage's peak memory for a report's table: MiB to one decimal, marked when it is
    /// the process peak so far rather than the stage's own.
    pub fn peak_mib_label(&self) -> String {
        let mib = self.peak_memory_bytes as f64 / (1u64 << 20) as f64;
        if self.memory_exact {
            format!("{mib:.1}")
        } else {
            format!("{mib:.1} (process peak)")
        }
    }
}

/// Wall and CPU seconds (user + system, all threads, [`cpu_seconds`]' 1/100 s ticks) since
/// it was started.
#[derive(Debug, Clone, Copy)]
pub struct Stopwatch {
    t0: Instant,
    cpu0: f64,
}

impl Stopwatch {
    /// Start now.
    pub fn start() -> Self {
        Stopwatch {
            t0: Instant::now(),
            cpu0: cpu_seconds(),
        }
    }

    /// `(wall, cpu)` seconds since [`Stopwatch::start`].
    pub fn elapsed(&self) -> (f64, f64) {
        (
            self.t0.elapsed().as_secs_f64(),
            (cpu_seconds() - self.cpu0).max(0.0),
        )
    }
}

/// Records stages in the order they ran.
#[derive(Debug, Default)]
pub struct Stages {
    /// Finished stages.
    pub records: Vec<StageRecord>,
}

impl Stages {
    /// An empty recorder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Run `f` as stage `name` and record its cost. Stages with the same name accumulate.
    pub fn run<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let exact = reset_peak_rss();
        let watch = Stopwatch::start();
        let out = f();
        let (seconds, cpu_seconds) = watch.elapsed();
        let record = StageRecord {
            name: name.to_string(),
            seconds,
            cpu_seconds,
            peak_memory_bytes: peak_rss_bytes(),
            memory_exact: exact,
        };
        if let Some(r) = self.records.iter_mut().find(|r| r.name == name) {
            r.seconds += record.seconds;
            r.cpu_seconds += record.cpu_seconds;
            r.peak_memory_bytes = r.peak_memory_bytes.max(record.peak_memory_bytes);
            r.memory_exact &= record.memory_exact;
        } else {
            self.records.push(record);
        }
        out
    }

    /// Largest per-stage peak (the run's peak resident memory).
    pub fn peak_memory_bytes(&self) -> u64 {
        self.records
            .iter()
            .map(|r| r.peak_memory_bytes)
            .max()
            .unwrap_or(0)
            .max(peak_rss_bytes())
    }

    /// Total wall seconds over all stages.
    pub fn total_seconds(&self) -> f64 {
        self.records.iter().map(|r| r.seconds).sum()
    }
}

/// Reset the kernel's resident-set high-water mark; `true` when it worked.
fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// The resident-set high-water mark (`VmHWM`) in bytes, 0 when unknown.
pub fn peak_rss_bytes() -> u64 {
    proc_status_kib("VmHWM:").map_or(0, |k| k * 1024)
}

/// The current resident set (`VmRSS`) in bytes, 0 when unknown.
pub fn rss_bytes() -> u64 {
    proc_status_kib("VmRSS:").map_or(0, |k| k * 1024)
}

/// Physical memory available to new allocations (`MemAvailable`), when known.
pub fn available_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

fn proc_status_kib(key: &str) -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// CPU seconds of this process's live threads so far, in nanoseconds' resolution: the sum
/// of the first field of `/proc/self/task/*/schedstat`. Unlike [`cpu_seconds`] (1/100 s
/// ticks, exited threads included) it resolves microsecond kernels, for benchmarks that
/// keep their threads (rayon's pool) alive. 0 where unavailable.
pub fn cpu_seconds_fine() -> f64 {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return 0.0;
    };
    dir.filter_map(|e| e.ok())
        .filter_map(|e| std::fs::read_to_string(e.path().join("schedstat")).ok())
        .filter_map(|t| {
            t.split_whitespace()
                .next()
                .and_then(|x| x.parse::<f64>().ok())
        })
        .sum::<f64>()
        * 1e-9
}

/// CPU seconds (user + system) used by this process so far, from `/proc/self/stat`
/// (fields 14 and 15, in clock ticks of 1/100 s, the Linux `USER_HZ`).
pub fn cpu_seconds() -> f64 {
    let Ok(text) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // The command name (field 2) is in parentheses and may hold spaces: split after it.
    let Some(after) = text.rfind(')').map(|i| &text[i + 1..]) else {
        return 0.0;
    };
    let fields: Vec<&str> = after.split_whitespace().collect();
    // After ')' the first field is field 3 (state): utime is field 14 → index 11.
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|s| s.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / 100.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stage_that_allocates_shows_its_memory_and_time() {
        let mut stages = Stages::new();
        let n = 64 << 20; // 64 MiB, touched so that it is resident.
        let sum = stages.run("alloc", || {
            let v = vec![1u8; n];
            v.iter().map(|&x| x as u64).sum::<u64>()
        });
        assert_eq!(sum, n as u64);
        let r = &stages.records[0];
        assert_eq!(r.name, "alloc");
        assert!(r.seconds > 0.0);
        if cfg!(target_os = "linux") {
            // The peak must include the 64 MiB buffer (the process itself is smaller than
            // the buffer plus the test harness, so no upper bound is asserted).
            assert!(r.peak_memory_bytes >= n as u64, "{r:?}");
        }
    }

    /// Every unit counted by a ticker reaches the bar: in whole batches while it runs, the
    /// rest when it is dropped.
    #[test]
    fn a_ticker_passes_on_every_unit() {
        let bar = ProgressBar::hidden();
        set_active(Some(bar.clone()));
        {
            let mut t = Ticker::default();
            for _ in 0..TICK_BATCH + 5 {
                t.tick(1);
            }
            assert_eq!(bar.position(), TICK_BATCH, "one batch passed on so far");
        }
        assert_eq!(bar.position(), TICK_BATCH + 5, "the rest on drop");
        set_active(None);
    }
}
