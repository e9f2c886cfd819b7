//! What the estimator returns: the fitted lights and materials ([`Estimate`]), its log per
//! outer iteration ([`Iteration`]), the conditioning of the systems it solved, early
//! stopping's record, and the starting materials it takes ([`Materials0`]).

/// One outer iteration's log line.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Iteration {
    /// Seconds since the estimation started.
    pub seconds: f64,
    /// Objective `F` (module docs) after the iteration, IRLS weights of its lighting step.
    pub objective: f64,
    /// RMSE over observations with `α > 0` and channels, unweighted, linear RGB (the
    /// fitted observations: validation ones excluded).
    pub train_rmse: f64,
    /// Early stopping's score of this iterate ([`Validation`]), when on.
    pub validation_rel: Option<f64>,
    /// What this iteration's lighting and material steps cost.
    #[serde(flatten)]
    pub steps: StepTimes,
}

/// Wall and CPU seconds (all threads, [`crate::stages::Stopwatch`]) of the lighting step
/// (Eq. 10, every photo) and the material step (Eq. 11–12, with the basis responses) of
/// one outer iteration, or summed over several; the rest of an iteration is the
/// objective, extrapolation and early stopping.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct StepTimes {
    /// Lighting step, wall seconds.
    pub lighting_seconds: f64,
    /// Lighting step, CPU seconds.
    pub lighting_cpu_seconds: f64,
    /// Material step, wall seconds.
    pub material_seconds: f64,
    /// Material step, CPU seconds.
    pub material_cpu_seconds: f64,
}

impl std::ops::AddAssign for StepTimes {
    fn add_assign(&mut self, o: Self) {
        self.lighting_seconds += o.lighting_seconds;
        self.lighting_cpu_seconds += o.lighting_cpu_seconds;
        self.material_seconds += o.material_seconds;
        self.material_cpu_seconds += o.material_cpu_seconds;
    }
}

impl std::iter::Sum for StepTimes {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(StepTimes::default(), |mut a, t| {
            a += t;
            a
        })
    }
}

/// Early stopping's record ([`crate::solve::EstimateOptions::validation_fraction`]).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Validation {
    /// Observations left out of the fit and scored.
    pub observations: usize,
    /// Fraction asked for.
    pub fraction: f64,
    /// Per outer iteration: `sqrt(Σ α (y − ŷ)²) / sqrt(Σ α y²)` over the validation
    /// observations and channels.
    pub errors: Vec<f64>,
    /// The iterate returned (1-based outer iteration, the lowest error).
    pub best_iteration: usize,
    /// Whether the loop ended by patience (no lower error for `patience` iterations).
    pub stopped_early: bool,
}

impl Validation {
    /// The validation error of the iterate returned, `errors[best_iteration − 1]`.
    pub fn best_error(&self) -> f64 {
        self.errors[self.best_iteration - 1]
    }
}

/// Starting materials: `λ` (`K × B`, per channel) and blending weights `w` (`V × K`).
#[derive(Debug, Clone)]
pub struct Materials0 {
    /// `lambda[k][b][c]`.
    pub lambda: Vec<Vec<[f64; 3]>>,
    /// Row-major `V × K`.
    pub weights: Vec<f64>,
}

impl Materials0 {
    /// From clustered initial materials: the median colour as the Lambertian weight
    /// (basis `lambert_basis`), every other basis 0 (paper Sec. 5.2).
    pub fn from_initial(
        init: &crate::solve::cluster::InitialMaterials,
        n_basis: usize,
        lambert_basis: usize,
    ) -> Self {
        let lambda = init
            .albedo
            .iter()
            .map(|a| {
                let mut row = vec![[0.0; 3]; n_basis];
                if lambert_basis < n_basis {
                    row[lambert_basis] = *a;
                }
                row
            })
            .collect();
        Materials0 {
            lambda,
            weights: init.weights.clone(),
        }
    }
}

/// Condition-number figures of the systems solved (issue 8).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Conditioning {
    /// Per photo: lower bound on the lighting system's condition number (Ritz values of
    /// the GPCG runs, three channels together), from the last lighting step.
    pub lighting: Vec<f64>,
    /// Per channel: condition number of the last λ system (with ridge), exact.
    pub lambda: [f64; 3],
    /// Largest condition number over the last w systems with a full-rank normal matrix.
    pub weights_max: f64,
    /// How many vertices' w systems were singular (fewer independent rows than materials).
    pub weights_singular: usize,
    /// Lighting QPs that hit the iteration cap before the KKT tolerance.
    pub qp_unconverged: usize,
    /// Lighting QPs (photo × IRLS pass) of the last lighting step that stopped at the
    /// alternation's cap ([`crate::solve::EstimateOptions::alternation_qp_iters`]), by design.
    pub qp_alternation_capped: usize,
    /// Lighting QPs solved so far (photos × IRLS passes × outer iterations).
    pub lighting_qps: usize,
    /// Most Hessian products of one lighting QP so far.
    pub lighting_matvecs_max: usize,
    /// Hessian products of all lighting QPs so far (the lighting step's cost unit).
    pub lighting_matvecs: usize,
}

impl Conditioning {
    /// The largest finite lighting bound over the photos (`None` when no photo has one).
    pub fn lighting_max(&self) -> Option<f64> {
        self.lighting
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .reduce(f64::max)
    }
}

/// The estimation result.
#[derive(Debug, Clone)]
pub struct Estimate {
    /// Per photo, per channel: the texels of the `n_global²` global octahedral map, `≥ 0`.
    pub lights: Vec<[Vec<f64>; 3]>,
    /// `lambda[k][b][c] ≥ 0`.
    pub lambda: Vec<Vec<[f64; 3]>>,
    /// Row-major `V × K`, `≥ 0`.
    pub weights: Vec<f64>,
    /// One entry per outer iteration.
    pub timeline: Vec<Iteration>,
    /// The scale normalisation applied, in words.
    pub normalisation: String,
    /// Laplacian weights `μ_{I,c}` used (after normalisation's rescaling).
    pub mu: Vec<[f64; 3]>,
    /// Final IRLS weights per observation and channel (1 without robust loss).
    pub irls_weights: Vec<[f32; 3]>,
    /// Conditioning of the systems.
    pub conditioning: Conditioning,
    /// Early stopping's record, when on.
    pub validation: Option<Validation>,
    /// The lighting sample's check, when a photo's lighting step used a sample
    /// ([`crate::solve::EstimateOptions::lighting_sample`]).
    pub lighting_sample: Option<crate::solve::subsample::SampleCheck>,
    /// The ratio step's record ([`crate::solve::ratio_step`]).
    pub ratio_moves: RatioMoves,
    /// The variable-projection step's record ([`crate::solve::varpro_step`]; its
    /// `stopped_after` unused).
    pub varpro_moves: RatioMoves,
    /// Each photo's recovered sun and sky under the sun-and-sky model
    /// ([`crate::solve::light::sky`]); `None` under another light model.
    pub sky: Option<crate::solve::light::sky::summary::SkyFit>,
}

/// What the ratio step did over the alternation ([`crate::solve::ratio_step`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct RatioMoves {
    /// Moves tried (directions × rounds that took the step).
    pub tried: usize,
    /// Moves kept (`F` dropped and the held-back observations did not get worse).
    pub kept: usize,
    /// Rounds asked for in which the light model could not take the step (its channels
    /// not separable, or its parameters not mixable).
    pub unsupported: usize,
    /// The round after which the step stopped because [`crate::solve::ratio_step::PATIENCE`]
    /// rounds in a row kept no move (`None`: it ran every round asked for).
    pub stopped_after: Option<usize>,
}

impl Estimate {
    /// Early stopping's validation error of the iterate returned
    /// ([`Validation::best_error`]); NaN without validation.
    pub fn validation_error(&self) -> f64 {
        self.validation
            .as_ref()
            .map_or(f64::NAN, Validation::best_error)
    }

    /// The iterate returned, counted from 1: early stopping's best one
    /// ([`Validation::best_iteration`]), else the last of the timeline.
    pub fn kept_iteration(&self) -> usize {
        self.validation
            .as_ref()
            .map_or(self.timeline.len(), |v| v.best_iteration)
    }

    /// An estimate holding only `lights`, `lambda` and `weights`, with no record of a fit
    /// (empty timeline, no validation): for predicting with given reflectance and light.
    pub fn from_parts(
        lights: Vec<[Vec<f64>; 3]>,
        lambda: Vec<Vec<[f64; 3]>>,
        weights: Vec<f64>,
    ) -> Estimate {
        Estimate {
            lights,
            lambda,
            weights,
            timeline: Vec::new(),
            normalisation: String::new(),
            mu: Vec::new(),
            irls_weights: Vec::new(),
            conditioning: Default::default(),
            validation: None,
            lighting_sample: None,
            ratio_moves: RatioMoves::default(),
            varpro_moves: RatioMoves::default(),
            sky: None,
        }
    }
}

/// The state after an outer iteration (before the final normalisation), for callers that
/// evaluate it as it goes, e.g. the held-out error against run time.
pub struct IterState<'a> {
    /// Per photo and channel, the map texels.
    pub lights: &'a [[Vec<f64>; 3]],
    /// `lambda[k][b][c]`.
    pub lambda: &'a [Vec<[f64; 3]>],
    /// Row-major `V × K`.
    pub weights: &'a [f64],
}
