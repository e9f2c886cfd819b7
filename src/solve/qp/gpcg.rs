//! GPCG, matrix-free gradient projection + conjugate gradients for the bound QP (Moré &
//! Toraldo 1991; module docs of [`super`]).

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use crate::{Error, Result};
use nalgebra::{DMatrix, DVector};

use super::kkt_violation;

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
/// active face settles (`Gpcg::projection_phase`), then CG on the free face
/// (`Gpcg::face_phase`).
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
