//! Lawson–Hanson active-set NNLS (Lawson & Hanson 1974, ch. 23) on the normal equations
//! (module docs of [`super`]).

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use crate::{Error, Result};
use nalgebra::{DMatrix, DVector};

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
