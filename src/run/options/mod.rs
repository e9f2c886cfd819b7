//! The options of `run` ([`RunOptions`]), their defaults and their checks (each a plain
//! [`Error::Config`] naming the flag).

pub use crate::solve::matched::StartBrightness;
use crate::solve::{EstimateOptions, SumScope};
use crate::transport::brdf::BasisBrdf;
use crate::{Error, Result, Vec3};
use std::path::PathBuf;

mod achromatic;
mod large_mesh;
mod light_by_scene;
mod smoothness;
mod values;
mod weights_bic;
pub use achromatic::{achromatic_for, Achromatic, ACHROMATIC_FROM_MATERIALS};
pub use large_mesh::{LargeMeshSettings, LARGE_MESH};
pub use light_by_scene::{scene_light, FitShape, CONSTRAINED_FROM_MATERIALS, PRIOR_FROM_PHOTOS};
pub(crate) use smoothness::smoothness_base;
pub use smoothness::{pilot_smoothness_for, smoothness_for, SMOOTHNESS_FROM_PHOTOS};
pub use values::{
    Holdout, MaterialCount, PriorStrength, RatioSteps, Restart, VarproPlan, VarproSteps,
    WeightsSmoothness, WeightsSum,
};
pub use weights_bic::{weights_bic_for, BIC_FROM_PHOTOS};

/// Checked options of a run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// The COLMAP workspace.
    pub workspace: PathBuf,
    /// Output folder.
    pub out: PathBuf,
    /// A mesh to use instead of the workspace's.
    pub mesh: Option<PathBuf>,
    /// Held-out photos.
    pub holdout: Holdout,
    /// World up; estimated from the cameras when `None`.
    pub up: Option<Vec3>,
    /// Number of materials.
    pub materials: MaterialCount,
    /// Basis BRDF specifications (`lambert`, `phong:50`, `ggx:0.2`); the first Lambertian
    /// one carries the diffuse colour.
    pub basis: Vec<BasisBrdf>,
    /// Global octahedral map side.
    pub global_resolution: usize,
    /// Local hemi-octahedral map side.
    pub local_resolution: usize,
    /// Local map side of the renderer (held-out views, renders, `relight.bin`); `None`:
    /// `local_resolution` ([`super::shading::render_local_resolution`]).
    pub render_local_resolution: Option<usize>,
    /// Normal-grid side of the rotation.
    pub normal_grid: usize,
    /// Haar coefficients kept per transport row (0 = all).
    pub keep: usize,
    /// Energy tolerance of the blended lighting rows
    /// ([`EstimateOptions::blend_tolerance`]; 0 = the exact blend).
    pub blend_tolerance: f64,
    /// Visibility rays per local texel when `edge_rays` is 0.
    pub rays_per_texel: usize,
    /// Adaptive visibility: one ray per texel, then this many more in each texel on a
    /// visibility edge ([`crate::transport::visibility::Sampling::Adaptive`]); 0 = uniform
    /// `rays_per_texel`.
    pub edge_rays: usize,
    /// Adaptive visibility: the spacing of the texels whose first ray is always traced
    /// (1 = every texel; 2 = every other one, the texels between them traced only where
    /// their lattice neighbours disagree, [`crate::transport::visibility::Sampling::Adaptive`]).
    pub ray_lattice: usize,
    /// Outer iterations at most.
    pub max_iterations: usize,
    /// Stop when the objective improves by less than this fraction.
    pub rel_tol: f64,
    /// Laplacian smoothness, as a fraction of the largest system value, or by the fit's
    /// photos and map size ([`PriorStrength::Auto`], [`smoothness_for`]).
    pub smoothness: PriorStrength,
    /// Weight `κ` of the maps' chroma smoothness prior relative to the Laplacian's
    /// ([`crate::solve::light`] `chroma`); 0 = off.
    pub chroma_smoothness: f64,
    /// IRLS passes per lighting step of the robust loss (1 = no reweighting).
    pub irls_iterations: usize,
    /// The data loss ([`crate::solve::loss_choice`]): the robust loss, plain least
    /// squares, or `auto` (both fitted below [`LargeMeshSettings::FROM_VERTICES`]
    /// vertices, each scored on the right halves of [`RunOptions::light_choice_halves`]
    /// training photos held back, the lower kept; the robust loss from that size on).
    pub loss: crate::solve::loss_choice::LossChoice,
    /// GPCG iterations per lighting QP inside the alternation
    /// ([`EstimateOptions::alternation_qp_iters`]); 0 = every QP to the KKT tolerance.
    pub lighting_qp_iterations: usize,
    /// Conjugate-gradient steps per GPCG iteration of a lighting QP inside the alternation
    /// ([`EstimateOptions::alternation_cg_iters`]); 0 = the solver's own cap
    /// ([`EstimateOptions::qp_max_cg`]).
    pub lighting_cg_iterations: usize,
    /// Early stopping: outer iterations without a better validation score before the
    /// alternation stops ([`EstimateOptions::patience`]).
    pub patience: usize,
    /// Early stopping: the first outer iteration at which the patience may stop the
    /// alternation ([`EstimateOptions::min_iterations`]).
    pub min_iterations: usize,
    /// The first rounds that take the ratio step ([`EstimateOptions::ratio_steps`]).
    pub ratio_steps: RatioSteps,
    /// The first rounds that take the variable-projection step
    /// ([`EstimateOptions::varpro_steps`]) and its Jacobian.
    pub varpro_steps: VarproSteps,
    /// At most this many observations per photo in its lighting QPs, a stratified sample
    /// ([`EstimateOptions::lighting_sample`]); 0 = all.
    pub lighting_sample: usize,
    /// Starts of the alternation tried, the best kept ([`crate::solve::starts`]; not in the
    /// paper): 1 = the paper's clustered start alone. Each start costs one estimate.
    pub starts: usize,
    /// Where the start's blending weights come from
    /// ([`crate::solve::cluster::StartWeights`]; not in the paper): the clustering's,
    /// unmixed from the mean colours, or both fitted and the better one by validation kept.
    pub start_weights: crate::solve::cluster::StartWeights,
    /// After the fit, fits from starts that differ in the materials' relative brightness
    /// and keeps the deepest ([`crate::solve::materials::brightness::search`]; not in the
    /// paper).
    pub start_search: bool,
    /// After the fit (and the start search), with two or more materials, a second fit
    /// ([`Restart`]) and the one with the lower validation error kept (not in the paper);
    /// [`Restart::Auto`] by the fit's basis ([`Restart::resolve`]).
    pub restart: Restart,
    /// Where the start's material brightness comes from: the clustered colours, matched
    /// by normal, or the pilot's choice ([`StartBrightness::Auto`]).
    pub start_brightness: StartBrightness,
    /// Lower bound on IRLS's robust scale relative to each photo's RMS radiance
    /// ([`EstimateOptions::robust_floor`]; 0 = the residuals' MAD alone).
    pub robust_floor: f64,
    /// Prior that each vertex's blending weights sum to one, relative to its data
    /// ([`EstimateOptions::weights_sum`]; 0 = off, the paper's free weights), or the
    /// pilot's choice ([`WeightsSum::Auto`]).
    pub weights_sum: WeightsSum,
    /// Which vertices a given [`Self::weights_sum`] ties
    /// ([`EstimateOptions::weights_sum_scope`]); with [`WeightsSum::Auto`] the pilot's choice.
    pub weights_sum_scope: SumScope,
    /// Prior pulling each vertex's blending weights toward its neighbours' mean
    /// ([`EstimateOptions::weights_smoothness`]; 0 = off), over the 8-nearest-neighbour
    /// graph of the vertices ([`crate::solve::materials::propagate::knn_graph`]), or the
    /// pilot's choice ([`WeightsSmoothness::Auto`]).
    pub weights_smoothness: WeightsSmoothness,
    /// The multiple of BIC's penalty by which each vertex drops materials it does not need
    /// ([`EstimateOptions::weights_bic`]; 0 = off, the paper's NNLS), or by the fit's
    /// lobes, photos and materials ([`PriorStrength::Auto`], [`weights_bic_for`]).
    pub weights_bic: PriorStrength,
    /// One specular weight per material across R, G and B
    /// ([`EstimateOptions::achromatic_specular`]), or by the fit's materials and lobes
    /// ([`Achromatic::Auto`], [`achromatic_for`]).
    pub achromatic_specular: Achromatic,
    /// Fraction of the training observations held back, seeded, for early stopping
    /// ([`EstimateOptions::validation_fraction`]; 0 = off: the last iterate is returned).
    pub validation: f64,
    /// Early stopping holds back blocks of this many consecutive vertex ids
    /// ([`EstimateOptions::validation_block`]; 0 = single observations).
    pub validation_block: usize,
    /// Early stopping holds back the right halves of this many training photos instead
    /// ([`EstimateOptions::validation_halves`]; 0 = off).
    pub validation_halves: usize,
    /// Overexposure threshold on the encoded [0, 1] scale.
    pub clip: f32,
    /// What the fit does with overexposed observations' clipped channels ([`Clipped`]).
    pub clipped: Clipped,
    /// Seed of every random choice.
    pub seed: u64,
    /// Progress bars on standard error.
    pub progress: bool,
    /// Replace an existing output folder.
    pub force: bool,
    /// Write renders of every view (not only held-out ones).
    pub render_training: bool,
    /// Leave out what the scene does not need ([`crate::solve::adapt`]): redundant photos,
    /// basis BRDFs whose weights vanish, map resolution and coefficient budget beyond what
    /// the kept lobes resolve; the number of materials by held-out error. The requested
    /// resolutions and `keep` are then upper bounds. Off in [`RunOptions::new`] (the full
    /// model, as the benchmarks' knobs assume); the CLI turns it on unless `--adaptive off`.
    pub adaptive: bool,
    /// Most seen vertices the adaptive pilot fits, a seeded sample above it (0 = every
    /// vertex; [`crate::solve::adapt::PILOT_MAX_VERTICES`] by default).
    pub pilot_vertices: usize,
    /// Use [`LARGE_MESH`] when the mesh has at least
    /// [`LargeMeshSettings::FROM_VERTICES`] vertices ([`LargeMeshSettings::for_mesh`]).
    /// Off in [`RunOptions::new`] (the options as given); the CLI turns it on
    /// unless `--large-mesh`, `--no-large-mesh` or one of the three settings is given.
    pub large_mesh_auto: bool,
    /// The per-photo light model ([`crate::solve::light::choose`]): the paper's free map, the
    /// map under the statistical prior, the shared map, the sun and sky, or `auto` (each
    /// that applies, the one with the lower validation score kept,
    /// [`RunOptions::light_choice_halves`]).
    pub light: crate::solve::light::choose::LightChoice,
    /// Choose [`RunOptions::light`] by the scene ([`scene_light`]): `auto` below
    /// [`LargeMeshSettings::FROM_VERTICES`] vertices when the fit keeps a shiny lobe;
    /// `prior` below it for two or more materials over the Lambertian lobe alone from
    /// [`PRIOR_FROM_PHOTOS`] training photos; else `paper`. Off in [`RunOptions::new`]
    /// (`light` as given); the CLI turns it on unless `--light` is given.
    pub light_by_scene: bool,
    /// Mask transient occluders in the training photos before the estimate
    /// (`super::transients`): a short pilot fit, its residuals' spatially coherent
    /// outliers get weight 0, and each photo's mask is written to `outliers/`. Off by
    /// default: on planted occluders it finds about half of their pixels and moves the
    /// held-out error by 2%, at the cost of two pilot fits (`bench-results/realphoto.md`).
    pub transients: bool,
    /// Down-weight observations near silhouettes and depth edges
    /// ([`crate::observe::margins`], [`crate::observe::DEFAULT_EDGE_MARGIN`]).
    pub edge_margin: bool,
    /// The light prior of held-out protocol (b)'s fit ([`super::half_prior`]): `Auto`
    /// (none, the training maps' shape prior at a weight, or the light model's own prior,
    /// as replaying the protocol on training photos says), `Off` (the Laplacian alone),
    /// `Model` (the light model's own, at [`super::half_prior::MODEL_PRIOR_SCALE`] of its
    /// noise levels) or a fixed weight of the training maps' prior.
    pub half_prior: super::half_prior::HalfPriorMode,
    /// The Laplacian weight of held-out protocol (b)'s fit
    /// ([`super::half_prior::HalfSmoothnessMode`]): `Fit` (the training fit's own) or a
    /// fixed weight.
    pub half_smoothness: super::half_prior::HalfSmoothnessMode,
    /// Groups of photos under one sky for `--light shared` ([`super::light_groups`]); `None`:
    /// by EXIF capture time.
    pub light_groups: Option<std::path::PathBuf>,
    /// Photos taken at most this many minutes apart share a sky when grouped by capture
    /// time (0 = never by time).
    pub light_group_minutes: f64,
    /// Under `--light sky`, fix the sun of each geotagged photo (EXIF GPS place and UTC
    /// time) from the solar position, up to one north for the collection
    /// ([`crate::solve::light::sky::clock`]); `false` searches every sun.
    pub geotag_suns: bool,
    /// Under `--light auto` (and `--loss auto`), the candidates are scored on the right
    /// halves of this many training photos held back whole (the `half` protocol's split),
    /// and the one kept is fitted again with the run's own early stopping; 0 scores the
    /// light models on the early stopping's held-back observations and keeps the robust
    /// loss ([`DEFAULT_LIGHT_CHOICE_HALVES`]).
    pub light_choice_halves: usize,
    /// The per-channel scale anchor between reflectance and light
    /// ([`crate::solve::normalise::ScaleAnchor`]).
    pub scale_anchor: crate::solve::normalise::ScaleAnchor,
}

/// Default of [`RunOptions::light_choice_halves`]: 4 photos' right halves, as
/// `--validation-halves 4` holds back. A free map per photo predicts observations held
/// back at random among its photo's others well whatever the reflectance, so that score
/// kept the paper's map on geotagged sun-and-sky scenes where the sun-and-sky model's
/// held-out error under the true light was 2–11% lower; a whole half of a photo asks the
/// light model to extrapolate (`bench-results/light-choice-halves.md`).
pub const DEFAULT_LIGHT_CHOICE_HALVES: usize = 4;

/// Default of [`RunOptions::light_group_minutes`]: 5 minutes, in which the sun moves
/// about 1.25° and a sky's light changes little unless clouds pass.
pub const DEFAULT_LIGHT_GROUP_MINUTES: f64 = 5.0;

/// Default of [`RunOptions::lighting_sample`]: 2,000 observations per photo. On
/// `spot-varying` at 30K vertices (13 photos of 1 MP, the Minerva model;
/// `bench-results/lighting-sample.md`) the estimate took 5.3× less CPU than with every
/// observation (32.6 against 171.3 s; the run 2.3×, 119.4 against 276.7 s) with held-out
/// error 0.07732 against 0.07711 (+0.3%); 4,000 took 65.7 s at 0.07806 (+1.2%): the error
/// moves by about 1% either way with the sample, not monotonically. Photos with fewer
/// fitted observations (the built-in example, scenes under ~6,000 vertices) are not
/// sampled.
pub const DEFAULT_LIGHTING_SAMPLE: usize = 2000;

/// The lighting sample's check fails (a note in the report says so) when the fit's relative
/// RMSE on the observations outside the samples exceeds this multiple of that inside
/// ([`crate::solve::subsample::SampleCheck`]): a 10% gap is well beyond the sampling noise of a
/// mean square over thousands of observations (`√(2/n)` ≈ 2% at n = 5,000).
pub const LIGHTING_SAMPLE_MAX_RATIO: f64 = 1.1;

impl RunOptions {
    /// The transport's sizes at these options: the global and local map sides and the
    /// Haar coefficients kept per row.
    pub(crate) fn transport_options(&self) -> crate::transport::TransportOptions {
        crate::transport::TransportOptions {
            n_global: self.global_resolution,
            n_local: self.local_resolution,
            keep: self.keep,
        }
    }

    /// Default of [`RunOptions::lighting_qp_iterations`]: the estimator's
    /// ([`EstimateOptions::alternation_qp_iters`], `None` → 0).
    pub fn default_lighting_qp_iterations() -> usize {
        EstimateOptions::default().alternation_qp_iters.unwrap_or(0)
    }
    /// Default of [`RunOptions::lighting_cg_iterations`]: the estimator's
    /// ([`EstimateOptions::alternation_cg_iters`], `None` → 0).
    pub fn default_lighting_cg_iterations() -> usize {
        EstimateOptions::default().alternation_cg_iters.unwrap_or(0)
    }
    /// Default of [`RunOptions::patience`]: outer rounds without a better validation score
    /// after which `run` stops the fit: 3, where the estimator's own default is 1
    /// ([`EstimateOptions::patience`]). The held-back
    /// score can rise for a round or two and then fall below its best: in the light-model
    /// ablation's `defaults` row (`bench-results/ratio-step-directions.md`, section 4) the
    /// diffuse scene stopped at round 6 (synth seed 1) and 4 (seed 2) with patience 1, and
    /// with 3 it ran on to a better round 8: worst albedo ratio error 0.148 → 0.046 and
    /// 0.399 → 0.110, relit 1.16× → 1.12× and 1.81× → 1.29× the Monte Carlo floor
    /// (held-out 1.08× → 1.12× and 1.34× → 1.21×); the glossy and three-material rows
    /// already ran to the cap. Through the CLI only the fits patience 1 stops before the
    /// cap can change (12 of 42 runs of 21 workspaces): 3 moved (held-out under the true
    /// light −1.0%, −2.3%, +0.3%); the real Buddha photos run 2 more rounds for the same
    /// figures (×1.17 wall). The built-in example and every run of the scaling table reach
    /// the cap with patience 1, so their figures and times do not change.
    pub const DEFAULT_PATIENCE: usize = 3;

    /// Default of [`RunOptions::max_iterations`]: outer rounds at most.
    pub const DEFAULT_MAX_ITERATIONS: usize = 8;
    /// Default of [`RunOptions::rel_tol`]: the relative-improvement stop.
    pub const DEFAULT_REL_TOL: f64 = 1e-3;
    /// Default of [`RunOptions::normal_grid`]: the light pre-rotated to `32²` normals
    /// (a `64²` grid gave the ablation's glossy scene nothing more,
    /// `bench-results/normal-grid-floor.md`, section 6).
    pub const DEFAULT_NORMAL_GRID: usize = 32;
    /// Defaults for a workspace (the README says why each default).
    pub fn new(workspace: PathBuf, out: PathBuf) -> Self {
        RunOptions {
            workspace,
            out,
            mesh: None,
            holdout: Holdout::Default,
            up: None,
            materials: MaterialCount::Auto,
            basis: vec![
                BasisBrdf::Lambert,
                BasisBrdf::Phong { exponent: 50.0 },
                BasisBrdf::Phong { exponent: 500.0 },
                BasisBrdf::Ggx { alpha: 0.3 },
            ],
            global_resolution: 64,
            local_resolution: 32,
            render_local_resolution: None,
            normal_grid: Self::DEFAULT_NORMAL_GRID,
            keep: 128,
            blend_tolerance: crate::solve::options::BLEND_TOLERANCE,
            rays_per_texel: 2,
            edge_rays: 4,
            ray_lattice: 1,
            max_iterations: Self::DEFAULT_MAX_ITERATIONS,
            rel_tol: Self::DEFAULT_REL_TOL,
            smoothness: PriorStrength::Auto,
            chroma_smoothness: 0.0,
            irls_iterations: 3,
            loss: crate::solve::loss_choice::LossChoice::Auto,
            lighting_qp_iterations: Self::default_lighting_qp_iterations(),
            lighting_cg_iterations: Self::default_lighting_cg_iterations(),
            patience: Self::DEFAULT_PATIENCE,
            min_iterations: crate::solve::options::MIN_ITERATIONS,
            ratio_steps: RatioSteps::Auto,
            varpro_steps: VarproSteps::Auto,
            lighting_sample: DEFAULT_LIGHTING_SAMPLE,
            starts: 1,
            start_weights: crate::solve::cluster::StartWeights::Clustered,
            start_search: false,
            restart: Restart::Auto,
            start_brightness: StartBrightness::Auto,
            robust_floor: EstimateOptions::default().robust_floor,
            weights_sum: WeightsSum::Auto,
            weights_sum_scope: SumScope::Every,
            weights_smoothness: WeightsSmoothness::Auto,
            weights_bic: PriorStrength::Auto,
            achromatic_specular: Achromatic::Auto,
            validation: EstimateOptions::default().validation_fraction,
            validation_block: 0,
            validation_halves: 0,
            clip: crate::import::photo::DEFAULT_CLIP,
            clipped: Clipped::Auto,
            seed: 1,
            progress: true,
            force: false,
            render_training: true,
            adaptive: false,
            pilot_vertices: crate::solve::adapt::PILOT_MAX_VERTICES,
            large_mesh_auto: false,
            light_by_scene: false,
            light: crate::solve::light::choose::LightChoice::Paper,
            transients: false,
            edge_margin: true,
            half_prior: super::half_prior::HalfPriorMode::Auto,
            half_smoothness: super::half_prior::HalfSmoothnessMode::Fit,
            light_groups: None,
            light_group_minutes: DEFAULT_LIGHT_GROUP_MINUTES,
            geotag_suns: true,
            light_choice_halves: DEFAULT_LIGHT_CHOICE_HALVES,
            scale_anchor: crate::solve::normalise::ScaleAnchor::Start,
        }
    }

    /// Reject impossible values with a message naming the option.
    pub fn check(&self) -> Result<()> {
        self.check_resolutions()?;
        self.check_input()?;
        self.check_model()?;
        self.check_visibility()?;
        self.check_estimator()?;
        Ok(())
    }

    /// The map and grid sides: powers of two in their ranges.
    fn check_resolutions(&self) -> Result<()> {
        let pow2 = |name: &str, v: usize, lo: usize, hi: usize| {
            if v.is_power_of_two() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(Error::Config(format!(
                    "--{name} {v}: must be a power of two from {lo} to {hi}"
                )))
            }
        };
        pow2("global-resolution", self.global_resolution, 4, 256)?;
        pow2("local-resolution", self.local_resolution, 4, 128)?;
        if let Some(n) = self.render_local_resolution {
            pow2("render-local-resolution", n, 4, 128)?;
        }
        pow2("normal-grid", self.normal_grid, 2, 128)?;
        Ok(())
    }

    /// The input flags: the clip level, world up, the held-out rule, the light groups' window.
    fn check_input(&self) -> Result<()> {
        if !(self.clip > 0.0 && self.clip <= 1.0) {
            return Err(Error::Config(format!(
                "--clip {}: must be in (0, 1]",
                self.clip
            )));
        }
        if let Some(up) = self.up {
            if !(up.norm() > 0.0 && up.iter().all(|v| v.is_finite())) {
                return Err(Error::Config(
                    "--up: must be a non-zero finite vector".into(),
                ));
            }
        }
        if let Holdout::Every(0) = self.holdout {
            return Err(Error::Config(
                "--holdout-every 0: must be at least 1".into(),
            ));
        }
        if !(self.light_group_minutes >= 0.0 && self.light_group_minutes.is_finite()) {
            return Err(Error::Config(format!(
                "--light-group-minutes {}: must be a finite number of minutes, 0 or more",
                self.light_group_minutes
            )));
        }
        Ok(())
    }

    /// The model: a basis, a material count from 1 to 32.
    fn check_model(&self) -> Result<()> {
        if self.basis.is_empty() {
            return Err(Error::Config(
                "--basis: at least one basis BRDF is needed".into(),
            ));
        }
        use crate::solve::adapt::{MAX_MATERIALS, PILOT_MIN_VERTICES};
        if self.pilot_vertices != 0 && self.pilot_vertices < PILOT_MIN_VERTICES {
            return Err(Error::Config(format!(
                "--pilot-vertices {}: must be 0 (every vertex) or at least {PILOT_MIN_VERTICES}: the trial fit clusters up to {MAX_MATERIALS} colours and scores held-back observations on that sample",
                self.pilot_vertices
            )));
        }
        if let MaterialCount::Fixed(k) = self.materials {
            if k == 0 || k > 32 {
                return Err(Error::Config(format!(
                    "--materials {k}: must be from 1 to 32, or auto"
                )));
            }
        }
        Ok(())
    }

    /// The visibility rays.
    fn check_visibility(&self) -> Result<()> {
        if self.rays_per_texel == 0 || self.rays_per_texel > 64 {
            return Err(Error::Config(format!(
                "--rays-per-texel {}: must be from 1 to 64",
                self.rays_per_texel
            )));
        }
        if self.edge_rays > 64 {
            return Err(Error::Config(format!(
                "--edge-rays {}: must be from 0 to 64",
                self.edge_rays
            )));
        }
        if !(1..=2).contains(&self.ray_lattice) {
            return Err(Error::Config(format!(
                "--ray-lattice {}: must be 1 or 2",
                self.ray_lattice
            )));
        }
        Ok(())
    }

    /// The estimator: the prior strengths, tolerances, iteration counts and early stopping.
    fn check_estimator(&self) -> Result<()> {
        if let PriorStrength::Fixed(v) = self.smoothness {
            non_negative("--smoothness", v, "")?;
        }
        non_negative("--tolerance", self.rel_tol, "")?;
        if self.max_iterations == 0 {
            return Err(Error::Config(
                "--iterations 0: at least one is needed".into(),
            ));
        }
        if self.irls_iterations == 0 {
            return Err(Error::Config(
                "--irls-iterations 0: at least one (plain least squares) is needed".into(),
            ));
        }
        fraction(
            "--blend-tolerance",
            self.blend_tolerance,
            "a fraction of each row's energy",
        )?;
        fraction(
            "--robust-floor",
            self.robust_floor,
            "a fraction of the RMS radiance",
        )?;
        if let WeightsSum::Fixed(v) = self.weights_sum {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::Config(format!(
                    "--weights-sum {v}: must be auto or a finite number ≥ 0 (0 = off)"
                )));
            }
        } else if self.weights_sum_scope != SumScope::Every {
            return Err(Error::Config(
                "--weights-sum-on blends: give --weights-sum a number too (with auto the pilot chooses where the prior applies)".into(),
            ));
        }
        if let WeightsSmoothness::Fixed(v) = self.weights_smoothness {
            non_negative("--weights-smoothness", v, " (0 = off)")?;
        }
        if let PriorStrength::Fixed(v) = self.weights_bic {
            non_negative("--weights-bic", v, " (0 = off)")?;
        }
        if self.starts == 0 {
            return Err(Error::Config(
                "--starts 0: the alternation needs at least one start".into(),
            ));
        }
        if self.patience == 0 {
            return Err(Error::Config(
                "--patience 0: at least one iteration without improvement must be allowed".into(),
            ));
        }
        if !(0.0..0.5).contains(&self.validation) {
            return Err(Error::Config(format!(
                "--validation {}: the held-back fraction must be in [0, 0.5) (0 turns early \
                 stopping off)",
                self.validation
            )));
        }
        Ok(())
    }
}

/// `Ok` when `v` is a finite number ≥ 0; else the error naming `flag` and `v`, with `note`
/// after the rule.
fn non_negative(flag: &str, v: f64, note: &str) -> Result<()> {
    if v >= 0.0 && v.is_finite() {
        return Ok(());
    }
    Err(Error::Config(format!(
        "{flag} {v}: must be a finite number ≥ 0{note}"
    )))
}

/// `Ok` when `v` is in `[0, 1)`; else the error naming `flag` and `v`, and `what` the
/// fraction is of.
fn fraction(flag: &str, v: f64, what: &str) -> Result<()> {
    if (0.0..1.0).contains(&v) {
        return Ok(());
    }
    Err(Error::Config(format!(
        "{flag} {v}: must be in [0, 1) ({what})"
    )))
}

/// What the fit does with an overexposed observation's clipped channels (`--clipped`,
/// docs/method.md, "Clipped channels as lower bounds").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clipped {
    /// `Bound` when at least [`CLIPPED_AUTO_SHARE`] of the training observations have a
    /// clipped channel, else `Drop` (the run resolves it after extracting them).
    Auto,
    /// Left out, as in the paper.
    Drop,
    /// Clipped channels read as lower bounds, the others as values
    /// ([`crate::solve::EstimateOptions::clipped_bounds`]).
    Bound,
}

impl Clipped {
    /// Parse `auto`, `drop` or `bound`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "auto" => Ok(Clipped::Auto),
            "drop" => Ok(Clipped::Drop),
            "bound" => Ok(Clipped::Bound),
            other => Err(Error::Config(format!(
                "--clipped {other}: expected `auto`, `drop` or `bound`"
            ))),
        }
    }
}

/// The share of the training observations with a clipped channel from which
/// [`Clipped::Auto`] reads them as bounds (`bench-results/clipped-bounds.md`): on rendered
/// Spots, dropping them chose the wrong material count on every run from 25% clipped on
/// and on none at 17% or below.
pub const CLIPPED_AUTO_SHARE: f64 = 0.2;
