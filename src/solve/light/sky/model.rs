//! [`SkyLight`]: the sun-and-sky light model as a [`LightModel`] (the math in the parent
//! module's docs). Photos are fitted in parallel, largest first; each fit is sequential,
//! so results do not depend on the thread count. Geotagged photos share one thing: the
//! frame azimuth of north, chosen before the photos' steps from their summed search errors
//! (each photo's profile over the candidates computed in parallel, summed in photo order). The model fits by plain
//! least squares (its IRLS weights are 1) on all of a photo's observations (no lighting
//! sample); clipped channels read as lower bounds, when asked, have weight 0 where the
//! light a pass starts at already meets them ([`SkyLight::bound_weights`], the one-sided
//! term of [`crate::solve::light::bounds`]).

// Kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use std::borrow::Cow;
use std::sync::Arc;

use super::clock::ClockSun;
use super::search::{Candidate, SearchData, ALL_FREE, SUN_FIXED};
use super::summary::{SkyFit, SkyPhotoFit};
use joint::{split_joint, JointQp};
pub(super) use mix::combine_photo;
use north::clock_theta;

mod joint;
mod mix;
mod north;
use super::{
    coefficient_scales, residual_penalty, residual_weights, SkyBasis, SunSky, N_BASIS, SUB_TEXELS,
};
use crate::solve::light::bounds::{censor, clipped_in};
use crate::solve::light::sh_prior::LightPrior;
use crate::solve::light::system::{texel_diag_vec, PhotoSystem};
use crate::solve::light::{LightModel, LightingInput, LightingOutput};
use crate::solve::options::EstimateOptions;
use crate::solve::problem::{haar3, par_largest_first, Problem};
use crate::solve::qp::QpResult;
use crate::{Error, Result};

/// Relative noise level `η` of the residual's prior by default (`σ = η · rms(y)`).
/// Measured on `spot-sky` (`bench-results/estimator-sky.md`), held-out error against the
/// photos: 0.257 (η = 0.1), 0.249 (η = 1) on 8-bit photos; noise-free, against the true
/// model, 0.151 (η = 1), 0.154 (η = 10).
pub const SKY_RESIDUAL_NOISE: f64 = 1.0;
/// Turbidity and lobe sharpness of the first step's grid.
const GRID_TURBIDITY: f64 = 3.0;
const GRID_KAPPA: f64 = 64.0;
/// Pattern-search steps `(azimuth, elevation, ln κ, T)` after the grid (half its spacing)
/// and warm-started from the previous outer iteration.
const FIRST_STEPS: [f64; 4] = [0.16, 0.16, 1.0, 2.0];
const WARM_STEPS: [f64; 4] = [0.04, 0.04, 0.25, 0.5];
/// The search ends when its angular step is below 0.25°.
const MIN_ANGLE: f64 = 0.25 * std::f64::consts::PI / 180.0;
/// Evaluation caps of the first and of a warm-started search.
const FIRST_EVALS: usize = 200;
const WARM_EVALS: usize = 60;
/// Outer iterations through which the grid is searched again (the materials move most
/// early on, and a sun found under the starting materials may be a wrong local minimum);
/// the better of the grid's best and the previous `θ` is refined.
const REGRID_ITERATIONS: usize = 3;
/// Most passes of a photo's step when clipped channels are read as bounds: each pass
/// re-reads which bounds its start meets, as the paper's map does before each of its
/// IRLS passes ([`crate::solve::light::bounds`]).
const BOUND_PASSES: usize = 3;

/// Options of the sun-and-sky model ([`EstimateOptions::light_sky`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SkyOptions {
    /// `η` of the residual's prior (`σ = η · rms(y)`); larger keeps the map closer to the
    /// parametric sky.
    pub residual_noise: f64,
}

impl Default for SkyOptions {
    fn default() -> Self {
        SkyOptions {
            residual_noise: SKY_RESIDUAL_NOISE,
        }
    }
}

/// One photo's sun-and-sky parameters.
#[derive(Debug, Clone)]
pub struct SkyPhoto {
    /// The non-linear values.
    pub theta: SunSky,
    /// The bases at `theta`.
    pub basis: Arc<SkyBasis>,
    /// `w_{j,c}`, `≥ 0`.
    pub weights: [[f64; 3]; N_BASIS],
    /// The residual's texels per channel, `≥ 0`.
    pub residual: [Vec<f64>; 3],
}

impl SkyPhoto {
    /// The map: `Σ_j w_{j,c} B_{j,c} + r_c`.
    pub fn map(&self) -> [Vec<f64>; 3] {
        let mut m = self.basis.combine(&self.weights);
        for (mc, rc) in m.iter_mut().zip(&self.residual) {
            mc.iter_mut().zip(rc).for_each(|(a, b)| *a += b);
        }
        m
    }
}

/// The residual prior's state of one photo: `σ²` and the light's scale `h_{0,c}`.
#[derive(Debug, Clone, Copy, Default)]
struct ResidualScale {
    sigma2: f64,
    h0: [f64; 3],
}

/// The sun-and-sky light model (module docs).
pub struct SkyLight {
    params: Vec<SkyPhoto>,
    scale: Vec<Option<ResidualScale>>,
    /// Whether a photo's `θ` was searched (its next search is warm-started).
    searched: Vec<bool>,
    /// Per photo, its sun from its geotag ([`super::clock`]); empty without geotags.
    clock: Vec<Option<ClockSun>>,
    /// The frame azimuth of north `ν` found from the geotagged photos.
    north: Option<f64>,
    /// Whether `north` was given ([`SkyLight::fix_north`]) rather than searched.
    north_fixed: bool,
    /// Whether the lighting steps keep every searched `θ` and north
    /// ([`LightModel::hold_shape`]: the ratio step's probes).
    hold: bool,
    /// `b_k` per Haar coefficient.
    b: Vec<f64>,
    opts: EstimateOptions,
    sky: SkyOptions,
    /// QP caps inside the alternation (as for the paper's map).
    qp_max_iter: usize,
    qp_max_cg: usize,
}

impl SkyLight {
    /// Zero light for every photo of `problem` (sun at the zenith, every weight 0).
    pub fn new(problem: &Problem, opts: &EstimateOptions, sky: &SkyOptions) -> Result<Self> {
        let n = problem.transport.n_global;
        let prior = LightPrior::builtin()?;
        let scales = prior.haar_scales(n).ok_or_else(|| {
            Error::Config(format!(
                "--light sky: no wavelet statistics for a {n}² global map (sides 4 to 128, powers of two)"
            ))
        })?;
        let b = coefficient_scales(n, scales);
        let theta = SunSky {
            sun: crate::Vec3::z(),
            turbidity: GRID_TURBIDITY,
            kappa: GRID_KAPPA,
        };
        let basis = Arc::new(SkyBasis::new(n, SUB_TEXELS, &theta)?);
        let zero = SkyPhoto {
            theta,
            basis,
            weights: [[0.0; 3]; N_BASIS],
            residual: std::array::from_fn(|_| vec![0.0; n * n]),
        };
        let lighting = opts.alternation_lighting();
        let clock = match &opts.sun_clock {
            Some(c) if c.per_photo.len() != problem.n_photos => {
                return Err(Error::Internal(format!(
                    "sun-and-sky model: {} geotag suns for {} photos",
                    c.per_photo.len(),
                    problem.n_photos
                )))
            }
            Some(c) => c.per_photo.clone(),
            None => Vec::new(),
        };
        Ok(SkyLight {
            params: vec![zero; problem.n_photos],
            scale: vec![None; problem.n_photos],
            searched: vec![false; problem.n_photos],
            clock,
            north: None,
            north_fixed: false,
            hold: false,
            b,
            opts: opts.clone(),
            sky: sky.clone(),
            qp_max_iter: lighting.qp_max_iter,
            qp_max_cg: lighting.qp_max_cg,
        })
    }

    /// The recovered `θ` per photo.
    pub fn thetas(&self) -> Vec<SunSky> {
        self.params.iter().map(|p| p.theta).collect()
    }

    /// The frame azimuth of north found from the geotagged photos (radians; `None`
    /// without geotags or before the first lighting step).
    pub fn north(&self) -> Option<f64> {
        self.north
    }

    /// Holds north at frame azimuth `north` instead of searching it: a held-out photo's
    /// fit under the training collection's north ([`super::held_out`]).
    pub fn fix_north(&mut self, north: f64) {
        self.north = Some(north);
        self.north_fixed = true;
    }

    /// Photo `photo`'s geotag sun, if it has one.
    fn clock_sun(&self, photo: usize) -> Option<ClockSun> {
        self.clock.get(photo).copied().flatten()
    }
}

/// One photo's lighting step result.
struct PhotoFit {
    photo: SkyPhoto,
    scale: ResidualScale,
    qp: Option<QpResult>,
    /// The data weights `ω` of the photo's observations the pass read: 1, or 0 on a
    /// clipped channel whose bound the light it started at met ([`SkyLight::bound_weights`]).
    omega: Vec<[f64; 3]>,
}

/// What every pass of a photo's step reads ([`SkyLight::fit_pass`]).
#[derive(Clone, Copy)]
struct PassInput<'a> {
    problem: &'a Problem<'a>,
    rows: &'a Rows,
    /// The texel-basis diagonal of the data term (`α`, without `ω`): the same for every
    /// pass, the joint QP's Jacobi scaling ([`texel_diag_vec`]).
    tdiag: &'a [[f64; 3]],
    photo: usize,
    outer_iteration: usize,
}

/// The photo's observations as the step reads them.
struct Rows {
    range: std::ops::Range<usize>,
    alpha: Vec<f64>,
    y: Vec<[f64; 3]>,
    /// The channels read as lower bounds, or empty ([`clipped_in`]).
    clipped: Vec<u8>,
}

impl Rows {
    fn new(problem: &Problem, photo: usize) -> Self {
        let range = problem.obs.photo_ranges[photo].clone();
        let o = problem.obs;
        Rows {
            alpha: range.clone().map(|p| o.weight[p] as f64).collect(),
            y: range.clone().map(|p| o.rgb[p].map(f64::from)).collect(),
            clipped: clipped_in(o, range.clone()),
            range,
        }
    }

    /// The α-weighted mean square radiance.
    fn mean_square(&self) -> f64 {
        let (mut num, mut den) = (0.0, 0.0);
        for (a, y) in self.alpha.iter().zip(&self.y) {
            num += a * (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]) / 3.0;
            den += a;
        }
        if den > 0.0 {
            num / den
        } else {
            0.0
        }
    }
}

impl SkyLight {
    /// One photo's lighting step: the `θ` search with the residual fixed, the residual
    /// prior at the current light's scale, then the joint QP over the sky's colour weights
    /// and the residual ([`Self::fit_pass`]). With clipped channels read as bounds the step
    /// makes up to [`BOUND_PASSES`] passes, each with the bounds its start meets left out
    /// ([`Self::bound_weights`]): the first from the previous light, the next from the pass
    /// before, until that set stops changing.
    fn fit_photo(
        &self,
        problem: &Problem,
        beta: &[[f64; 3]],
        photo: usize,
        outer_iteration: usize,
    ) -> Result<PhotoFit> {
        let rows = Rows::new(problem, photo);
        let mut sys = self.photo_system(problem, beta, &rows);
        let omega = self.bound_weights(&sys, &rows, &self.params[photo]);
        let tdiag = texel_diag_vec(problem, beta, rows.range.clone(), &rows.alpha);
        let pass = PassInput {
            problem,
            rows: &rows,
            tdiag: &tdiag,
            photo,
            outer_iteration,
        };
        let mut fit = self.fit_pass(&pass, &mut sys, omega)?;
        let passes = if rows.clipped.is_empty() {
            1
        } else {
            BOUND_PASSES
        };
        for _ in 1..passes {
            let next = self.bound_weights(&sys, &rows, &fit.photo);
            if next == fit.omega {
                break;
            }
            fit = self.fit_pass(&pass, &mut sys, next)?;
        }
        Ok(fit)
    }

    /// One pass of the photo's step with the data weights `α ω` (kept in its result); the
    /// search and the QP start from the previous outer iteration's light whichever pass
    /// it is.
    fn fit_pass(
        &self,
        pass: &PassInput,
        sys: &mut PhotoSystem,
        omega: Vec<[f64; 3]>,
    ) -> Result<PhotoFit> {
        let PassInput {
            problem,
            rows,
            tdiag,
            photo,
            outer_iteration,
        } = *pass;
        let n = problem.transport.n_global;
        let prev = &self.params[photo];
        for (q, (d, o)) in sys.dw.iter_mut().zip(&omega).enumerate() {
            *d = o.map(|v| v * rows.alpha[q]);
        }
        let best = self.search_theta(sys, rows, photo, outer_iteration)?;
        let basis = best.basis();
        let (scale, d) = self.residual_prior(&best, &basis, prev, rows, n);
        let qp = JointQp {
            sys,
            basis: &basis,
            d,
        };
        let qp_result = self.joint_qp(&qp, rows, &best, photo, tdiag)?;
        let (weights, residual) = split_joint(qp_result.as_ref(), n);
        Ok(PhotoFit {
            photo: SkyPhoto {
                theta: best.theta,
                basis: Arc::new(basis),
                weights,
                residual,
            },
            scale,
            qp: qp_result,
            omega,
        })
    }

    /// The data weights `ω` of the photo's observations: 1, and 0 on each clipped channel
    /// whose bound the light `start` already meets at the current materials ([`censor`]);
    /// a pass then fits the squared hinge on the bounds still active. A zero light meets
    /// no bound.
    fn bound_weights(&self, sys: &PhotoSystem, rows: &Rows, start: &SkyPhoto) -> Vec<[f64; 3]> {
        let mut omega = vec![[1.0; 3]; rows.y.len()];
        let lit = start.weights.iter().flatten().any(|&w| w != 0.0)
            || start.residual.iter().flatten().any(|&r| r != 0.0);
        if rows.clipped.is_empty() || !lit {
            return omega;
        }
        let mut pred = vec![[0.0; 3]; rows.y.len()];
        sys.forward_rows(&haar3(&start.map(), sys.n), &mut pred);
        censor(&rows.clipped, &rows.y, &pred, &mut omega);
        omega
    }

    /// The photo's lighting system at the materials `beta` (its rows weighted by `α`).
    fn photo_system(&self, problem: &Problem, beta: &[[f64; 3]], rows: &Rows) -> PhotoSystem {
        let dw: Vec<[f64; 3]> = rows.alpha.iter().map(|&a| [a; 3]).collect();
        PhotoSystem::new(
            problem,
            beta,
            rows.range.clone(),
            problem.transport.n_global,
            dw,
            self.opts.blend_tolerance,
        )
    }

    /// The targets of the `θ` search: the observations less the previous residual's
    /// prediction.
    fn search_target(&self, sys: &PhotoSystem, rows: &Rows, photo: usize) -> Vec<[f64; 3]> {
        let mut resid_pred = vec![[0.0; 3]; rows.y.len()];
        sys.forward_rows(&haar3(&self.params[photo].residual, sys.n), &mut resid_pred);
        rows.y
            .iter()
            .zip(&resid_pred)
            .map(|(y, r)| [0, 1, 2].map(|c| y[c] - r[c]))
            .collect()
    }

    /// Step 1, `θ` (sun direction, turbidity, sun lobe) with the residual fixed. A photo
    /// with a geotag sun takes its direction at the collection's north and searches only
    /// the turbidity and the lobe. Otherwise: from the previous `θ` (and a fresh grid in
    /// the first [`REGRID_ITERATIONS`] iterations, kept when better), or from the grid at
    /// the photo's first step, then refined.
    fn search_theta(
        &self,
        sys: &PhotoSystem,
        rows: &Rows,
        photo: usize,
        outer_iteration: usize,
    ) -> Result<Candidate> {
        let prev = &self.params[photo];
        let target = self.search_target(sys, rows, photo);
        let search = SearchData::new(sys, &target);
        if self.hold && self.searched[photo] {
            return search.evaluate(prev.theta);
        }
        if let (Some(sun), Some(north)) = (self.clock_sun(photo), self.north) {
            let start = search.evaluate(clock_theta(sun, north, &prev.theta))?;
            let steps = if self.searched[photo] {
                WARM_STEPS
            } else {
                FIRST_STEPS
            };
            return search.refine(start, steps, SUN_FIXED, MIN_ANGLE, FIRST_EVALS);
        }
        if !self.searched[photo] {
            let start = search.grid(GRID_TURBIDITY, GRID_KAPPA)?;
            return search.refine(start, FIRST_STEPS, ALL_FREE, MIN_ANGLE, FIRST_EVALS);
        }
        let warm = search.evaluate(prev.theta)?;
        let grid = if outer_iteration <= REGRID_ITERATIONS {
            Some(search.grid(GRID_TURBIDITY, GRID_KAPPA)?)
        } else {
            None
        };
        match grid {
            Some(g) if g.sse < warm.sse => {
                search.refine(g, FIRST_STEPS, ALL_FREE, MIN_ANGLE, FIRST_EVALS)
            }
            _ => search.refine(warm, WARM_STEPS, ALL_FREE, MIN_ANGLE, WARM_EVALS),
        }
    }

    /// Step 2, the residual prior at the current light's scale: `σ²` from the photo's mean
    /// square, `h0` the total light's mean per channel, and the per-coefficient weights
    /// `d` ([`residual_weights`]); `basis` is `best`'s ([`Candidate::basis`]).
    fn residual_prior(
        &self,
        best: &Candidate,
        basis: &SkyBasis,
        prev: &SkyPhoto,
        rows: &Rows,
        n: usize,
    ) -> (ResidualScale, [Vec<f64>; 3]) {
        let sigma2 = self.sky.residual_noise.powi(2) * rows.mean_square();
        let mut total = basis.combine(&best.weights);
        for (t, r) in total.iter_mut().zip(&prev.residual) {
            t.iter_mut().zip(r).for_each(|(a, b)| *a += b);
        }
        let h0_all = haar3(&total, n)[0];
        let h0_max = h0_all.iter().fold(0.0_f64, |a, &v| a.max(v));
        let h0 = h0_all.map(|v| v.max(1e-9 * h0_max).max(f64::MIN_POSITIVE));
        let hr = haar3(&prev.residual, n);
        let d: [Vec<f64>; 3] = std::array::from_fn(|c| {
            let hc: Vec<f64> = hr.iter().map(|v| v[c]).collect();
            residual_weights(&hc, h0[c], &self.b, sigma2)
        });
        (ResidualScale { sigma2, h0 }, d)
    }
}

impl LightModel for SkyLight {
    type Params = Vec<SkyPhoto>;

    fn name(&self) -> &'static str {
        "sky: Hosek–Wilkie sky + sun lobe + ground per photo, penalised wavelet residual"
    }

    fn parameter_count(&self) -> usize {
        self.params
            .iter()
            .map(|p| 4 + 3 * N_BASIS + p.residual.iter().map(Vec::len).sum::<usize>())
            .sum()
    }

    fn sky_fit(&self) -> Option<SkyFit> {
        let photos = self
            .params
            .iter()
            .enumerate()
            .map(|(i, p)| SkyPhotoFit {
                theta: p.theta,
                from_clock: self.north.is_some() && self.clock_sun(i).is_some(),
            })
            .collect();
        Some(SkyFit {
            photos,
            north: self.north,
        })
    }

    fn fit(&mut self, input: &LightingInput, out: &mut LightingOutput) -> Result<()> {
        let problem = input.problem;
        if !self.hold {
            self.update_north(problem, input.beta, input.outer_iteration)?;
        }
        let sizes: Vec<usize> = problem.obs.photo_ranges.iter().map(|r| r.len()).collect();
        let results: Vec<Result<PhotoFit>> = par_largest_first(&sizes, |i| {
            self.fit_photo(problem, input.beta, i, input.outer_iteration)
        });
        let cond = &mut *out.conditioning;
        cond.lighting.clear();
        cond.qp_unconverged = 0;
        cond.qp_alternation_capped = 0;
        for (i, r) in results.into_iter().enumerate() {
            let fit = r?;
            let range = problem.obs.photo_ranges[i].clone();
            for (o, w) in out.irls_weights[range].iter_mut().zip(&fit.omega) {
                *o = w.map(|v| v as f32);
            }
            if let Some(res) = &fit.qp {
                cond.lighting.push(res.cond_lower_bound);
                cond.qp_unconverged += usize::from(!res.converged);
                cond.lighting_matvecs += res.matvecs;
                cond.lighting_qps += 1;
                cond.lighting_matvecs_max = cond.lighting_matvecs_max.max(res.matvecs);
                if self.qp_max_iter < self.opts.qp_max_iter {
                    cond.qp_alternation_capped += usize::from(!res.converged);
                }
            }
            self.params[i] = fit.photo;
            self.scale[i] = Some(fit.scale);
            self.searched[i] = true;
        }
        Ok(())
    }

    fn params(&self) -> &Vec<SkyPhoto> {
        &self.params
    }

    fn set_params(&mut self, params: Vec<SkyPhoto>) {
        self.params = params;
    }

    fn maps<'a>(&'a self, params: &'a Vec<SkyPhoto>) -> Cow<'a, [[Vec<f64>; 3]]> {
        Cow::Owned(params.iter().map(SkyPhoto::map).collect())
    }

    fn penalty(&self, params: &Vec<SkyPhoto>) -> f64 {
        self.residual_penalties(params).iter().sum()
    }

    fn channel_penalty(&self, params: &Vec<SkyPhoto>) -> Option<[f64; 3]> {
        Some(self.residual_penalties(params))
    }

    /// Holds every searched `θ` and the north (the `θ` search and `update_north` skip).
    fn hold_shape(&mut self, hold: bool) {
        self.hold = hold;
    }

    /// Per photo, the parts' colour weights and residuals each mixed per channel with the
    /// weights, projected on `≥ 0`. The ratio step's probes hold every `θ`
    /// ([`LightModel::hold_shape`]), and the map is linear in (weights, residual) at fixed
    /// `θ`, so the mix is the parts' maps mixed (before the projection); the step keeps
    /// it only where `F` drops. Where the parts' `θ` differ after all (a photo not yet
    /// searched), the photo takes the light of the part with the largest weight.
    fn combine(&self, parts: &[(&Vec<SkyPhoto>, [f64; 3])]) -> Option<Vec<SkyPhoto>> {
        let photos = parts.first()?.0.len();
        Some((0..photos).map(|i| combine_photo(parts, i)).collect())
    }

    fn extrapolate(
        &self,
        params: &Vec<SkyPhoto>,
        prev: &Vec<SkyPhoto>,
        sigma: f64,
    ) -> Vec<SkyPhoto> {
        let ext = |a: f64, b: f64| (a + sigma * (a - b)).max(0.0);
        params
            .iter()
            .zip(prev)
            .map(|(p, q)| {
                let mut e = p.clone();
                for j in 0..N_BASIS {
                    for c in 0..3 {
                        e.weights[j][c] = ext(p.weights[j][c], q.weights[j][c]);
                    }
                }
                for c in 0..3 {
                    for (v, w) in e.residual[c].iter_mut().zip(&q.residual[c]) {
                        *v = ext(*v, *w);
                    }
                }
                e
            })
            .collect()
    }

    fn divide_channel(&mut self, c: usize, f: f64) {
        for p in self.params.iter_mut() {
            p.weights.iter_mut().for_each(|w| w[c] /= f);
            p.residual[c].iter_mut().for_each(|v| *v /= f);
        }
        for s in self.scale.iter_mut().flatten() {
            s.h0[c] /= f;
        }
    }

    fn normalise(&mut self, s: f64) {
        for c in 0..3 {
            self.divide_channel(c, s);
        }
    }

    fn prior_weights(&self) -> Vec<[f64; 3]> {
        vec![[0.0; 3]; self.params.len()]
    }

    fn into_maps(self) -> Vec<[Vec<f64>; 3]> {
        self.params.iter().map(SkyPhoto::map).collect()
    }
}
