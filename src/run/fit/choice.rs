//! The light model and the data loss a fit keeps, each chosen by a validation score.
//!
//! `--light` names one model or lets the validation score choose among candidates
//! ([`choose::candidates`], [`choose::decide`]); `--loss auto` then fits the kept model
//! with the robust loss and with plain least squares and keeps plain least squares only
//! when it scores more than [`loss_choice::PLAIN_GAIN`] lower ([`loss_choice::decide`];
//! under the sun and sky, which does not reweight, it keeps the robust loss without the
//! second fit: [`loss_choice::loss_acts`]).
//! Both choices score on the same split: the right halves of a few training photos held
//! back whole ([`FitStart::choice_halves`]), which a free map per photo cannot
//! extrapolate into. The fit kept is then fitted again with the run's own early stopping
//! (observations held back at random), so a chosen model or loss gives bit for bit the fit
//! the same model or loss given by flag gives.

use super::alternation::{iteration_line, timeline_point, Estimated, Monitor};
use super::start::FitStart;
use crate::report::TimelinePoint;
use crate::run::state::RunLog;
use crate::run::RunOptions;
use crate::solve::light::choose::{self, LightCandidate, LightChoice, LightDecision};
use crate::solve::loss_choice;
use crate::solve::options::PhotoHalves;
use crate::solve::starts::{self, MultiStart};
use crate::solve::{self, EstimateOptions, Problem};
use crate::Result;
use std::sync::Arc;

/// Each candidate light model (`--light`) fitted from every start and the one the
/// validation score keeps ([`choose_light`]); then, with `--loss auto`, the data loss for
/// it ([`choose_loss`]); then, when the choices scored on held-back photo halves, the fit
/// kept fitted again with the run's own early stopping. Each choice's reason is pushed to
/// `start`.
pub(super) fn fit_light_models(
    opts: &RunOptions,
    problem: &Problem,
    family: &[starts::Start],
    start: &mut FitStart,
    monitor: &Monitor,
    log: &mut RunLog,
) -> Result<Estimated> {
    let mut timeline: Vec<TimelinePoint> = Vec::new();
    let models = choose::candidates(opts.light, &start.eopts)?;
    let choosing_light = models.len() > 1;
    // `--loss auto` has a choice only under a light model the loss acts on.
    let loss_auto = start.loss_auto && models.iter().any(|m| loss_choice::loss_acts(&m.options));
    let f = ModelFitter {
        problem,
        family,
        monitor,
        halves: (start.choice_halves.clone()).filter(|_| choosing_light || loss_auto),
        per_fit: monitor.bar.length().unwrap_or(0),
    };
    let refit = f.halves.is_some();
    let fits_planned = models.len() + usize::from(refit) + usize::from(loss_auto);
    monitor.bar.set_length(f.per_fit * fits_planned as u64);
    let light = choose_light(opts, &f, &models, &mut timeline, log)?;
    let d = &light.decision;
    start
        .reasons
        .push(format!("light model `{}`: {}", d.model, d.why));
    let mut kept = light.kept;
    if loss_auto {
        let why = &mut start.reasons;
        kept = choose_loss(&f, kept, refit, &mut timeline, log, why)?;
    } else if start.loss_auto {
        start.reasons.push(loss_choice::SKY_WHY.to_string());
    }
    if refit {
        kept.fit = f.fit(&kept.options, &mut timeline, log)?;
    }
    Ok(Estimated {
        est: kept.fit.est,
        multi: kept.fit.multi,
        eopts: kept.options,
        light_decision: light.decision,
        // The timeline of the fit kept.
        timeline: timeline.drain(kept.fit.points).collect(),
    })
}

/// The light model kept and the words of its choice.
struct KeptLight {
    kept: LossCandidate,
    decision: LightDecision,
}

/// Each of `models` fitted and scored ([`ModelFitter::fit_scored`]); the one
/// [`choose::decide`] keeps.
fn choose_light(
    opts: &RunOptions,
    f: &ModelFitter,
    models: &[LightCandidate],
    timeline: &mut Vec<TimelinePoint>,
    log: &mut RunLog,
) -> Result<KeptLight> {
    let mut fits = Vec::with_capacity(models.len());
    for model in models {
        fits.push(f.fit_scored(&model.options, timeline, log)?);
    }
    let scores: Vec<f64> = fits.iter().map(|f| f.est.validation_error()).collect();
    let names: Vec<&str> = models.iter().map(|m| m.name).collect();
    let (pick, decision) = choose::decide(opts.light, &names, &scores);
    let halves = f.halves.as_deref().filter(|_| models.len() > 1);
    Ok(KeptLight {
        kept: LossCandidate {
            fit: fits.swap_remove(pick),
            options: models[pick].options.clone(),
        },
        decision: light_why(opts, decision, halves),
    })
}

/// `--loss auto` ([`loss_choice`]): the light model kept, fitted with the robust loss
/// (`robust`, already scored), against the same model under plain least squares fitted and
/// scored the same way; the one kept, its reason pushed to `reasons` (saying so when the
/// kept loss is to be `refit` without the halves).
fn choose_loss(
    f: &ModelFitter,
    robust: LossCandidate,
    refit: bool,
    timeline: &mut Vec<TimelinePoint>,
    log: &mut RunLog,
    reasons: &mut Vec<String>,
) -> Result<LossCandidate> {
    if !loss_choice::loss_acts(&robust.options) {
        reasons.push(loss_choice::SKY_WHY.to_string());
        f.unplan_fit();
        return Ok(robust);
    }
    let plain_options = loss_choice::plain(&robust.options);
    let plain = f.fit_scored(&plain_options, timeline, log)?;
    // The halves both were scored on: the choice's, else the user's `--validation-halves`.
    let halves = f
        .halves
        .as_ref()
        .or(robust.options.validation_halves.as_ref());
    let n_halves = halves.map_or(0, |h| h.right.len());
    let (r, p) = (
        robust.fit.est.validation_error(),
        plain.est.validation_error(),
    );
    let mut decision = loss_choice::decide(r, p, n_halves);
    if refit {
        decision.why += "; the loss kept fitted again with early stopping's own held-back \
                         observations";
    }
    reasons.push(decision.why);
    Ok(if decision.plain {
        LossCandidate {
            fit: plain,
            options: plain_options,
        }
    } else {
        robust
    })
}

/// A fit and the options it was fitted with (before held-back halves were added).
struct LossCandidate {
    fit: ModelFit,
    options: EstimateOptions,
}

/// What a fit from every start needs besides its options: the problem, the starts, the
/// progress, and the photo halves the choices score on (`None`: early stopping's own
/// held-back observations, or the `--validation-halves` the options carry).
struct ModelFitter<'a> {
    problem: &'a Problem<'a>,
    family: &'a [starts::Start],
    monitor: &'a Monitor<'a>,
    halves: Option<Arc<PhotoHalves>>,
    /// The progress bar's length for one fit (outer iterations × starts).
    per_fit: u64,
}

impl ModelFitter<'_> {
    /// `eopts` fitted from every start ([`fit_model`]).
    fn fit(
        &self,
        eopts: &EstimateOptions,
        timeline: &mut Vec<TimelinePoint>,
        log: &mut RunLog,
    ) -> Result<ModelFit> {
        let (problem, family, monitor) = (self.problem, self.family, self.monitor);
        fit_model(problem, family, eopts, monitor, timeline, log)
    }

    /// One planned fit fewer on the progress bar (a choice with nothing to choose).
    fn unplan_fit(&self) {
        let bar = self.monitor.bar;
        bar.set_length(bar.length().unwrap_or(0).saturating_sub(self.per_fit));
    }

    /// `eopts` fitted from every start and scored on the choices' halves, when there are.
    fn fit_scored(
        &self,
        eopts: &EstimateOptions,
        timeline: &mut Vec<TimelinePoint>,
        log: &mut RunLog,
    ) -> Result<ModelFit> {
        let scored = EstimateOptions {
            validation_halves: self
                .halves
                .clone()
                .or_else(|| eopts.validation_halves.clone()),
            ..eopts.clone()
        };
        self.fit(&scored, timeline, log)
    }
}

/// One light model's fit from every start, and its points' range in the timeline.
struct ModelFit {
    est: solve::Estimate,
    multi: MultiStart,
    points: std::ops::Range<usize>,
}

/// The light decision's words: the halves its candidates were scored on (`halves`, when
/// the light was chosen on them) and, without `--light`, the scene's rule.
fn light_why(
    opts: &RunOptions,
    mut d: LightDecision,
    halves: Option<&PhotoHalves>,
) -> LightDecision {
    if let Some(h) = halves {
        d.why = format!(
            "{}, each scored on the right halves of {} training photos held back whole; \
             the model kept fitted again with early stopping's own held-back observations",
            d.why,
            h.right.len()
        );
    }
    if opts.light_by_scene {
        d.why = by_scene_why(opts.light, &d.why);
    }
    d
}

/// One light model's options fitted from every start, its iterations on the console and
/// appended to `timeline`.
fn fit_model(
    problem: &Problem,
    family: &[starts::Start],
    eopts: &EstimateOptions,
    monitor: &Monitor,
    timeline: &mut Vec<TimelinePoint>,
    log: &mut RunLog,
) -> Result<ModelFit> {
    let n_starts = family.len();
    let first = timeline.len();
    let family = family.to_vec();
    let (est, multi) = log.stages.run("estimate", || {
        starts::estimate_best(problem, family, eopts, &mut |si, it, state| {
            monitor.bar.inc(1);
            let holdout_rmse = monitor.held_out(state);
            let n_it = timeline
                .iter()
                .skip(first)
                .filter(|p| p.start == si)
                .count()
                + 1;
            monitor.say(&iteration_line(n_starts, si, n_it, it, holdout_rmse));
            timeline.push(timeline_point(si, it.seconds, it, holdout_rmse));
        })
    })?;
    Ok(ModelFit {
        est,
        multi,
        points: first..timeline.len(),
    })
}

/// The report's words for a light model `run` picked without `--light`: `auto`'s scores,
/// or the model `choice` named (not "as given", which it was not), then why it is the
/// default.
fn by_scene_why(choice: LightChoice, decided: &str) -> String {
    let why = "--light not given: the default for the mesh's size, the fit's lobes, its \
               materials and training photos; see the notes";
    match choice {
        c if c.chooses() => format!("{decided} ({why})"),
        c => format!("--light {} ({why})", c.name()),
    }
}
