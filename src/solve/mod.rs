//! The estimator (paper Sec. 5): per-photo illumination and per-vertex materials by
//! alternating non-negative solves of the objective (Eq. 9)
//!
//! `F = Σ_p Σ_c α_p ω_{p,c} (y_{p,c} − Σ_b β_{x,b,c} ⟨g_{p,b}, W x_{I,c}⟩)²
//!      + Σ_{I,c} μ_{I,c} ‖Δ x_{I,c}‖² + β_λ ‖λ‖²`,
//!
//! with `β_{x,b,c} = Σ_k w_k(x) λ_{k,b,c}` (Eq. 11), `x_{I,c}` the texels of photo `I`'s
//! global octahedral map in channel `c` (`W` = [`crate::sphere::haar::forward`], orthonormal, so
//! `⟨g, W x⟩ = ⟨Wᵀ g, x⟩`), `Δ` the 4-neighbour graph Laplacian of the map across its folded
//! seams ([`crate::sphere::SphereGrid::neighbors`]), `ω` the IRLS weights (1 without a
//! robust loss). Every unknown is constrained `≥ 0`: texels, `λ`, `w`.
//!
//! 1. Lighting step (Sec. 5.1, Eq. 10), per photo, the three channels together:
//!    `min_x ½ xᵀ(Wᵀ Aᵀ D A W + μ ΔᵀΔ) x − (Wᵀ Aᵀ D y)ᵀ x`, `x ≥ 0`, solved matrix-free by
//!    [`qp::bound_qp`]: one product is a forward Haar, a pass over the photo's sparse
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
//!    NNLS problems solved exactly by the active-set [`crate::solve::qp::nnls`], so each step
//!    minimises `F` over its block and `F` never increases (without IRLS; with it, the
//!    weights change between steps).
//!
//! Scale: `F` is invariant under `x → s x`, `λ → λ / s` (and `w_k → t w_k`, `λ_k → λ_k / t`)
//! up to the tiny regularisers. After the alternation the result is normalised once:
//! every material's median blending weight over the observed vertices pure in it is 1,
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
//!
//! Files: [`alternation`] (the loop, `estimate`), [`light`] (the per-photo light model:
//! the [`light::LightModel`] trait, the paper's map in [`light::paper`], its per-photo QP
//! in [`light::photo`] over the system of [`light::system`]), [`materials`],
//! [`objective`], [`validation`] (early stopping), [`normalise`], [`problem`] (the data
//! and the forward map), [`options`], [`result`]. Beside the estimator: [`cluster`] (the
//! initial materials), [`starts`], [`adapt`] (the pilot fit), [`budget`] (memory), [`qp`]
//! (the non-negative solvers).

pub mod accel;
pub mod adapt;
pub mod alternation;
pub mod budget;
pub mod cluster;
pub mod light;
pub mod lobe_prune;
pub mod loss_choice;
pub mod matched;
pub mod materials;
pub mod normalise;
pub mod objective;
pub mod options;
pub mod paired;
pub mod problem;
pub mod qp;
pub mod ratio_step;
pub mod result;
pub(crate) mod start_check;
pub mod starts;
pub mod subsample;
pub mod validation;
pub mod varpro_step;

pub use alternation::{estimate, estimate_with};
pub use light::photo::{
    fit_light_frozen, lighting_sample, lighting_step, lighting_step_full, lighting_step_on,
    LightingResult,
};
pub use materials::{lambda_step, weights_step, LambdaStep, WeightsRules, WeightsStep};
pub use options::{
    EstimateOptions, Robust, SmoothnessScale, SumScope, ALTERNATION_CG_ITERS, ALTERNATION_QP_ITERS,
    BLEND_FLOOR, PATIENCE, ROBUST_FLOOR, VALIDATION_MIN_FIT, WEIGHTS_SUM,
};
pub use problem::{
    basis_responses, beta_per_vertex, par_largest_first, predict, predict_from, Problem,
};
pub use result::{
    Conditioning, Estimate, IterState, Iteration, Materials0, RatioMoves, StepTimes, Validation,
};
pub use validation::{validation_split, validation_split_blocked};
