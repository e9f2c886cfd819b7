//! The estimator's options ([`EstimateOptions`]) and their defaults, each with the
//! measurement or the paper passage behind it.

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

/// Options of [`crate::solve::estimate`].
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
    /// Weight `κ` of the chroma smoothness prior relative to the Laplacian's,
    /// `ν = κ · mean_c μ_c` ([`crate::solve::light::chroma`]); 0 = off.
    pub chroma_smoothness: f64,
    /// Robust loss of the lighting step (IRLS); its final weights carry to the materials.
    pub robust: Robust,
    /// IRLS passes per lighting step (the first one unweighted); 1 = plain weighted LS.
    pub irls_iters: usize,
    /// Ridge on λ, relative to the largest diagonal entry of the first λ system.
    pub beta: f64,
    /// Known reflectance (Sec. 6.1): only the lighting is estimated.
    pub fixed_materials: bool,
    /// With [`Self::fixed_materials`], still hold back the validation split and score the
    /// fit on it (`run --restart coarse-light`, whose second fit holds the materials and is
    /// kept only when that score beats the first fit's); default off (Sec. 6.1 fits every
    /// observation).
    pub validate_fixed_materials: bool,
    /// Lighting QP stopping rule: projected gradient ≤ `qp_rel_tol · ‖Wᵀ Aᵀ D y‖∞`.
    pub qp_rel_tol: f64,
    /// Cap on GPCG iterations per lighting QP.
    pub qp_max_iter: usize,
    /// Cap on GPCG iterations of each lighting QP inside the alternation, where every QP
    /// starts from the previous iterate and the next material step changes the system
    /// anyway (an inexact block step: GPCG never raises the QP's objective, so `F` still
    /// does not increase). `None`: `qp_max_iter`, i.e. solved to the KKT tolerance.
    /// Single lighting fits (fixed materials, [`crate::solve::fit_light_frozen`]) always use
    /// `qp_max_iter`. Measured in `bench-results/archive/lighting-solver.md`.
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
    /// after each outer iteration (relative RMSE, [`crate::solve::result::Validation`]); the iterate with the
    /// lowest score is returned. 0 = off: every observation is fitted and the last
    /// iterate returned. Ignored with `fixed_materials` (one lighting step, nothing to
    /// choose). Default 0.1.
    pub validation_fraction: f64,
    /// Draw early stopping's validation observations as whole blocks of this many
    /// consecutive vertex ids (all observations of a drawn vertex held back,
    /// [`crate::solve::validation::validation_split_blocked`]), their weights refitted on
    /// all observations after the best iterate is restored; 0 = per observation. Default
    /// 0: on the real-photo fixture `colmap-dense-buddha` blocks of 64 stop at the first
    /// iteration (headline 0.9114 → 0.9035) but the built-in example stops at the 5th
    /// (headline 0.486 → 0.546), `bench-results/validation-split.md`.
    pub validation_block: usize,
    /// Hold back, instead, the right halves of a few training photos
    /// ([`crate::solve::validation::photo_halves_split`]); built by `crate::run` from the
    /// cameras. Takes precedence over `validation_block`. Default `None`.
    pub validation_halves: Option<std::sync::Arc<PhotoHalves>>,
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
    /// With validation: never stop for the patience before this outer iteration (the best
    /// iterate is still the one returned). Default [`MIN_ITERATIONS`].
    pub min_iterations: usize,
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
    /// Energy tolerance of the blended lighting rows
    /// (`crate::solve::light::system::PhotoSystem`): an observation's `β`-blended
    /// transport row `e_p = Σ_b β_b g_{p,b}` drops its smallest entries for as long as
    /// their energy `Σ_c e_{p,c}²` sums to at most this fraction `ε` of the row's: the row
    /// stays within `√ε` of the exact blend in `ℓ²`. Not in the paper (issue 26). 0 = the
    /// exact blend (the default here); a run's default is [`BLEND_TOLERANCE`].
    pub blend_tolerance: f64,
    /// Prior on each photo's map (issue 25, not in the paper; `None`: the paper's free
    /// map): extra quadratic terms of the lighting QP ([`crate::solve::light::sh_prior`]).
    pub light_prior: Option<crate::solve::light::sh_prior::LightPriorOptions>,
    /// The photos' background pixels as direct views of their maps (beyond the paper;
    /// `None`: off): a diagonal term of the paper's lighting QP
    /// ([`crate::solve::light::background`]), indexed by the problem's photos, so options
    /// for another set of photos must not carry it.
    pub background: Option<std::sync::Arc<crate::solve::light::background::BackgroundTerm>>,
    /// The sun-and-sky light model instead of the paper's free map (issue 25, `--light
    /// sky`; `None`: the paper's map, with `light_prior` if set): [`crate::solve::light::sky`].
    pub light_sky: Option<crate::solve::light::sky::SkyOptions>,
    /// The training photos' suns from their geotags, for the sun-and-sky model
    /// ([`crate::solve::light::sky::clock`]): a photo with one has its sun's direction fixed
    /// up to the collection's one unknown north. `None`: every sun is searched.
    pub sun_clock: Option<crate::solve::light::sky::clock::ClockSuns>,
    /// Prior on each vertex's blending weights summing to one (issue 25, not in the
    /// paper; 0 = off, the paper's free non-negative weights): the material step's `w`
    /// part and `F` gain `Σ_x γ_x (Σ_k w_k(x) − 1)²` with
    /// `γ_x = weights_sum · Σ_{p ∈ x} α_p ‖y_p‖²` ([`crate::solve::materials::sum_weights_gamma`]).
    /// Free weights let a vertex's brightness absorb any function of its normal that all
    /// photos' lights share, which moves the albedo ratios of materials facing different
    /// ways; the prior ties a vertex's brightness to its materials. At 1 it charges a
    /// relative change `δ` of a vertex's brightness what its data would charge for it.
    /// Default [`WEIGHTS_SUM`].
    pub weights_sum: f64,
    /// Which vertices [`Self::weights_sum`] ties ([`SumScope`]); default every vertex.
    pub weights_sum_scope: SumScope,
    /// Prior pulling each vertex's blending weights toward the mean of its neighbours'
    /// (issue 25, not in the paper; 0 = off): the `w` step and `F` gain
    /// `Σ_x η_x ‖w(x) − w̄_N(x)‖²` with `η_x = weights_smoothness · Σ_{p ∈ x} α_p ‖y_p‖²`
    /// (the sum-to-one prior's scale) and `w̄_N(x)` the mean over [`Self::weights_graph`]'s
    /// neighbours of `x`, taken at the step's start (a Jacobi sweep per material step).
    pub weights_smoothness: f64,
    /// Each vertex drops the materials it does not need (not in the paper; 0 = off, the
    /// paper's NNLS that keeps every material lowering the vertex's data term at all):
    /// after each `w` step, backward elimination by the Bayesian information criterion
    /// with its penalty `σ² ln n_x` times this ([`crate::solve::materials::support`]).
    /// NNLS gives a vertex of one material a few percent of the others wherever that fits
    /// its noise, which moves its albedo by that share of the colours' difference.
    pub weights_bic: f64,
    /// Overexposed observations' clipped channels read as lower bounds (issue 25, not in
    /// the paper): each takes its confidence [`crate::observe::Observations::bound_weight`]
    /// and a one-sided data term (`solve::light::bounds::censor`) in the fit, under
    /// every light model (the sun and sky and the shared light re-read the active set before
    /// each of their passes). Off, an overexposed observation has no weight, as in the paper.
    pub clipped_bounds: bool,
    /// The vertex graph of [`Self::weights_smoothness`]; empty = off.
    pub weights_graph: std::sync::Arc<crate::solve::materials::propagate::VertexGraph>,
    /// Specular lobes reflect the light's colour (issue 25, not in the paper): every basis
    /// but [`Self::lambert_basis`] gets one weight per material shared by R, G and B in the
    /// λ step ([`crate::solve::materials`], the dichromatic model of dielectrics). Default
    /// off (the paper's independent channels).
    pub achromatic_specular: bool,
    /// Anderson acceleration of the alternation over `λ` with this many differences
    /// ([`crate::solve::accel`], safeguarded: a candidate is kept only when `F` drops; each
    /// try costs one more lighting step); 0 = off (default).
    pub anderson_depth: usize,
    /// The first rounds that take the ratio step ([`crate::solve::ratio_step`], issue 25,
    /// not in the paper; two more lighting steps a round and direction); 0 = off.
    pub ratio_steps: usize,
    /// The first rounds that take the variable-projection step
    /// ([`crate::solve::varpro_step`], issue 25, not in the paper; `K·B + 2` more lighting
    /// steps a round); 0 = off.
    pub varpro_steps: usize,
    /// The variable-projection step's Jacobian by forward differences in its first round
    /// only, then by Broyden's update from each kept step's secant
    /// ([`crate::solve::varpro_step::broyden_update`]; a round then costs 2 lighting
    /// steps, not `K·B + 2`); a round that keeps nothing probes again in the next.
    pub varpro_broyden: bool,
    /// With [`EstimateOptions::varpro_broyden`], probe the Jacobian afresh every this many
    /// rounds (rounds 1, 1 + n, 1 + 2n, …); 0 = only in the first round.
    pub varpro_refresh: usize,
    /// From this round on each material keeps one shiny lobe, the one it weights most
    /// ([`crate::solve::lobe_prune`], issue 25, not in the paper); 0 = off.
    pub prune_round: usize,
    /// Photos that share one map with per-photo gains (issue 25, not in the paper;
    /// [`crate::solve::light::shared`]); `None`: a map per photo.
    pub light_groups: Option<LightGroups>,
    /// How the per-channel scale between reflectance and light is fixed after the
    /// alternation ([`ScaleAnchor`]).
    pub scale_anchor: ScaleAnchor,
}

/// Which vertices the blending weights' sum-to-one prior ([`EstimateOptions::weights_sum`])
/// ties.
///
/// The prior ties a vertex's brightness to its materials. Where two materials blend,
/// `w_A + w_B = 1` also ties material A's brightness to material B's: the albedo ratio that
/// a free map per photo leaves open. At a pure vertex it only forbids brightness the
/// material does not explain, which on a real object is its texture (the real Buddha photos
/// lose 3.6–8.5% of their headline with the prior everywhere,
/// `bench-results/weights-sum-blends.md`). [`SumScope::Blends`] keeps the first tie at full
/// strength and weakens the second.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum SumScope {
    /// Every vertex at its full `γ_x` ([`crate::solve::materials::sum_weights_gamma`]).
    #[default]
    Every,
    /// `γ_x` scaled before every `w` step by `max(b_x, floor)`, with the vertex's blend
    /// `b_x = min(1, 2 (1 − max_k w_k / Σ_k w_k))` at the step's start: 1 where two
    /// materials blend evenly, 0 at a pure vertex
    /// ([`crate::solve::materials::blend_scaled_gamma`]).
    Blends {
        /// The smallest scale, so that a pure vertex keeps part of the tie.
        floor: f64,
    },
}

/// The floor of [`SumScope::Blends`] that `run` uses: measured against 0 on the real Buddha
/// photos and five rendered scenes (`bench-results/weights-sum-blends.md`,
/// `bench-results/weights-sum-scope.md`). With 0 the pilot's held-out score moved by
/// 0.4–4.8% (noise between two refits is ~3%, [`crate::solve::adapt::BASIS_TOL`]), too
/// little to choose by; with 0.2 the real photos' pilots scored it 4.6–6.1% worse and the
/// rendered scenes' 3.4–14.2% better.
pub const BLEND_FLOOR: f64 = 0.2;

/// Default of [`EstimateOptions::weights_sum`]: 0, the paper's free weights. A run with the
/// adaptive model chooses between 0 and 1 by the pilot's held-out error
/// ([`crate::solve::adapt`], step 3b; `--weights-sum auto`). `1` is the
/// measured recommendation (`bench-results/estimator-ablation.md`, 8-bit photos, relit
/// under unseen maps: diffuse Spot 0.139 → 0.107, glossy 0.175 → 0.146, three materials
/// 0.184 → 0.149; the built-in example's held-out RMSE under the true light 0.0626 /
/// 0.0860 → 0.0538 / 0.0675), not a fixed default: on the real-photo Buddha fixture it does
/// not help (headline 0.9109 → 0.9131), and with [`PATIENCE`] 1 the validation score stops
/// `estimate_planted`'s joint recovery after 15 of 40 iterations (0.016 against noise 0.01;
/// run to the end 0.0073, free weights 0.0081) (`bench-results/weights-sum-default.md`).
pub const WEIGHTS_SUM: f64 = 0.0;

/// Default of [`EstimateOptions::alternation_qp_iters`]: 3 GPCG iterations per lighting QP,
/// each round continuing from the last round's lights (≤ ~75 Hessian products with
/// [`ALTERNATION_CG_ITERS`]). Capping the QPs at all: on the Minerva model (`spot-varying`,
/// 2,930 vertices, 13 photos of 1024²) 5 iterations took 7.3× less estimate CPU than
/// solving every QP to the KKT tolerance (48.8 s against 357.9 s) with held-out error
/// 0.0765 against 0.0791 (`bench-results/archive/lighting-solver.md`). 3 instead of 5,
/// paired over 10 seeds (`bench-results/example-knobs.md`): the built-in example −11.0% ±
/// 0.5% CPU with every held-out figure 1–4% lower; the real Buddha photos −4.9% CPU,
/// headline +0.1% ± 0.1%; 100K vertices × 13 photos −5% CPU, `truth` 0.07637 → 0.07608
/// (`bench-results/large-mesh.md`); the rendered ablation scenes the same or better
/// (three materials held-out 1.71× → 1.64× the photo floor,
/// `bench-results/estimator-ablation-qp3.md`). 4 bought less (example −6.4% CPU).
pub const ALTERNATION_QP_ITERS: usize = 3;

/// Default of [`EstimateOptions::alternation_cg_iters`]: 20 conjugate-gradient steps per
/// GPCG iteration (≤ ~120 Hessian products per lighting QP with the 5 GPCG iterations of
/// [`ALTERNATION_QP_ITERS`]). Measured on the Minerva model (`spot-varying`, 2,930 vertices,
/// 13 photos of 1024², `bench-results/archive/estimator-knobs.md`): estimate 83.5 → 28.5 CPU s
/// (×2.9) against the old cap of 100, held-out error 0.0765 → 0.0767, training 0.0340 →
/// 0.0339; 10 steps are too few (the alternation runs 8 iterations instead of 5 and ends at
/// 0.0782), 30 gave 0.0766 at 36.8 s.
pub const ALTERNATION_CG_ITERS: usize = 20;

/// Default of [`EstimateOptions::patience`]: stop at the first outer iteration whose
/// validation score is not a new best. Measured with [`ALTERNATION_CG_ITERS`] on the Minerva
/// model (`bench-results/archive/estimator-knobs.md`, then `spot-varying` at 1 MP): every scene
/// kept the same iterate with 1 as with 2 or 3 — 2,930 vertices (2 of 3 instead of 2 of 4),
/// 11,714 (3 of 4 / 3 of 5: estimate 87.4 → 75.3 CPU s), 100,000 (4 of 5 / 4 of 6) — and the
/// joint bench (`ESTIMATOR_BENCH=joint`: 566 validation observations, its score improving
/// for 23 iterations) kept iteration 23 of 24 instead of 23 of 25 with every figure
/// identical, 16.9 s instead of 23.6 s. The extra iterations only confirmed the best one.
pub const PATIENCE: usize = 1;

/// Default of [`EstimateOptions::min_iterations`]: 1, no floor (the patience alone).
/// From the k-means start the validation score can rise for two or three iterations
/// before it falls: on the built-in example at seed 3 with `--ray-lattice 2` it went
/// 0.1964, 0.1972, 0.1983 and the fit kept iteration 1 (training RMSE 0.0489 against
/// 0.0357), where the same seed with every first ray traced fell from 0.1978 to 0.1666
/// over 8 iterations. A floor of 4 brought both such seeds of ten (3 and 5) back to the
/// others' level and changed no fit that did not stop before it; with the default
/// visibility it changed none of the ten example fits, and one of eight Buddha seeds
/// (seed 5, headline 0.8697 → 0.8876: it kept a later iterate with a better validation
/// score), so it stays opt-in (`bench-results/visibility-lattice.md`).
pub const MIN_ITERATIONS: usize = 1;

/// Default of [`EstimateOptions::robust_floor`]: IRLS's robust scale is at least 5% of the
/// photo's RMS radiance in each channel. Against the MAD alone (0), measured on `spot-varying`
/// (`bench-results/archive/estimator-joint-floor.md`, `estimator-robust-floor.md`,
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

/// A run's [`EstimateOptions::blend_tolerance`]: 10⁻³ of each blended row's energy (its
/// norm within 3.2%). Measured against the exact blend (`bench-results/blend-tolerance.md`):
/// at 100K vertices × 13 photos the estimate −12% and the evaluation −19% of their CPU,
/// held-out `truth` within ±0.7% per photo; on the built-in example over 10 seeds the
/// estimate −27%, headline −0.4% ± 1.5%. A fixed count instead (the 128 largest entries)
/// was as fast but raised the example's `truth` by 2.9% ± 1.6% and 4.5% ± 2.4%.
pub const BLEND_TOLERANCE: f64 = 1e-3;

/// Early stopping leaves an observation out only where its vertex keeps at least this many
/// fitted observations (its `K` blending weights stay determined).
pub const VALIDATION_MIN_FIT: usize = 2;

impl EstimateOptions {
    /// The options a lighting step inside the alternation solves with: `qp_max_iter` and
    /// `qp_max_cg` capped by [`Self::alternation_qp_iters`] and
    /// [`Self::alternation_cg_iters`] (each at least 1), unless the materials are fixed
    /// (a single lighting fit is solved to the KKT tolerance).
    pub fn alternation_lighting(&self) -> EstimateOptions {
        let capped = |cap: Option<usize>, max: usize| match (self.fixed_materials, cap) {
            (false, Some(c)) => c.clamp(1, max.max(1)),
            _ => max,
        };
        EstimateOptions {
            qp_max_iter: capped(self.alternation_qp_iters, self.qp_max_iter),
            qp_max_cg: capped(self.alternation_cg_iters, self.qp_max_cg),
            ..self.clone()
        }
    }
}

impl Default for EstimateOptions {
    fn default() -> Self {
        EstimateOptions {
            max_outer: 12,
            rel_tol: 1e-4,
            smoothness: 1e-3,
            smoothness_scale: SmoothnessScale::TexelMax,
            smoothness_decay: 1.0,
            smoothness_min: 0.0,
            chroma_smoothness: 0.0,
            robust: Robust::Huber { k: 1.345 },
            irls_iters: 4,
            beta: 1e-8,
            fixed_materials: false,
            validate_fixed_materials: false,
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
            validation_block: 0,
            validation_halves: None,
            validation_seed: 1,
            robust_floor: ROBUST_FLOOR,
            fix_gauge: false,
            materials_cut_only: false,
            patience: PATIENCE,
            min_iterations: MIN_ITERATIONS,
            lighting_sample: 0,
            lighting_strata: Vec::new(),
            blend_tolerance: 0.0,
            light_prior: None,
            background: None,
            light_sky: None,
            sun_clock: None,
            weights_sum: WEIGHTS_SUM,
            weights_sum_scope: SumScope::Every,
            weights_smoothness: 0.0,
            weights_bic: 0.0,
            clipped_bounds: false,
            weights_graph: Default::default(),
            achromatic_specular: false,
            anderson_depth: 0,
            ratio_steps: 0,
            varpro_steps: 0,
            varpro_broyden: false,
            varpro_refresh: 0,
            prune_round: 0,
            light_groups: None,
            scale_anchor: ScaleAnchor::Start,
        }
    }
}

/// A validation split by photo half: for each chosen training photo (its index in the
/// observations' `photo`), which vertices project right of the object's middle in it.
/// The rule is per (photo, vertex), so it applies to any observation list over the same
/// photos; `crate::run` builds it from the cameras.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhotoHalves {
    /// `(photo, right)`: `right[x]` when vertex `x` projects right of the middle.
    pub right: Vec<(u32, Vec<bool>)>,
}

/// Which photos share a map: a group index per photo of the problem (training photos, in
/// problem order), groups numbered `0..n_groups` in order of first appearance.
#[derive(Debug, Clone, PartialEq)]
pub struct LightGroups {
    /// `g(I)` per photo.
    pub group: Vec<usize>,
    /// Where the groups came from, in words (the report's).
    pub source: String,
}

impl LightGroups {
    /// Groups from any labels per photo, renumbered in order of first appearance.
    pub fn from_labels<T: PartialEq + Clone>(labels: &[T], source: String) -> Self {
        let mut seen: Vec<T> = Vec::new();
        let group = labels
            .iter()
            .map(|l| match seen.iter().position(|s| s == l) {
                Some(g) => g,
                None => {
                    seen.push(l.clone());
                    seen.len() - 1
                }
            })
            .collect();
        LightGroups { group, source }
    }

    /// The number of groups.
    pub fn n_groups(&self) -> usize {
        self.group.iter().max().map_or(0, |&g| g + 1)
    }

    /// The photos of each group, ascending.
    pub fn members(&self) -> Vec<Vec<usize>> {
        let mut m = vec![Vec::new(); self.n_groups()];
        for (i, &g) in self.group.iter().enumerate() {
            m[g].push(i);
        }
        m
    }

    /// Whether some group holds more than one photo (else the model is the paper's).
    pub fn any_shared(&self) -> bool {
        self.members().iter().any(|m| m.len() > 1)
    }
}

/// How the per-channel scale between reflectance and light is fixed (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ScaleAnchor {
    /// The start's per-channel balance; the mean Lambertian weight at its start value.
    #[default]
    Start,
    /// Mean diffuse albedo over the surface = 0.5 per channel.
    GreyWorld,
}

impl ScaleAnchor {
    /// Parse `start` or `grey-world`.
    pub fn parse(s: &str) -> crate::Result<Self> {
        match s {
            "start" => Ok(ScaleAnchor::Start),
            "grey-world" => Ok(ScaleAnchor::GreyWorld),
            other => Err(crate::Error::Config(format!(
                "--scale-anchor {other}: expected `start` or `grey-world`"
            ))),
        }
    }

    /// The name `parse` reads (the report's `scale_anchor.name`).
    pub fn name(self) -> &'static str {
        match self {
            ScaleAnchor::Start => "start",
            ScaleAnchor::GreyWorld => "grey-world",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_alternations_lighting_caps_the_solver_unless_the_materials_are_fixed() {
        // Inside the alternation the caps replace the solver's limits, at least 1 and at
        // most the limit; a fixed-materials fit keeps the limits; no cap keeps them too.
        let base = EstimateOptions {
            qp_max_iter: 50,
            qp_max_cg: 20,
            alternation_qp_iters: Some(3),
            alternation_cg_iters: Some(0),
            ..EstimateOptions::default()
        };
        let a = base.alternation_lighting();
        assert_eq!((a.qp_max_iter, a.qp_max_cg), (3, 1));
        let over = EstimateOptions {
            alternation_qp_iters: Some(500),
            ..base.clone()
        }
        .alternation_lighting();
        assert_eq!(over.qp_max_iter, 50);
        let fixed = EstimateOptions {
            fixed_materials: true,
            ..base.clone()
        }
        .alternation_lighting();
        assert_eq!((fixed.qp_max_iter, fixed.qp_max_cg), (50, 20));
        let uncapped = EstimateOptions {
            alternation_qp_iters: None,
            alternation_cg_iters: None,
            ..base.clone()
        }
        .alternation_lighting();
        assert_eq!((uncapped.qp_max_iter, uncapped.qp_max_cg), (50, 20));
        // Every other option is carried over.
        assert_eq!(a.max_outer, base.max_outer);
        assert_eq!(a.smoothness, base.smoothness);
    }
}
