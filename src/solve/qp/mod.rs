//! Non-negative quadratic programs: the solvers behind the lighting and material steps
//! (paper Sec. 5, Eq. 10–12, all unknowns constrained `≥ 0`).
//!
//! Every problem here is the bound-constrained convex QP
//!
//! `min_x ½ xᵀ H x − bᵀ x   subject to   x ≥ 0`,   `H` symmetric positive semi-definite,
//!
//! whose KKT conditions are `x ≥ 0`, `g = H x − b ≥ 0`, `xᵢ gᵢ = 0`, or equivalently
//! `P(x − g) = x` with `P` the projection onto the non-negative orthant. The residual
//! `‖P(x − g) − x‖∞` ([`kkt_violation`]) is zero exactly at the solution and is the stopping
//! rule of both solvers, so every answer can be checked by the caller.
//!
//! - [`nnls`]: Lawson–Hanson active-set NNLS (Lawson & Hanson 1974, ch. 23) on the normal
//!   equations (`H = AᵀA`, `b = Aᵀy`, the Bro–De Jong 1997 formulation). Finite termination;
//!   used for the small dense systems of the material step (K·B unknowns for λ, K for w).
//! - [`bound_qp`]: matrix-free gradient projection + conjugate gradients (GPCG, Moré &
//!   Toraldo 1991, SIAM J. Optim. 1(1)): projected-gradient steps with an Armijo projected
//!   search identify the active face, CG on the free variables solves the reduced Newton
//!   system, and a projected search along the CG direction keeps feasibility. Used for the
//!   lighting step (thousands of texels, Hessian applied through the sparse transport).
//!
//! An interior-point QP crate (clarabel) solves the same problems. It is not used: the
//! material step's systems have 1–42 unknowns, where the active set terminates finitely with
//! an exact solve on the identified face and needs no tolerance tuning, and the lighting
//! step needs a matrix-free method (forming its Hessian costs more than solving). A measured
//! comparison against clarabel is still to be made.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use crate::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// `‖P(x − g) − x‖∞`, the projected-gradient KKT residual of `min f(x)` s.t. `x ≥ 0`, where
/// `g = ∇f(x)` and `P` clamps to `≥ 0`. Zero exactly at a KKT point.
pub fn kkt_violation(grad: &[f64], x: &[f64]) -> f64 {
    grad.iter()
        .zip(x)
        // For xᵢ ≥ 0, max(xᵢ − gᵢ, 0) − xᵢ = −min(gᵢ, xᵢ): the same value without rounding.
        .map(|(&g, &xi)| {
            if xi >= 0.0 {
                g.min(xi).abs()
            } else {
                ((xi - g).max(0.0) - xi).abs()
            }
        })
        .fold(0.0, f64::max)
}

/// Options of [`nnls`].
#[derive(Debug, Clone, Copy)]
pub struct NnlsOptions {
    /// Dual-feasibility tolerance relative to `max(‖Aᵀy‖∞, max diag(AᵀA))`:
    /// the solver stops when no inactive variable has gradient `< −rel_tol · scale`.
    pub rel_tol: f64,
    /// Cap on outer (variable-adding) iterations; 0 means `3 n`.
    pub max_iter: usize,
}

impl Default for NnlsOptions {
    fn default() -> Self {
        NnlsOptions {
            rel_tol: 1e-11,
            max_iter: 0,
        }
    }
}

/// Solves `H_PP z = b_P` on the passive set `P` (Cholesky; symmetric eigen pseudo-inverse
/// when the sub-matrix is singular to working precision).
fn solve_passive(ata: &DMatrix<f64>, atb: &DVector<f64>, passive: &[usize]) -> Vec<f64> {
    let m = passive.len();
    let sub = DMatrix::from_fn(m, m, |i, j| ata[(passive[i], passive[j])]);
    let rhs = DVector::from_fn(m, |i, _| atb[passive[i]]);
    let max_diag = (0..m).map(|i| sub[(i, i)]).fold(0.0, f64::max);
    if let Some(ch) = sub.clone().cholesky() {
        let z = ch.solve(&rhs);
        // Reject a numerically singular factorisation (huge pivots ratio).
        let min_l = (0..m).map(|i| ch.l()[(i, i)]).fold(f64::INFINITY, f64::min);
        if z.iter().all(|v| v.is_finite()) && min_l * min_l > 1e-14 * max_diag {
            return z.iter().copied().collect();
        }
    }
    let eig = sub.symmetric_eigen();
    let cut = 1e-13 * eig.eigenvalues.iter().fold(0.0_f64, |a, &v| a.max(v.abs()));
    let mut z = DVector::zeros(m);
    for (k, &ev) in eig.eigenvalues.iter().enumerate() {
        if ev > cut {
            let u = eig.eigenvectors.column(k);
            z += u * (u.dot(&rhs) / ev);
        }
    }
    z.iter().copied().collect()
}

/// Non-negative least squares on the normal equations: `min ½ xᵀ(AᵀA)x − (Aᵀy)ᵀx`, `x ≥ 0`,
/// by the Lawson–Hanson active-set method. `ata` must be symmetric positive semi-definite.
///
/// Returns `Error::Numeric` on non-finite input. Terminates in finitely many steps; after
/// `max_iter` outer steps the current (feasible, improved) iterate is returned.
pub fn nnls(ata: &DMatrix<f64>, atb: &DVector<f64>, opts: &NnlsOptions) -> Result<DVector<f64>> {
    check_nnls_inputs(ata, atb)?;
    let n = atb.len();
    let mut x = DVector::<f64>::zeros(n);
    if n == 0 {
        return Ok(x);
    }
    let scale = atb
        .amax()
        .max((0..n).map(|i| ata[(i, i)]).fold(0.0, f64::max))
        .max(f64::MIN_POSITIVE);
    let tol = opts.rel_tol * scale;
    let max_iter = if opts.max_iter == 0 {
        3 * n
    } else {
        opts.max_iter
    };
    let mut sets = ActiveSets {
        passive: vec![false; n],
        barred: vec![false; n],
    };
    for _ in 0..max_iter {
        // Dual variables w = Aᵀy − AᵀA x (negative gradient).
        let w = atb - ata * &x;
        let Some(j) = sets.entering(&w, tol) else {
            break;
        };
        sets.passive[j] = true;
        sets.feasible_passive_solution(ata, atb, &mut x, j);
    }
    Ok(x)
}

/// The normal equations of [`nnls`] are square, of the vector's size, and finite.
fn check_nnls_inputs(ata: &DMatrix<f64>, atb: &DVector<f64>) -> Result<()> {
    let n = atb.len();
    if ata.nrows() != n || ata.ncols() != n {
        return Err(Error::Numeric {
            stage: "nnls".into(),
            message: format!("matrix is {}×{}, vector {n}", ata.nrows(), ata.ncols()),
        });
    }
    if ata.iter().chain(atb.iter()).any(|v| !v.is_finite()) {
        return Err(Error::Numeric {
            stage: "nnls".into(),
            message: "non-finite entry in the normal equations".into(),
        });
    }
    Ok(())
}

/// Lawson–Hanson's sets: the passive (free) variables, and the variables that failed to
/// enter (rounding), barred until the next successful step.
struct ActiveSets {
    passive: Vec<bool>,
    barred: Vec<bool>,
}

impl ActiveSets {
    /// The variable to enter: the largest dual `w_j > tol` among those neither passive nor
    /// barred (the first of equals).
    fn entering(&self, w: &DVector<f64>, tol: f64) -> Option<usize> {
        let mut best: Option<(usize, f64)> = None;
        for j in 0..w.len() {
            if !self.passive[j]
                && !self.barred[j]
                && w[j] > tol
                && best.is_none_or(|(_, v)| w[j] > v)
            {
                best = Some((j, w[j]));
            }
        }
        best.map(|(j, _)| j)
    }

    /// Lawson–Hanson's inner loop after `j` entered: solve on the passive set; while the
    /// solution `z` has a non-positive entry, step from `x` toward `z` until the first
    /// passive variable hits zero and drop it. A rounding artefact (the entering `z_j ≤ 0`)
    /// bars `j` and keeps the iterate.
    fn feasible_passive_solution(
        &mut self,
        ata: &DMatrix<f64>,
        atb: &DVector<f64>,
        x: &mut DVector<f64>,
        j: usize,
    ) {
        let n = x.len();
        let mut first = true;
        loop {
            let set: Vec<usize> = (0..n).filter(|&i| self.passive[i]).collect();
            let z = solve_passive(ata, atb, &set);
            if first {
                first = false;
                // In exact arithmetic w_j > 0 makes the entering z_j positive (Lawson–Hanson
                // Lemma 23.17); a non-positive one is a rounding artefact of a near-zero
                // dual: bar j until the next successful step and keep the iterate.
                let pos = set.iter().position(|&i| i == j).unwrap_or(0);
                if z[pos] <= 0.0 {
                    self.passive[j] = false;
                    self.barred[j] = true;
                    return;
                }
            }
            if z.iter().all(|&v| v > 0.0) {
                for (i, &v) in set.iter().zip(&z) {
                    x[*i] = v;
                }
                for i in 0..n {
                    if !self.passive[i] {
                        x[i] = 0.0;
                    }
                }
                self.barred.iter_mut().for_each(|b| *b = false);
                return;
            }
            self.step_toward(x, &set, &z);
            if !self.passive.iter().any(|&p| p) {
                return;
            }
        }
    }

    /// Step from `x` toward `z` (on `set`) until the first passive variable hits zero; the
    /// variables at zero leave the passive set.
    fn step_toward(&mut self, x: &mut DVector<f64>, set: &[usize], z: &[f64]) {
        let mut alpha = f64::INFINITY;
        let mut hit = set[0];
        for (i, &v) in set.iter().zip(z) {
            if v <= 0.0 {
                let a = if x[*i] - v > 0.0 {
                    x[*i] / (x[*i] - v)
                } else {
                    0.0
                };
                if a < alpha {
                    alpha = a;
                    hit = *i;
                }
            }
        }
        let alpha = alpha.min(1.0);
        for (i, &v) in set.iter().zip(z) {
            x[*i] += alpha * (v - x[*i]);
        }
        x[hit] = 0.0;
        for &i in set {
            if x[i] <= 0.0 {
                x[i] = 0.0;
                self.passive[i] = false;
            }
        }
    }
}

/// Options of [`bound_qp`].
#[derive(Debug, Clone, Copy)]
pub struct QpOptions {
    /// Stop when `‖P(x − ∇f) − x‖∞ ≤ tol` (absolute, in the units of `b`).
    pub tol: f64,
    /// Cap on outer (gradient projection + CG) iterations.
    pub max_iter: usize,
    /// Cap on CG iterations per outer iteration.
    pub max_cg: usize,
}

impl Default for QpOptions {
    fn default() -> Self {
        QpOptions {
            tol: 1e-9,
            max_iter: 500,
            max_cg: 100,
        }
    }
}

/// Answer of [`bound_qp`].
#[derive(Debug, Clone)]
pub struct QpResult {
    /// The minimiser, `≥ 0`.
    pub x: Vec<f64>,
    /// `‖P(x − ∇f) − x‖∞` at `x`.
    pub kkt: f64,
    /// `½ xᵀHx − bᵀx` at `x`.
    pub objective: f64,
    /// Outer iterations done.
    pub iterations: usize,
    /// Hessian products done.
    pub matvecs: usize,
    /// Whether `kkt ≤ tol` was reached (else the iteration cap was).
    pub converged: bool,
    /// Lower bound on the condition number of `H`: the ratio of the largest to the smallest
    /// Rayleigh quotient / Ritz value met along the search directions and in the CG
    /// (Lanczos) runs on the free faces. Tight when CG ran many steps.
    pub cond_lower_bound: f64,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// State shared by the two kinds of projected search.
struct Iterate {
    x: Vec<f64>,
    hx: Vec<f64>,
    g: Vec<f64>,
    f: f64,
}

impl Iterate {
    fn refresh(&mut self, b: &[f64]) {
        for i in 0..self.x.len() {
            self.g[i] = self.hx[i] - b[i];
        }
        self.f = 0.5 * dot(&self.x, &self.hx) - dot(b, &self.x);
    }
}

/// Projected Armijo search along `d` from `it` (`hd = H d`), first trial step `alpha`.
/// Returns whether a step was accepted (and then updates `it`).
fn projected_search<H: Fn(&[f64], &mut [f64])>(
    hess_mul: &H,
    b: &[f64],
    it: &mut Iterate,
    d: &[f64],
    hd: &[f64],
    mut alpha: f64,
    matvecs: &mut usize,
) -> bool {
    let n = it.x.len();
    let mut xn = vec![0.0; n];
    let mut hxn = vec![0.0; n];
    for _ in 0..60 {
        let mut clipped = false;
        for i in 0..n {
            let v = it.x[i] + alpha * d[i];
            if v < 0.0 {
                clipped = true;
                xn[i] = 0.0;
            } else {
                xn[i] = v;
            }
        }
        if clipped {
            hess_mul(&xn, &mut hxn);
            *matvecs += 1;
        } else {
            for i in 0..n {
                hxn[i] = it.hx[i] + alpha * hd[i];
            }
        }
        // f(xn) − f(x) = gᵀs + ½ sᵀHs with s = xn − x, summed without the cancellation of
        // differencing two objective values.
        let (mut gstep, mut df) = (0.0, 0.0);
        for i in 0..n {
            let s = xn[i] - it.x[i];
            gstep += it.g[i] * s;
            df += s * (it.g[i] + 0.5 * (hxn[i] - it.hx[i]));
        }
        if gstep < 0.0 && df <= 1e-4 * gstep {
            std::mem::swap(&mut it.x, &mut xn);
            std::mem::swap(&mut it.hx, &mut hxn);
            it.refresh(b);
            return true;
        }
        alpha *= 0.5;
    }
    false
}

/// Widens `spec = (min, max)` by a positive Rayleigh quotient `q`.
fn record(spec: &mut (f64, f64), q: f64) {
    if q > 0.0 && q.is_finite() {
        spec.0 = spec.0.min(q);
        spec.1 = spec.1.max(q);
    }
}

/// Extreme eigenvalues of the Lanczos tridiagonal built from CG steps `(α_j, β_j)`:
/// `T_jj = 1/α_j + β_{j−1}/α_{j−1}`, `T_{j,j+1} = √β_j / α_j` (Saad, Iterative Methods, §6.7.3).
fn ritz_extremes(steps: &[(f64, f64)]) -> Option<(f64, f64)> {
    let k = steps.len();
    if k < 2 {
        return None;
    }
    let mut t = DMatrix::zeros(k, k);
    for j in 0..k {
        let (a, _) = steps[j];
        t[(j, j)] = 1.0 / a
            + if j > 0 {
                steps[j - 1].1 / steps[j - 1].0
            } else {
                0.0
            };
        if j + 1 < k {
            let off = steps[j].1.sqrt() / a;
            t[(j, j + 1)] = off;
            t[(j + 1, j)] = off;
        }
    }
    let ev = t.symmetric_eigenvalues();
    let lo = ev.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ev.iter().copied().fold(0.0, f64::max);
    (lo > 0.0 && hi.is_finite()).then_some((lo, hi))
}

/// Matrix-free `min ½ xᵀHx − bᵀx` s.t. `x ≥ 0` by GPCG (Moré & Toraldo 1991), `H` symmetric
/// positive semi-definite given by `hess_mul(v, out)` (`out = H v`). Starts from `P(x0)`.
///
/// Stops when `‖P(x − ∇f) − x‖∞ ≤ opts.tol`, or after `opts.max_iter` outer iterations (then
/// `converged == false`; the iterate is feasible and no worse than the start).
pub fn bound_qp<H: Fn(&[f64], &mut [f64])>(
    hess_mul: H,
    b: &[f64],
    x0: &[f64],
    opts: &QpOptions,
) -> Result<QpResult> {
    bound_qp_scaled(hess_mul, b, x0, opts, None)
}

/// [`bound_qp`] with a diagonal (Jacobi) scaling `M = diag(m)`, `m > 0`: the gradient
/// projection steps follow `−M⁻¹ g` (still a descent direction, zero on the active bounds
/// like `−g`) and the face solves are preconditioned CG with `M_FF`. The stopping rule is
/// unchanged (the unscaled projected gradient), so the answer meets the same KKT
/// tolerance; only the path and the number of products change. With scaling, the
/// condition-number bound comes from Rayleigh quotients of `H` alone (the CG's Ritz
/// values then describe `M⁻¹H`, not `H`). Entries of `m` that are not finite and positive
/// count as 1.
///
/// Each outer iteration is Moré & Toraldo's two phases: gradient projection until the
/// active face settles ([`Gpcg::projection_phase`]), then CG on the free face
/// ([`Gpcg::face_phase`]).
pub fn bound_qp_scaled<H: Fn(&[f64], &mut [f64])>(
    hess_mul: H,
    b: &[f64],
    x0: &[f64],
    opts: &QpOptions,
    diag: Option<&[f64]>,
) -> Result<QpResult> {
    let inv_m = check_qp_inputs(b, x0, diag)?;
    let mut s = Gpcg::new(&hess_mul, b, x0, inv_m);
    let (mut iterations, mut converged) = (0, false);
    let mut kkt = kkt_violation(&s.it.g, &s.it.x);
    while iterations < opts.max_iter {
        if !kkt.is_finite() || !s.it.f.is_finite() {
            return Err(Error::Numeric {
                stage: "bound_qp".into(),
                message: "the iterate became non-finite (is H positive semi-definite?)".into(),
            });
        }
        if kkt <= opts.tol {
            converged = true;
            break;
        }
        iterations += 1;
        // Exact products now and then, against drift of the updated H x.
        if iterations % 8 == 0 {
            s.exact_product();
        }
        s.projection_phase();
        kkt = kkt_violation(&s.it.g, &s.it.x);
        if kkt <= opts.tol {
            converged = true;
            break;
        }
        s.face_phase(opts.max_cg);
        kkt = kkt_violation(&s.it.g, &s.it.x);
    }
    if !converged && kkt <= opts.tol {
        converged = true;
    }
    let (lo, hi) = s.spec;
    Ok(QpResult {
        objective: s.it.f,
        kkt,
        x: s.it.x,
        iterations,
        matvecs: s.matvecs,
        converged,
        cond_lower_bound: if lo.is_finite() && lo > 0.0 {
            hi / lo
        } else {
            f64::INFINITY
        },
    })
}

/// The inputs of [`bound_qp_scaled`] checked (lengths, finite entries); the inverse of the
/// scaling, `1/m_i` (1 where `m_i` is not finite and positive), when given.
fn check_qp_inputs(b: &[f64], x0: &[f64], diag: Option<&[f64]>) -> Result<Option<Vec<f64>>> {
    let n = b.len();
    if diag.is_some_and(|m| m.len() != n) {
        return Err(Error::Numeric {
            stage: "bound_qp".into(),
            message: format!(
                "scaling has {} entries, b has {n}",
                diag.map_or(0, |m| m.len())
            ),
        });
    }
    if x0.len() != n {
        return Err(Error::Numeric {
            stage: "bound_qp".into(),
            message: format!("start has {} entries, b has {n}", x0.len()),
        });
    }
    if b.iter().chain(x0).any(|v| !v.is_finite()) {
        return Err(Error::Numeric {
            stage: "bound_qp".into(),
            message: "non-finite entry in b or the start".into(),
        });
    }
    Ok(diag.map(|m| {
        m.iter()
            .map(|&v| {
                if v.is_finite() && v > 0.0 {
                    1.0 / v
                } else {
                    1.0
                }
            })
            .collect()
    }))
}

/// The GPCG solver's state: the iterate, the scaling, the product count, the extreme
/// Rayleigh quotients / Ritz values seen `(min, max)`, and scratch vectors.
struct Gpcg<'a, H: Fn(&[f64], &mut [f64])> {
    hess_mul: &'a H,
    b: &'a [f64],
    inv_m: Option<Vec<f64>>,
    it: Iterate,
    matvecs: usize,
    spec: (f64, f64),
    d: Vec<f64>,
    hd: Vec<f64>,
    p: Vec<f64>,
    hp: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
}

impl<'a, H: Fn(&[f64], &mut [f64])> Gpcg<'a, H> {
    /// The state at `P(x0)`, its product `H x` formed.
    fn new(hess_mul: &'a H, b: &'a [f64], x0: &[f64], inv_m: Option<Vec<f64>>) -> Self {
        let n = b.len();
        let zeros = || vec![0.0; n];
        let mut s = Gpcg {
            hess_mul,
            b,
            inv_m,
            it: Iterate {
                x: x0.iter().map(|v| v.max(0.0)).collect(),
                hx: zeros(),
                g: zeros(),
                f: 0.0,
            },
            matvecs: 0,
            spec: (f64::INFINITY, 0.0),
            d: zeros(),
            hd: zeros(),
            p: zeros(),
            hp: zeros(),
            r: zeros(),
            z: zeros(),
        };
        s.exact_product();
        s
    }

    /// `H x` formed anew (not updated), then the gradient and objective.
    fn exact_product(&mut self) {
        (self.hess_mul)(&self.it.x, &mut self.it.hx);
        self.matvecs += 1;
        self.it.refresh(self.b);
    }

    /// Phase 1, gradient projection: steepest descent (`−M⁻¹ g`, zero on the active
    /// bounds) with a projected search, until the active face settles or progress stalls
    /// (Moré–Toraldo, η₂ = 0.25), at most 12 steps.
    fn projection_phase(&mut self) {
        let n = self.b.len();
        let Gpcg {
            hess_mul,
            b,
            inv_m,
            it,
            matvecs,
            spec,
            d,
            hd,
            ..
        } = self;
        let scale = |i: usize| inv_m.as_ref().map_or(1.0, |w| w[i]);
        let mut best_dec = 0.0_f64;
        for _ in 0..12 {
            for i in 0..n {
                d[i] = if it.x[i] <= 0.0 && it.g[i] > 0.0 {
                    0.0
                } else {
                    -it.g[i] * scale(i)
                };
            }
            let dd = dot(d, d);
            if dd == 0.0 {
                break;
            }
            hess_mul(d, hd);
            *matvecs += 1;
            let dhd = dot(d, hd);
            record(spec, dhd / dd);
            // Exact minimiser along d: −gᵀd / dᵀHd (= dᵀd / dᵀHd unscaled).
            let gd = -dot(&it.g, d);
            let alpha = if dhd > 0.0 && gd > 0.0 { gd / dhd } else { 1.0 };
            let before: Vec<bool> = it.x.iter().map(|&v| v > 0.0).collect();
            let f_old = it.f;
            if !projected_search(*hess_mul, b, it, d, hd, alpha, matvecs) {
                break;
            }
            let dec = f_old - it.f;
            best_dec = best_dec.max(dec);
            let same_face = it.x.iter().zip(&before).all(|(&v, &b0)| (v > 0.0) == b0);
            if same_face || dec <= 0.25 * best_dec {
                break;
            }
        }
    }

    /// Phase 2, (preconditioned) CG on the free face `F = {x > 0}`: `H_FF d_F = −g_F` to a
    /// forcing tolerance, at most `max_cg` steps, then a projected search along `d`.
    fn face_phase(&mut self, max_cg: usize) {
        let n = self.b.len();
        let Gpcg {
            hess_mul,
            b,
            inv_m,
            it,
            matvecs,
            spec,
            d,
            hd,
            p,
            hp,
            r,
            z,
        } = self;
        let scale = |i: usize| inv_m.as_ref().map_or(1.0, |w| w[i]);
        let free: Vec<bool> = it.x.iter().map(|&v| v > 0.0).collect();
        for i in 0..n {
            r[i] = if free[i] { -it.g[i] } else { 0.0 };
            d[i] = 0.0;
            hd[i] = 0.0;
        }
        let rr0 = dot(r, r);
        if rr0 <= 0.0 {
            return;
        }
        // z = M⁻¹ r (z = r unscaled); rz = rᵀz drives the (P)CG recurrences, the unscaled
        // ‖r‖ the stopping rule.
        for i in 0..n {
            z[i] = r[i] * scale(i);
        }
        p.copy_from_slice(z);
        let mut rz = dot(r, z);
        // Forcing term: superlinear near the solution, loose far from it.
        let eta = (rr0.sqrt().sqrt()).clamp(1e-10, 0.1);
        // CG's (α, β) define the Lanczos tridiagonal whose Ritz values bound the spectrum
        // of H_FF from inside: used for the condition-number estimate.
        let mut lanczos: Vec<(f64, f64)> = Vec::new();
        for _ in 0..max_cg {
            hess_mul(p, hp);
            *matvecs += 1;
            let php: f64 = (0..n).filter(|&i| free[i]).map(|i| p[i] * hp[i]).sum();
            record(spec, php / dot(p, p));
            if php <= 0.0 {
                break;
            }
            let a = rz / php;
            for i in 0..n {
                d[i] += a * p[i];
                hd[i] += a * hp[i];
                if free[i] {
                    r[i] -= a * hp[i];
                }
            }
            let rr_new = dot(r, r);
            if rr_new.sqrt() <= eta * rr0.sqrt() {
                break;
            }
            for i in 0..n {
                z[i] = r[i] * scale(i);
            }
            let rz_new = dot(r, z);
            let beta = rz_new / rz;
            lanczos.push((a, beta));
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
            rz = rz_new;
        }
        if inv_m.is_none() {
            if let Some((lo, hi)) = ritz_extremes(&lanczos) {
                record(spec, lo);
                record(spec, hi);
            }
        }
        projected_search(*hess_mul, b, it, d, hd, 1.0, matvecs);
    }
}

/// Dense convenience: `bound_qp` with `H` given as a matrix.
pub fn bound_qp_dense(
    h: &DMatrix<f64>,
    b: &DVector<f64>,
    x0: &[f64],
    opts: &QpOptions,
) -> Result<QpResult> {
    let n = b.len();
    bound_qp(
        |v: &[f64], out: &mut [f64]| {
            for (i, o) in out.iter_mut().enumerate().take(n) {
                *o = (0..n).map(|j| h[(i, j)] * v[j]).sum();
            }
        },
        b.as_slice(),
        x0,
        opts,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kkt_violation_is_zero_exactly_at_kkt_points() {
        // x=0 with g ≥ 0 and x>0 with g=0 are KKT points; a negative gradient at 0 is not.
        assert_eq!(kkt_violation(&[1.0, 0.0], &[0.0, 2.0]), 0.0);
        assert_eq!(kkt_violation(&[-0.5, 0.0], &[0.0, 2.0]), 0.5);
        assert_eq!(kkt_violation(&[0.3, 0.0], &[2.0, 2.0]), 0.3);
    }

    /// The scaled solver meets the same KKT conditions as the unscaled one on a badly
    /// scaled problem (`H = S A Aᵀ S + 10⁻³ I`, `S` spanning 10⁻²…10², an optimum with
    /// active bounds) and reaches the same point: `H` is positive definite, so the KKT
    /// point is the unique minimiser. KKT tolerance 1e-10, so each answer is within about
    /// `tol · √n / λ_min(H) ≈ 1e-10 · 6.3 / 1e-3 ≈ 6e-7` of it; they must agree to 1e-6
    /// of the solution's norm.
    #[test]
    fn scaled_matches_unscaled_on_a_badly_scaled_problem() {
        let n = 40;
        let mut seed = 7_u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let a = DMatrix::from_fn(n, n, |_, _| rnd());
        let sc: Vec<f64> = (0..n)
            .map(|i| 10f64.powf(-2.0 + 4.0 * i as f64 / (n - 1) as f64))
            .collect();
        let mut h = &a * a.transpose();
        for i in 0..n {
            for j in 0..n {
                h[(i, j)] *= sc[i] * sc[j];
            }
            h[(i, i)] += 1e-3;
        }
        let b = DVector::from_fn(n, |i, _| rnd() * sc[i]);
        let opts = QpOptions {
            tol: 1e-10,
            max_iter: 5000,
            max_cg: 200,
        };
        let zero = vec![0.0; n];
        let mul = |v: &[f64], out: &mut [f64]| {
            for (i, o) in out.iter_mut().enumerate() {
                *o = (0..n).map(|j| h[(i, j)] * v[j]).sum();
            }
        };
        let plain = bound_qp(mul, b.as_slice(), &zero, &opts).unwrap();
        let diag: Vec<f64> = (0..n).map(|i| h[(i, i)]).collect();
        let scaled = bound_qp_scaled(mul, b.as_slice(), &zero, &opts, Some(&diag)).unwrap();
        assert!(plain.converged && scaled.converged, "{plain:?} {scaled:?}");
        // KKT of the scaled answer, recomputed here from H and b.
        let g: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| h[(i, j)] * scaled.x[j]).sum::<f64>() - b[i])
            .collect();
        assert!(kkt_violation(&g, &scaled.x) <= 1e-10);
        assert!(scaled.x.iter().all(|&v| v >= 0.0));
        assert!(
            scaled.x.iter().filter(|&&v| v == 0.0).count() > 0,
            "no active bound"
        );
        let norm = plain.x.iter().map(|v| v * v).sum::<f64>().sqrt();
        let diff = plain
            .x
            .iter()
            .zip(&scaled.x)
            .map(|(p, q)| (p - q) * (p - q))
            .sum::<f64>()
            .sqrt();
        assert!(
            norm >= 1.0 && diff <= 1e-6 * norm,
            "diff {diff} norm {norm}"
        );
        // A wrong-length scaling is an error, not a panic.
        assert!(bound_qp_scaled(mul, b.as_slice(), &zero, &opts, Some(&diag[1..])).is_err());
    }

    #[test]
    fn nnls_one_dimensional_closed_form() {
        // min ½ a x² − c x, x ≥ 0: x = max(c/a, 0).
        let a = DMatrix::from_element(1, 1, 2.0);
        let x = nnls(&a, &DVector::from_element(1, 3.0), &NnlsOptions::default()).unwrap();
        assert!((x[0] - 1.5).abs() < 1e-14);
        let x = nnls(&a, &DVector::from_element(1, -3.0), &NnlsOptions::default()).unwrap();
        assert_eq!(x[0], 0.0);
    }
}
