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
//! - [`nnls()`]: Lawson–Hanson active-set NNLS (Lawson & Hanson 1974, ch. 23) on the normal
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

mod gpcg;
mod nnls;

pub use gpcg::{bound_qp, bound_qp_dense, bound_qp_scaled, QpOptions, QpResult};
pub use nnls::{nnls, NnlsOptions};

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

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

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
