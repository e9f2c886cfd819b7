//! The stages of `run` as functions with typed inputs and outputs (the types in
//! [`super::state`]): [`import`] → [`Imported`] → [`observe`] → [`Observed`] →
//! [`prepare`] → [`Prepared`] → [`fit`](super::fit::fit) → [`Fit`] (holding the [`Fitted`](super::Fitted) model) →
//! `evaluate` → [`Evaluated`] → [`super::write`] (the result folder and the
//! [`RunReport`]). Each stage is timed by [`crate::stages::Stages`] and adds its notes to the
//! report through [`RunLog`].

use std::path::Path;
use std::sync::Arc;

use nalgebra::Matrix3;

use super::evaluate;
use super::fit::{estimate_options, lambert_of, Fit};
use super::shading::{self, render_local_resolution};
use super::state::{Evaluated, Imported, Observed, Prepared, RunLog};
use super::truth::Truth;
use super::{
    decisions::adaptive_decisions, env_from_world, estimate_up, holdout_rule, holdout_views,
    mean_colours, pilot_smoothness_for, Holdout, LargeMeshSettings, Progress, RunOptions,
    LARGE_MESH,
};
use crate::import::scene::{self, Scene};
use crate::import::workspace::Workspace;
use crate::observe::trace::SceneBvh;
use crate::observe::{self, Observations};
use crate::report::RunReport;
use crate::solve::adapt::Decision;
use crate::solve::EstimateOptions;
use crate::sphere::rotation::{Rotation, RotationForm};
use crate::stages::Stages;
use crate::transport::visibility::Visibility;
use crate::transport::{self, Transport, TransportOptions};
use crate::{Error, Result, Vec3};

/// The pipeline into `dir` (module docs).
pub(crate) fn run_into(opts: &RunOptions, dir: &Path, progress: &Progress) -> Result<RunReport> {
    let mut log = RunLog {
        stages: Stages::new(),
        notes: Vec::new(),
    };
    let imported = import(opts, &mut log, progress)?;
    let sized = sized_for_mesh(opts, imported.scene.mesh.positions.len(), &mut log);
    let opts = sized.as_ref().unwrap_or(opts);
    let observed = observe_training(opts, &imported, &mut log, progress)?;
    let resolved = super::clipped::resolve(opts, &observed.obs, &mut log);
    let opts = resolved.as_ref().unwrap_or(opts);
    let (observed, prepared) = prepare(opts, &imported, observed, &mut log, progress)?;
    let mut fit = super::fit::fit(opts, &imported, observed, prepared, &mut log, progress)?;
    let evaluated = evaluation(opts, &imported, &mut fit, &mut log, dir, progress)?;
    super::write::write(
        opts,
        fit,
        evaluated,
        imported.truth.as_ref(),
        &mut log,
        dir,
        progress,
    )
}

/// Stage 7, the held-out photos: protocol (b)'s light prior, then the evaluation
/// ([`evaluate::evaluate`]).
fn evaluation(
    opts: &RunOptions,
    imported: &Imported,
    fit: &mut Fit,
    log: &mut RunLog,
    dir: &Path,
    progress: &Progress,
) -> Result<Evaluated> {
    progress.stage("evaluation");
    fit.fitted.held_out_suns = super::half_fit::held_out_suns(&fit.fitted);
    let n = fit.fitted.held_out_suns.iter().flatten().count();
    if n > 0 {
        log.notes.push(format!(
            "protocol `half` fits the light of {n} of the {} held-out photos (those with a geotag) within the sun-and-sky model the training photos were fitted in ({} lighting steps, the sun from the photo's clock at the training photos' north), the others as a free map",
            fit.fitted.held.len(),
            crate::solve::light::sky::held_out::HELD_OUT_ROUNDS
        ));
    }
    let half_fit_prior = if fit.fitted.held.is_empty() {
        None
    } else {
        let hp = log.stages.run("half-fit prior", || {
            let o = super::half_prior::half_fit_options(&fit.fitted);
            super::half_prior::prepare(&fit.fitted, opts.half_prior, opts.half_smoothness, &o)
        })?;
        fit.fitted.half_fit = Some(hp.setup);
        Some(hp.report)
    };
    let evaluation = log.stages.run("evaluation", || {
        evaluate::evaluate(&fit.fitted, imported.truth.as_ref(), dir, progress)
    })?;
    Ok(Evaluated {
        evaluation,
        holdout_rule: imported.holdout_rule.clone(),
        half_fit_prior,
    })
}

/// The run's options on a mesh of `vertices` ([`LargeMeshSettings::for_mesh`]), with a
/// note when they differ from those given.
fn sized_for_mesh(opts: &RunOptions, vertices: usize, log: &mut RunLog) -> Option<RunOptions> {
    let sized = LARGE_MESH.for_mesh(opts, vertices)?;
    log.notes.push(format!(
        "large mesh: {vertices} vertices, at least {}, so the run uses the --large-mesh settings {} ({}; --no-large-mesh keeps the full settings)",
        LargeMeshSettings::FROM_VERTICES,
        LARGE_MESH.flags(),
        LargeMeshSettings::GAIN
    ));
    Some(sized)
}

/// Stage 1, import: the workspace, the model, the mesh and the photos; the held-out split.
fn import(opts: &RunOptions, log: &mut RunLog, progress: &Progress) -> Result<Imported> {
    // 1. Import.
    progress.stage("import");
    let (scene, photos) = log.stages.run("import", || -> Result<_> {
        let ws = Workspace::discover(&opts.workspace, opts.mesh.as_deref())?;
        let scene = scene::load_scene(ws)?;
        let photos = scene::load_photos(&scene, opts.clip)?;
        Ok((scene, photos))
    })?;
    log.notes.extend(scene.workspace.notes.iter().cloned());
    log.notes
        .extend(scene.skipped.iter().map(|s| format!("skipped {s}")));
    for s in &scene.skipped {
        progress.warn(&format!("skipped photo {s}"));
    }
    let truth = match &scene.workspace.truth_dir {
        Some(t) => Some(Truth::read(t)?),
        None => None,
    };
    let held = holdout_views(&scene, &opts.holdout, truth.as_ref())?;
    let holdout_rule = holdout_rule(&scene, &opts.holdout, truth.is_some(), &held);
    if matches!(opts.holdout, Holdout::Default) && truth.is_none() && !held.is_empty() {
        progress.note(&format!("held out: {holdout_rule}"));
    }
    log.notes.push(format!("held-out photos: {holdout_rule}"));
    let train: Vec<usize> = (0..scene.views.len())
        .filter(|i| !held.contains(i))
        .collect();
    Ok(Imported {
        scene,
        photos,
        truth,
        held,
        train,
        holdout_rule,
    })
}

/// Stage 2, the observations of the training photos (held-out ones are extracted by the
/// evaluation), checked against the memory budget; duplicate photos dropped by the
/// adaptive model.
fn observe_training(
    opts: &RunOptions,
    im: &Imported,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<Observed> {
    let scene = &im.scene;
    let mut train = im.train.clone();
    let (bvh, mut obs) = extract_observations(opts, im, log, progress)?;
    check_light_observed(&obs, train.len())?;
    for (k, &i) in train.iter().enumerate() {
        if obs.photo_ranges[k].is_empty() {
            log.notes.push(format!(
                "{}: no vertex observed in it; its map stays black",
                scene.views[i].image.name
            ));
        }
    }
    let mut decisions: Vec<crate::solve::adapt::Decision> = Vec::new();
    if opts.adaptive {
        decisions.push(drop_duplicate_photos(
            scene, &mut obs, &mut train, log, progress,
        ));
    }
    Ok(Observed {
        bvh,
        obs,
        train,
        decisions,
    })
}

/// The training photos' observations and the BVH they were traced with, checked against
/// the memory budget with the real observation count before anything large (visibility,
/// rotations, transport, solver) is allocated.
fn extract_observations(
    opts: &RunOptions,
    im: &Imported,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<(SceneBvh, Observations)> {
    let (scene, photos, held, train) = (&im.scene, &im.photos, &im.held, &im.train);
    let nv = scene.mesh.positions.len();
    let photo_pixels: u64 = photos
        .iter()
        .map(|p| p.width as u64 * p.height as u64)
        .sum();
    let sizes = |observations: u64| crate::solve::budget::Sizes {
        vertices: nv as u64,
        photos: train.len() as u64,
        held_photos: held.len() as u64,
        photo_pixels,
        threads: rayon::current_num_threads() as u64,
        observations,
        basis: opts.basis.len() as u64,
        global_resolution: opts.global_resolution as u64,
        local_resolution: opts.local_resolution as u64,
        render_local_resolution: render_local_resolution(opts) as u64,
        normal_grid: opts.normal_grid as u64,
        keep: opts.keep as u64,
    };
    progress.stage("observations");
    let (bvh, obs) = log.stages.run("observations", || {
        let bvh = SceneBvh::new(&scene.mesh);
        let views: Vec<_> = train.iter().map(|&i| scene.views[i].clone()).collect();
        let ph: Vec<&crate::import::photo::Photo> = train.iter().map(|&i| &photos[i]).collect();
        let obs = observe::extract(
            &scene.mesh,
            &bvh,
            &views,
            &ph,
            &super::observe_options(opts),
        );
        (bvh, obs)
    });
    let budget = crate::solve::budget::check(&sizes(obs.len() as u64))?;
    log.notes.push(format!(
        "memory plan: {:.0} MiB for the large arrays (largest: {})",
        budget.total() as f64 / (1u64 << 20) as f64,
        budget.largest().name
    ));
    Ok((bvh, obs))
}

/// Refuses observations with nothing to fit: no vertex seen un-clipped, or every pixel
/// black (`n_train` photos).
fn check_light_observed(obs: &Observations, n_train: usize) -> Result<()> {
    let useful = obs.weight.iter().filter(|&&w| w > 0.0).count();
    if useful == 0 {
        return Err(Error::Numeric {
            stage: "observations".into(),
            message: "no vertex is seen un-clipped in any training photo: check the mesh \
                      against the cameras (`relight-cpc inspect`) and the --clip threshold"
                .into(),
        });
    }
    // Photos with no light in them carry no information about reflectance or light: refuse
    // rather than fit zero maps and arbitrary materials. The threshold is far below one
    // 8-bit step (sRGB 1/255 decodes to 3e-4 linear).
    let brightest = obs
        .rgb
        .iter()
        .zip(&obs.weight)
        .filter(|(_, &w)| w > 0.0)
        .map(|(c, _)| c[0].max(c[1]).max(c[2]))
        .fold(0.0f32, f32::max);
    if brightest <= 1e-5 {
        return Err(Error::Numeric {
            stage: "observations".into(),
            message: format!(
                "every observed pixel of the {} training photos is black (brightest {:.1e} linear): \
                 there is no light to fit; check the photos and their exposure",
                n_train,
                brightest
            ),
        });
    }
    Ok(())
}

/// Drops the training photos that add no new observation (adaptive model,
/// [`crate::solve::adapt`] step 1) from `obs` and `train`; the decision, for the report.
fn drop_duplicate_photos(
    scene: &Scene,
    obs: &mut Observations,
    train: &mut Vec<usize>,
    log: &mut RunLog,
    progress: &Progress,
) -> crate::solve::adapt::Decision {
    let red = crate::solve::adapt::redundant_photos(obs, scene.mesh.positions.len());
    let n = train.len();
    if !red.is_empty() && red.len() < n {
        let drop: Vec<usize> = red.iter().map(|r| r.0).collect();
        for &(k, by) in &red {
            progress.line(&format!(
                "skipped photo {}: it adds no new observation (duplicates {})",
                scene.views[train[k]].image.name, scene.views[train[by]].image.name
            ));
            log.notes.push(format!(
                "{}: skipped, it adds no new observation (every vertex it sees is seen in {} from within {}° and with the same colour within {:.0}%)",
                scene.views[train[k]].image.name,
                scene.views[train[by]].image.name,
                crate::solve::adapt::DUPLICATE_ANGLE_DEG,
                100.0 * crate::solve::adapt::DUPLICATE_RGB
            ));
        }
        *obs = crate::solve::adapt::drop_photos(obs, &drop);
        *train = train
            .iter()
            .enumerate()
            .filter(|(k, _)| !drop.contains(k))
            .map(|(_, &i)| i)
            .collect();
        crate::solve::adapt::Decision::new(
            "photos",
            n,
            train.len(),
            format!(
                "{} training photo(s) duplicate an earlier one (same view within {}°, same colour within {:.0}%): a duplicate adds a light map to estimate and no information",
                drop.len(),
                crate::solve::adapt::DUPLICATE_ANGLE_DEG,
                100.0 * crate::solve::adapt::DUPLICATE_RGB
            ),
        )
    } else {
        crate::solve::adapt::Decision::new(
            "photos",
            n,
            n,
            format!(
                "every training photo adds observations: none repeats an earlier photo's view (within {}°) with the same colours (within {:.0}%); a photo from the same view under another light is new information, since every photo has its own light",
                crate::solve::adapt::DUPLICATE_ANGLE_DEG,
                100.0 * crate::solve::adapt::DUPLICATE_RGB
            ),
        )
    }
}

/// Stages 3–5: frames, visibility, the adaptive pilot, the rotation and the transport rows.
fn prepare(
    opts: &RunOptions,
    im: &Imported,
    observed: Observed,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<(Observed, Prepared)> {
    let scene = &im.scene;
    let Observed {
        bvh,
        obs,
        train,
        mut decisions,
    } = observed;
    let nv = scene.mesh.positions.len();
    let frames = Frames::new(opts, scene, log)?;
    let at = TraceScene {
        scene,
        bvh: &bvh,
        env_from_world: &frames.env_from_world,
    };
    let traced = visibility(&first_trace_options(opts), &at, log, progress);
    let vis = &traced.0;
    // Strata of the lighting step's sample: normal × open sky.
    let strata =
        crate::solve::subsample::lighting_strata(&frames.normals_env, &vis.open_fractions());
    let (mean_rgb, seen) = mean_colours(&obs, nv);
    let pilot_data = PilotData {
        normals_env: &frames.normals_env,
        env_from_world: &frames.env_from_world,
        obs: &obs,
        vis,
        strata: &strata,
        mean_rgb: &mean_rgb,
        seen: &seen,
    };
    let adapted = adapt(opts, &pilot_data, log, progress)?;
    decisions.extend(adapted.decisions);
    let eff = adapted.eff;
    let (vis, render_vis) = fit_visibility(&eff, traced, &at, log, progress);
    let TransportStage { rot, topts, tr } =
        transport_stage(&eff, &frames, &obs, &vis, log, progress)?;
    Ok((
        Observed {
            bvh,
            obs,
            train,
            decisions,
        },
        Prepared {
            env_from_world: frames.env_from_world,
            normals_env: frames.normals_env,
            vis,
            render_vis,
            eff,
            pilot_k: adapted.pilot_k,
            mean_rgb,
            seen,
            rot,
            topts,
            tr,
            strata,
        },
    ))
}

/// The environment frame (stage 3): world up (`--up` or the cameras'), the frame with that
/// up as its z, and the vertex normals in it.
struct Frames {
    env_from_world: Matrix3<f64>,
    normals_env: Vec<Vec3>,
}

impl Frames {
    fn new(opts: &RunOptions, scene: &scene::Scene, log: &mut RunLog) -> Result<Self> {
        let up = world_up(opts, &scene.views, log)?;
        let env_from_world = env_from_world(&up)?;
        let normals_env = scene
            .mesh
            .normals
            .iter()
            .map(|n| env_from_world * n)
            .collect();
        Ok(Frames {
            env_from_world,
            normals_env,
        })
    }
}

/// Stages 4–5 at the effective options: the rotation, the transport's sizes and the
/// transport rows.
struct TransportStage {
    rot: Rotation,
    topts: TransportOptions,
    tr: Transport,
}

/// Stages 4–5: the rotation ([`rotation`]), then the transport row of every training
/// observation ([`transport::build`]) with a progress bar over the observations.
fn transport_stage(
    eff: &RunOptions,
    frames: &Frames,
    obs: &Observations,
    vis: &Visibility,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<TransportStage> {
    let rot = rotation(eff, log, progress);
    let topts = eff.transport_options();
    progress.stage("transport");
    let bar = progress.stage_bar(obs.vertex.len() as u64, "observations");
    let tr = log.stages.run("transport", || {
        transport::build(
            &frames.normals_env,
            obs,
            &frames.env_from_world,
            vis,
            &eff.basis,
            &rot,
            &topts,
        )
    })?;
    drop(bar);
    Ok(TransportStage { rot, topts, tr })
}

/// The options the visibility is first traced with (stage 3): with the adaptive model on,
/// the local side at most the pilot's ([`crate::solve::adapt::PILOT_LOCAL`]), since the
/// pilot chooses the fit's side after it (`crate::solve::adapt`, step 5) and the pilot
/// itself reads no finer maps; otherwise the options as given.
fn first_trace_options(opts: &RunOptions) -> RunOptions {
    let mut first = opts.clone();
    if opts.adaptive {
        first.local_resolution = opts.local_resolution.min(crate::solve::adapt::PILOT_LOCAL);
    }
    first
}

/// What a visibility trace reads of the scene.
#[derive(Clone, Copy)]
struct TraceScene<'a> {
    scene: &'a Scene,
    bvh: &'a SceneBvh,
    env_from_world: &'a Matrix3<f64>,
}

/// The visibility at the fit's local sides (`eff`: the estimator's and the renderer's):
/// the first trace `traced` as it is when its sides are the fit's, averaged down when it is
/// finer ([`crate::solve::adapt::downsample_visibility`], as [`shading::trace_visibility`]
/// does), else traced again at the fit's sides (the pilot chose a finer local map than its
/// own: a sharp lobe's 64² global map).
fn fit_visibility(
    eff: &RunOptions,
    traced: (Arc<Visibility>, Arc<Visibility>),
    at: &TraceScene,
    log: &mut RunLog,
    progress: &Progress,
) -> (Arc<Visibility>, Arc<Visibility>) {
    let (n_fit, n_render) = (eff.local_resolution, render_local_resolution(eff));
    let (vis, render_vis) = traced;
    if vis.n_local == n_fit && render_vis.n_local == n_render {
        return (vis, render_vis);
    }
    // The first trace is the finer of the two; the other was averaged down from it.
    let fine = if render_vis.n_local > vis.n_local {
        render_vis
    } else {
        vis
    };
    if fine.n_local < n_fit.max(n_render) {
        return visibility(eff, at, log, progress);
    }
    (
        shading::at_side(&fine, n_fit),
        shading::at_side(&fine, n_render),
    )
}

/// Stage 3, visibility at the estimator's and the renderer's local resolutions
/// ([`shading::trace_visibility`]), with its note.
fn visibility(
    opts: &RunOptions,
    at: &TraceScene,
    log: &mut RunLog,
    progress: &Progress,
) -> (Arc<Visibility>, Arc<Visibility>) {
    let TraceScene {
        scene,
        bvh,
        env_from_world,
    } = *at;
    let nv = scene.mesh.positions.len();
    progress.stage("visibility");
    let bar = progress.stage_bar(nv as u64, "vertices");
    let (vis, render_vis) = log.stages.run("visibility", || {
        shading::trace_visibility(&scene.mesh, bvh, env_from_world, opts)
    });
    drop(bar);
    log.notes.push(format!(
        "visibility at {}² texels per vertex: {} of {} vertices have a provably open hemisphere and skipped their rays; {} rays traced ({}); {} more answered without tracing, their texels' cone of directions holding no triangle",
        vis.n_local.max(render_vis.n_local),
        vis.open_count(),
        nv,
        vis.rays_traced,
        visibility_sampling_note(opts),
        vis.rays_known_open
    ));
    (vis, render_vis)
}

/// What the adaptive pilot reads of the prepared scene.
struct PilotData<'a> {
    normals_env: &'a [Vec3],
    env_from_world: &'a Matrix3<f64>,
    obs: &'a Observations,
    vis: &'a Visibility,
    strata: &'a [u32],
    mean_rgb: &'a [[f64; 3]],
    seen: &'a [bool],
}

/// The options in effect after the adaptive model, its material count and reason (for
/// the start) and its decisions (for the report).
struct Adapted {
    eff: RunOptions,
    pilot_k: Option<(usize, String)>,
    decisions: Vec<Decision>,
}

/// The adaptive model (`crate::solve::adapt` steps 2–5): with `--adaptive on` a pilot fit
/// decides the materials, the bases, the map resolution and the coefficient budget;
/// otherwise the options as given.
fn adapt(
    opts: &RunOptions,
    d: &PilotData,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<Adapted> {
    let mut eff = opts.clone();
    if !opts.adaptive {
        return Ok(Adapted {
            eff,
            pilot_k: None,
            decisions: Vec::new(),
        });
    }
    progress.stage("pilot");
    let spinner = progress.spinner("pilot fits");
    let lambert = lambert_of(&opts.basis)?;
    let (smoothness, why) = pilot_smoothness_for(opts.smoothness, d.obs.photo_ranges.len());
    log.notes.extend(why);
    let outcome = log.stages.run("pilot", || {
        crate::solve::adapt::pilot(&crate::solve::adapt::PilotInput {
            normals_env: d.normals_env,
            obs: d.obs,
            env_from_world: d.env_from_world,
            vis: d.vis,
            basis: &opts.basis,
            lambert,
            normal_grid: opts.normal_grid,
            global_resolution: opts.global_resolution,
            keep: opts.keep,
            // The pilot holds out its own observations: no early stopping inside it; and
            // no ratio step (`estimate_options` leaves it off): the pilot compares models,
            // it does not converge one.
            estimate: EstimateOptions {
                validation_fraction: 0.0,
                smoothness,
                ..estimate_options(opts, lambert, d.strata)
            },
            mean_rgb: d.mean_rgb,
            seen: d.seen,
            materials: opts.materials.fixed(),
            choose_weights_sum: opts.weights_sum == super::WeightsSum::Auto,
            start: opts.start_brightness,
            max_vertices: opts.pilot_vertices,
            seed: opts.seed,
        })
    })?;
    drop(spinner);
    let nv = d.normals_env.len();
    let decisions = adaptive_decisions(opts, &outcome, d.vis, nv, &mut eff);
    Ok(Adapted {
        eff,
        pilot_k: Some((outcome.materials, outcome.materials_reason.clone())),
        decisions,
    })
}

/// World up: `--up`, or estimated from the cameras' −y axes (noted in the report).
fn world_up(opts: &RunOptions, views: &[scene::View], log: &mut RunLog) -> Result<Vec3> {
    Ok(match opts.up {
        Some(u) => u.normalize(),
        None => {
            let u = estimate_up(views).ok_or_else(|| {
                Error::Config("cannot estimate world up from the cameras (their −y axes cancel out); give --up X,Y,Z".into())
            })?;
            log.notes.push(format!(
                "world up estimated from the cameras' −y axes: ({:.4}, {:.4}, {:.4})",
                u.x, u.y, u.z
            ));
            u
        }
    })
}

/// Stage 4, the rotation of the light into each normal's frame at the effective
/// resolutions (`eff`).
fn rotation(eff: &RunOptions, log: &mut RunLog, progress: &Progress) -> Rotation {
    progress.stage("rotation");
    let bar = progress.stage_bar((eff.normal_grid * eff.normal_grid) as u64, "normals");
    let rot = log.stages.run("rotation", || {
        Rotation::new(
            eff.global_resolution,
            eff.local_resolution,
            eff.normal_grid,
            RotationForm::Factored,
        )
    });
    drop(bar);
    rot
}

/// How the visibility rays were spread, in words for the report's notes.
fn visibility_sampling_note(opts: &RunOptions) -> String {
    if opts.edge_rays == 0 {
        return format!("{} per texel", opts.rays_per_texel.max(1));
    }
    let first = if opts.ray_lattice >= 2 {
        "a first ray in every other texel of each row and column, and between them where those disagree"
    } else {
        "a first ray in every texel"
    };
    format!(
        "{first}; {} more in each texel on a shadow edge",
        opts.edge_rays
    )
}
