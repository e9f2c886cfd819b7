//! The estimator (paper Sec. 5): per-photo illumination and per-vertex materials by
//! alternating non-negative solves of the objective (Eq. 9)
//!
//! `F = Σ_p Σ_c α_p ω_{p,c} (y_{p,c} − Σ_b β_{x,b,c} ⟨g_{p,b}, W x_{I,c}⟩)²
//!      + Σ_{I,c} μ_{I,c} ‖Δ x_{I,c}‖² + β_λ ‖λ‖²`,
//!
//! with `β_{x,b,c} = Σ_k w_k(x) λ_{k,b,c}` (Eq. 11), `x_{I,c}` the texels of photo `I`'s
//! global octahedral map in channel `c` (`W` = [`crate::haar::forward`], orthonormal, so
//! `⟨g, W x⟩ = ⟨Wᵀ g, x⟩`), `Δ` the 4-neighbour graph Laplacian of the map across its folded
//! seams ([`crate::sphere::SphereGrid::neighbors`]), `ω` the IRLS weights (1 without a
//! robust loss). Every unknown is constrained `≥ 0`: texels, `λ`, `w`.
//!
//! 1. Lighting step (Sec. 5.1, Eq. 10), per photo, the three channels together:
//!    `min_x ½ xᵀ(Wᵀ Aᵀ D A W + μ ΔᵀΔ) x − (Wᵀ Aᵀ D y)ᵀ x`, `x ≥ 0`, solved matrix-free by
//!    [`crate::qp::bound_qp`]: one product is a forward Haar, a pass over the photo's sparse
//!    transport rows and back (`Aᵀ`), an inverse Haar and the Laplacian twice. `μ_{I,c}` =
//!    `smoothness` × the largest diagonal entry of `Aᵀ D A` (in the Haar basis), fixed at
//!    the photo's first lighting step. IRLS (Huber or Tukey on residuals scaled by
//!    `σ = max(1.4826 · MAD, robust_floor · rms(y))` per photo and channel, the floor a
//!    stated noise level, [`EstimateOptions::robust_floor`]) restarts from unit weights at
//!    every lighting step, as the paper says.
//!    Photos are independent and solved in parallel. Inside the alternation each QP is an
//!    inexact block step: it starts from the previous iterate and stops after
//!    [`EstimateOptions::alternation_qp_iters`] GPCG iterations of at most
//!    [`EstimateOptions::alternation_cg_iters`] CG steps each (or at the KKT tolerance);
//!    GPCG only accepts steps that lower the QP's objective, so `F` still never rises.
//! 2. Material step (Sec. 5.2, Eq. 11–12): with `s_{p,b,c} = ⟨g_{p,b}, W x_{I,c}⟩` fixed,
//!    `λ` per channel from all observations jointly (`K·B` unknowns, design row
//!    `w_k(x_p) s_{p,b,c}`, ridge `β_λ`), then `w(x)` per vertex from its observations in
//!    all three channels (`K` unknowns, row `Σ_b λ_{k,b,c} s_{p,b,c}`). With Huber IRLS the
//!    `w` step leaves out observations whose lighting residual exceeds `weights_reject · σ`
//!    ([`EstimateOptions::weights_reject`]): a vertex's few observations cannot outvote a
//!    gross outlier that Huber only down-weights. Both are small dense
//!    NNLS problems solved exactly by the active-set [`crate::qp::nnls`], so each step
//!    minimises `F` over its block and `F` never increases (without IRLS; with it, the
//!    weights change between steps).
//!
//! Scale: `F` is invariant under `x → s x`, `λ → λ / s` (and `w_k → t w_k`, `λ_k → λ_k / t`)
//! up to the tiny regularisers. After the alternation the result is normalised once:
//! every material's median blending weight over the vertices where it is the largest is 1,
//! then the mean Lambertian weight
//! (basis `lambert_basis`) over materials and channels equals that of the start (the initial
//! materials' median colours), the maps taking the inverse scale. The exact rule is in
//! [`Estimate::normalisation`]. With `fixed_materials` (Sec. 6.1) nothing is rescaled.
//!
//! Early stopping ([`EstimateOptions::validation_fraction`], not in the paper): a seeded
//! fraction of the training observations is given `α = 0` for the whole alternation and
//! scored after every outer iteration, `sqrt(Σ α (y − ŷ)²) / sqrt(Σ α y²)`; the iterate
//! with the lowest score is returned ([`Validation`]), and the loop ends after `patience`
//! iterations without a lower one.
//!
//! Deterministic: every reduction runs in a fixed order (fixed chunks reduced in sequence),
//! so the output does not depend on the number of threads.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use std::time::Instant;

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::haar;
use crate::observe::Observations;
use crate::qp::{bound_qp_scaled, nnls, NnlsOptions, QpOptions};
use crate::sphere::SphereGrid;
use crate::transport::{HaarIndex, Transport};
use crate::{Error, Result};

/// The data of one estimation: observations, their transport, and the sizes.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// Observations sorted by photo (`photo_ranges`).
    pub obs: &'a Observations,
    /// Transport rows `g_{p,b}`, one per observation and basis BRDF.
    pub transport: &'a Transport,
    /// Number of mesh vertices `V`.
    pub n_vertices: usize,
    /// Number of photos (`obs.photo_ranges.len()`).
    pub n_photos: usize,
}

impl Problem<'_> {
    /// Checks sizes and indices; `Error::Config` naming the first inconsistency.
    pub fn validate(&self) -> Result<()> {
        let o = self.obs;
        let p = o.vertex.len();
        let bad = |m: String| Err(Error::Config(format!("estimation problem: {m}")));
        if o.photo.len() != p || o.rgb.len() != p || o.weight.len() != p {
            return bad(format!(
                "observation arrays differ in length (vertex {p}, photo {}, rgb {}, weight {})",
                o.photo.len(),
                o.rgb.len(),
                o.weight.len()
            ));
        }
        let t = self.transport;
        if t.n_obs != p || t.offsets.len() != p * t.n_basis + 1 {
            return bad(format!(
                "transport has {} observations × {} bases ({} offsets) for {p} observations",
                t.n_obs,
                t.n_basis,
                t.offsets.len()
            ));
        }
        if t.n_basis == 0 || t.n_global < 2 || !t.n_global.is_power_of_two() {
            return bad(format!(
                "transport has {} bases and map side {}",
                t.n_basis, t.n_global
            ));
        }
        let n2 = (t.n_global * t.n_global) as u32;
        if let Some(i) = t.index.iter().position(|&m| u32::from(m) >= n2) {
            return bad(format!(
                "transport entry {i} indexes coefficient {} ≥ {n2}",
                t.index[i]
            ));
        }
        if o.photo_ranges.len() != self.n_photos {
            return bad(format!(
                "{} photo ranges for {} photos",
                o.photo_ranges.len(),
                self.n_photos
            ));
        }
        for (i, r) in o.photo_ranges.iter().enumerate() {
            if r.end > p || r.start > r.end {
                return bad(format!("photo {i} range {r:?} outside 0..{p}"));
            }
            if let Some(q) = r.clone().find(|&q| o.photo[q] as usize != i) {
                return bad(format!(
                    "observation {q} is in photo {i}'s range but names photo {}",
                    o.photo[q]
                ));
            }
        }
        if let Some(q) = o.vertex.iter().position(|&x| x as usize >= self.n_vertices) {
            return bad(format!(
                "observation {q} names vertex {} of {}",
                o.vertex[q], self.n_vertices
            ));
        }
        if let Some(q) = (0..p).find(|&q| {
            !(o.weight[q].is_finite() && o.weight[q] >= 0.0)
                || o.rgb[q].iter().any(|v| !v.is_finite())
        }) {
            return bad(format!(
                "observation {q} has weight {} and colour {:?}",
                o.weight[q], o.rgb[q]
            ));
        }
        Ok(())
    }
}

/// Robust loss for IRLS, thresholds in units of the residuals' robust scale
/// `σ = max(1.4826 · median |r|, robust_floor · rms(y))` (per photo and channel,
/// [`EstimateOptions::robust_floor`]).
///
/// Measured trade-off (`bench-results/estimator.md`, part 3): with 5% gross bright
/// outliers in a joint fit, Huber alone lets the per-vertex weights absorb them (held-out
/// error ×2.9 of the clean fit); with the default w-step cut
/// ([`EstimateOptions::weights_reject`]) ×1.05, Tukey ×1.04. Tukey is not the default
/// because it also rejects the genuine, noisier highlights of glossy surfaces in the
/// lighting step (known-reflectance Phong 50 sphere, `tests/suite/estimate_synth.rs` sizes: fit
/// 0.245 against the true map's 0.144, Huber 0.124).
///
/// The price on clean data (`bench-results/estimator-convergence.md`, `spot-varying` with
/// photos made by the true model through its own transport, 20 outer iterations): the
/// MAD scale shrinks with the residuals, so Huber keeps down-weighting the model's own
/// misfit (highlights the current λ cannot make yet) in the lighting and material steps:
/// training / held-out relative error 12.2% / 13.2% against 1.9% / 9.2% without IRLS,
/// at 4× the lighting cost; `k = 3` does not close the gap (10.7% / 12.4% after 16).
/// A floor on the scale ([`EstimateOptions::robust_floor`], [`ROBUST_FLOOR`] by default)
/// removes most of it: at 0.1, 4.0% / 9.9% after 20 (0.05: 6.8% / 10.6%; 0.02: 7.2% / 11.6%).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Robust {
    /// Plain least squares, no reweighting.
    None,
    /// Huber: weight `min(1, kσ / |r|)` (k = 1.345 is 95% efficient on Gaussian noise).
    Huber { k: f64 },
    /// Tukey's biweight: weight `(1 − (r / cσ)²)²` inside `|r| < cσ`, 0 outside (c = 4.685).
    Tukey { c: f64 },
}

/// The diagonal of the lighting system `Wᵀ Aᵀ D A W` that the Laplacian weight is measured
/// against: `μ_{I,c} = smoothness × scale_{I,c}`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SmoothnessScale {
    /// The largest diagonal entry in the Haar basis. Dominated by the scaling coefficient
    /// (the map's mean), which collects a whole lobe's energy: `~n²/4` times a texel's
    /// entry for a diffuse row, so `μ` grows with the map resolution and blurs suns.
    HaarMax,
    /// The largest diagonal entry in the texel basis, the one the Laplacian acts in:
    /// `max_t Σ_p α_p ω_{p,c} ((Wᵀ e_{p,c})_t)²` (`e` the β-blended transport row).
    TexelMax,
    /// The mean diagonal entry, `trace / n²` (the same in both bases).
    Mean,
}

/// Options of [`estimate`].
#[derive(Debug, Clone)]
pub struct EstimateOptions {
    /// Cap on outer (lighting + materials) iterations.
    pub max_outer: usize,
    /// Stop when the objective's relative decrease falls below this.
    pub rel_tol: f64,
    /// Laplacian weight `μ` relative to the lighting system's scale `smoothness_scale`.
    pub smoothness: f64,
    /// What `smoothness` is relative to (the system's "largest value").
    pub smoothness_scale: SmoothnessScale,
    /// Laplacian schedule over the outer iterations: iteration `t` (1-based) uses
    /// `μ_t = μ_1 · max(smoothness_decay^(t−1), smoothness_min / smoothness)`, `μ_1` fixed
    /// at the photo's first lighting step. 1 = the same `μ` throughout. A smooth start
    /// keeps the first maps stable while the materials are far off; a weaker Laplacian
    /// later removes its bias from the minimiser. Default 1 (off): on noise-free
    /// `spot-varying` (`bench-results/estimator-convergence.md`) 0.7 down to 10⁻⁵ keeps a
    /// start at the true materials at 2.3% held-out after 20 iterations (constant: drifts
    /// to 7.4%), but from the clustered start gives 10.1% against 9.9% at ~5× the wall time
    /// (the weaker Laplacian conditions the lighting QP worse).
    pub smoothness_decay: f64,
    /// The smallest relative Laplacian weight the schedule reaches (see `smoothness_decay`).
    pub smoothness_min: f64,
    /// Robust loss of the lighting step (IRLS); its final weights carry to the materials.
    pub robust: Robust,
    /// IRLS passes per lighting step (the first one unweighted); 1 = plain weighted LS.
    pub irls_iters: usize,
    /// Ridge on λ, relative to the largest diagonal entry of the first λ system.
    pub beta: f64,
    /// Known reflectance (Sec. 6.1): only the lighting is estimated.
    pub fixed_materials: bool,
    /// Lighting QP stopping rule: projected gradient ≤ `qp_rel_tol · ‖Wᵀ Aᵀ D y‖∞`.
    pub qp_rel_tol: f64,
    /// Cap on GPCG iterations per lighting QP.
    pub qp_max_iter: usize,
    /// Cap on GPCG iterations of each lighting QP inside the alternation, where every QP
    /// starts from the previous iterate and the next material step changes the system
    /// anyway (an inexact block step: GPCG never raises the QP's objective, so `F` still
    /// does not increase). `None`: `qp_max_iter`, i.e. solved to the KKT tolerance.
    /// Single lighting fits (fixed materials, [`fit_light_frozen`]) always use
    /// `qp_max_iter`. Measured in `bench-results/lighting-solver.md`.
    pub alternation_qp_iters: Option<usize>,
    /// Cap on conjugate-gradient steps on the free face per GPCG iteration of a lighting
    /// QP (each step is one Hessian product).
    pub qp_max_cg: usize,
    /// Cap on those CG steps inside the alternation (as `alternation_qp_iters`: an inexact
    /// block step that never raises the QP's objective). `None`: `qp_max_cg`.
    pub alternation_cg_iters: Option<usize>,
    /// λ / w alternations per material step.
    pub material_sweeps: usize,
    /// Index of the Lambertian basis BRDF (used by the normalisation).
    pub lambert_basis: usize,
    /// Extrapolate the alternation (accepted only when the objective drops).
    pub extrapolate: bool,
    /// With Huber IRLS: observations whose last lighting residual exceeds this many robust
    /// scales `σ` (Huber weight below `k / weights_reject`) are left out of the per-vertex
    /// `w` step (a redescending cut there only). A vertex has a handful of observations and
    /// `K` unknowns, so a gross outlier that Huber only down-weights is fitted exactly by
    /// its `w`; the λ step (all observations pooled) and the lighting step keep Huber's
    /// weights, so genuine highlights still shape the maps and the specular `λ`.
    /// `None`: the `w` step uses the Huber weights as they are. Default 4.685 (Tukey's
    /// cut-off): on `spot-varying` with 5% gross outliers the held-out error goes from
    /// ×2.7 to ×1.05 of the clean fit, and the clean fit does not change measurably.
    pub weights_reject: Option<f64>,
    /// Early stopping (not in the paper): this fraction of the training observations with
    /// `α > 0`, drawn with `validation_seed` (only at vertices keeping at least
    /// [`VALIDATION_MIN_FIT`] fitted observations), is left out of every step and scored
    /// after each outer iteration (relative RMSE, [`Validation`]); the iterate with the
    /// lowest score is returned. 0 = off: every observation is fitted and the last
    /// iterate returned. Ignored with `fixed_materials` (one lighting step, nothing to
    /// choose). Default 0.1.
    pub validation_fraction: f64,
    /// Hold the per-channel scale of the reflectance (`Σ_x Σ_b β_{x,b,c}`) at its start
    /// value after every material step, the maps taking the inverse factor. Default off:
    /// on noise-free `spot-varying` it changed the held-out error after 20 iterations
    /// from 13.2% to 12.8% (`bench-results/estimator-convergence.md`).
    pub fix_gauge: bool,
    /// With Huber IRLS and `weights_reject`: the material step (λ and w) weighs every
    /// observation by `α` alone, leaving out only those beyond the cut, instead of `α ω`.
    /// Default off: on noise-free `spot-varying` 12.6% held-out against 13.2% after 20
    /// iterations, far from the 9.2% without IRLS (`bench-results/estimator-convergence.md`).
    pub materials_cut_only: bool,
    /// Lower bound on IRLS's robust scale, relative to the observed radiance: per photo
    /// and channel `σ = max(1.4826 · median |r|, robust_floor · rms(y))`, `rms(y)` over the
    /// photo's fitted observations in that channel. The floor is a stated noise level: a
    /// residual within `k · robust_floor` of the RMS radiance is never down-weighted, so
    /// IRLS acts only on gross residuals and not on the model's own shrinking misfit (the
    /// MAD alone goes to 0 with the residuals and stalls the fit on clean data). 0 = the
    /// MAD alone. Default [`ROBUST_FLOOR`] (0.05).
    pub robust_floor: f64,
    /// Seed of the validation draw.
    pub validation_seed: u64,
    /// With validation: stop after this many outer iterations without a lower score.
    pub patience: usize,
    /// Lighting step on a stratified subsample ([`crate::solve::subsample`]): at most this
    /// many of a photo's fitted observations enter its lighting QPs, each weighted by its
    /// stratum's `N_h / n_h` so that the data term and its normal equations keep their
    /// expected value; the IRLS scale and weights still come from every observation, and
    /// the material step uses them all. 0 = every observation. Measured in
    /// `bench-results/lighting-sample.md`.
    pub lighting_sample: usize,
    /// Per-vertex strata of that sample (normal and open-sky bins,
    /// [`crate::solve::subsample::vertex_strata`]), crossed with each vertex's dominant
    /// starting material; empty: the materials alone.
    pub lighting_strata: Vec<u32>,
    /// Prior on each photo's map (issue 25, not in the paper; `None`: the paper's free
    /// map): extra quadratic terms of the lighting QP ([`crate::light_sh_prior`]).
    pub light_prior: Option<crate::light_sh_prior::LightPriorOptions>,
}

/// Default of [`EstimateOptions::alternation_qp_iters`]: 5 GPCG iterations per lighting QP
/// (≤ ~630 Hessian products with the old CG cap of 100, ≤ ~120 with
/// [`ALTERNATION_CG_ITERS`]). On the Minerva model (`spot-varying`, 2,930 vertices, 13
/// photos of 1024²) the estimate took 7.3× less CPU than solving every QP to the KKT
/// tolerance (48.8 s against 357.9 s) with held-out error 0.0765 against 0.0791 and
/// training error 0.0340 against 0.0331 (`bench-results/lighting-solver.md`).
pub const ALTERNATION_QP_ITERS: usize = 5;

/// Default of [`EstimateOptions::alternation_cg_iters`]: 20 conjugate-gradient steps per
/// GPCG iteration (≤ ~120 Hessian products per lighting QP with the 5 GPCG iterations of
/// [`ALTERNATION_QP_ITERS`]). Measured on the Minerva model (`spot-varying`, 2,930 vertices,
/// 13 photos of 1024², `bench-results/estimator-knobs.md`): estimate 83.5 → 28.5 CPU s
/// (×2.9) against the old cap of 100, held-out error 0.0765 → 0.0767, training 0.0340 →
/// 0.0339; 10 steps are too few (the alternation runs 8 iterations instead of 5 and ends at
/// 0.0782), 30 gave 0.0766 at 36.8 s.
pub const ALTERNATION_CG_ITERS: usize = 20;

/// Default of [`EstimateOptions::patience`]: stop at the first outer iteration whose
/// validation score is not a new best. Measured with [`ALTERNATION_CG_ITERS`] on the Minerva
/// model (`bench-results/estimator-knobs.md`, then `spot-varying` at 1 MP): every scene
/// kept the same iterate with 1 as with 2 or 3 — 2,930 vertices (2 of 3 instead of 2 of 4),
/// 11,714 (3 of 4 / 3 of 5: estimate 87.4 → 75.3 CPU s), 100,000 (4 of 5 / 4 of 6) — and the
/// joint bench (`ESTIMATOR_BENCH=joint`: 566 validation observations, its score improving
/// for 23 iterations) kept iteration 23 of 24 instead of 23 of 25 with every figure
/// identical, 16.9 s instead of 23.6 s. The extra iterations only confirmed the best one.
pub const PATIENCE: usize = 1;

/// Default of [`EstimateOptions::robust_floor`]: IRLS's robust scale is at least 5% of the
/// photo's RMS radiance in each channel. Against the MAD alone (0), measured on `spot-varying`
/// (`bench-results/estimator-joint-floor.md`, `estimator-robust-floor.md`,
/// `estimator-joint-32-starts.md`): the joint bench (16² / 8², 96² photos) 17.5% held-out
/// against 18.3% (12 fixed iterations 17.3% / 18.3%; 5% gross outliers ×1.03 of the clean
/// fit); the finer joint case (32² / 16², 192² photos at 32 spp) 13.2% against 14.7% in
/// 94 s instead of 173 s; the Minerva model at 10K vertices 0.0764 against 0.0765. 0.1 did as
/// well on the finer cases (13.2%, 100K vertices 0.0757 against 0.0763) but made early
/// stopping return iteration 2 on the small bench (20.5%: its validation score jumps from
/// 0.19 to 0.27 at iteration 3) and costs ×1.18 with outliers on the finer case; 0.2 fails
/// the outliers (×1.54, a larger σ lets Huber's bounded influence `kσ` grow). Noise-free
/// (`estimator-convergence.md`, 20 iterations) 0.1 gives training / held-out 4.0% / 9.9%
/// against 12.2% / 13.2% with the MAD alone, which keeps down-weighting the fit's own
/// shrinking misfit (every highlight at the clustered start).
pub const ROBUST_FLOOR: f64 = 0.05;

/// Early stopping leaves an observation out only where its vertex keeps at least this many
/// fitted observations (its `K` blending weights stay determined).
pub const VALIDATION_MIN_FIT: usize = 2;

impl Default for EstimateOptions {
    fn default() -> Self {
        EstimateOptions {
            max_outer: 12,
            rel_tol: 1e-4,
            smoothness: 1e-3,
            smoothness_scale: SmoothnessScale::TexelMax,
            smoothness_decay: 1.0,
            smoothness_min: 0.0,
            robust: Robust::Huber { k: 1.345 },
            irls_iters: 4,
            beta: 1e-8,
            fixed_materials: false,
            qp_rel_tol: 1e-7,
            qp_max_iter: 300,
            alternation_qp_iters: Some(ALTERNATION_QP_ITERS),
            qp_max_cg: 100,
            alternation_cg_iters: Some(ALTERNATION_CG_ITERS),
            material_sweeps: 1,
            lambert_basis: 0,
            extrapolate: true,
            weights_reject: Some(4.685),
            validation_fraction: 0.1,
            validation_seed: 1,
            robust_floor: ROBUST_FLOOR,
            fix_gauge: false,
            materials_cut_only: false,
            patience: PATIENCE,
            lighting_sample: 0,
            lighting_strata: Vec::new(),
            light_prior: None,
        }
    }
}

/// `f(i)` for `i` in `0..sizes.len()`, in parallel, in index order, the items started
/// largest first: each worker takes the largest item not yet started (greedy "longest
/// processing time first"). A few items of unequal cost (photos: 10 of 10K–19K
/// observations at 46,850 vertices) split in halves by index leave one core idle while
/// the other finishes its larger half; largest first bounds the idle tail by the smallest
/// items. Each `f(i)` runs alone, so the results do not depend on the order.
pub fn par_largest_first<T, F>(sizes: &[usize], f: F) -> Vec<T>
where
    T: Send,
    F: Fn(usize) -> T + Sync + Send,
{
    use rayon::iter::ParallelBridge;
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    order.sort_by_key(|&i| (std::cmp::Reverse(sizes[i]), i));
    let mut done: Vec<(usize, T)> = order.into_iter().par_bridge().map(|i| (i, f(i))).collect();
    done.sort_by_key(|d| d.0);
    done.into_iter().map(|d| d.1).collect()
}

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

/// Early stopping's record ([`EstimateOptions::validation_fraction`]).
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
        init: &crate::cluster::InitialMaterials,
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
    /// alternation's cap ([`EstimateOptions::alternation_qp_iters`]), by design.
    pub qp_alternation_capped: usize,
    /// Lighting QPs solved so far (photos × IRLS passes × outer iterations).
    pub lighting_qps: usize,
    /// Most Hessian products of one lighting QP so far.
    pub lighting_matvecs_max: usize,
    /// Hessian products of all lighting QPs so far (the lighting step's cost unit).
    pub lighting_matvecs: usize,
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
    /// ([`EstimateOptions::lighting_sample`]).
    pub lighting_sample: Option<crate::solve::subsample::SampleCheck>,
}

/// `β_{x,b,c} = Σ_k w_k(x) λ_{k,b,c}`, row-major `V × B`.
pub fn beta_per_vertex(
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    n_vertices: usize,
) -> Vec<[f64; 3]> {
    let k_count = lambda.len();
    let nb = lambda.first().map_or(0, |l| l.len());
    let mut out = vec![[0.0; 3]; n_vertices * nb];
    for x in 0..n_vertices {
        for (k, lk) in lambda.iter().enumerate() {
            let w = weights[x * k_count + k];
            if w == 0.0 {
                continue;
            }
            for b in 0..nb {
                for c in 0..3 {
                    out[x * nb + b][c] += w * lk[b][c];
                }
            }
        }
    }
    out
}

/// The map's graph Laplacian `Δ` on the full octahedral grid (4 neighbours across seams):
/// `(Δ x)_t = Σ_{s ∈ N(t)} (x_t − x_s)`, with `apply` and its transpose.
struct Laplacian {
    nb: Vec<[usize; 4]>,
}

impl Laplacian {
    fn new(n: usize) -> Self {
        let g = SphereGrid::full(n);
        Laplacian {
            nb: (0..n * n).map(|t| g.neighbors(t)).collect(),
        }
    }
    fn apply(&self, x: &[f64], out: &mut [f64]) {
        for (t, nb) in self.nb.iter().enumerate() {
            out[t] = nb.iter().map(|&s| x[t] - x[s]).sum();
        }
    }
    /// `out += μ ΔᵀΔ x`.
    fn add_normal(&self, x: &[f64], mu: f64, out: &mut [f64]) {
        let mut lx = vec![0.0; x.len()];
        self.apply(x, &mut lx);
        for (t, nb) in self.nb.iter().enumerate() {
            let v = mu * lx[t];
            for &s in nb {
                out[t] += v;
                out[s] -= v;
            }
        }
    }
    /// The diagonal of `ΔᵀΔ`: `Σ_r Δ_{r,t}²` with row `r` of `Δ` = 4 at `r`, −1 at each
    /// neighbour (repeated neighbours add up).
    fn normal_diag(&self) -> Vec<f64> {
        let mut diag = vec![0.0; self.nb.len()];
        let mut cols: Vec<(usize, f64)> = Vec::with_capacity(5);
        for (r, nb) in self.nb.iter().enumerate() {
            cols.clear();
            cols.push((r, nb.len() as f64));
            for &s in nb {
                match cols.iter_mut().find(|(c, _)| *c == s) {
                    Some(e) => e.1 -= 1.0,
                    None => cols.push((s, -1.0)),
                }
            }
            for &(c, v) in &cols {
                diag[c] += v * v;
            }
        }
        diag
    }
    fn energy(&self, x: &[f64]) -> f64 {
        let mut lx = vec![0.0; x.len()];
        self.apply(x, &mut lx);
        lx.iter().map(|v| v * v).sum()
    }
}

/// Haar coefficients of three texel maps, interleaved per coefficient.
fn haar3(tex: &[Vec<f64>; 3], n: usize) -> Vec<[f64; 3]> {
    let mut out = vec![[0.0; 3]; n * n];
    for (c, t) in tex.iter().enumerate() {
        let mut h = t.clone();
        haar::forward(&mut h, n);
        for (o, v) in out.iter_mut().zip(&h) {
            o[c] = *v;
        }
    }
    out
}

/// One photo's data for the lighting step.
///
/// With `β` fixed for the whole lighting step, an observation's `B` transport rows enter
/// every product only through their per-channel blend `e_{p,c} = Σ_b β_{x,b,c} g_{p,b}`.
/// [`PhotoSystem::new`] merges them once into one sparse row per observation (the union of
/// the bases' kept indices, ascending, values `[f32; 3]`, one per channel), so a product
/// costs one gather or scatter per merged entry instead of `B` per kept entry. The blend
/// is summed in `f64` in basis order and rounded once to `f32` (relative error ≤ 2⁻²⁴, the
/// precision the transport values are stored in); forward and adjoint products read the
/// same stored values, so the Hessian stays exactly symmetric.
struct PhotoSystem {
    /// `0..rows`: the system's rows (the photo's observations, or its lighting sample).
    range: std::ops::Range<usize>,
    n: usize,
    /// `α_p ω_{p,c}` for the range's observations.
    dw: Vec<[f64; 3]>,
    /// Merged row `q` (range order) spans `index[offsets[q]..offsets[q + 1]]`.
    offsets: Vec<usize>,
    /// Haar coefficient indices of the merged rows, ascending within a row (2 bytes, the
    /// transport's own index type: 14 bytes an entry with the values, was 16).
    index: Vec<HaarIndex>,
    /// `e_{p,c}` at those indices.
    value: Vec<[f32; 3]>,
    /// The merged rows cut into [`PRODUCT_CHUNKS`] contiguous ranges of about equal
    /// entries: the parallel parts of [`Self::normal_rows`].
    chunks: Vec<std::ops::Range<usize>>,
}

/// Parts of one lighting-step product ([`PhotoSystem::normal_rows`]): each part's rows are
/// scattered into a buffer of its own, in parallel, and the buffers summed in part order.
/// A fixed number, not the thread count, so the sum (and every result) does not depend on
/// the machine. Lone QPs (protocol (b)'s light fits, the last photos of a lighting step)
/// then use every core; inside the estimate's parallel photos the parts only add a
/// `PRODUCT_CHUNKS × n²` buffer sum to a product that reads every merged row.
const PRODUCT_CHUNKS: usize = 4;

/// `parts` contiguous ranges of `0..offsets.len() − 1` (rows), cut where the running entry
/// count `offsets[q]` crosses `k/parts` of the total; empty ranges are dropped.
fn entry_chunks(offsets: &[usize], parts: usize) -> Vec<std::ops::Range<usize>> {
    let rows = offsets.len().saturating_sub(1);
    let total = offsets.last().copied().unwrap_or(0);
    let mut cuts = vec![0];
    for k in 1..parts {
        let target = total * k / parts;
        let q = offsets.partition_point(|&o| o < target).min(rows);
        cuts.push(q.max(*cuts.last().unwrap_or(&0)));
    }
    cuts.push(rows);
    cuts.windows(2)
        .filter(|w| w[1] > w[0])
        .map(|w| w[0]..w[1])
        .collect()
}

/// `⟨e_c, h_c⟩` per channel for one merged transport row (`idx`, `val`) and a light `h`
/// (interleaved Haar): the forward half of the lighting step's products.
#[inline]
fn row_dot(idx: &[HaarIndex], val: &[[f32; 3]], h: &[[f64; 3]]) -> [f64; 3] {
    let mut acc = [0.0_f64; 3];
    for (&m, e) in idx.iter().zip(val) {
        let hm = &h[m as usize];
        acc[0] += e[0] as f64 * hm[0];
        acc[1] += e[1] as f64 * hm[1];
        acc[2] += e[2] as f64 * hm[2];
    }
    acc
}

/// `out_c += e_c u_c` for one merged transport row: the adjoint half.
#[inline]
fn row_scatter(idx: &[HaarIndex], val: &[[f32; 3]], u: [f64; 3], out: &mut [[f64; 3]]) {
    for (&m, e) in idx.iter().zip(val) {
        let o = &mut out[m as usize];
        o[0] += e[0] as f64 * u[0];
        o[1] += e[1] as f64 * u[1];
        o[2] += e[2] as f64 * u[2];
    }
}

impl PhotoSystem {
    /// Merge the range's transport rows with `β` (struct docs).
    fn new(
        problem: &Problem,
        beta: &[[f64; 3]],
        rows: impl IntoIterator<Item = usize>,
        n: usize,
        dw: Vec<[f64; 3]>,
    ) -> Self {
        let t = problem.transport;
        let nb = t.n_basis;
        let n2 = n * n;
        let mut dense = vec![[0.0_f64; 3]; n2];
        let mut seen = vec![false; n2];
        let mut touched: Vec<HaarIndex> = Vec::new();
        let mut offsets = Vec::with_capacity(dw.len() + 1);
        offsets.push(0);
        let mut index = Vec::new();
        let mut value = Vec::new();
        for p in rows {
            let x = problem.obs.vertex[p] as usize;
            for b in 0..nb {
                let be = beta[x * nb + b];
                if be == [0.0; 3] {
                    continue;
                }
                let (idx, val) = t.row(p, b);
                for (&m, &g) in idx.iter().zip(val) {
                    let mu = m as usize;
                    if !seen[mu] {
                        seen[mu] = true;
                        touched.push(m);
                    }
                    let g = g as f64;
                    let d = &mut dense[mu];
                    d[0] += be[0] * g;
                    d[1] += be[1] * g;
                    d[2] += be[2] * g;
                }
            }
            touched.sort_unstable();
            for &m in &touched {
                let mu = m as usize;
                let d = dense[mu];
                if d != [0.0; 3] {
                    index.push(m);
                    value.push(d.map(|v| v as f32));
                }
                dense[mu] = [0.0; 3];
                seen[mu] = false;
            }
            touched.clear();
            offsets.push(index.len());
        }
        let chunks = entry_chunks(&offsets, PRODUCT_CHUNKS);
        PhotoSystem {
            range: 0..offsets.len() - 1,
            n,
            dw,
            offsets,
            index,
            value,
            chunks,
        }
    }

    /// Merged row `q` (range order): indices and per-channel values.
    fn merged(&self, q: usize) -> (&[HaarIndex], &[[f32; 3]]) {
        let (lo, hi) = (self.offsets[q], self.offsets[q + 1]);
        (&self.index[lo..hi], &self.value[lo..hi])
    }

    /// `s_{p,c} = Σ_b β_{x,b,c} ⟨g_{p,b}, h_c⟩ = ⟨e_{p,c}, h_c⟩` for the range (`h`
    /// interleaved Haar).
    fn forward_rows(&self, h: &[[f64; 3]], out: &mut [[f64; 3]]) {
        debug_assert_eq!(out.len(), self.range.len());
        for (q, o) in out.iter_mut().enumerate() {
            let (idx, val) = self.merged(q);
            *o = row_dot(idx, val, h);
        }
    }

    /// `out += Aᵀ u` in the Haar basis (`u` per observation of the range and channel).
    fn adjoint_rows(&self, u: &[[f64; 3]], out: &mut [[f64; 3]]) {
        for (q, uq) in u.iter().enumerate() {
            if *uq == [0.0; 3] {
                continue;
            }
            let (idx, val) = self.merged(q);
            row_scatter(idx, val, *uq, out);
        }
    }

    /// `out += Aᵀ D A h` in the Haar basis (`D = dw`), one pass over the merged rows:
    /// each row's response is formed and scattered back at once, so the rows are read
    /// once per product instead of twice. The rows are cut into [`PRODUCT_CHUNKS`] parts
    /// done in parallel, each into its own buffer, then added to `out` in part order.
    fn normal_rows(&self, h: &[[f64; 3]], out: &mut [[f64; 3]]) {
        let part = |rows: &std::ops::Range<usize>| {
            let mut acc = vec![[0.0_f64; 3]; out.len()];
            for q in rows.clone() {
                let d = self.dw[q];
                let (idx, val) = self.merged(q);
                let r = row_dot(idx, val, h);
                let uq = [r[0] * d[0], r[1] * d[1], r[2] * d[2]];
                if uq == [0.0; 3] {
                    continue;
                }
                row_scatter(idx, val, uq, &mut acc);
            }
            acc
        };
        let parts: Vec<Vec<[f64; 3]>> = self.chunks.par_iter().map(part).collect();
        for p in &parts {
            for (o, v) in out.iter_mut().zip(p) {
                o[0] += v[0];
                o[1] += v[1];
                o[2] += v[2];
            }
        }
    }

    /// Largest diagonal entry of `Aᵀ D A` per channel, in the Haar basis:
    /// `max_m Σ_p d_{p,c} e_{p,c,m}²`.
    fn max_diag(&self) -> [f64; 3] {
        let mut diag = vec![[0.0; 3]; self.n * self.n];
        for (q, d) in self.dw.iter().enumerate() {
            let (idx, val) = self.merged(q);
            for (&m, e) in idx.iter().zip(val) {
                let o = &mut diag[m as usize];
                for c in 0..3 {
                    let v = e[c] as f64;
                    o[c] += d[c] * v * v;
                }
            }
        }
        let mut mx = [0.0_f64; 3];
        for d in &diag {
            for c in 0..3 {
                mx[c] = mx[c].max(d[c]);
            }
        }
        mx
    }
}

/// Largest and mean diagonal entries per channel of the unweighted-by-IRLS lighting system
/// `Wᵀ Aᵀ D A W` in the texel basis (`D = α`): `Σ_p α_p ((Wᵀ e_{p,c})_t)²`, with
/// `e_{p,c} = Σ_b β_{x,b,c} g_{p,b}` rebuilt densely and inverse-Haar transformed per
/// observation (`O(n²)` each, once per photo).
fn texel_diag(
    problem: &Problem,
    beta: &[[f64; 3]],
    range: impl IntoIterator<Item = usize>,
    alpha: &[f64],
) -> ([f64; 3], [f64; 3]) {
    let diag = texel_diag_vec(problem, beta, range, alpha);
    let n2 = diag.len();
    let (mut mx, mut sum) = ([0.0_f64; 3], [0.0_f64; 3]);
    for d in &diag {
        for c in 0..3 {
            mx[c] = mx[c].max(d[c]);
            sum[c] += d[c];
        }
    }
    (mx, sum.map(|v| v / n2 as f64))
}

/// The diagonal itself, per texel and channel (see [`texel_diag`]).
fn texel_diag_vec(
    problem: &Problem,
    beta: &[[f64; 3]],
    range: impl IntoIterator<Item = usize>,
    alpha: &[f64],
) -> Vec<[f64; 3]> {
    let t = problem.transport;
    let (n, nb) = (t.n_global, t.n_basis);
    let n2 = n * n;
    let mut diag = vec![[0.0_f64; 3]; n2];
    let mut dense = [vec![0.0_f64; n2], vec![0.0; n2], vec![0.0; n2]];
    let mut scratch = Vec::new();
    for (q, p) in range.into_iter().enumerate() {
        let a = alpha[q];
        if a <= 0.0 {
            continue;
        }
        let x = problem.obs.vertex[p] as usize;
        for d in dense.iter_mut() {
            d.fill(0.0);
        }
        for b in 0..nb {
            let be = beta[x * nb + b];
            let (idx, val) = t.row(p, b);
            for (&m, &g) in idx.iter().zip(val) {
                for c in 0..3 {
                    dense[c][m as usize] += be[c] * g as f64;
                }
            }
        }
        for (c, d) in dense.iter_mut().enumerate() {
            haar::inverse_with(d, n, &mut scratch);
            for (o, v) in diag.iter_mut().zip(d.iter()) {
                o[c] += a * v * v;
            }
        }
    }
    diag
}

/// Whether the lighting QP is scaled by its texel-basis diagonal
/// ([`crate::qp::bound_qp_scaled`]): `diag(Wᵀ Aᵀ α A W) + μ diag(ΔᵀΔ)` per channel, the data
/// part without the IRLS weights. Same stopping rule, fewer products (bench-results/pipeline-minerva.md, bench-results/lighting-solver.md).
const LIGHTING_JACOBI: bool = true;

/// Result of one photo's lighting step.
#[derive(Debug, Clone)]
pub struct LightingResult {
    /// Texels per channel, `≥ 0`.
    pub light: [Vec<f64>; 3],
    /// Laplacian weights used.
    pub mu: [f64; 3],
    /// Final IRLS weights `ω` for the photo's observations (range order).
    pub irls_weights: Vec<[f32; 3]>,
    /// Condition-number lower bound of the last QP.
    pub cond_lower_bound: f64,
    /// Whether every QP met its KKT tolerance.
    pub converged: bool,
    /// Hessian products used.
    pub matvecs: usize,
    /// QPs solved (one per IRLS pass with light reaching an observation).
    pub qps: usize,
    /// QPs that stopped at the iteration cap.
    pub unconverged_qps: usize,
    /// Most Hessian products of one QP.
    pub matvecs_max: usize,
}

fn robust_weight(robust: Robust, r: f64, sigma: f64) -> f64 {
    match robust {
        Robust::None => 1.0,
        Robust::Huber { k } => {
            let t = k * sigma;
            if r.abs() <= t {
                1.0
            } else {
                t / r.abs()
            }
        }
        Robust::Tukey { c } => {
            let u = r / (c * sigma);
            if u.abs() < 1.0 {
                (1.0 - u * u).powi(2)
            } else {
                0.0
            }
        }
    }
}

/// Lighting step for one photo with full control: start texels (`None` = zeros), Laplacian
/// weights (`None` = `smoothness` × largest system diagonal, computed here). With
/// [`EstimateOptions::lighting_sample`] the QPs see a stratified sample of the photo's
/// observations (strata from [`EstimateOptions::lighting_strata`]).
pub fn lighting_step_full(
    problem: &Problem,
    beta: &[[f64; 3]],
    photo: usize,
    start: Option<&[Vec<f64>; 3]>,
    mu: Option<[f64; 3]>,
    opts: &EstimateOptions,
) -> Result<LightingResult> {
    let sample = lighting_sample(problem, photo, opts, None);
    lighting_step_on(problem, beta, photo, start, mu, opts, sample.as_ref())
}

/// The stratified sample of `photo`'s fitted observations (positions in its range) that its
/// lighting QPs see ([`EstimateOptions::lighting_sample`]); `None` when the photo has no
/// more fitted observations than the budget. Strata: `opts.lighting_strata` of the vertex
/// crossed with `dominant[x]` (a material index) when given.
pub fn lighting_sample(
    problem: &Problem,
    photo: usize,
    opts: &EstimateOptions,
    dominant: Option<&[u32]>,
) -> Option<crate::solve::subsample::Subsample> {
    let budget = opts.lighting_sample;
    let obs = problem.obs;
    let range = obs.photo_ranges[photo].clone();
    let eligible: Vec<bool> = range.clone().map(|p| obs.weight[p] > 0.0).collect();
    if budget == 0 || eligible.iter().filter(|&&e| e).count() <= budget {
        return None;
    }
    let k = dominant.map_or(1, |d| d.iter().max().map_or(1, |&m| m as usize + 1));
    let strata: Vec<u32> = range
        .map(|p| {
            let x = obs.vertex[p] as usize;
            let v = opts.lighting_strata.get(x).copied().unwrap_or(0) as usize;
            (v * k + dominant.map_or(0, |d| d[x] as usize)) as u32
        })
        .collect();
    let seed = opts
        .validation_seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(photo as u64);
    Some(crate::solve::subsample::stratified(
        &strata, &eligible, budget, seed,
    ))
}

/// `Σ_b β_{x,b,c} ⟨g_{p,b}, h_c⟩` for the observations `range` straight from the transport
/// rows (`h` interleaved Haar): the prediction of observations outside a lighting sample.
fn forward_full(
    problem: &Problem,
    beta: &[[f64; 3]],
    range: std::ops::Range<usize>,
    h: &[[f64; 3]],
) -> Vec<[f64; 3]> {
    let t = problem.transport;
    let nb = t.n_basis;
    range
        .map(|p| {
            let x = problem.obs.vertex[p] as usize;
            let mut acc = [0.0; 3];
            for b in 0..nb {
                let be = beta[x * nb + b];
                if be == [0.0; 3] {
                    continue;
                }
                let (idx, val) = t.row(p, b);
                let mut r = [0.0; 3];
                for (&m, &g) in idx.iter().zip(val) {
                    let hm = &h[m as usize];
                    let g = g as f64;
                    r[0] += g * hm[0];
                    r[1] += g * hm[1];
                    r[2] += g * hm[2];
                }
                for c in 0..3 {
                    acc[c] += be[c] * r[c];
                }
            }
            acc
        })
        .collect()
}

/// [`lighting_step_full`] on a given sample of the photo's observations (`None`: all).
pub fn lighting_step_on(
    problem: &Problem,
    beta: &[[f64; 3]],
    photo: usize,
    start: Option<&[Vec<f64>; 3]>,
    mu: Option<[f64; 3]>,
    opts: &EstimateOptions,
    sample: Option<&crate::solve::subsample::Subsample>,
) -> Result<LightingResult> {
    let t = problem.transport;
    let n = t.n_global;
    let n2 = n * n;
    let range = problem.obs.photo_ranges[photo].clone();
    let obs = problem.obs;
    // The QP's rows: positions in the range (all, or the sample) and their
    // Horvitz–Thompson weights (1 without a sample).
    let (pos, ht): (Vec<usize>, Vec<f64>) = match sample {
        Some(s) => (s.index.clone(), s.weight.clone()),
        None => ((0..range.len()).collect(), vec![1.0; range.len()]),
    };
    let rows = || pos.iter().map(|&q| range.start + q);
    let alpha: Vec<f64> = rows()
        .zip(&ht)
        .map(|(p, w)| obs.weight[p] as f64 * w)
        .collect();
    let y: Vec<[f64; 3]> = rows().map(|p| obs.rgb[p].map(f64::from)).collect();
    // Every observation of the photo: IRLS's scale and weights come from all of them.
    let alpha_all: Vec<f64> = range.clone().map(|p| obs.weight[p] as f64).collect();
    let y_all: Vec<[f64; 3]> = range.clone().map(|p| obs.rgb[p].map(f64::from)).collect();
    let mut sys = PhotoSystem::new(
        problem,
        beta,
        rows(),
        n,
        alpha.iter().map(|&a| [a; 3]).collect(),
    );
    // The texel-basis diagonal of the data term (α, without IRLS weights): the Jacobi
    // scaling of the QP (LIGHTING_JACOBI) and, for the default smoothness scale, μ.
    let tdiag = (LIGHTING_JACOBI
        || (mu.is_none() && opts.smoothness_scale == SmoothnessScale::TexelMax))
        .then(|| texel_diag_vec(problem, beta, rows(), &alpha));
    let mu = match mu {
        Some(m) => m,
        None => match opts.smoothness_scale {
            SmoothnessScale::HaarMax => sys.max_diag(),
            SmoothnessScale::TexelMax => match &tdiag {
                Some(d) => d.iter().fold([0.0_f64; 3], |mut m, v| {
                    for c in 0..3 {
                        m[c] = m[c].max(v[c]);
                    }
                    m
                }),
                None => texel_diag(problem, beta, rows(), &alpha).0,
            },
            SmoothnessScale::Mean => texel_diag(problem, beta, rows(), &alpha).1,
        }
        .map(|d| opts.smoothness * d),
    };
    let lap = Laplacian::new(n);
    let jacobi: Option<Vec<f64>> = match (&tdiag, LIGHTING_JACOBI) {
        (Some(d), true) => {
            let ld = lap.normal_diag();
            Some(
                (0..3)
                    .flat_map(|c| (0..n2).map(move |t| (c, t)))
                    .map(|(c, t)| d[t][c] + mu[c] * ld[t])
                    .collect(),
            )
        }
        _ => None,
    };
    let mut x: Vec<f64> = match start {
        Some(s) => s.iter().flat_map(|c| c.iter().copied()).collect(),
        None => vec![0.0; 3 * n2],
    };
    if x.len() != 3 * n2 {
        return Err(Error::Config(format!(
            "lighting start has {} texels, expected {}",
            x.len(),
            3 * n2
        )));
    }
    let mut omega = vec![[1.0_f64; 3]; range.len()];
    let mut passes = if opts.robust == Robust::None {
        1
    } else {
        opts.irls_iters.max(1)
    };
    // The light prior is linearised at the current iterate: from zero, a second pass.
    let prior_proj = opts
        .light_prior
        .as_ref()
        .map(|_| crate::light_sh_prior::ShProjection::new(n, 4));
    if prior_proj.is_some() && x.iter().all(|v| *v == 0.0) {
        passes = passes.max(2);
    }
    let y_ms = {
        let (num, den) = (0..range.len()).fold((0.0, 0.0), |(a, b), q| {
            let yy = (y[q][0].powi(2) + y[q][1].powi(2) + y[q][2].powi(2)) / 3.0;
            (a + alpha[q] * yy, b + alpha[q])
        });
        if den > 0.0 {
            num / den
        } else {
            0.0
        }
    };
    let mut cond = 0.0_f64;
    let mut converged = true;
    let mut matvecs = 0;
    let (mut qps, mut unconverged_qps, mut matvecs_max) = (0, 0, 0);
    let mut pred = vec![[0.0; 3]; range.len()];
    for pass in 0..passes {
        // Reweight from the current residuals (the first pass: unit weights, a restart).
        if pass > 0 {
            let h = haar3(&split3(&x, n2), n);
            match sample {
                Some(_) => pred = forward_full(problem, beta, range.clone(), &h),
                None => sys.forward_rows(&h, &mut pred),
            }
            for c in 0..3 {
                let mut ab: Vec<f64> = (0..range.len())
                    .filter(|&q| alpha_all[q] > 0.0)
                    .map(|q| (y_all[q][c] - pred[q][c]).abs())
                    .collect();
                if ab.is_empty() {
                    continue;
                }
                let n_fit = ab.len();
                let mid = n_fit / 2;
                let (_, med, _) = ab.select_nth_unstable_by(mid, f64::total_cmp);
                let scale = y_all.iter().map(|v| v[c].abs()).sum::<f64>() / y_all.len() as f64;
                // The noise floor: a fraction of the RMS observed radiance (struct docs of
                // `EstimateOptions::robust_floor`).
                let rms = ((0..range.len())
                    .filter(|&q| alpha_all[q] > 0.0)
                    .map(|q| y_all[q][c] * y_all[q][c])
                    .sum::<f64>()
                    / n_fit as f64)
                    .sqrt();
                let sigma = (1.4826 * *med)
                    .max(opts.robust_floor * rms)
                    .max(1e-9 * scale)
                    .max(f64::MIN_POSITIVE);
                for q in 0..range.len() {
                    omega[q][c] = robust_weight(opts.robust, y_all[q][c] - pred[q][c], sigma);
                }
            }
        }
        for (r, &q) in pos.iter().enumerate() {
            for c in 0..3 {
                sys.dw[r][c] = alpha[r] * omega[q][c];
            }
        }
        // Right-hand side Wᵀ Aᵀ D y.
        let u: Vec<[f64; 3]> = (0..pos.len())
            .map(|q| [0, 1, 2].map(|c| sys.dw[q][c] * y[q][c]))
            .collect();
        let mut hb = vec![[0.0; 3]; n2];
        sys.adjoint_rows(&u, &mut hb);
        let b = unhaar3(&hb, n);
        let bmax = b.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        if bmax == 0.0 {
            // No light reaches any weighted observation: the minimiser is x = 0.
            x.iter_mut().for_each(|v| *v = 0.0);
            continue;
        }
        let prior = match (&opts.light_prior, &prior_proj) {
            (Some(lp), Some(pp)) => lp.pass(photo, pp, &x, n, y_ms),
            _ => None,
        };
        let jac_pass: Option<Vec<f64>> = match (&jacobi, &prior) {
            (Some(j), Some(p)) => Some(j.iter().zip(p.diagonal()).map(|(a, b)| a + b).collect()),
            (j, _) => j.clone(),
        };
        let sys_ref = &sys;
        let lap_ref = &lap;
        let prior_ref = prior.as_ref();
        let hess = |v: &[f64], out: &mut [f64]| {
            let h = haar3(&split3(v, n2), n);
            let mut hb = vec![[0.0; 3]; n2];
            sys_ref.normal_rows(&h, &mut hb);
            if let Some(p) = prior_ref {
                p.add_haar(&h, &mut hb);
            }
            let r = unhaar3(&hb, n);
            out.copy_from_slice(&r);
            if let Some(p) = prior_ref {
                p.add_texel(v, out);
            }
            for c in 0..3 {
                lap_ref.add_normal(
                    &v[c * n2..(c + 1) * n2],
                    mu[c],
                    &mut out[c * n2..(c + 1) * n2],
                );
            }
        };
        let qp = QpOptions {
            tol: opts.qp_rel_tol * bmax,
            max_iter: opts.qp_max_iter,
            max_cg: opts.qp_max_cg.max(1),
        };
        let res = bound_qp_scaled(hess, &b, &x, &qp, jac_pass.as_deref()).map_err(|e| {
            Error::Numeric {
                stage: format!("lighting step, photo {photo}"),
                message: e.to_string(),
            }
        })?;
        converged &= res.converged;
        matvecs += res.matvecs;
        qps += 1;
        unconverged_qps += usize::from(!res.converged);
        matvecs_max = matvecs_max.max(res.matvecs);
        if res.cond_lower_bound.is_finite() {
            cond = res.cond_lower_bound;
        }
        x = res.x;
    }
    Ok(LightingResult {
        light: split3(&x, n2),
        mu,
        irls_weights: omega.iter().map(|o| o.map(|v| v as f32)).collect(),
        cond_lower_bound: cond,
        converged,
        matvecs,
        qps,
        unconverged_qps,
        matvecs_max,
    })
}

fn split3(x: &[f64], n2: usize) -> [Vec<f64>; 3] {
    [0, 1, 2].map(|c| x[c * n2..(c + 1) * n2].to_vec())
}

/// Channel-major texels `Wᵀ h` of interleaved Haar coefficients.
fn unhaar3(h: &[[f64; 3]], n: usize) -> Vec<f64> {
    let n2 = n * n;
    let mut out = vec![0.0; 3 * n2];
    for c in 0..3 {
        let ch = &mut out[c * n2..(c + 1) * n2];
        for (o, v) in ch.iter_mut().zip(h) {
            *o = v[c];
        }
        haar::inverse(ch, n);
    }
    out
}

/// Lighting step (Eq. 10 + Laplacian + IRLS) for one photo from zero: its three channels'
/// texels. `beta` is [`beta_per_vertex`].
pub fn lighting_step(
    problem: &Problem,
    beta: &[[f64; 3]],
    photo: usize,
    opts: &EstimateOptions,
) -> Result<[Vec<f64>; 3]> {
    Ok(lighting_step_full(problem, beta, photo, None, None, opts)?.light)
}

/// Lighting with the reflectance frozen (held-out protocol (b)): `problem` holds only the
/// fitting half's observations of the photo, from `start` (`None`: zero), to the KKT
/// tolerance or `opts`' iteration caps.
pub fn fit_light_frozen(
    problem: &Problem,
    beta: &[[f64; 3]],
    photo: usize,
    start: Option<&[Vec<f64>; 3]>,
    opts: &EstimateOptions,
) -> Result<[Vec<f64>; 3]> {
    Ok(lighting_step_full(problem, beta, photo, start, None, opts)?.light)
}

/// `s_{p,b,c} = ⟨g_{p,b}, W x_{I(p),c}⟩` for every observation and basis, row-major `P × B`.
pub fn basis_responses(problem: &Problem, lights: &[[Vec<f64>; 3]]) -> Vec<[f64; 3]> {
    let t = problem.transport;
    let n = t.n_global;
    let nb = t.n_basis;
    let hs: Vec<Vec<[f64; 3]>> = lights.par_iter().map(|l| haar3(l, n)).collect();
    let mut out = vec![[0.0; 3]; problem.obs.vertex.len() * nb];
    out.par_chunks_mut(nb.max(1))
        .enumerate()
        .for_each(|(p, o)| {
            let h = &hs[problem.obs.photo[p] as usize];
            for (b, ob) in o.iter_mut().enumerate() {
                let (idx, val) = t.row(p, b);
                let mut acc = [0.0; 3];
                for (&m, &g) in idx.iter().zip(val) {
                    let hm = h[m as usize];
                    for c in 0..3 {
                        acc[c] += g as f64 * hm[c];
                    }
                }
                *ob = acc;
            }
        });
    out
}

/// Model prediction per observation: `Σ_b β_{x,b,c} s_{p,b,c}`.
pub fn predict(problem: &Problem, est: &Estimate) -> Vec<[f64; 3]> {
    let beta = beta_per_vertex(&est.lambda, &est.weights, problem.n_vertices);
    let s = basis_responses(problem, &est.lights);
    predict_from(problem, &beta, &s)
}

fn predict_from(problem: &Problem, beta: &[[f64; 3]], s: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let nb = problem.transport.n_basis;
    (0..problem.obs.vertex.len())
        .into_par_iter()
        .map(|p| {
            let x = problem.obs.vertex[p] as usize;
            let mut y = [0.0; 3];
            for b in 0..nb {
                for c in 0..3 {
                    y[c] += beta[x * nb + b][c] * s[p * nb + b][c];
                }
            }
            y
        })
        .collect()
}

/// Observations per fixed-size chunk in ordered parallel reductions.
const CHUNK: usize = 4096;

/// λ (`K × B × 3`), per-channel condition numbers, per-channel largest diagonal entries.
pub type LambdaStep = (Vec<Vec<[f64; 3]>>, [f64; 3], [f64; 3]);

/// Lights, λ and w of one outer iteration (for extrapolation).
type State = (Vec<[Vec<f64>; 3]>, Vec<Vec<[f64; 3]>>, Vec<f64>);

/// Material step, λ part: per channel, NNLS over all observations (`K·B` unknowns) with
/// ridge `ridge[c]` (absolute). Returns λ and each channel system's condition number and
/// largest diagonal entry (before the ridge).
pub fn lambda_step(
    problem: &Problem,
    s: &[[f64; 3]],
    weights: &[f64],
    n_materials: usize,
    dw: &[[f64; 3]],
    ridge: Option<[f64; 3]>,
    rel_ridge: f64,
) -> Result<LambdaStep> {
    let nb = problem.transport.n_basis;
    let kk = n_materials;
    let m = kk * nb;
    let obs = problem.obs;
    let np = obs.vertex.len();
    // Ordered reduction: fixed chunks in parallel, summed in chunk order.
    let partial: Vec<[(DMatrix<f64>, DVector<f64>); 3]> = (0..np.div_ceil(CHUNK))
        .into_par_iter()
        .map(|ci| {
            let mut acc =
                [0, 1, 2].map(|_| (DMatrix::<f64>::zeros(m, m), DVector::<f64>::zeros(m)));
            let mut a = vec![0.0; m];
            for p in ci * CHUNK..((ci + 1) * CHUNK).min(np) {
                let x = obs.vertex[p] as usize;
                for c in 0..3 {
                    let d = dw[p][c];
                    if d == 0.0 {
                        continue;
                    }
                    for k in 0..kk {
                        let w = weights[x * kk + k];
                        for b in 0..nb {
                            a[k * nb + b] = w * s[p * nb + b][c];
                        }
                    }
                    let (mat, rhs) = &mut acc[c];
                    let yc = obs.rgb[p][c] as f64;
                    for i in 0..m {
                        if a[i] == 0.0 {
                            continue;
                        }
                        let ai = d * a[i];
                        rhs[i] += ai * yc;
                        for j in 0..=i {
                            mat[(i, j)] += ai * a[j];
                        }
                    }
                }
            }
            acc
        })
        .collect();
    let mut sys = [0, 1, 2].map(|_| (DMatrix::<f64>::zeros(m, m), DVector::<f64>::zeros(m)));
    for part in partial {
        for (c, (pm, pr)) in part.into_iter().enumerate() {
            sys[c].0 += pm;
            sys[c].1 += pr;
        }
    }
    let mut lambda = vec![vec![[0.0; 3]; nb]; kk];
    let mut cond = [0.0; 3];
    let mut maxd = [0.0; 3];
    for c in 0..3 {
        let (mat, rhs) = &mut sys[c];
        for i in 0..m {
            for j in 0..i {
                mat[(j, i)] = mat[(i, j)];
            }
        }
        maxd[c] = (0..m).map(|i| mat[(i, i)]).fold(0.0, f64::max);
        let r = ridge.map_or(rel_ridge * maxd[c], |r| r[c]);
        for i in 0..m {
            mat[(i, i)] += r;
        }
        let ev = mat.clone().symmetric_eigenvalues();
        let (lo, hi) = ev
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(l, h), &v| (l.min(v), h.max(v)));
        cond[c] = if lo > 0.0 { hi / lo } else { f64::INFINITY };
        let sol = nnls(mat, rhs, &NnlsOptions::default()).map_err(|e| Error::Numeric {
            stage: format!("material step (λ, channel {c})"),
            message: e.to_string(),
        })?;
        for k in 0..kk {
            for b in 0..nb {
                lambda[k][b][c] = sol[k * nb + b];
            }
        }
    }
    Ok((lambda, cond, maxd))
}

/// Observations of each vertex (CSR over vertices): `(offsets, obs indices)`.
fn by_vertex(obs: &Observations, n_vertices: usize) -> (Vec<usize>, Vec<usize>) {
    let mut off = vec![0usize; n_vertices + 1];
    for &x in &obs.vertex {
        off[x as usize + 1] += 1;
    }
    for i in 0..n_vertices {
        off[i + 1] += off[i];
    }
    let mut fill = off.clone();
    let mut list = vec![0usize; obs.vertex.len()];
    for (p, &x) in obs.vertex.iter().enumerate() {
        list[fill[x as usize]] = p;
        fill[x as usize] += 1;
    }
    (off, list)
}

/// Material step, w part (Eq. 12): per vertex, NNLS over its observations in all channels.
/// Vertices without weighted observations keep their weights. Returns the new weights, the
/// largest finite condition number and the count of singular systems.
pub fn weights_step(
    problem: &Problem,
    s: &[[f64; 3]],
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    dw: &[[f64; 3]],
) -> Result<(Vec<f64>, f64, usize)> {
    let nb = problem.transport.n_basis;
    let kk = lambda.len();
    let obs = problem.obs;
    let (off, list) = by_vertex(obs, problem.n_vertices);
    let rows: Vec<Result<(Vec<f64>, f64)>> = (0..problem.n_vertices)
        .into_par_iter()
        .map(|x| {
            let mut mat = DMatrix::<f64>::zeros(kk, kk);
            let mut rhs = DVector::<f64>::zeros(kk);
            let mut a = vec![0.0; kk];
            let mut any = false;
            for &p in &list[off[x]..off[x + 1]] {
                for c in 0..3 {
                    let d = dw[p][c];
                    if d == 0.0 {
                        continue;
                    }
                    any = true;
                    for k in 0..kk {
                        a[k] = (0..nb).map(|b| lambda[k][b][c] * s[p * nb + b][c]).sum();
                    }
                    let yc = obs.rgb[p][c] as f64;
                    for i in 0..kk {
                        rhs[i] += d * a[i] * yc;
                        for j in 0..kk {
                            mat[(i, j)] += d * a[i] * a[j];
                        }
                    }
                }
            }
            let old = weights[x * kk..(x + 1) * kk].to_vec();
            if !any {
                return Ok((old, 0.0));
            }
            let ev = mat.clone().symmetric_eigenvalues();
            let (lo, hi) = ev
                .iter()
                .fold((f64::INFINITY, 0.0_f64), |(l, h), &v| (l.min(v), h.max(v)));
            let cond = if lo > 1e-14 * hi && hi > 0.0 {
                hi / lo
            } else {
                f64::INFINITY
            };
            let sol = nnls(&mat, &rhs, &NnlsOptions::default()).map_err(|e| Error::Numeric {
                stage: format!("material step (w, vertex {x})"),
                message: e.to_string(),
            })?;
            Ok((sol.iter().copied().collect(), cond))
        })
        .collect();
    let mut out = Vec::with_capacity(weights.len());
    let (mut cmax, mut singular) = (0.0_f64, 0usize);
    for r in rows {
        let (w, c) = r?;
        out.extend(w);
        if c.is_finite() {
            cmax = cmax.max(c);
        } else {
            singular += 1;
        }
    }
    Ok((out, cmax, singular))
}

/// Data term, train RMSE: `(Σ α ω r², RMSE over α > 0)`.
fn data_fit(problem: &Problem, pred: &[[f64; 3]], omega: &[[f32; 3]]) -> (f64, f64) {
    let obs = problem.obs;
    let np = obs.vertex.len();
    let parts: Vec<(f64, f64, usize)> = (0..np.div_ceil(CHUNK))
        .into_par_iter()
        .map(|ci| {
            let (mut f, mut sq, mut cnt) = (0.0, 0.0, 0usize);
            for p in ci * CHUNK..((ci + 1) * CHUNK).min(np) {
                let a = obs.weight[p] as f64;
                if a <= 0.0 {
                    continue;
                }
                cnt += 1;
                for c in 0..3 {
                    let r = obs.rgb[p][c] as f64 - pred[p][c];
                    f += a * omega[p][c] as f64 * r * r;
                    sq += r * r;
                }
            }
            (f, sq, cnt)
        })
        .collect();
    let (mut f, mut sq, mut cnt) = (0.0, 0.0, 0usize);
    for (a, b, c) in parts {
        f += a;
        sq += b;
        cnt += c;
    }
    (
        f,
        if cnt > 0 {
            (sq / (3 * cnt) as f64).sqrt()
        } else {
            0.0
        },
    )
}

/// Objective `F` (module docs) and train RMSE for a state; `s` = its basis responses when
/// already computed.
#[allow(clippy::too_many_arguments)]
fn evaluate(
    problem: &Problem,
    lights: &[[Vec<f64>; 3]],
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    mu: &[Option<[f64; 3]>],
    ridge: Option<[f64; 3]>,
    omega: &[[f32; 3]],
    lap: &Laplacian,
    s: Option<&[[f64; 3]]>,
) -> (f64, f64) {
    let owned;
    let s = match s {
        Some(s) => s,
        None => {
            owned = basis_responses(problem, lights);
            &owned
        }
    };
    let beta = beta_per_vertex(lambda, weights, problem.n_vertices);
    let pred = predict_from(problem, &beta, s);
    let (data, rmse) = data_fit(problem, &pred, omega);
    let smooth: f64 = lights
        .iter()
        .zip(mu)
        .map(|(l, m)| {
            let m = m.unwrap_or([0.0; 3]);
            (0..3).map(|c| m[c] * lap.energy(&l[c])).sum::<f64>()
        })
        .sum();
    let rid: f64 = ridge.map_or(0.0, |r| {
        lambda
            .iter()
            .flatten()
            .map(|v| (0..3).map(|c| r[c] * v[c] * v[c]).sum::<f64>())
            .sum()
    });
    (data + smooth + rid, rmse)
}

/// Per channel `Σ_x Σ_b β_{x,b,c} = Σ_k (Σ_x w_k(x)) (Σ_b λ_{k,b,c})`: the scale that
/// [`EstimateOptions::fix_gauge`] holds fixed.
fn gauge(lambda: &[Vec<[f64; 3]>], weights: &[f64], n_vertices: usize) -> [f64; 3] {
    let kk = lambda.len();
    let mut g = [0.0; 3];
    for (k, lk) in lambda.iter().enumerate() {
        let wsum: f64 = (0..n_vertices).map(|x| weights[x * kk + k]).sum();
        for c in 0..3 {
            g[c] += wsum * lk.iter().map(|v| v[c]).sum::<f64>();
        }
    }
    g
}

/// Early stopping's validation observations (sorted): per vertex in order, each of its
/// `α > 0` observations is drawn with probability `fraction` (seeded PCG), never leaving
/// the vertex fewer than [`VALIDATION_MIN_FIT`] fitted ones.
pub fn validation_split(
    obs: &Observations,
    n_vertices: usize,
    fraction: f64,
    seed: u64,
) -> Vec<usize> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let (off, list) = by_vertex(obs, n_vertices);
    let mut out = Vec::new();
    for x in 0..n_vertices {
        let mine: Vec<usize> = list[off[x]..off[x + 1]]
            .iter()
            .copied()
            .filter(|&p| obs.weight[p] > 0.0)
            .collect();
        let mut left = mine.len();
        for p in mine {
            let u: f64 = rng.random();
            if u < fraction && left > VALIDATION_MIN_FIT {
                out.push(p);
                left -= 1;
            }
        }
    }
    out.sort_unstable();
    out
}

/// Early stopping's score: `sqrt(Σ α (y − ŷ)²) / sqrt(Σ α y²)` over the observations `idx`
/// and channels (`α` from `obs`, the unmasked observations).
fn validation_error(
    problem: &Problem,
    obs: &Observations,
    lights: &[[Vec<f64>; 3]],
    beta: &[[f64; 3]],
    idx: &[usize],
) -> f64 {
    let t = problem.transport;
    let (n, nb) = (t.n_global, t.n_basis);
    let hs: Vec<Vec<[f64; 3]>> = lights.par_iter().map(|l| haar3(l, n)).collect();
    let parts: Vec<(f64, f64)> = idx
        .par_chunks(CHUNK)
        .map(|ch| {
            let (mut se, mut yy) = (0.0, 0.0);
            for &p in ch {
                let h = &hs[obs.photo[p] as usize];
                let x = obs.vertex[p] as usize;
                let mut pred = [0.0; 3];
                for b in 0..nb {
                    let (ix, val) = t.row(p, b);
                    let be = beta[x * nb + b];
                    for (&m, &g) in ix.iter().zip(val) {
                        let hm = h[m as usize];
                        for c in 0..3 {
                            pred[c] += be[c] * g as f64 * hm[c];
                        }
                    }
                }
                let a = obs.weight[p] as f64;
                for c in 0..3 {
                    let y = obs.rgb[p][c] as f64;
                    se += a * (y - pred[c]).powi(2);
                    yy += a * y * y;
                }
            }
            (se, yy)
        })
        .collect();
    let (se, yy) = parts
        .into_iter()
        .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    if yy > 0.0 {
        (se / yy).sqrt()
    } else {
        se.sqrt()
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

/// The alternation (Sec. 5): lighting steps for all photos (in parallel), then the material
/// step, until the objective's relative decrease is below `rel_tol` or `max_outer` is reached.
/// `on_iter` sees every outer iteration's log line and the state it reached.
pub fn estimate(
    problem: &Problem,
    init: Materials0,
    opts: &EstimateOptions,
    on_iter: &mut dyn FnMut(&Iteration, &IterState),
) -> Result<Estimate> {
    problem.validate()?;
    let t0 = Instant::now();
    let nb = problem.transport.n_basis;
    let n2 = problem.transport.n_global * problem.transport.n_global;
    let kk = init.lambda.len();
    let nv = problem.n_vertices;
    if kk == 0 || init.lambda.iter().any(|l| l.len() != nb) || init.weights.len() != nv * kk {
        return Err(Error::Config(format!(
            "initial materials: {kk} materials with {:?} bases and {} weights, expected B = {nb}, V·K = {}",
            init.lambda.iter().map(|l| l.len()).collect::<Vec<_>>(),
            init.weights.len(),
            nv * kk
        )));
    }
    if init
        .lambda
        .iter()
        .flatten()
        .flatten()
        .chain(&init.weights)
        .any(|v| !v.is_finite() || *v < 0.0)
    {
        return Err(Error::Config(
            "initial materials must be finite and non-negative".into(),
        ));
    }
    // Early stopping: the validation observations get α = 0 in the fitted copy.
    let val_idx = if !opts.fixed_materials && opts.validation_fraction > 0.0 && opts.max_outer > 1 {
        validation_split(
            problem.obs,
            problem.n_vertices,
            opts.validation_fraction,
            opts.validation_seed,
        )
    } else {
        Vec::new()
    };
    let masked;
    let full_obs = problem.obs;
    let problem_fit;
    let problem = if val_idx.is_empty() {
        problem
    } else {
        let mut m = full_obs.clone();
        for &p in &val_idx {
            m.weight[p] = 0.0;
        }
        masked = m;
        problem_fit = Problem {
            obs: &masked,
            ..*problem
        };
        &problem_fit
    };
    let g0 = gauge(&init.lambda, &init.weights, problem.n_vertices);
    let mut val_errors: Vec<f64> = Vec::new();
    let mut best: Option<(usize, State, Vec<[f32; 3]>)> = None;
    let mut stopped_early = false;
    let mut lambda = init.lambda.clone();
    let mut weights = init.weights.clone();
    let np = problem.obs.vertex.len();
    let mut lights: Vec<[Vec<f64>; 3]> = (0..problem.n_photos)
        .map(|_| [vec![0.0; n2], vec![0.0; n2], vec![0.0; n2]])
        .collect();
    let mut mu: Vec<Option<[f64; 3]>> = vec![None; problem.n_photos];
    // μ of each photo's first lighting step, the schedule's `μ_1`.
    let mut mu_first: Vec<Option<[f64; 3]>> = vec![None; problem.n_photos];
    let mut omega = vec![[1.0_f32; 3]; np];
    let mut ridge: Option<[f64; 3]> = None;
    let mut timeline = Vec::new();
    let mut cond = Conditioning::default();
    let lap = Laplacian::new(problem.transport.n_global);
    let mut prev_obj = f64::INFINITY;
    let mut prev_state: Option<State> = None;
    let outer = if opts.fixed_materials {
        1
    } else {
        opts.max_outer.max(1)
    };
    // Inside the alternation the lighting QPs are inexact block steps (option docs).
    let capped = |cap: Option<usize>, max: usize| match (opts.fixed_materials, cap) {
        (false, Some(c)) => c.clamp(1, max.max(1)),
        _ => max,
    };
    let light_opts = EstimateOptions {
        qp_max_iter: capped(opts.alternation_qp_iters, opts.qp_max_iter),
        qp_max_cg: capped(opts.alternation_cg_iters, opts.qp_max_cg),
        ..opts.clone()
    };
    // The lighting sample of each photo, fixed for the whole alternation (the QPs'
    // objective stays one function): strata crossed with the starting dominant material.
    let dominant = crate::solve::subsample::dominant_material(&init.weights, kk);
    let samples: Vec<Option<crate::solve::subsample::Subsample>> = (0..problem.n_photos)
        .map(|i| lighting_sample(problem, i, opts, Some(&dominant)))
        .collect();
    for outer_it in 1..=outer {
        // 1. Lighting, photos in parallel (each photo's solve is sequential: deterministic).
        let beta = beta_per_vertex(&lambda, &weights, nv);
        let mu_factor = if opts.smoothness_decay == 1.0 || opts.smoothness <= 0.0 {
            1.0
        } else {
            opts.smoothness_decay
                .powi(outer_it as i32 - 1)
                .max(opts.smoothness_min / opts.smoothness)
                .min(1.0)
        };
        let sizes: Vec<usize> = problem.obs.photo_ranges.iter().map(|r| r.len()).collect();
        let watch = crate::stages::Stopwatch::start();
        let results: Vec<Result<LightingResult>> = par_largest_first(&sizes, |i| {
            let m = mu_first[i].map(|m| m.map(|v| v * mu_factor));
            let sample = samples[i].as_ref();
            lighting_step_on(problem, &beta, i, Some(&lights[i]), m, &light_opts, sample)
        });
        cond.lighting.clear();
        cond.qp_unconverged = 0;
        cond.qp_alternation_capped = 0;
        for (i, r) in results.into_iter().enumerate() {
            let r = r?;
            let range = problem.obs.photo_ranges[i].clone();
            omega[range].copy_from_slice(&r.irls_weights);
            lights[i] = r.light;
            if mu_first[i].is_none() {
                mu_first[i] = Some(r.mu);
            }
            mu[i] = Some(r.mu);
            cond.lighting.push(r.cond_lower_bound);
            cond.qp_unconverged += usize::from(!r.converged);
            cond.lighting_matvecs += r.matvecs;
            cond.lighting_qps += r.qps;
            cond.lighting_matvecs_max = cond.lighting_matvecs_max.max(r.matvecs_max);
            if light_opts.qp_max_iter < opts.qp_max_iter {
                cond.qp_alternation_capped += r.unconverged_qps;
            }
        }
        let (lighting_seconds, lighting_cpu_seconds) = watch.elapsed();
        // 2. Materials.
        let watch = crate::stages::Stopwatch::start();
        let cut = match (opts.robust, opts.weights_reject) {
            (Robust::Huber { k }, Some(c)) if c > 0.0 => k / c,
            _ => 0.0,
        };
        let dw: Vec<[f64; 3]> = (0..np)
            .map(|p| {
                let a = problem.obs.weight[p] as f64;
                omega[p].map(|o| {
                    if !opts.materials_cut_only || cut == 0.0 {
                        o as f64 * a
                    } else if (o as f64) < cut {
                        0.0
                    } else {
                        a
                    }
                })
            })
            .collect();
        let dw_w: Vec<[f64; 3]> = (0..np)
            .map(|p| {
                [0, 1, 2].map(|c| {
                    if (omega[p][c] as f64) < cut {
                        0.0
                    } else {
                        dw[p][c]
                    }
                })
            })
            .collect();
        let mut s = basis_responses(problem, &lights);
        if !opts.fixed_materials {
            for _ in 0..opts.material_sweeps.max(1) {
                let (l, c, maxd) = lambda_step(problem, &s, &weights, kk, &dw, ridge, opts.beta)?;
                if ridge.is_none() {
                    ridge = Some(maxd.map(|d| opts.beta * d));
                }
                lambda = l;
                cond.lambda = c;
                let (w, cmax, sing) = weights_step(problem, &s, &lambda, &weights, &dw_w)?;
                weights = w;
                cond.weights_max = cmax;
                cond.weights_singular = sing;
            }
            if opts.fix_gauge {
                // Per channel, `G_c = Σ_x Σ_b β_{x,b,c}` back to its start value, the maps
                // (and their responses `s`) taking the inverse factor: the data term is
                // unchanged, and `μ`, fixed at the first lighting step, keeps its meaning.
                let g_now = gauge(&lambda, &weights, nv);
                for c in 0..3 {
                    if g_now[c] > 0.0 && g0[c] > 0.0 {
                        let f = g0[c] / g_now[c];
                        for v in lambda.iter_mut().flatten() {
                            v[c] *= f;
                        }
                        for l in lights.iter_mut() {
                            l[c].iter_mut().for_each(|v| *v /= f);
                        }
                        for v in s.iter_mut() {
                            v[c] /= f;
                        }
                    }
                }
            }
        }
        let (material_seconds, material_cpu_seconds) = watch.elapsed();
        // 3. Extrapolate (Bro 1998, "Multi-way analysis", §4.5: alternating least squares
        //    crawls along the bilinear valley): try θ + σ(θ − θ_prev), σ = t^{1/3},
        //    projected to ≥ 0, kept only when the objective drops, so F stays monotone.
        let (mut objective, mut rmse) = evaluate(
            problem,
            &lights,
            &lambda,
            &weights,
            &mu,
            ridge,
            &omega,
            &lap,
            Some(&s),
        );
        if !opts.fixed_materials && opts.extrapolate {
            if let Some((pl, plam, pw)) = &prev_state {
                let sig = (outer_it as f64).cbrt();
                let ext = |a: f64, b: f64| (a + sig * (a - b)).max(0.0);
                let cl: Vec<[Vec<f64>; 3]> = lights
                    .iter()
                    .zip(pl)
                    .map(|(l, q)| {
                        [0, 1, 2]
                            .map(|c| l[c].iter().zip(&q[c]).map(|(&a, &b)| ext(a, b)).collect())
                    })
                    .collect();
                let clam: Vec<Vec<[f64; 3]>> = lambda
                    .iter()
                    .zip(plam)
                    .map(|(l, q)| {
                        l.iter()
                            .zip(q)
                            .map(|(a, b)| [0, 1, 2].map(|c| ext(a[c], b[c])))
                            .collect()
                    })
                    .collect();
                let cw: Vec<f64> = weights.iter().zip(pw).map(|(&a, &b)| ext(a, b)).collect();
                let (fo, ro) = evaluate(problem, &cl, &clam, &cw, &mu, ridge, &omega, &lap, None);
                if fo < objective {
                    lights = cl;
                    lambda = clam;
                    weights = cw;
                    objective = fo;
                    rmse = ro;
                }
            }
            prev_state = Some((lights.clone(), lambda.clone(), weights.clone()));
        }
        if !objective.is_finite() {
            return Err(Error::Numeric {
                stage: "estimation".into(),
                message: "the objective became non-finite".into(),
            });
        }
        let validation_rel = if val_idx.is_empty() {
            None
        } else {
            let beta = beta_per_vertex(&lambda, &weights, nv);
            let e = validation_error(problem, full_obs, &lights, &beta, &val_idx);
            val_errors.push(e);
            if best.as_ref().is_none_or(|b| e < val_errors[b.0 - 1]) {
                best = Some((
                    outer_it,
                    (lights.clone(), lambda.clone(), weights.clone()),
                    omega.clone(),
                ));
            }
            Some(e)
        };
        let it = Iteration {
            seconds: t0.elapsed().as_secs_f64(),
            objective,
            train_rmse: rmse,
            validation_rel,
            steps: StepTimes {
                lighting_seconds,
                lighting_cpu_seconds,
                material_seconds,
                material_cpu_seconds,
            },
        };
        on_iter(
            &it,
            &IterState {
                lights: &lights,
                lambda: &lambda,
                weights: &weights,
            },
        );
        timeline.push(it);
        if let Some(b) = &best {
            if outer_it >= b.0 + opts.patience.max(1) {
                stopped_early = outer_it < outer;
                break;
            }
        }
        if prev_obj.is_finite() && (prev_obj - objective).abs() <= opts.rel_tol * prev_obj.abs() {
            break;
        }
        prev_obj = objective;
    }
    let validation = best.map(|(it, (l, lam, w), om)| {
        lights = l;
        lambda = lam;
        weights = w;
        omega = om;
        Validation {
            observations: val_idx.len(),
            fraction: opts.validation_fraction,
            errors: val_errors,
            best_iteration: it,
            stopped_early,
        }
    });

    let sample_check = samples.iter().any(Option::is_some).then(|| {
        let beta = beta_per_vertex(&lambda, &weights, nv);
        let pred = predict_from(problem, &beta, &basis_responses(problem, &lights));
        let o = problem.obs;
        crate::solve::subsample::sample_check(
            &pred,
            &o.rgb,
            &o.weight,
            &o.photo_ranges,
            &samples,
            opts.lighting_sample,
        )
    });
    // Normalisation (module docs).
    let mut mu: Vec<[f64; 3]> = mu.into_iter().map(|m| m.unwrap_or([0.0; 3])).collect();
    let normalisation = if opts.fixed_materials {
        "none: the reflectance is given, so the lights carry the absolute scale".to_string()
    } else {
        // Per material: the median weight over the vertices where it dominates becomes 1
        // (pure-material vertices get weight ≈ 1; robust to blends and stray large weights).
        for k in 0..kk {
            let mut dom: Vec<f64> = (0..nv)
                .filter(|&x| {
                    let row = &weights[x * kk..(x + 1) * kk];
                    row[k] > 0.0 && row.iter().all(|&v| v <= row[k])
                })
                .map(|x| weights[x * kk + k])
                .collect();
            if dom.is_empty() {
                continue;
            }
            let mid = dom.len() / 2;
            let (_, med, _) = dom.select_nth_unstable_by(mid, f64::total_cmp);
            let scale = *med;
            if scale > 0.0 {
                for x in 0..nv {
                    weights[x * kk + k] /= scale;
                }
                for v in lambda[k].iter_mut().flatten() {
                    *v *= scale;
                }
            }
        }
        let lb = opts.lambert_basis.min(nb - 1);
        let mean_l = |l: &[Vec<[f64; 3]>]| {
            l.iter().map(|r| r[lb].iter().sum::<f64>()).sum::<f64>() / (3 * kk) as f64
        };
        let mean_all =
            |l: &[Vec<[f64; 3]>]| l.iter().flatten().flatten().sum::<f64>() / (3 * kk * nb) as f64;
        let (target, now, what) = if mean_l(&init.lambda) > 0.0 && mean_l(&lambda) > 0.0 {
            (
                mean_l(&init.lambda),
                mean_l(&lambda),
                format!("the mean Lambertian weight λ_k,{lb},c over materials and channels"),
            )
        } else {
            (
                mean_all(&init.lambda),
                mean_all(&lambda),
                "the mean of all λ_k,b,c".to_string(),
            )
        };
        if target > 0.0 && now > 0.0 {
            let s = target / now;
            for v in lambda.iter_mut().flatten().flatten() {
                *v *= s;
            }
            for l in lights.iter_mut() {
                for v in l.iter_mut().flatten() {
                    *v /= s;
                }
            }
            for m in mu.iter_mut() {
                for v in m.iter_mut() {
                    *v *= s * s;
                }
            }
        }
        format!(
            "every material's median blending weight over the vertices it dominates is 1; then {what} equals its initial value {target:.6e}; maps scaled inversely"
        )
    };
    Ok(Estimate {
        lights,
        lambda,
        weights,
        timeline,
        normalisation,
        mu,
        irls_weights: omega,
        conditioning: cond,
        validation,
        lighting_sample: sample_check,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// One photo of `rows` observations (vertex = observation) over an `n²` map: each row
    /// 24 random Haar coefficients of the low levels (the first `n²/4`), positive values;
    /// `y` from a known smooth light plus Gaussian-like noise (`σ` relative).
    fn planted_photo(rows: usize, n: usize, noise: f64, seed: u64) -> (Observations, Transport) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let n2 = n * n;
        let light: Vec<[f64; 3]> = {
            let tex: [Vec<f64>; 3] = [0, 1, 2].map(|c| {
                (0..n2)
                    .map(|t| 1.0 + 0.5 * ((t % n) as f64 / n as f64 + c as f64).sin())
                    .collect()
            });
            haar3(&tex, n)
        };
        let mut t = Transport {
            n_global: n,
            n_basis: 1,
            n_obs: rows,
            offsets: vec![0],
            ..Default::default()
        };
        let mut obs = Observations::default();
        for p in 0..rows {
            let mut idx: Vec<HaarIndex> = (0..24)
                .map(|_| rng.random_range(0..n2 / 4) as HaarIndex)
                .collect();
            idx.sort_unstable();
            idx.dedup();
            let val: Vec<f32> = idx.iter().map(|_| rng.random_range(0.1..1.0)).collect();
            let clean = row_dot(
                &idx,
                &val.iter().map(|&v| [v; 3]).collect::<Vec<_>>(),
                &light,
            );
            t.index.extend(&idx);
            t.value.extend(&val);
            t.offsets.push(t.index.len());
            obs.vertex.push(p as u32);
            obs.photo.push(0);
            // Sum of 4 uniforms on [-1, 1]: mean 0, variance 4/3.
            let mut e = || {
                (0..4).map(|_| rng.random_range(-1.0..1.0)).sum::<f64>() / (4.0_f64 / 3.0).sqrt()
            };
            obs.rgb
                .push(clean.map(|v| (v * (1.0 + noise * e())) as f32));
            obs.weight.push(1.0);
            obs.dir.push([0.0, 0.0, 1.0]);
        }
        let all = 0..rows;
        obs.photo_ranges = vec![all];
        (obs, t)
    }

    #[test]
    fn a_lighting_sample_leaves_the_map_where_all_observations_put_it() {
        // 6,000 observations, 3 × 256 unknowns of which the rows reach the 64 coarsest
        // Haar levels: the full fit against fits on 1,500 sampled rows (four seeds), all to
        // the KKT tolerance. With 2% noise the full fit's own error against the truth is
        // the yardstick: a sample of a quarter of the rows has about twice the variance
        // (√4 = 2 × the standard error), so the sampled map must stay within 3 × the full
        // fit's distance from the truth of the full map, and its predictions of the rows
        // it never saw must be as good as of those it saw (ratio < 1.1, the run's check).
        let n = 16;
        let (obs, t) = planted_photo(6000, n, 0.02, 11);
        let problem = Problem {
            obs: &obs,
            transport: &t,
            n_vertices: obs.len(),
            n_photos: 1,
        };
        let beta = vec![[1.0; 3]; obs.len()];
        let opts = EstimateOptions {
            robust: Robust::None,
            irls_iters: 1,
            smoothness: 1e-4,
            qp_rel_tol: 1e-9,
            qp_max_iter: 500,
            ..EstimateOptions::default()
        };
        let full = lighting_step_full(&problem, &beta, 0, None, None, &opts).unwrap();
        let dist = |a: &[Vec<f64>; 3], b: &[Vec<f64>; 3]| -> f64 {
            let ha = haar3(a, n);
            let hb = haar3(b, n);
            // Only the coefficients the rows reach are determined by the data.
            let (mut d, mut s) = (0.0, 0.0);
            for m in 0..n * n / 4 {
                for c in 0..3 {
                    d += (ha[m][c] - hb[m][c]).powi(2);
                    s += hb[m][c].powi(2);
                }
            }
            (d / s).sqrt()
        };
        let truth: [Vec<f64>; 3] = [0, 1, 2].map(|c| {
            (0..n * n)
                .map(|t| 1.0 + 0.5 * ((t % n) as f64 / n as f64 + c as f64).sin())
                .collect()
        });
        let full_err = dist(&full.light, &truth);
        assert!(full_err < 0.05, "the full fit itself: {full_err}");
        for seed in 1..=4 {
            let sampled_opts = EstimateOptions {
                lighting_sample: 1500,
                validation_seed: seed,
                ..opts.clone()
            };
            let sample = lighting_sample(&problem, 0, &sampled_opts, None).unwrap();
            assert_eq!(sample.index.len(), 1500);
            let r = lighting_step_on(&problem, &beta, 0, None, None, &sampled_opts, Some(&sample))
                .unwrap();
            assert_eq!(
                r.irls_weights.len(),
                obs.len(),
                "weights for every observation"
            );
            let moved = dist(&r.light, &full.light);
            assert!(
                moved < 3.0 * full_err,
                "seed {seed}: moved {moved}, full fit's error {full_err}"
            );
            let pred = predict_from(
                &problem,
                &beta,
                &basis_responses(&problem, std::slice::from_ref(&r.light)),
            );
            let check = crate::solve::subsample::sample_check(
                &pred,
                &obs.rgb,
                &obs.weight,
                &obs.photo_ranges,
                &[Some(sample)],
                1500,
            );
            assert_eq!(check.in_sample + check.out_of_sample, obs.len());
            assert!(check.ratio < 1.1, "seed {seed}: {check:?}");
        }
    }

    #[test]
    fn entry_chunks_cover_the_rows_in_order_and_balance_the_entries() {
        // 1,000 rows of 0–99 entries.
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let mut offsets = vec![0];
        for _ in 0..1000 {
            let len = rng.random_range(0..100);
            offsets.push(offsets.last().unwrap() + len);
        }
        let chunks = entry_chunks(&offsets, 4);
        assert_eq!(chunks.len(), 4);
        assert_eq!(chunks[0].start, 0);
        assert_eq!(chunks.last().unwrap().end, 1000);
        for w in chunks.windows(2) {
            assert_eq!(w[0].end, w[1].start);
        }
        let total = *offsets.last().unwrap();
        for c in &chunks {
            let e = offsets[c.end] - offsets[c.start];
            // A cut lands on a row boundary, so a part is off its quarter by less than one
            // row (< 100 entries).
            assert!((e as i64 - total as i64 / 4).abs() < 100, "{e} of {total}");
        }
        // Fewer rows than parts, and no rows: no empty part.
        assert_eq!(entry_chunks(&[0, 5, 9], 4), vec![0..1, 1..2]);
        assert!(entry_chunks(&[0], 4).is_empty());
    }

    #[test]
    fn the_parallel_product_is_the_forward_scale_adjoint_sequence() {
        // Random merged rows over a 16² map; the fused, chunked `Aᵀ D A h` against the
        // forward rows, the scaling by `D` and the adjoint rows done one after the other.
        // Only the order of the additions differs: 1e-12 relative.
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let n = 16;
        let rows = 500;
        let mut offsets = vec![0];
        let (mut index, mut value) = (Vec::new(), Vec::new());
        for _ in 0..rows {
            let mut idx: Vec<HaarIndex> = (0..n * n)
                .filter(|_| rng.random_bool(0.2))
                .map(|m| m as HaarIndex)
                .collect();
            idx.sort_unstable();
            for _ in &idx {
                value.push([0, 1, 2].map(|_| rng.random_range(-1.0_f32..1.0)));
            }
            index.extend(idx);
            offsets.push(index.len());
        }
        let dw: Vec<[f64; 3]> = (0..rows)
            .map(|_| [0, 1, 2].map(|_| rng.random_range(0.0..2.0)))
            .collect();
        let chunks = entry_chunks(&offsets, PRODUCT_CHUNKS);
        let sys = PhotoSystem {
            range: 0..rows,
            n,
            dw: dw.clone(),
            offsets,
            index,
            value,
            chunks,
        };
        let h: Vec<[f64; 3]> = (0..n * n)
            .map(|_| [0, 1, 2].map(|_| rng.random_range(-1.0..1.0)))
            .collect();
        let mut fused = vec![[0.0; 3]; n * n];
        sys.normal_rows(&h, &mut fused);
        let mut s = vec![[0.0; 3]; rows];
        sys.forward_rows(&h, &mut s);
        let u: Vec<[f64; 3]> = s
            .iter()
            .zip(&dw)
            .map(|(s, d)| [s[0] * d[0], s[1] * d[1], s[2] * d[2]])
            .collect();
        let mut seq = vec![[0.0; 3]; n * n];
        sys.adjoint_rows(&u, &mut seq);
        let scale = seq.iter().flatten().fold(0.0_f64, |a, v| a.max(v.abs()));
        assert!(scale > 1.0);
        for (a, b) in fused.iter().zip(&seq) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-12 * scale, "{} vs {}", a[c], b[c]);
            }
        }
    }
}
