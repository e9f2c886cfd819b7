//! Stage 6 of `run`: the estimate. Initial materials (clustering or the pilot's count),
//! the starts, the alternation with the held-out tracker, then the fitted model
//! ([`Fitted`]) that the evaluation and the outputs read.
//!
//! - [`start`]: the initial materials and the estimator's options ([`start::FitStart`]);
//! - [`alternation`]: the alternation under each candidate light model, the start search,
//!   and the console and timeline of each iterate;
//! - [`options`]: the estimator's options from the run's.

mod alternation;
mod choice;
mod options;
mod start;

pub(crate) use options::{estimate_options, lambert_of};

use super::state::{Imported, Observed, Prepared, RunLog};
use super::tracker::HoldoutTracker;
use super::{check_finite, conditioning_map, train_errors, Fitted, Progress, RunOptions};
use crate::observe::Observations;
use crate::report::{TimelinePoint, TrainEntry};
use crate::solve::adapt::Decision;
use crate::solve::materials::propagate::{propagate_unseen_over, VertexGraph};
use crate::solve::starts::MultiStart;
use crate::solve::{self, EstimateOptions, Problem};
use crate::Result;
use alternation::{alternate, Estimated};
pub use options::photo_halves;
use start::prepare_start;

/// After the fit: the fitted model and what the report needs of the fit.
pub(crate) struct Fit<'a> {
    pub(crate) fitted: Fitted<'a>,
    pub(crate) train_entries: Vec<TrainEntry>,
    pub(crate) timeline: Vec<TimelinePoint>,
    pub(crate) multi: MultiStart,
    /// Why the model has its size (materials).
    pub(crate) reasons: Vec<String>,
    pub(crate) decisions: Vec<Decision>,
    /// The per-photo light model kept and why.
    pub(crate) light_decision: crate::solve::light::choose::LightDecision,
    /// What the transient pass masked (`None`: `--transients off`).
    pub(crate) transients: Option<super::transients::Transients>,
}

/// Stage 6, the estimate: initial materials, the starts, the alternation; the fitted model.
/// Steps: the start and the estimator's options ([`prepare_start`]), the alternation under
/// each candidate light model with the held-out tracker ([`alternate`]), the unseen
/// vertices' materials ([`fill_unseen`]), then the [`Fitted`] model ([`FinalEstimate`],
/// [`fitted_model`]).
pub(crate) fn fit<'a>(
    opts: &RunOptions,
    im: &'a Imported,
    observed: Observed,
    prepared: Prepared,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<Fit<'a>> {
    let scene = &im.scene;
    let Observed {
        bvh,
        mut obs,
        train,
        decisions,
    } = observed;
    let p = prepared;
    let nv = scene.mesh.positions.len();
    // The baseline is the photos' own colours: its medians ignore the transient mask.
    let baseline = super::baseline::VertexMedians::from_observations(&obs, nv);
    let mut start = prepare_start(opts, im, &p, &train, &mut obs, log, progress)?;
    let chosen = start.by_scene.take();
    let opts = chosen.as_ref().unwrap_or(opts);
    let problem = Problem {
        obs: &obs,
        transport: &p.tr,
        n_vertices: nv,
        n_photos: train.len(),
    };
    let Estimated {
        est: mut estimate,
        multi,
        eopts,
        light_decision,
        timeline,
    } = {
        let tracker = held_out_tracker(im, &bvh, &p, log, progress)?;
        alternate(opts, &p, &problem, &mut start, tracker, log, progress)?
    };
    fill_unseen(
        &obs,
        &scene.mesh.positions,
        &eopts.weights_graph,
        &mut estimate,
        &mut start.reasons,
        log,
    )?;
    let done = FinalEstimate::new(scene, &problem, &train, estimate)?;
    let fitted = fitted_model(
        im,
        p,
        FitParts {
            train,
            bvh,
            est: done.est,
            beta: done.beta,
            train_predictions: done.train_predictions,
            estimate_options: eopts,
            baseline,
        },
    );
    Ok(Fit {
        fitted,
        train_entries: done.train_entries,
        timeline,
        multi,
        reasons: start.reasons,
        decisions,
        light_decision,
        transients: start.transients,
    })
}

/// The estimate once it is final, with what the fitted model and the report derive from
/// it: the per-vertex diffuse albedo `β`, the training photos' predictions and errors.
struct FinalEstimate {
    est: solve::Estimate,
    beta: Vec<[f64; 3]>,
    train_predictions: Vec<Vec<(u32, [f32; 3])>>,
    train_entries: Vec<TrainEntry>,
}

impl FinalEstimate {
    /// `est` checked finite (else the error names the conditioning), then `β` and the
    /// training photos' predictions.
    fn new(
        scene: &crate::import::scene::Scene,
        problem: &Problem,
        train: &[usize],
        est: solve::Estimate,
    ) -> Result<Self> {
        check_finite(&est, &conditioning_map(&est.conditioning))?;
        let beta = solve::beta_per_vertex(&est.lambda, &est.weights, problem.n_vertices);
        let pred = solve::predict(problem, &est);
        Ok(FinalEstimate {
            train_entries: train_errors(scene, train, problem.obs, &pred),
            train_predictions: photo_predictions(problem.obs, &pred),
            est,
            beta,
        })
    }
}

/// What the fit adds to the prepared stage to make the [`Fitted`] model.
struct FitParts {
    train: Vec<usize>,
    bvh: crate::observe::trace::SceneBvh,
    est: solve::Estimate,
    beta: Vec<[f64; 3]>,
    train_predictions: Vec<Vec<(u32, [f32; 3])>>,
    estimate_options: EstimateOptions,
    baseline: super::baseline::VertexMedians,
}

/// The fitted model the evaluation and the outputs read. The training transport rows are
/// the run's largest arrays and nothing after the estimate reads them: they are freed here,
/// before the evaluation builds its own.
fn fitted_model<'a>(im: &'a Imported, p: Prepared, parts: FitParts) -> Fitted<'a> {
    let Prepared {
        env_from_world,
        normals_env,
        vis,
        render_vis,
        eff,
        rot,
        tr,
        ..
    } = p;
    drop(tr);
    Fitted {
        scene: &im.scene,
        photos: &im.photos,
        train: parts.train,
        held: im.held.clone(),
        env_from_world,
        normals_env,
        vis,
        rot,
        render_rot: crate::sphere::rotation::SplatRotation::with_default_supersample(
            eff.global_resolution,
            render_vis.n_local,
        ),
        render_vis,
        basis: eff.basis.clone(),
        est: parts.est,
        beta: parts.beta,
        train_predictions: parts.train_predictions,
        opts: eff,
        estimate_options: parts.estimate_options,
        bvh: parts.bvh,
        baseline: parts.baseline,
        half_fit: None,
        held_out_suns: Vec::new(),
    }
}

/// The held-out photos' observations and transport for the timeline's held-out error
/// ([`HoldoutTracker`]; `None` without held-out photos).
fn held_out_tracker(
    im: &Imported,
    bvh: &crate::observe::trace::SceneBvh,
    p: &Prepared,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<Option<HoldoutTracker>> {
    let _spinner = progress.spinner("held-out transport");
    log.stages.run("transport", || {
        HoldoutTracker::new(
            &im.scene,
            &im.photos,
            &im.held,
            bvh,
            &p.normals_env,
            &p.env_from_world,
            &p.vis,
            &p.eff.basis,
            &p.rot,
            &p.topts,
            im.truth.as_ref(),
        )
    })
}

/// The vertices no training photo sees kept their start: give them their seen
/// neighbours' materials (the harmonic extension, `solve::materials::propagate`), over the
/// neighbour prior's graph when it built one (`graph` not empty; the same graph).
fn fill_unseen(
    obs: &Observations,
    positions: &[crate::Vec3],
    graph: &VertexGraph,
    est: &mut solve::Estimate,
    reasons: &mut Vec<String>,
    log: &mut RunLog,
) -> Result<()> {
    let seen_now = super::mean_colours(obs, positions.len()).1;
    let k = est.lambda.len();
    let filled = log.stages.run("estimate", || {
        let built = Some(graph).filter(|g| !g.is_empty());
        propagate_unseen_over(positions, built, &seen_now, &mut est.weights, k)
    })?;
    if filled.filled > 0 {
        reasons.push(format!(
            "materials of the {} vertices no training photo sees: from their seen neighbours",
            filled.filled
        ));
    }
    Ok(())
}

/// Per training photo, the fitted prediction `pred` of each of its observations, by vertex.
fn photo_predictions(obs: &Observations, pred: &[[f64; 3]]) -> Vec<Vec<(u32, [f32; 3])>> {
    obs.photo_ranges
        .iter()
        .map(|r| {
            r.clone()
                .map(|p| (obs.vertex[p], pred[p].map(|v| v as f32)))
                .collect()
        })
        .collect()
}
