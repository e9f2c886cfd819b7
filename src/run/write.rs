//! Stage 8 of `run`: the result folder's files ([`super::output`]) and the run report
//! (`report.json`, `report.md`, `report.html` with its pictures) assembled from the fit and
//! the evaluation.

use std::path::Path;

use super::fit::Fit;
use super::state::{Evaluated, RunLog};
use super::truth::Truth;
use super::{conditioning_map, conditioning_use, output, Fitted, Progress, RunOptions};
use crate::report::{ModelReport, RunReport};
use crate::solve::adapt::Decision;
use crate::Result;

/// Stage 8, outputs and the report.
pub(crate) fn write(
    opts: &RunOptions,
    fit: Fit,
    evaluated: Evaluated,
    truth: Option<&Truth>,
    log: &mut RunLog,
    dir: &Path,
    progress: &Progress,
) -> Result<RunReport> {
    let Fit {
        fitted,
        train_entries,
        timeline,
        multi,
        reasons,
        decisions,
        light_decision,
        transients,
    } = fit;
    progress.stage("output");
    log.stages
        .run("output", || output::write_results(&fitted, dir, progress))?;
    if let Some(t) = &transients {
        transients_note(t, &fitted, dir, log)?;
    }
    super::notes::fit_notes(opts, &fitted, &multi, log);
    let mut model = model_report(opts, &fitted, reasons, decisions, light_decision);
    model.sky = super::sky_report::sky_report(&fitted, truth);
    let mut report = RunReport {
        version: env!("CARGO_PKG_VERSION").to_string(),
        workspace: opts.workspace.display().to_string(),
        seed: opts.seed,
        // The iterate returned: early stopping's choice, else the last.
        train_rmse: fitted
            .est
            .validation
            .as_ref()
            .and_then(|v| fitted.est.timeline.get(v.best_iteration - 1))
            .or(fitted.est.timeline.last())
            .map_or(f64::NAN, |t| t.train_rmse),
        train: train_entries,
        timeline,
        model,
        notes: std::mem::take(&mut log.notes),
        conditioning: conditioning_map(&fitted.est.conditioning),
        conditioning_use: conditioning_use(
            &fitted.est.conditioning,
            &fitted.estimate_options,
            opts.adaptive,
        ),
        starts: (multi.starts.len() > 1).then_some(multi),
        ..Default::default()
    };
    add_evaluation(&mut report, evaluated, &fitted);
    progress.stage("report");
    write_report(&mut report, &fitted, truth, log, dir)?;
    Ok(report)
}

/// The transient pass's masks written and its note.
fn transients_note(
    t: &super::transients::Transients,
    fitted: &Fitted,
    dir: &Path,
    log: &mut RunLog,
) -> Result<()> {
    let folder = super::transients::write_masks(t, fitted.scene, &fitted.train, dir)?;
    log.notes.push(format!(
        "transient occluders: {} of {} training observations masked ({} rounds of a {}-iteration pilot fit's residuals, coherent over the mesh) in {} of {} photos; masks in {folder}/",
        t.count(),
        t.used_before,
        super::transients::PILOT_ROUNDS,
        super::transients::PILOT_ITERATIONS,
        t.masked.iter().filter(|m| !m.is_empty()).count(),
        t.masked.len()
    ));
    Ok(())
}

/// The report's model section: sizes, resolutions and why.
fn model_report(
    opts: &RunOptions,
    fitted: &Fitted,
    reasons: Vec<String>,
    decisions: Vec<Decision>,
    light_decision: crate::solve::light::choose::LightDecision,
) -> ModelReport {
    let eff = &fitted.opts;
    ModelReport {
        materials: fitted.est.lambda.len(),
        basis: eff.basis.iter().map(|b| b.label()).collect(),
        global_resolution: eff.global_resolution,
        local_resolution: eff.local_resolution,
        render_local_resolution: fitted.render_vis.n_local,
        normal_grid: eff.normal_grid,
        kept_coefficients: eff.keep,
        blend_tolerance: fitted.estimate_options.blend_tolerance,
        reasons,
        adaptive: if opts.adaptive { Some(decisions) } else { None },
        light: Some(light_decision),
        scale_anchor: Some(crate::report::ScaleAnchorReport {
            name: fitted.estimate_options.scale_anchor.name().to_string(),
            rule: fitted.est.normalisation.clone(),
        }),
        ratio_step: Some(ratio_step_report(opts, fitted)),
        varpro_step: Some(crate::report::VarproStepReport {
            mode: opts.varpro_steps.mode().to_string(),
            rounds: fitted.estimate_options.varpro_steps,
            jacobian: if fitted.estimate_options.varpro_broyden {
                "broyden"
            } else {
                "forward-differences"
            }
            .to_string(),
            tried: fitted.est.varpro_moves.tried,
            kept: fitted.est.varpro_moves.kept,
            unsupported: fitted.est.varpro_moves.unsupported,
        }),
        sky: None,
    }
}

/// The ratio step's mode, its rounds in this fit and what they did.
fn ratio_step_report(opts: &RunOptions, fitted: &Fitted) -> crate::report::RatioStepReport {
    crate::report::RatioStepReport {
        mode: opts.ratio_steps.mode().to_string(),
        rounds: fitted.estimate_options.ratio_steps,
        training_photos: fitted.train.len(),
        moves: fitted.est.ratio_moves,
    }
}

/// The evaluation's figures and notes, the albedo against the truth among them, into
/// `report`.
fn add_evaluation(report: &mut RunReport, evaluated: Evaluated, fitted: &Fitted) {
    let Evaluated {
        evaluation,
        holdout_rule,
        half_fit_prior,
    } = evaluated;
    report.holdout = evaluation.holdout;
    report.headline = evaluation.headline.map(|h| h.ratio);
    report.headline_detail = evaluation.headline;
    report.half_fit_prior = half_fit_prior;
    report.metrics = evaluation.metrics;
    report.truth_check_floor_ratio =
        crate::report::metrics::truth_check_floor_ratio(&evaluation.truth_check);
    report.truth_check = evaluation.truth_check;
    report.albedo_truth = evaluation.albedo_truth;
    report.holdout_rule = holdout_rule;
    report.notes.extend(super::notes::evaluation_notes(
        fitted,
        evaluation.render_seconds,
        evaluation.half_fit_seconds,
        evaluation.mean_holdout_rmse,
    ));
}

/// The stage records, `report.json`, `report.md` and `report.html` with its pictures. The
/// report's own writing is timed but cannot appear in the file it is writing.
fn write_report(
    report: &mut RunReport,
    fitted: &Fitted,
    truth: Option<&Truth>,
    log: &RunLog,
    dir: &Path,
) -> Result<()> {
    report.stage_details = log.stages.records.clone();
    report.stages = report
        .stage_details
        .iter()
        .map(|s| (s.name.clone(), s.seconds))
        .collect();
    report.peak_memory_bytes = log.stages.peak_memory_bytes();
    let maps = output::gallery_maps(fitted);
    let refs: Vec<(String, usize, usize, &[[f32; 3]])> = maps
        .iter()
        .map(|(n, ll)| (n.clone(), ll.width, ll.height, ll.rgb.as_slice()))
        .collect();
    report.write(dir, &refs)?;
    let inputs = super::html_inputs::html_inputs(fitted, truth, dir)?;
    crate::report::html::write(dir, report, &inputs)
}
