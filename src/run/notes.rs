//! The report's notes written after the fit and the evaluation (stage 8 of `run`): plain
//! sentences on what the figures alone do not say.

use super::state::RunLog;
use super::{Fitted, LargeMeshSettings, RunOptions, LARGE_MESH, LIGHTING_SAMPLE_MAX_RATIO};

/// Whether the ratio step (`--ratio-steps`) ran, why, and what it did, in words.
fn ratio_note(opts: &RunOptions, fitted: &Fitted) -> String {
    let rounds = fitted.estimate_options.ratio_steps;
    let photos = fitted.train.len();
    let m = &fitted.est.ratio_moves;
    let min = crate::solve::ratio_step::MIN_PHOTOS;
    let why = match opts.ratio_steps {
        super::RatioSteps::Fixed(n) => format!("--ratio-steps {n}"),
        super::RatioSteps::Auto if rounds > 0 => {
            format!("--ratio-steps auto: {rounds} rounds with {photos} training photos")
        }
        super::RatioSteps::Auto => {
            let max = crate::solve::ratio_step::MAX_MATERIALS;
            let k = fitted.est.lambda.len();
            return format!("the ratio step did not run: --ratio-steps auto takes it from {min} training photos on and up to {max} materials, and this fit has {photos} photos and {k} materials (bench-results/ratio-step.md)");
        }
    };
    if rounds == 0 {
        return format!("the ratio step did not run ({why})");
    }
    if m.tried == 0 && m.unsupported == 0 {
        return format!("the ratio step ({why}) had nothing to move: one material");
    }
    let what = format!(
        "the ratio step ({why}) kept {} of {} moves of a material's brightness per channel along the valley the free maps leave (docs/method.md, \"The ratio step\")",
        m.kept, m.tried
    );
    if m.unsupported > 0 {
        format!("{what}; the light model could not take it in {} rounds (its parameters do not mix between probes)", m.unsupported)
    } else if let Some(r) = m.stopped_after {
        format!(
            "{what}; it stopped after round {r}, when {} rounds in a row had kept no move",
            crate::solve::ratio_step::PATIENCE
        )
    } else {
        what
    }
}

/// What the variable-projection step (`--varpro-steps`) did, when asked for.
fn varpro_note(opts: &RunOptions, fitted: &Fitted) -> Option<String> {
    let rounds = fitted.estimate_options.varpro_steps;
    let m = &fitted.est.varpro_moves;
    (rounds > 0).then(|| {
        let flag = match opts.varpro_steps {
            crate::run::VarproSteps::Auto => "auto".to_string(),
            crate::run::VarproSteps::Fixed(n) => n.to_string(),
        };
        let jacobian = if fitted.estimate_options.varpro_broyden {
            "its Jacobian updated by Broyden's secant after the first round"
        } else {
            "its Jacobian by forward differences"
        };
        let what = format!(
            "the variable-projection step (--varpro-steps {flag}: {rounds} rounds, {jacobian}) kept {} of {} Gauss-Newton steps of every material's lobes with the lights re-solved (docs/method.md, \"The variable-projection step\")",
            m.kept, m.tried
        );
        if m.unsupported > 0 {
            format!("{what}; the light model could not take it in {} rounds (its channels are not separable or its parameters do not mix)", m.unsupported)
        } else {
            what
        }
    })
}

/// The specular lobes' colour, when the fit has any besides the Lambertian one and the
/// flag was given (with `auto` the fit's reasons say it, [`super::achromatic_for`]).
fn specular_note(opts: &RunOptions, fitted: &Fitted) -> Option<String> {
    if fitted.basis.len() < 2 {
        return None;
    }
    match opts.achromatic_specular {
        super::Achromatic::Auto => None,
        super::Achromatic::On => Some("specular lobes achromatic (--achromatic-specular on): one specular weight per material for R, G and B, the colour in the diffuse lobe, as for dielectrics (docs/method.md, \"Achromatic specular lobes\")".to_string()),
        super::Achromatic::Off => Some("specular lobes coloured (--achromatic-specular off): each channel's specular weight free".to_string()),
    }
}

/// The report's notes on the fit: ill-conditioned solves, the starts tried, the scale
/// normalisation, early stopping and the lighting sample.
pub(crate) fn fit_notes(
    opts: &RunOptions,
    fitted: &Fitted,
    multi: &crate::solve::starts::MultiStart,
    log: &mut RunLog,
) {
    let est = &fitted.est;
    log.notes
        .extend(conditioning_notes(opts, &est.conditioning));
    log.notes.push(ratio_note(opts, fitted));
    log.notes.extend(varpro_note(opts, fitted));
    log.notes.extend(specular_note(opts, fitted));
    log.notes.extend(starts_note(multi));
    log.notes
        .push(format!("scale normalisation: {}", est.normalisation));
    log.notes
        .extend(large_mesh_note(opts, fitted.scene.mesh.positions.len()));
    log.notes
        .extend(est.validation.as_ref().map(early_stopping_note));
    log.notes
        .extend(est.lighting_sample.as_ref().map(lighting_sample_note));
}

/// Vertices whose weights are minimum-norm, and lighting solves stopped at their cap.
fn conditioning_notes(opts: &RunOptions, c: &crate::solve::Conditioning) -> Vec<String> {
    let mut notes = Vec::new();
    if c.weights_singular > 0 {
        notes.push(format!(
            "{} vertices had fewer independent observations than materials (their blending weights are minimum-norm)",
            c.weights_singular
        ));
    }
    if c.qp_unconverged > 0 {
        notes.push(format!(
            "{} photos' lighting solves in the last outer iteration stopped at the iteration cap before the KKT tolerance ({} of the QPs, one per photo and IRLS pass, at the alternation's cap of {} GPCG iterations, by design: --lighting-qp-iterations)",
            c.qp_unconverged,
            c.qp_alternation_capped,
            opts.lighting_qp_iterations
        ));
    }
    notes
}

/// Which start was kept and each start's score, when more than one ran.
fn starts_note(multi: &crate::solve::starts::MultiStart) -> Option<String> {
    (multi.starts.len() > 1).then(|| {
        format!(
            "{} starts tried, kept start {} ({}) by the {}: {}",
            multi.starts.len(),
            multi.chosen + 1,
            multi.starts[multi.chosen].label,
            multi.criterion,
            multi
                .starts
                .iter()
                .enumerate()
                .map(|(i, r)| format!("start {} {:.4} in {:.1} s", i + 1, r.score, r.seconds))
                .collect::<Vec<_>>()
                .join(", ")
        )
    })
}

/// A large mesh fitted without (all of) `--large-mesh`'s settings.
fn large_mesh_note(opts: &RunOptions, vertices: usize) -> Option<String> {
    (vertices >= LargeMeshSettings::FROM_VERTICES && !LARGE_MESH.in_effect(opts)).then(|| {
        format!(
            "the mesh has {vertices} vertices, but the run kept (some of) the full settings that --large-mesh replaces (--no-large-mesh, or one of its three flags given): --large-mesh takes {}",
            LargeMeshSettings::GAIN
        )
    })
}

/// The held-back observations' score per outer iteration and the iteration kept.
fn early_stopping_note(v: &crate::solve::result::Validation) -> String {
    format!(
        "early stopping: {} training observations ({:.0}%) left out of the fit and scored after every outer iteration (relative RMSE {}); kept iteration {} of {}{}",
        v.observations,
        100.0 * v.fraction,
        v.errors
            .iter()
            .map(|e| format!("{e:.4}"))
            .collect::<Vec<_>>()
            .join(", "),
        v.best_iteration,
        v.errors.len(),
        if v.stopped_early {
            " (stopped: no lower score for the patience)"
        } else {
            ""
        }
    )
}

/// The lighting steps' observation sample and whether the maps over-fit it.
fn lighting_sample_note(s: &crate::solve::subsample::SampleCheck) -> String {
    format!(
        "lighting sample: the lighting steps of {} photo(s) saw at most {} of their observations each (stratified by normal, open sky and material); relative RMSE of the fit {:.4} on the {} sampled observations and {:.4} on the {} others (ratio {:.3}){}",
        s.photos_sampled,
        s.budget,
        s.rel_rmse_in,
        s.in_sample,
        s.rel_rmse_out,
        s.out_of_sample,
        s.ratio,
        if s.ratio > LIGHTING_SAMPLE_MAX_RATIO {
            format!(": above {LIGHTING_SAMPLE_MAX_RATIO}, the maps over-fit their samples; rerun with a larger --lighting-sample or 0 (all)")
        } else {
            String::new()
        }
    )
}

/// The report's notes on the evaluation: its cost, the baseline's unseen vertices and the
/// held-out figure the timeline uses.
pub(crate) fn evaluation_notes(
    fitted: &Fitted,
    render_seconds: [f64; 2],
    half_fit_seconds: [f64; 2],
    mean_holdout_rmse: Option<f64>,
) -> Vec<String> {
    let mut notes = Vec::new();
    if !fitted.held.is_empty() {
        let (r, h) = (render_seconds, half_fit_seconds);
        notes.push(format!(
            "evaluation of {} held-out photos: renders (with the truth check's training \
             photos when there is a truth) {:.1} s wall / {:.1} CPU s, the half protocol's \
             light fits {:.1} s / {:.1} CPU s",
            fitted.held.len(),
            r[0],
            r[1],
            h[0],
            h[1]
        ));
    }
    if fitted.baseline.unseen > 0 && !fitted.held.is_empty() {
        notes.push(format!(
            "baseline: {} of {} vertices are in no training photo; they take the median of the other vertices' medians",
            fitted.baseline.unseen,
            fitted.scene.mesh.positions.len()
        ));
    }
    if let Some(h) = mean_holdout_rmse {
        notes.push(format!(
            "the timeline's held-out RMSE is over the held-out photos' observations (per vertex, after the best global scale, true light when known, else the mean training map); the final per-pixel figure, mean over held-out photos, is {h:.5}"
        ));
    }
    notes
}
