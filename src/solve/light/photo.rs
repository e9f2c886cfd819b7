//! The lighting step for one photo (paper Sec. 5.1, Eq. 10 with the Laplacian prior and
//! IRLS): `min_x ½ xᵀ(Wᵀ Aᵀ D A W + μ ΔᵀΔ) x − (Wᵀ Aᵀ D y)ᵀ x`, `x ≥ 0`, the three channels
//! together, solved matrix-free by [`crate::solve::qp::bound_qp_scaled`]. IRLS (Huber or
//! Tukey on residuals scaled by `σ = max(1.4826 · MAD, robust_floor · rms(y))`) restarts
//! from unit weights at every call, as the paper says.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use crate::solve::light::laplacian::Laplacian;
use crate::solve::light::system::{split3, texel_diag, texel_diag_vec, unhaar3, PhotoSystem};
use crate::solve::options::{EstimateOptions, Robust, SmoothnessScale};
use crate::solve::problem::{haar3, Problem};
use crate::solve::qp::{bound_qp_scaled, QpOptions};
use crate::{Error, Result};

/// Whether the lighting QP is scaled by its texel-basis diagonal
/// ([`crate::solve::qp::bound_qp_scaled`]): `diag(Wᵀ Aᵀ α A W) + μ diag(ΔᵀΔ)` per channel, the data
/// part without the IRLS weights. Same stopping rule, fewer products (bench-results/pipeline-minerva.md, bench-results/lighting-solver.md).
pub(crate) const LIGHTING_JACOBI: bool = true;

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

pub(crate) fn robust_weight(robust: Robust, r: f64, sigma: f64) -> f64 {
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

/// One photo's observations as its lighting step reads them.
struct PhotoData {
    range: std::ops::Range<usize>,
    /// `α_p` per observation of the range.
    alpha: Vec<f64>,
    /// `y_{p,c}` per observation of the range.
    y: Vec<[f64; 3]>,
}

impl PhotoData {
    fn new(problem: &Problem, photo: usize) -> Self {
        let range = problem.obs.photo_ranges[photo].clone();
        let obs = problem.obs;
        PhotoData {
            alpha: range.clone().map(|p| obs.weight[p] as f64).collect(),
            y: range.clone().map(|p| obs.rgb[p].map(f64::from)).collect(),
            range,
        }
    }
}

/// The solver's figures over one lighting step's QPs.
struct QpStats {
    cond: f64,
    converged: bool,
    matvecs: usize,
    qps: usize,
    unconverged_qps: usize,
    matvecs_max: usize,
}

impl QpStats {
    fn new() -> Self {
        QpStats {
            cond: 0.0,
            converged: true,
            matvecs: 0,
            qps: 0,
            unconverged_qps: 0,
            matvecs_max: 0,
        }
    }

    fn add(&mut self, res: &crate::solve::qp::QpResult) {
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
/// weights (`None` = `smoothness` × largest system diagonal, computed here).
pub fn lighting_step_full(
    problem: &Problem,
    beta: &[[f64; 3]],
    photo: usize,
    start: Option<&[Vec<f64>; 3]>,
    mu: Option<[f64; 3]>,
    opts: &EstimateOptions,
) -> Result<LightingResult> {
    let n = problem.transport.n_global;
    let n2 = n * n;
    let data = PhotoData::new(problem, photo);
    let dw0 = data.alpha.iter().map(|&a| [a; 3]).collect();
    let mut sys = PhotoSystem::new(problem, beta, data.range.clone(), n, dw0);
    // The texel-basis diagonal of the data term (α, without IRLS weights): the Jacobi
    // scaling of the QP (LIGHTING_JACOBI) and, for the default smoothness scale, μ.
    let tdiag = (LIGHTING_JACOBI
        || (mu.is_none() && opts.smoothness_scale == SmoothnessScale::TexelMax))
        .then(|| texel_diag_vec(problem, beta, data.range.clone(), &data.alpha));
    let mu = match mu {
        Some(m) => m,
        None => smoothness_weights(problem, beta, &data, &sys, tdiag.as_deref(), opts),
    };
    let lap = Laplacian::new(n);
    let jacobi = jacobi_scaling(tdiag.as_deref(), &lap, mu, n2);
    let mut x = start_texels(start, n2)?;
    let mut omega = vec![[1.0_f64; 3]; data.range.len()];
    let passes = if opts.robust == Robust::None {
        1
    } else {
        opts.irls_iters.max(1)
    };
    let mut stats = QpStats::new();
    for pass in 0..passes {
        // Reweight from the current residuals (the first pass: unit weights, a restart).
        if pass > 0 {
            reweight(&sys, &x, &data, opts, &mut omega);
        }
        for q in 0..data.range.len() {
            for c in 0..3 {
                sys.dw[q][c] = data.alpha[q] * omega[q][c];
            }
        }
        let system = PassSystem {
            sys: &sys,
            lap: &lap,
            mu,
            jacobi: jacobi.as_deref(),
        };
        match solve_pass(&system, &data, &x, opts, photo)? {
            // No light reaches any weighted observation: the minimiser is x = 0.
            None => x.iter_mut().for_each(|v| *v = 0.0),
            Some(res) => {
                stats.add(&res);
                x = res.x;
            }
        }
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

/// `μ` per channel when not given: `smoothness` × the system diagonal's largest (or mean)
/// entry on the chosen scale ([`SmoothnessScale`]).
fn smoothness_weights(
    problem: &Problem,
    beta: &[[f64; 3]],
    data: &PhotoData,
    sys: &PhotoSystem,
    tdiag: Option<&[[f64; 3]]>,
    opts: &EstimateOptions,
) -> [f64; 3] {
    let range = data.range.clone();
    match opts.smoothness_scale {
        SmoothnessScale::HaarMax => sys.max_diag(),
        SmoothnessScale::TexelMax => match tdiag {
            Some(d) => d.iter().fold([0.0_f64; 3], |mut m, v| {
                for c in 0..3 {
                    m[c] = m[c].max(v[c]);
                }
                m
            }),
            None => texel_diag(problem, beta, range, &data.alpha).0,
        },
        SmoothnessScale::Mean => texel_diag(problem, beta, range, &data.alpha).1,
    }
    .map(|d| opts.smoothness * d)
}

/// The QP's Jacobi scaling `diag(Wᵀ Aᵀ α A W) + μ diag(ΔᵀΔ)`, channel-major, when
/// [`LIGHTING_JACOBI`] is on.
fn jacobi_scaling(
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
fn start_texels(start: Option<&[Vec<f64>; 3]>, n2: usize) -> Result<Vec<f64>> {
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

/// IRLS: `ω` from the residuals of `x`, per channel scaled by
/// `σ = max(1.4826 · MAD, robust_floor · rms(y))` (module docs).
fn reweight(
    sys: &PhotoSystem,
    x: &[f64],
    data: &PhotoData,
    opts: &EstimateOptions,
    omega: &mut [[f64; 3]],
) {
    let (n, len) = (sys.n, data.range.len());
    let (alpha, y) = (&data.alpha, &data.y);
    let mut pred = vec![[0.0; 3]; len];
    let h = haar3(&split3(x, n * n), n);
    sys.forward_rows(&h, &mut pred);
    for c in 0..3 {
        let mut ab: Vec<f64> = (0..len)
            .filter(|&q| alpha[q] > 0.0)
            .map(|q| (y[q][c] - pred[q][c]).abs())
            .collect();
        if ab.is_empty() {
            continue;
        }
        let n_fit = ab.len();
        let mid = n_fit / 2;
        let (_, med, _) = ab.select_nth_unstable_by(mid, f64::total_cmp);
        let scale = y.iter().map(|v| v[c].abs()).sum::<f64>() / y.len() as f64;
        // The noise floor: a fraction of the RMS observed radiance (struct docs of
        // `EstimateOptions::robust_floor`).
        let rms = ((0..len)
            .filter(|&q| alpha[q] > 0.0)
            .map(|q| y[q][c] * y[q][c])
            .sum::<f64>()
            / n_fit as f64)
            .sqrt();
        let sigma = (1.4826 * *med)
            .max(opts.robust_floor * rms)
            .max(1e-9 * scale)
            .max(f64::MIN_POSITIVE);
        for q in 0..len {
            omega[q][c] = robust_weight(opts.robust, y[q][c] - pred[q][c], sigma);
        }
    }
}

/// The quadratic of one IRLS pass: the photo's system with its current weights, the prior
/// and the scaling.
struct PassSystem<'a> {
    sys: &'a PhotoSystem,
    lap: &'a Laplacian,
    mu: [f64; 3],
    jacobi: Option<&'a [f64]>,
}

/// One pass's QP from `x`; `None` when no light reaches a weighted observation (the
/// right-hand side is 0).
fn solve_pass(
    p: &PassSystem,
    data: &PhotoData,
    x: &[f64],
    opts: &EstimateOptions,
    photo: usize,
) -> Result<Option<crate::solve::qp::QpResult>> {
    let (sys, n) = (p.sys, p.sys.n);
    let n2 = n * n;
    // Right-hand side Wᵀ Aᵀ D y.
    let u: Vec<[f64; 3]> = (0..data.range.len())
        .map(|q| [0, 1, 2].map(|c| sys.dw[q][c] * data.y[q][c]))
        .collect();
    let mut hb = vec![[0.0; 3]; n2];
    sys.adjoint_rows(&u, &mut hb);
    let b = unhaar3(&hb, n);
    let bmax = b.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    if bmax == 0.0 {
        return Ok(None);
    }
    let hess = |v: &[f64], out: &mut [f64]| {
        let h = haar3(&split3(v, n2), n);
        let mut hb = vec![[0.0; 3]; n2];
        sys.normal_rows(&h, &mut hb);
        let r = unhaar3(&hb, n);
        out.copy_from_slice(&r);
        for c in 0..3 {
            p.lap.add_normal(
                &v[c * n2..(c + 1) * n2],
                p.mu[c],
                &mut out[c * n2..(c + 1) * n2],
            );
        }
    };
    let qp = QpOptions {
        tol: opts.qp_rel_tol * bmax,
        max_iter: opts.qp_max_iter,
        max_cg: opts.qp_max_cg.max(1),
    };
    let res = bound_qp_scaled(hess, &b, x, &qp, p.jacobi).map_err(|e| Error::Numeric {
        stage: format!("lighting step, photo {photo}"),
        message: e.to_string(),
    })?;
    Ok(Some(res))
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
