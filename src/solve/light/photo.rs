//! The lighting step for one photo (paper Sec. 5.1, Eq. 10 with the Laplacian prior and
//! IRLS): `min_x ½ xᵀ(Wᵀ Aᵀ D A W + μ ΔᵀΔ) x − (Wᵀ Aᵀ D y)ᵀ x`, `x ≥ 0`, the three channels
//! together, solved matrix-free by [`crate::solve::qp::bound_qp_scaled`]. IRLS (Huber or
//! Tukey on residuals scaled by `σ = max(1.4826 · MAD, robust_floor · rms(y))`) restarts
//! from unit weights at every call, as the paper says ("started from scratch in each
//! iteration"), except inside the alternation ([`WARM_IRLS`]).
//!
//! *Warm IRLS* (the alternation's steps after a photo's first): one pass whose weights are
//! those of the residuals of the step's start (the previous iterate's light under the new
//! `β`). With weights `ω(r)` from the current iterate, the weighted quadratic majorises the
//! Huber loss there (Huber's `ω(r) = ψ(r)/r` is non-increasing in `|r|`: the standard IRLS
//! majorise–minimise argument, at the pass's `σ`), so one pass does not raise the robust
//! objective from the start, and the IRLS iterations continue across outer iterations instead of restarting.
//! The restart's first pass is an unweighted least-squares solve that the next passes
//! undo. On the built-in example the estimate's lighting took 0.68 → 0.27 CPU s per outer
//! iteration with every report figure within 7% (headline 0.4936 → 0.4926;
//! `bench-results/example-speed.md`).

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use crate::solve::light::background::PhotoBackground;
use crate::solve::light::chroma::ChromaPrior;
use crate::solve::light::irls::pass_weights;
use crate::solve::light::laplacian::Laplacian;
use crate::solve::light::sh_prior::{LightPriorOptions, PriorPass, ShProjection};
use crate::solve::light::system::{split3, texel_diag, texel_diag_vec, unhaar3, PhotoSystem};
use crate::solve::options::{EstimateOptions, Robust, SmoothnessScale};
use crate::solve::problem::{haar3, Problem};
use crate::solve::qp::{bound_qp_scaled, QpOptions, QpResult};
use crate::solve::subsample::Subsample;
use crate::{Error, Result};

/// Whether the lighting QP is scaled by its texel-basis diagonal
/// ([`crate::solve::qp::bound_qp_scaled`]): `diag(Wᵀ Aᵀ α A W) + μ diag(ΔᵀΔ)` per channel, the data
/// part without the IRLS weights. Same stopping rule, fewer products (bench-results/archive/pipeline-minerva.md, bench-results/archive/lighting-solver.md).
pub(crate) const LIGHTING_JACOBI: bool = true;

/// Whether the alternation's lighting steps after a photo's first run one warm IRLS pass
/// (module docs) instead of restarting from unit weights.
pub const WARM_IRLS: bool = true;

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

/// One photo's observations as its lighting step reads them: the QP's rows (all of the
/// photo's observations, or its lighting sample) and every observation (IRLS's scale and
/// weights come from all of them).
pub(crate) struct PhotoData {
    pub(crate) range: std::ops::Range<usize>,
    /// Positions in the range of the QP's rows.
    pub(crate) pos: Vec<usize>,
    /// `α_p` times the row's Horvitz–Thompson weight (1 without a sample), per row.
    pub(crate) alpha: Vec<f64>,
    /// `y_{p,c}` per row.
    pub(crate) y: Vec<[f64; 3]>,
    /// `α_p` of every observation of the photo.
    pub(super) alpha_all: Vec<f64>,
    /// `y_{p,c}` of every observation of the photo.
    pub(super) y_all: Vec<[f64; 3]>,
    /// The channels that are lower bounds ([`crate::observe::Observations::clipped`]) of
    /// every observation of the photo, when one with `α > 0` has any; else empty.
    pub(super) clipped_all: Vec<u8>,
    /// Whether the rows are a sample.
    pub(super) sampled: bool,
}

impl PhotoData {
    pub(crate) fn new(problem: &Problem, photo: usize, sample: Option<&Subsample>) -> Self {
        let range = problem.obs.photo_ranges[photo].clone();
        let obs = problem.obs;
        let (pos, ht): (Vec<usize>, Vec<f64>) = match sample {
            Some(s) => (s.index.clone(), s.weight.clone()),
            None => ((0..range.len()).collect(), vec![1.0; range.len()]),
        };
        let rows = pos.iter().map(|&q| range.start + q);
        PhotoData {
            alpha: rows
                .clone()
                .zip(&ht)
                .map(|(p, w)| obs.weight[p] as f64 * w)
                .collect(),
            y: rows.map(|p| obs.rgb[p].map(f64::from)).collect(),
            alpha_all: range.clone().map(|p| obs.weight[p] as f64).collect(),
            y_all: range.clone().map(|p| obs.rgb[p].map(f64::from)).collect(),
            clipped_all: super::bounds::clipped_in(obs, range.clone()),
            sampled: sample.is_some(),
            pos,
            range,
        }
    }

    /// Whether some observation of the photo is read as a lower bound ([`censor`]).
    pub(crate) fn has_bounds(&self) -> bool {
        !self.clipped_all.is_empty()
    }

    /// The QP's rows as observation indices.
    pub(crate) fn rows(&self) -> impl Iterator<Item = usize> + '_ {
        self.pos.iter().map(|&q| self.range.start + q)
    }

    /// The α-weighted mean square of the rows' radiance (the light prior's scale); over the QP's
    /// rows, whose `α` carries the sample's weights.
    pub(super) fn mean_square(&self) -> f64 {
        let (alpha, y) = (&self.alpha, &self.y);
        let (num, den) = (0..self.pos.len()).fold((0.0, 0.0), |(a, b), q| {
            let yy = (y[q][0].powi(2) + y[q][1].powi(2) + y[q][2].powi(2)) / 3.0;
            (a + alpha[q] * yy, b + alpha[q])
        });
        if den > 0.0 {
            num / den
        } else {
            0.0
        }
    }
}

/// The solver's figures over one lighting step's QPs.
pub(super) struct QpStats {
    pub(super) cond: f64,
    pub(super) converged: bool,
    pub(super) matvecs: usize,
    pub(super) qps: usize,
    pub(super) unconverged_qps: usize,
    pub(super) matvecs_max: usize,
}

impl QpStats {
    pub(super) fn new() -> Self {
        QpStats {
            cond: 0.0,
            converged: true,
            matvecs: 0,
            qps: 0,
            unconverged_qps: 0,
            matvecs_max: 0,
        }
    }

    pub(super) fn add(&mut self, res: &QpResult) {
        self.converged &= res.converged;
        self.matvecs += res.matvecs;
        self.qps += 1;
        self.unconverged_qps += usize::from(!res.converged);
        self.matvecs_max = self.matvecs_max.max(res.matvecs);
        if res.cond_lower_bound.is_finite() {
            self.cond = res.cond_lower_bound;
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
pub(crate) fn forward_full(
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
                    let g = f64::from(g);
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
    sample: Option<&Subsample>,
) -> Result<LightingResult> {
    lighting_step_warm(problem, beta, photo, start, mu, opts, sample, false)
}

/// [`lighting_step_on`]; with `warm_irls` and a non-zero `start`, one IRLS pass whose
/// weights come from the start's residuals (module docs, *warm IRLS*) instead of
/// [`EstimateOptions::irls_iters`] passes from unit weights.
#[allow(clippy::too_many_arguments)]
pub(crate) fn lighting_step_warm(
    problem: &Problem,
    beta: &[[f64; 3]],
    photo: usize,
    start: Option<&[Vec<f64>; 3]>,
    mu: Option<[f64; 3]>,
    opts: &EstimateOptions,
    sample: Option<&Subsample>,
    warm_irls: bool,
) -> Result<LightingResult> {
    let n = problem.transport.n_global;
    let n2 = n * n;
    let data = PhotoData::new(problem, photo, sample);
    let dw0 = data.alpha.iter().map(|&a| [a; 3]).collect();
    let mut sys = PhotoSystem::new(problem, beta, data.rows(), n, dw0, opts.blend_tolerance);
    // The texel-basis diagonal of the data term (α, without IRLS weights): the Jacobi
    // scaling of the QP (LIGHTING_JACOBI) and, for the default smoothness scale, μ.
    let tdiag = (LIGHTING_JACOBI
        || (mu.is_none() && opts.smoothness_scale == SmoothnessScale::TexelMax))
        .then(|| texel_diag_vec(problem, beta, data.rows(), &data.alpha));
    let mu = match mu {
        Some(m) => m,
        None => smoothness_weights(problem, beta, &data, &sys, tdiag.as_deref(), opts),
    };
    let lap = Laplacian::new(n);
    let jacobi = jacobi_scaling(tdiag.as_deref(), &lap, mu, n2);
    let mut x = start_texels(start, n2)?;
    let mut omega = vec![[1.0_f64; 3]; data.range.len()];
    let prior_proj = opts.light_prior.as_ref().map(|_| ShProjection::new(n, 4));
    let IrlsPasses { passes, warm } = irls_passes(opts, &x, prior_proj.is_some(), warm_irls);
    let y_ms = data.mean_square();
    let mut stats = QpStats::new();
    for pass in 0..passes {
        // Reweight from the current residuals (the first pass: unit weights, a restart,
        // unless warm).
        let reweigh = pass > 0 || warm;
        pass_weights(problem, beta, &sys, &x, &data, opts, reweigh, &mut omega);
        set_pass_weights(&mut sys, &data, &omega);
        let system = PassSystem::new(&sys, &lap, mu, jacobi.as_deref(), opts, &prior_proj, y_ms);
        let res = solve_pass(&system, &data, &x, opts, photo)?;
        take_pass(res, &mut x, &mut stats);
    }
    Ok(LightingResult {
        light: split3(&x, n2),
        mu,
        irls_weights: omega.iter().map(|o| o.map(|v| v as f32)).collect(),
        cond_lower_bound: stats.cond,
        converged: stats.converged,
        matvecs: stats.matvecs,
        qps: stats.qps,
        unconverged_qps: stats.unconverged_qps,
        matvecs_max: stats.matvecs_max,
    })
}

/// How many weighted solves a lighting step makes, and whether the first is reweighted
/// from the start's residuals ([`irls_passes`]).
struct IrlsPasses {
    passes: usize,
    warm: bool,
}

/// The passes of a lighting step from `start` (texels `x`): [`EstimateOptions::irls_iters`]
/// with a robust loss, else 1; at least 2 from a zero start under the light prior, which is
/// linearised at the current iterate; and 1 warm pass (weights from the start's
/// residuals) when `warm_irls` asks for it and the start is not zero.
fn irls_passes(opts: &EstimateOptions, x: &[f64], prior: bool, warm_irls: bool) -> IrlsPasses {
    let mut passes = if opts.robust == Robust::None {
        1
    } else {
        opts.irls_iters.max(1)
    };
    if prior && x.iter().all(|v| *v == 0.0) {
        passes = passes.max(2);
    }
    let warm = warm_irls && passes > 1 && x.iter().any(|v| *v != 0.0);
    IrlsPasses {
        passes: if warm { 1 } else { passes },
        warm,
    }
}

/// `μ` per channel when not given: `smoothness` × the system diagonal's largest (or mean)
/// entry on the chosen scale ([`SmoothnessScale`]).
pub(super) fn smoothness_weights(
    problem: &Problem,
    beta: &[[f64; 3]],
    data: &PhotoData,
    sys: &PhotoSystem,
    tdiag: Option<&[[f64; 3]]>,
    opts: &EstimateOptions,
) -> [f64; 3] {
    match opts.smoothness_scale {
        SmoothnessScale::HaarMax => sys.max_diag(),
        SmoothnessScale::TexelMax => match tdiag {
            Some(d) => d.iter().fold([0.0_f64; 3], |mut m, v| {
                for c in 0..3 {
                    m[c] = m[c].max(v[c]);
                }
                m
            }),
            None => texel_diag(problem, beta, data.rows(), &data.alpha).0,
        },
        SmoothnessScale::Mean => texel_diag(problem, beta, data.rows(), &data.alpha).1,
    }
    .map(|d| opts.smoothness * d)
}

/// The QP's Jacobi scaling `diag(Wᵀ Aᵀ α A W) + μ diag(ΔᵀΔ)`, channel-major, when
/// [`LIGHTING_JACOBI`] is on.
pub(super) fn jacobi_scaling(
    tdiag: Option<&[[f64; 3]]>,
    lap: &Laplacian,
    mu: [f64; 3],
    n2: usize,
) -> Option<Vec<f64>> {
    match (tdiag, LIGHTING_JACOBI) {
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
    }
}

/// The QP's start: `start`'s texels channel-major, or zeros.
pub(super) fn start_texels(start: Option<&[Vec<f64>; 3]>, n2: usize) -> Result<Vec<f64>> {
    let x: Vec<f64> = match start {
        Some(s) => s.iter().flat_map(|c| c.iter().copied()).collect(),
        None => vec![0.0; 3 * n2],
    };
    if x.len() != 3 * n2 {
        return Err(Error::Internal(format!(
            "lighting start has {} texels, expected {}",
            x.len(),
            3 * n2
        )));
    }
    Ok(x)
}

/// The prediction of texels `x` at every observation of the photo.
pub(super) fn predict_all(
    problem: &Problem,
    beta: &[[f64; 3]],
    sys: &PhotoSystem,
    x: &[f64],
    data: &PhotoData,
) -> Vec<[f64; 3]> {
    let n = sys.n;
    let h = haar3(&split3(x, n * n), n);
    if data.sampled {
        forward_full(problem, beta, data.range.clone(), &h)
    } else {
        let mut pred = vec![[0.0; 3]; data.range.len()];
        sys.forward_rows(&h, &mut pred);
        pred
    }
}

/// The quadratic of one IRLS pass: the photo's system with its current weights, the
/// Laplacian prior, the optional light prior and the scaling.
pub(super) struct PassSystem<'a> {
    pub(super) sys: &'a PhotoSystem,
    pub(super) lap: &'a Laplacian,
    pub(super) mu: [f64; 3],
    pub(super) jacobi: Option<&'a [f64]>,
    /// The light prior's options and projection, when on.
    pub(super) prior: Option<(&'a LightPriorOptions, &'a ShProjection)>,
    /// The rows' mean square radiance (the prior's scale).
    pub(super) y_ms: f64,
}

/// Pass `k`'s data weights `D_k = α ω_k` into the system's rows (`omega`: the IRLS
/// weights per observation of the photo, unit in the first pass).
pub(super) fn set_pass_weights(sys: &mut PhotoSystem, data: &PhotoData, omega: &[[f64; 3]]) {
    for (r, &q) in data.pos.iter().enumerate() {
        for c in 0..3 {
            sys.dw[r][c] = data.alpha[r] * omega[q][c];
        }
    }
}

/// A pass's answer ([`solve_pass`]) into `x`, its cost into `stats`; `None` (no light
/// reaches any weighted observation) means the minimiser `x = 0`.
pub(super) fn take_pass(res: Option<QpResult>, x: &mut Vec<f64>, stats: &mut QpStats) {
    match res {
        None => x.iter_mut().for_each(|v| *v = 0.0),
        Some(res) => {
            stats.add(&res);
            *x = res.x;
        }
    }
}

impl<'a> PassSystem<'a> {
    /// The pass's quadratic; the light prior from `opts` with its projection when on.
    pub(super) fn new(
        sys: &'a PhotoSystem,
        lap: &'a Laplacian,
        mu: [f64; 3],
        jacobi: Option<&'a [f64]>,
        opts: &'a EstimateOptions,
        prior_proj: &'a Option<ShProjection>,
        y_ms: f64,
    ) -> Self {
        let prior = opts.light_prior.as_ref().zip(prior_proj.as_ref());
        PassSystem {
            sys,
            lap,
            mu,
            jacobi,
            prior,
            y_ms,
        }
    }
}

/// One pass's QP from `x`; `None` when no light reaches a weighted observation (the
/// right-hand side is 0).
pub(super) fn solve_pass(
    p: &PassSystem,
    data: &PhotoData,
    x: &[f64],
    opts: &EstimateOptions,
    photo: usize,
) -> Result<Option<QpResult>> {
    let (sys, n) = (p.sys, p.sys.n);
    let n2 = n * n;
    let mut b = sys.texel_rhs(&data.y);
    let background = opts.background.as_deref().and_then(|t| t.photo(photo, n));
    if let Some(bg) = &background {
        bg.add_rhs(&mut b, [1.0; 3]);
    }
    // A photo with no lit observation and no background read keeps its map at 0.
    let bmax = b.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    if bmax == 0.0 {
        return Ok(None);
    }
    let prior = p
        .prior
        .and_then(|(lp, pp)| lp.pass(photo, pp, x, n, p.y_ms));
    // The chroma prior's gains from the pass's start, as the light prior is linearised there.
    let chroma = ChromaPrior::for_pass(opts.chroma_smoothness, p.mu, x, n2);
    let jac_pass = pass_jacobi(p, prior.as_ref(), chroma.as_ref(), background.as_ref());
    let prior_ref = prior.as_ref();
    let hess = |v: &[f64], out: &mut [f64]| {
        let h = haar3(&split3(v, n2), n);
        let mut hb = vec![[0.0; 3]; n2];
        sys.normal_rows(&h, &mut hb);
        if let Some(pr) = prior_ref {
            pr.add_haar(&h, &mut hb);
        }
        let r = unhaar3(&hb, n);
        out.copy_from_slice(&r);
        if let Some(pr) = prior_ref {
            pr.add_texel(v, out);
        }
        for c in 0..3 {
            p.lap.add_normal(
                &v[c * n2..(c + 1) * n2],
                p.mu[c],
                &mut out[c * n2..(c + 1) * n2],
            );
        }
        if let Some(ch) = &chroma {
            ch.add_normal(p.lap, v, out);
        }
        if let Some(bg) = &background {
            bg.add_normal(v, out, [1.0; 3]);
        }
    };
    let qp = QpOptions {
        tol: opts.qp_rel_tol * bmax,
        max_iter: opts.qp_max_iter,
        max_cg: opts.qp_max_cg.max(1),
    };
    let res =
        bound_qp_scaled(hess, &b, x, &qp, jac_pass.as_deref()).map_err(|e| Error::Numeric {
            stage: format!("lighting step, photo {photo}"),
            message: e.to_string(),
        })?;
    Ok(Some(res))
}

/// The Jacobi preconditioner of one pass: the system's texel diagonal (`None` when off)
/// plus the diagonals of the pass's light prior, chroma prior and background terms.
fn pass_jacobi(
    p: &PassSystem,
    prior: Option<&PriorPass>,
    chroma: Option<&ChromaPrior>,
    background: Option<&PhotoBackground>,
) -> Option<Vec<f64>> {
    let mut j = p.jacobi?.to_vec();
    if let Some(pr) = prior {
        j.iter_mut().zip(pr.diagonal()).for_each(|(a, b)| *a += b);
    }
    if let Some(ch) = chroma {
        j.iter_mut()
            .zip(ch.diagonal(p.lap))
            .for_each(|(a, b)| *a += b);
    }
    if let Some(bg) = background {
        bg.add_diagonal(&mut j, [1.0; 3]);
    }
    Some(j)
}

/// Lighting step (Eq. 10 + Laplacian + IRLS) for one photo from zero: its three channels'
/// texels. `beta` is [`crate::solve::beta_per_vertex`].
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The pass count by its rules, each case by hand: the robust loss's `irls_iters`
    /// (Huber, 3) or one solve (plain least squares); two from a zero start under the
    /// light prior; one warm pass from a non-zero start when asked.
    #[test]
    fn irls_passes_follow_the_loss_the_prior_and_the_start() {
        let huber = EstimateOptions {
            robust: Robust::Huber { k: 1.345 },
            irls_iters: 3,
            ..EstimateOptions::default()
        };
        let plain = EstimateOptions {
            robust: Robust::None,
            ..huber.clone()
        };
        let (zero, lit) = ([0.0; 4], [0.0, 1.0, 0.0, 0.0]);
        let count = |o: &EstimateOptions, x: &[f64], prior, warm| {
            let p = irls_passes(o, x, prior, warm);
            (p.passes, p.warm)
        };
        assert_eq!(count(&huber, &lit, false, false), (3, false));
        assert_eq!(count(&plain, &lit, false, false), (1, false));
        assert_eq!(count(&plain, &zero, true, false), (2, false));
        assert_eq!(count(&plain, &lit, true, false), (1, false));
        assert_eq!(count(&huber, &lit, false, true), (1, true));
        // A zero start has no residuals to reweight from: the full count, not warm.
        assert_eq!(count(&huber, &zero, false, true), (3, false));
        // One pass has nothing to warm.
        assert_eq!(count(&plain, &lit, false, true), (1, false));
    }
}
