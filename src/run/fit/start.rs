//! The fit's start ([`FitStart`]): the initial materials (the pilot's count,
//! `--materials`, or a count from the colours, then clustered), the estimator's options
//! that depend on the observations kept, the transient pass, and the start's brightness
//! matched by normal.

use super::options::{estimate_options, lambert_of, photo_halves};
use crate::import::scene::{Scene, View};
use crate::observe::Observations;
use crate::run::state::{Imported, Prepared, RunLog};
use crate::run::{
    achromatic_for, choose_material_count, scene_light, smoothness_for, weights_bic_for, FitShape,
    LargeMeshSettings, MaterialCount, Progress, RunOptions, StartBrightness,
};
use crate::solve::cluster::{initial_materials, unmixed_weights, InitialMaterials, StartWeights};
use crate::solve::light::choose::LightChoice;
use crate::solve::loss_choice::{is_robust, LossChoice};
use crate::solve::starts;
use crate::solve::{EstimateOptions, Materials0};
use crate::Result;

/// The start and the estimator's options ([`FitStart`]): the transient pass when on (it
/// masks occluders in `obs`, and the start keeps what it masked), the light model when
/// `--light` is not given (by the start's material count, [`light_by_scene`]), the
/// options that depend on the observations kept, and the start's brightness matched by
/// normal when the pilot chose it.
pub(super) fn prepare_start(
    opts: &RunOptions,
    im: &Imported,
    p: &Prepared,
    train: &[usize],
    obs: &mut Observations,
    log: &mut RunLog,
    progress: &Progress,
) -> Result<FitStart> {
    let scene = &im.scene;
    let lambert = lambert_of(&p.eff.basis)?;
    let mut start = FitStart::new(opts, p, &scene.mesh.positions, lambert, train.len())?;
    if p.eff.transients {
        start.mask_transients(opts, obs, p, scene, log, progress)?;
    }
    // The materials the fit starts with, after the transient pass clustered them again.
    let fitted = start.init.albedo.len();
    if let Some(asked) = opts.materials.fixed().filter(|&k| k > fitted) {
        progress.warn(&cluster_shortfall(asked, fitted));
    }
    let shape = FitShape {
        vertices: scene.mesh.positions.len(),
        basis: &p.eff.basis,
        photos: train.len(),
        materials: Some(fitted),
    };
    let by_scene = light_by_scene(opts, shape, log);
    let opts = by_scene.as_ref().unwrap_or(opts);
    start.finish_options(opts, scene, train, obs)?;
    if p.eff.start_brightness == StartBrightness::Matched {
        start.match_brightness(p, obs);
    }
    start.by_scene = by_scene;
    Ok(start)
}

/// The run's options with the light model `run` picks for a fit of `shape` when `--light`
/// is not given ([`scene_light`]), the choice noted in the log; `None` keeps `opts` as
/// they are. The material count is the start's: what the photos' colours give, which can
/// be fewer than `--materials` or the pilot asked for.
fn light_by_scene(opts: &RunOptions, shape: FitShape, log: &mut RunLog) -> Option<RunOptions> {
    scene_light(opts, shape).map(|(light, note)| {
        log.notes.push(note);
        RunOptions {
            light,
            ..opts.clone()
        }
    })
}

/// The fit's start: the initial materials, the estimator's options and the reasons so far.
pub(super) struct FitStart {
    init: InitialMaterials,
    pub(super) eopts: EstimateOptions,
    /// Why the model has its size (the report's reasons).
    pub(super) reasons: Vec<String>,
    /// What the transient pass masked (`None`: `--transients off`).
    pub(super) transients: Option<crate::run::transients::Transients>,
    /// Each vertex's mean colour and whether a training photo sees it, when the transient
    /// pass clustered the start again from them (else `Prepared`'s); `--start-weights`
    /// unmixes them.
    recoloured: Option<(Vec<[f64; 3]>, Vec<bool>)>,
    /// The photo halves `--light auto` scores its candidates on
    /// ([`RunOptions::light_choice_halves`]); `None`: early stopping's own score.
    pub(super) choice_halves: Option<std::sync::Arc<crate::solve::options::PhotoHalves>>,
    /// Whether the fit chooses its data loss by validation (`--loss auto` where it
    /// applies, [`FitStart::loss_applies`]).
    pub(super) loss_auto: bool,
    /// The run's options with the light model `run` picked for this fit when `--light`
    /// was not given ([`light_by_scene`]); `None`: the run's own.
    pub(super) by_scene: Option<RunOptions>,
}

impl FitStart {
    /// Each vertex's mean colour and whether a training photo sees it: the transient
    /// pass's when it clustered the start again, else `p`'s.
    fn colours<'a>(&'a self, p: &'a Prepared) -> (&'a [[f64; 3]], &'a [bool]) {
        match &self.recoloured {
            Some((m, s)) => (m, s),
            None => (&p.mean_rgb, &p.seen),
        }
    }

    /// Whether a training photo sees each vertex ([`FitStart::colours`]).
    pub(super) fn seen<'a>(&'a self, p: &'a Prepared) -> &'a [bool] {
        self.colours(p).1
    }

    /// The clustered start with the pilot's count (or `--materials`, or a count from the
    /// colours) and the estimator's options, with the ratio step's rounds for
    /// `training_photos` and the start's materials, and the neighbour prior's graph when on.
    fn new(
        opts: &RunOptions,
        p: &Prepared,
        positions: &[crate::Vec3],
        lambert: usize,
        training_photos: usize,
    ) -> Result<Self> {
        let mut reasons = Vec::new();
        let init = starting_materials(opts, p.pilot_k.clone(), &p.mean_rgb, &p.seen, &mut reasons)?;
        let mut eopts = estimate_options(&p.eff, lambert, &p.strata);
        eopts.ratio_steps = p.eff.ratio_steps.rounds(training_photos, init.albedo.len());
        let varpro = p
            .eff
            .varpro_steps
            .plan(training_photos, init.albedo.len(), &p.eff.basis);
        (eopts.varpro_steps, eopts.varpro_broyden) = (varpro.rounds, varpro.broyden);
        reasons.extend(varpro.why);
        let (bic, why) = weights_bic_for(
            p.eff.weights_bic,
            training_photos,
            init.albedo.len(),
            &p.eff.basis,
        );
        eopts.weights_bic = bic;
        reasons.extend(why);
        let (tied, why) =
            achromatic_for(p.eff.achromatic_specular, init.albedo.len(), &p.eff.basis);
        eopts.achromatic_specular = tied;
        reasons.extend(why);
        let (s, why) = smoothness_for(
            p.eff.smoothness,
            training_photos,
            init.albedo.len(),
            p.eff.global_resolution,
            &p.eff.basis,
        );
        eopts.smoothness = s;
        reasons.extend(why);
        if eopts.chroma_smoothness > 0.0 {
            reasons.push(format!(
                "the maps' colour smoothed over directions at {} × their Laplacian weight (--chroma-smoothness; exposure and white balance free)",
                eopts.chroma_smoothness
            ));
        }
        if eopts.weights_smoothness > 0.0 {
            // The neighbour prior's graph: the one the unseen vertices' materials spread over.
            use crate::solve::materials::propagate::{knn_graph, NEIGHBOURS};
            eopts.weights_graph = knn_graph(positions, NEIGHBOURS)?.into();
        }
        Ok(FitStart {
            init,
            eopts,
            reasons,
            transients: None,
            recoloured: None,
            choice_halves: None,
            loss_auto: false,
            by_scene: None,
        })
    }

    /// The transient pass (`--transients`): masks occluders in `obs` and keeps what it
    /// masked; when it masked any, the start is clustered again from the unmasked
    /// observations only (an occluder's colour would otherwise take a material of its own).
    fn mask_transients(
        &mut self,
        opts: &RunOptions,
        obs: &mut Observations,
        p: &Prepared,
        scene: &Scene,
        log: &mut RunLog,
        progress: &Progress,
    ) -> Result<()> {
        let lambert = self.eopts.lambert_basis;
        progress.stage("transients");
        let spinner = progress.spinner("pilot fit for transient occluders");
        let start = Materials0::from_initial(&self.init, p.eff.basis.len(), lambert);
        let t = log.stages.run("transients", || {
            crate::run::transients::mask_transients(obs, &p.tr, &scene.mesh, &start, &self.eopts)
        })?;
        drop(spinner);
        if t.count() > 0 {
            let (mean_rgb, seen) = crate::run::mean_colours(obs, scene.mesh.positions.len());
            self.reasons.clear();
            self.init =
                starting_materials(opts, p.pilot_k.clone(), &mean_rgb, &seen, &mut self.reasons)?;
            self.recoloured = Some((mean_rgb, seen));
        }
        self.transients = Some(t);
        Ok(())
    }

    /// The options that depend on the observations kept: the shared light's groups, the
    /// sky's geotag suns and early stopping's photo halves; the neighbour prior's reason.
    fn finish_options(
        &mut self,
        opts: &RunOptions,
        scene: &Scene,
        train: &[usize],
        obs: &Observations,
    ) -> Result<()> {
        if self.eopts.weights_smoothness > 0.0 {
            self.reasons.push(format!(
                "material weights pulled toward their {} nearest vertices' mean at {} (--weights-smoothness)",
                crate::solve::materials::propagate::NEIGHBOURS,
                self.eopts.weights_smoothness
            ));
        }
        if opts.light == LightChoice::Shared || opts.light.chooses() {
            let file = opts.light_groups.as_deref();
            self.eopts.light_groups =
                crate::run::light_groups::resolve(file, opts.light_group_minutes, scene, train)?;
            if let Some(g) = &self.eopts.light_groups {
                self.reasons.push(format!("shared light: {}", g.source));
            }
        }
        if opts.geotag_suns && (opts.light == LightChoice::Sky || opts.light.chooses()) {
            self.eopts.sun_clock = crate::run::geotag_suns::resolve(scene, train);
            if let Some(c) = &self.eopts.sun_clock {
                self.reasons.push(format!("sun and sky: {}", c.source));
            }
        }
        let views: Vec<&View> = train.iter().map(|&i| &scene.views[i]).collect();
        let positions = &scene.mesh.positions;
        self.eopts.validation_halves = photo_halves(&views, positions, obs, opts.validation_halves);
        let loss_asked = opts.loss == LossChoice::Auto && is_robust(&self.eopts);
        if (opts.light.chooses() || loss_asked) && self.eopts.validation_halves.is_none() {
            self.choice_halves = photo_halves(&views, positions, obs, opts.light_choice_halves);
        }
        if loss_asked {
            self.loss_auto = self.loss_applies(positions.len());
        }
        Ok(())
    }

    /// Whether `--loss auto` chooses the loss for a mesh of `vertices` vertices: below
    /// [`LargeMeshSettings::FROM_VERTICES`], with held-back photo halves to score on (the
    /// choice's or early stopping's). Else the robust loss stays, and the reasons say why.
    fn loss_applies(&mut self, vertices: usize) -> bool {
        let from = LargeMeshSettings::FROM_VERTICES;
        let halves = self.choice_halves.is_some() || self.eopts.validation_halves.is_some();
        let why = if vertices >= from {
            format!("from {from} vertices, where its two extra fits cost too much time: the mesh has {vertices}")
        } else if !halves {
            "without photo halves to score on (--light-choice-halves 0, or no more training \
             photos than halves)"
                .to_string()
        } else {
            return true;
        };
        self.reasons.push(format!(
            "loss: the robust loss (Huber; --loss auto keeps it {why}); --loss plain fits plain least squares"
        ));
        false
    }

    /// The start's material brightness matched by normal ([`crate::solve::matched`]) on
    /// the training observations; the change, or why none, goes to the reasons.
    fn match_brightness(&mut self, p: &Prepared, obs: &Observations) {
        let open = p.vis.open_fractions();
        let how =
            crate::solve::matched::match_start(&mut self.init, obs, &p.normals_env, &open, true);
        self.reasons.push(if how.applied() {
            format!("start brightness matched by normal: {}", how.describe())
        } else {
            format!(
                "start brightness: the clustered colours; {}",
                how.describe()
            )
        });
    }

    /// The starts the estimate runs from (`--starts`), and why when fewer exist.
    pub(super) fn family(
        &mut self,
        opts: &RunOptions,
        p: &Prepared,
        lambert: usize,
    ) -> Vec<starts::Start> {
        let n_basis = p.eff.basis.len();
        let available = starts::family_len(n_basis, lambert);
        if opts.starts > available {
            self.reasons.push(format!(
                "--starts {}: this basis gives {available} distinct starts, all tried",
                opts.starts
            ));
        }
        let materials0 = Materials0::from_initial(&self.init, n_basis, lambert);
        let mut family = starts::variants(materials0, lambert, starts::GLOSS_FRACTION, opts.starts);
        if opts.start_weights != StartWeights::Clustered {
            let (mean_rgb, seen) = self.colours(p);
            let (weights, _) = unmixed_weights(&self.init, mean_rgb, seen);
            self.reasons.push(match opts.start_weights {
                StartWeights::Both => "start weights: a fit from the clustered weights and one from the weights unmixed from the mean colours, the lower validation score kept (--start-weights both)".to_string(),
                _ => "start weights: unmixed from the mean colours (--start-weights unmixed)".to_string(),
            });
            if opts.start_weights == StartWeights::Unmixed {
                for s in &mut family {
                    s.materials.weights.clone_from(&weights);
                    s.label.push_str(", weights unmixed from the mean colours");
                }
            } else {
                family.push(starts::Start {
                    label: "the paper's start with its weights unmixed from the mean colours"
                        .into(),
                    materials: Materials0 {
                        lambda: family[0].materials.lambda.clone(),
                        weights,
                    },
                });
            }
        }
        family
    }
}

/// The starting materials: clustered mean colours with the pilot's count, `--materials`,
/// or a count chosen from the colours; why, pushed to `reasons`.
fn starting_materials(
    opts: &RunOptions,
    pilot_k: Option<(usize, String)>,
    mean_rgb: &[[f64; 3]],
    seen: &[bool],
    reasons: &mut Vec<String>,
) -> Result<InitialMaterials> {
    let (k, k_reason) = match (pilot_k, opts.materials) {
        (Some(p), _) => p,
        (None, MaterialCount::Fixed(k)) => (k, format!("materials: {k}, as given by --materials")),
        (None, MaterialCount::Auto) => choose_material_count(mean_rgb, seen, opts.seed),
    };
    let init = initial_materials(mean_rgb, seen, k, opts.seed)?;
    reasons.push(k_reason);
    if init.albedo.len() < k {
        reasons.push(cluster_shortfall(k, init.albedo.len()));
    }
    Ok(init)
}

/// Why fewer materials than `asked` are fitted: the start clusters the seen vertices by
/// hue and saturation ([`crate::solve::cluster::hue_feature`]), so photos without colour,
/// or an object of one colour, give fewer distinct clusters.
fn cluster_shortfall(asked: usize, got: usize) -> String {
    let (clusters, fitted) = if got == 1 {
        (
            "1 distinct hue cluster".to_string(),
            "1 material is".to_string(),
        )
    } else {
        (
            format!("{got} distinct hue clusters"),
            format!("{got} materials are"),
        )
    };
    format!(
        "{asked} materials were asked for, but the seen vertices' colours form only \
         {clusters} (grey photos have one hue), so {fitted} fitted"
    )
}
