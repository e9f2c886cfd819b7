//! The alternation ([`alternate`]) from every start under the light model and loss the
//! validation score keeps ([`super::choice`]), the start search around it
//! ([`search_starts`]), the restarts, and what the console and the report's timeline show
//! of each iterate ([`Monitor`]).

use super::choice::fit_light_models;
use super::start::FitStart;
use crate::report::TimelinePoint;
use crate::run::state::Prepared;
use crate::run::state::RunLog;
use crate::run::tracker::HoldoutTracker;
use crate::run::{Progress, Restart, RunOptions};
use crate::solve::light::choose::LightDecision;
use crate::solve::materials::{brightness, coarse_light, irradiance, reanchor};
use crate::solve::starts::MultiStart;
use crate::solve::{self, EstimateOptions, Materials0, Problem};
use crate::transport::brdf::BasisBrdf;
use crate::Result;

/// The alternation from the start's family ([`FitStart::family`]) under the light model
/// and loss chosen ([`fit_light_models`]), then the start search when asked, with a
/// progress bar and the held-out tracker ([`super::held_out_tracker`]) scoring every
/// iterate for the timeline. The tracker's transport rows (the held-out photos') are freed on return.
pub(super) fn alternate(
    opts: &RunOptions,
    p: &Prepared,
    problem: &Problem,
    start: &mut FitStart,
    tracker: Option<HoldoutTracker>,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<Estimated> {
    let lambert = start.eopts.lambert_basis;
    progress.stage("estimate");
    let family = start.family(opts, p, lambert);
    let bar = progress.bar(
        (p.eff.max_iterations * family.len()) as u64,
        "outer iterations",
    );
    let monitor = Monitor {
        bar: &bar,
        progress,
        tracker: tracker.as_ref(),
        n_vertices: problem.n_vertices,
    };
    let mut est = fit_light_models(opts, problem, &family, start, &monitor, log)?;
    if opts.start_search {
        est = search_starts(problem, est, &family[0].materials, lambert, &monitor, log)?;
    }
    if est.est.lambda.len() >= 2 {
        let mode = opts.restart.resolve(&p.eff.basis);
        if opts.restart == Restart::Auto {
            start.reasons.push(auto_restart_reason(mode, &p.eff.basis));
        }
        let first_fit = est.multi.chosen;
        for &mode in mode.steps() {
            let step = RestartStep { mode, first_fit };
            est = restart(problem, p, est, start, step, &monitor, log)?;
        }
    }
    bar.finish_and_clear();
    Ok(est)
}

/// The estimate's progress: its bar, its console lines and the held-out error of each
/// iterate (the report's timeline).
pub(super) struct Monitor<'a> {
    pub(super) bar: &'a indicatif::ProgressBar,
    progress: &'a Progress,
    tracker: Option<&'a HoldoutTracker>,
    n_vertices: usize,
}

impl Monitor<'_> {
    /// The held-out error of an iterate, for the timeline (finite, else none).
    pub(super) fn held_out(&self, state: &solve::IterState) -> Option<f64> {
        self.tracker
            .map(|t| t.rmse(state, self.n_vertices))
            .filter(|v| v.is_finite())
    }

    /// A console line under the bar (or alone when the bar is hidden).
    pub(super) fn say(&self, line: &str) {
        if self.bar.is_hidden() {
            self.progress.line(line);
        } else {
            self.bar.println(format!("          {line}"));
        }
    }
}

/// The estimate kept: the fit, its starts, its options and light model, its timeline.
pub(super) struct Estimated {
    pub(super) est: solve::Estimate,
    pub(super) multi: MultiStart,
    pub(super) eopts: EstimateOptions,
    pub(super) light_decision: LightDecision,
    pub(super) timeline: Vec<TimelinePoint>,
}

/// The start search (`--start-search`, [`brightness::search`]) from the kept fit, around
/// `base` (the first start's materials; `lambert` its Lambertian basis). The
/// timeline then follows the search's records: the kept start's iterations as start 0,
/// each searched start's after them on the same clock.
fn search_starts(
    problem: &Problem,
    fitted: Estimated,
    base: &Materials0,
    lambert: usize,
    monitor: &Monitor,
    log: &mut RunLog,
) -> Result<Estimated> {
    let Estimated {
        est,
        multi,
        eopts,
        light_decision,
        mut timeline,
    } = fitted;
    monitor.progress.stage("start search");
    let label = multi.starts[multi.chosen].label.clone();
    timeline.retain(|p| p.start == multi.chosen);
    timeline.iter_mut().for_each(|p| p.start = 0);
    let (mut clock, mut current, mut last) = (0.0, 0, timeline.last().map_or(0.0, |p| p.seconds));
    let (est, multi) = log.stages.run("start search", || {
        brightness::search(
            problem,
            est,
            &label,
            base,
            lambert,
            &eopts,
            &mut |si, it, state| {
                if si != current {
                    (clock, current) = (last, si);
                    monitor.bar.inc_length(eopts.max_outer as u64);
                }
                monitor.bar.inc(1);
                let holdout_rmse = monitor.held_out(state);
                let n_it = timeline.iter().filter(|p| p.start == si).count() + 1;
                let line = iteration_line(1, si, n_it, it, holdout_rmse);
                monitor.say(&format!("start search, start {}: {line}", si + 1));
                last = clock + it.seconds;
                timeline.push(timeline_point(si, last, it, holdout_rmse));
            },
        )
    })?;
    Ok(Estimated {
        est,
        multi,
        eopts,
        light_decision,
        timeline,
    })
}

/// The restart (`--restart`, [`Restart`]) from the kept fit: a fit from each of the
/// step's starts ([`restart_starts`]) in turn, each kept when its validation error is lower
/// than the fit kept before it ([`reanchor::fit_in_turn`]). Each one's iterations follow
/// the kept fit's in the timeline as one more start, its record is added to the starts,
/// and what it did (or why it was skipped) is one of the start's reasons.
fn restart(
    problem: &Problem,
    p: &Prepared,
    fitted: Estimated,
    start: &mut FitStart,
    step: RestartStep,
    monitor: &Monitor,
    log: &mut RunLog,
) -> Result<Estimated> {
    let mode = step.mode;
    let starts = restart_starts(problem, p, &fitted.est, start, mode)?;
    if starts.is_empty() {
        start.reasons.push(skipped_reason(mode));
        return Ok(fitted);
    }
    monitor.progress.stage("restart");
    let Estimated {
        est,
        mut multi,
        eopts,
        light_decision,
        mut timeline,
    } = fitted;
    let opts = restart_options(&eopts, mode);
    let si0 = multi.starts.len();
    let (mut current, mut clock) = (None, 0.0);
    let (est, outcomes) = log.stages.run("restart", || {
        reanchor::fit_in_turn(problem, est, starts, &opts, &mut |n, it, state| {
            if current != Some(n) {
                current = Some(n);
                clock = timeline.last().map_or(0.0, |p| p.seconds);
                monitor.bar.inc_length(opts.max_outer as u64);
            }
            let si = si0 + n;
            monitor.bar.inc(1);
            let holdout_rmse = monitor.held_out(state);
            let n_it = timeline.iter().filter(|p| p.start == si).count() + 1;
            let line = iteration_line(1, si, n_it, it, holdout_rmse);
            monitor.say(&format!("restart: {line}"));
            timeline.push(timeline_point(si, clock + it.seconds, it, holdout_rmse));
        })
    })?;
    for outcome in outcomes {
        let first_kept = multi.chosen == step.first_fit;
        start.reasons.push(restart_reason(&outcome, first_kept));
        if let reanchor::StepOutcome::Fitted {
            kept_restart,
            record,
            ..
        } = outcome
        {
            multi.starts.push(record);
            if kept_restart {
                multi.chosen = multi.starts.len() - 1;
            }
        }
    }
    Ok(Estimated {
        est,
        multi,
        eopts,
        light_decision,
        timeline,
    })
}

/// What one start of a restart step did, for the reasons: its score against the fit kept
/// before it and which was kept (`first_kept`: that fit is still the first), or why its
/// gate skipped it.
fn restart_reason(outcome: &reanchor::StepOutcome, first_kept: bool) -> String {
    match *outcome {
        reanchor::StepOutcome::Fitted {
            what,
            kept_restart,
            scores: [before, score],
            paired,
            ..
        } => {
            let kept = match (kept_restart, paired) {
                (true, Some(q)) => format!(
                    "kept: {} above the fit before it on the same held-back observations, within one, and with its materials held the more constrained fit (the one-standard-error rule)",
                    standard_errors(&q)
                ),
                (true, None) => "kept".to_string(),
                (false, q) => {
                    let which = if first_kept { "the first fit" } else { "the previous fit" };
                    let why = q.map_or(String::new(), |q| {
                        format!(" ({} above it, beyond one)", standard_errors(&q))
                    });
                    format!("{which} kept{why}")
                }
            };
            format!("restart from {what}: validation error {score:.4} against {before:.4}, {kept}")
        }
        reanchor::StepOutcome::Skipped {
            what,
            within,
            before: [before, score],
        } => format!(
            "restart from {what} skipped: the held fit before it scored {score:.4} against {before:.4}, more than {:.0}% above",
            100.0 * (within - 1.0)
        ),
    }
}

/// A paired difference in its standard errors, for the reasons ("0.62 standard errors");
/// "a difference with no spread" when the standard error is 0.
fn standard_errors(q: &crate::solve::paired::Paired) -> String {
    if q.standard_error > 0.0 {
        format!("{:.2} standard errors", q.difference / q.standard_error)
    } else {
        "a difference with no spread".to_string()
    }
}

/// One second fit of `--restart` ([`Restart::steps`]): which, and the first fit's place
/// among the starts (a refused restart's reason says whether the fit kept is still it).
#[derive(Debug, Clone, Copy)]
struct RestartStep {
    mode: Restart,
    first_fit: usize,
}

/// The restart's starts, in the order they are fitted: none when the ratio model finds a
/// material without the vertices it reads; the coarse-light model's two over the
/// Lambertian lobe alone, one over a shiny basis ([`coarse_light::restart_starts`]).
fn restart_starts(
    problem: &Problem,
    p: &Prepared,
    est: &solve::Estimate,
    start: &FitStart,
    mode: Restart,
) -> Result<Vec<reanchor::StepStart>> {
    let seen = start.seen(p);
    if mode == Restart::Reanchor {
        let m = reanchor::reanchor(&est.lambda, &est.weights, seen, reanchor::Reweight::Project)?;
        return Ok(vec![reanchor::StepStart {
            from: m,
            what: "the fit's own materials re-anchored (median fitted reflectance per material, weights projected)",
            within: None,
            keep: reanchor::Keep::Lower,
        }]);
    }
    let lambert = start.eopts.lambert_basis;
    if mode == Restart::CoarseLight {
        return coarse_light::restart_starts(problem, &est.lambda, &est.weights, seen, lambert);
    }
    let kk = est.lambda.len();
    let weights = irradiance::normalised_weights(&est.weights, kk);
    let open = p.vis.open_fractions();
    let rows = irradiance::pure_open_rows(&irradiance::RowsInput {
        obs: problem.obs,
        normals_env: &p.normals_env,
        open: &open,
        seen,
        weights: &weights,
        materials: kk,
        min_open: irradiance::MIN_OPEN,
    });
    let m = irradiance::irradiance_start(&est.lambda, weights, lambert, &rows, problem.n_photos)?;
    Ok(m.map_or_else(Vec::new, |m| {
        vec![reanchor::StepStart {
            from: m,
            what: "the fit's weights with each material's Lambertian colour ratios fitted by an order-2 irradiance model over its pure, open vertices",
            within: None,
            keep: reanchor::Keep::Lower,
        }]
    }))
}

/// The second fit's options: `coarse-light` holds the start's materials (the model's
/// ratios, the snapped weights) and fits the lights again from the first fit's, scored on
/// the same validation split as the first fit ([`coarse_light::held_fit_options`]); a free
/// second fit moves the ratios 2 points away from a start within 3% on the ablation's
/// diffuse scene (`bench-results/coarse-light-start.md`).
fn restart_options(eopts: &EstimateOptions, mode: Restart) -> EstimateOptions {
    if mode == Restart::CoarseLight {
        return coarse_light::held_fit_options(eopts);
    }
    eopts.clone()
}

/// What `--restart auto` chose over the fit's basis ([`Restart::resolve`]) and why.
fn auto_restart_reason(mode: Restart, basis: &[BasisBrdf]) -> String {
    if mode == Restart::CoarseLight {
        return "--restart auto: a restart from a coarse non-negative light, as the fit's basis is the Lambertian lobe alone".into();
    }
    let lobes: Vec<String> = basis.iter().map(BasisBrdf::label).collect();
    format!(
        "--restart auto: no restart, as the fit keeps a shiny lobe ({}): with one, the coarse-light restart (each shiny lobe tied to its material's diffuse one) raised the error under the true light on 7 of 7 rendered runs where the validation score kept it; --restart coarse-light makes it",
        lobes.join(", ")
    )
}

/// The reason a model restart was skipped: some material has no vertex it reads.
fn skipped_reason(mode: Restart) -> String {
    if mode == Restart::CoarseLight {
        return format!(
            "restart from a coarse non-negative light skipped: some material holds no seen vertex at a weight of at least {}",
            irradiance::PURE
        );
    }
    format!(
        "restart from an order-2 irradiance model skipped: some material holds no vertex that sees at least {:.0}% of its hemisphere at a weight of at least {}",
        100.0 * irradiance::MIN_OPEN,
        irradiance::PURE
    )
}

/// One point of the report's timeline: iteration `it` of start `start`, `seconds` on the
/// estimator's clock.
pub(super) fn timeline_point(
    start: usize,
    seconds: f64,
    it: &solve::Iteration,
    holdout_rmse: Option<f64>,
) -> TimelinePoint {
    TimelinePoint {
        start,
        seconds,
        objective: it.objective,
        train_rmse: it.train_rmse,
        holdout_rmse,
        steps: it.steps,
    }
}

/// The console line for outer iteration `n_it` of start `si` (of `n_starts`).
pub(super) fn iteration_line(
    n_starts: usize,
    si: usize,
    n_it: usize,
    it: &solve::Iteration,
    holdout_rmse: Option<f64>,
) -> String {
    format!(
        "{}iteration {n_it}: objective {:.4e}, training RMSE {:.5}{} ({:.1} s)",
        if n_starts > 1 {
            format!("start {} of {n_starts}, ", si + 1)
        } else {
            String::new()
        },
        it.objective,
        it.train_rmse,
        holdout_rmse.map_or(String::new(), |h| format!(", held-out {h:.5}")),
        it.seconds
    )
}
