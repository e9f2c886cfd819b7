//! The non-negative QP solvers against their defining conditions (KKT) and against an
//! independent answer: brute-force enumeration of the active sets on tiny problems.

#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use relight_cpc::solve::qp::{
    bound_qp, bound_qp_dense, kkt_violation, nnls, NnlsOptions, QpOptions,
};

fn gaussian(rng: &mut Pcg64) -> f64 {
    // Box–Muller; enough for test matrices.
    let u: f64 = rng.random::<f64>().max(1e-300);
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

/// `(AᵀA, Aᵀy)` for a random `m × n` A and y.
fn random_problem(rng: &mut Pcg64, m: usize, n: usize) -> (DMatrix<f64>, DVector<f64>) {
    let a = DMatrix::from_fn(m, n, |_, _| gaussian(rng));
    let y = DVector::from_fn(m, |_, _| gaussian(rng));
    (a.transpose() * &a, a.transpose() * y)
}

/// The unique minimiser of a strictly convex box QP by trying every active set: the one
/// whose free solution is non-negative and whose gradient is non-negative on the bound set.
fn brute_force(h: &DMatrix<f64>, b: &DVector<f64>) -> DVector<f64> {
    let n = b.len();
    let mut best: Option<(f64, DVector<f64>)> = None;
    for mask in 0..(1u32 << n) {
        let free: Vec<usize> = (0..n).filter(|&i| mask >> i & 1 == 1).collect();
        let m = free.len();
        let mut x = DVector::zeros(n);
        if m > 0 {
            let hs = DMatrix::from_fn(m, m, |i, j| h[(free[i], free[j])]);
            let bs = DVector::from_fn(m, |i, _| b[free[i]]);
            let z = hs
                .lu()
                .solve(&bs)
                .expect("strictly convex: sub-matrices invertible");
            if z.iter().any(|&v| v < 0.0) {
                continue;
            }
            for (k, &i) in free.iter().enumerate() {
                x[i] = z[k];
            }
        }
        let g = h * &x - b;
        if (0..n).any(|i| mask >> i & 1 == 0 && g[i] < -1e-12 * (1.0 + b.amax())) {
            continue;
        }
        let f = 0.5 * x.dot(&(h * &x)) - b.dot(&x);
        if best.as_ref().is_none_or(|(fb, _)| f < *fb) {
            best = Some((f, x));
        }
    }
    best.expect("a strictly convex box QP has a KKT point").1
}

/// Shared tolerance: absolute + relative to the problem's scale, growing with its size.
fn tol(n: usize, scale: f64) -> f64 {
    1e-9 * (n as f64) * (1.0 + scale)
}

#[test]
fn nnls_and_bound_qp_match_brute_force_on_tiny_problems() {
    let mut rng = Pcg64::seed_from_u64(7);
    for trial in 0..200 {
        let n = 1 + trial % 6;
        let m = n + 2 + trial % 3;
        let (h, b) = random_problem(&mut rng, m, n);
        let truth = brute_force(&h, &b);
        let scale = truth.amax();
        let x = nnls(&h, &b, &NnlsOptions::default()).unwrap();
        assert!(
            (&x - &truth).amax() <= tol(n, scale),
            "nnls trial {trial}: {x} vs {truth}"
        );
        let opts = QpOptions {
            tol: 1e-12 * (1.0 + b.amax()),
            ..QpOptions::default()
        };
        let r = bound_qp_dense(&h, &b, &vec![0.0; n], &opts).unwrap();
        assert!(r.converged, "bound_qp trial {trial} did not converge");
        // GPCG's stopping rule bounds the projected gradient by 1e-12·|b|; with the
        // condition numbers of these 2–8 row Gaussian systems (≲ 1e5) that bounds the error
        // by ≲ 1e-7·scale, so compare at 1e-6.
        let err = truth
            .iter()
            .zip(&r.x)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            err <= 1e-6 * (1.0 + scale),
            "bound_qp trial {trial}: {:?} vs {truth}",
            r.x
        );
    }
}

#[test]
fn kkt_holds_on_random_and_rank_deficient_problems() {
    let mut rng = Pcg64::seed_from_u64(11);
    for trial in 0..30 {
        let n = 10 + trial;
        // Half the trials rank deficient (fewer rows than unknowns): H only semi-definite.
        let m = if trial % 2 == 0 { n + 5 } else { n / 2 };
        let (h, b) = random_problem(&mut rng, m, n);
        let x = nnls(&h, &b, &NnlsOptions::default()).unwrap();
        let g = &h * &x - &b;
        assert!(x.iter().all(|&v| v >= 0.0));
        let scale = b.amax() + h.amax() * x.amax();
        assert!(
            kkt_violation(g.as_slice(), x.as_slice()) <= tol(n, scale),
            "nnls trial {trial}: kkt {}",
            kkt_violation(g.as_slice(), x.as_slice())
        );
        let opts = QpOptions {
            tol: 1e-10 * (1.0 + b.amax()),
            max_iter: 2000,
            ..QpOptions::default()
        };
        let r = bound_qp_dense(&h, &b, &vec![1.0; n], &opts).unwrap();
        let g2 = &h * DVector::from_column_slice(&r.x) - &b;
        assert!(r.converged && r.x.iter().all(|&v| v >= 0.0));
        // The returned kkt is recomputed independently here from H x − b.
        assert!(kkt_violation(g2.as_slice(), &r.x) <= 10.0 * opts.tol);
        // Both solvers minimise the same convex function: equal optimal values.
        let f = |x: &DVector<f64>| 0.5 * x.dot(&(&h * x)) - b.dot(x);
        let fx = f(&x);
        let fr = f(&DVector::from_column_slice(&r.x));
        assert!(
            (fx - fr).abs() <= 1e-7 * (1.0 + fx.abs()),
            "trial {trial}: {fx} vs {fr}"
        );
    }
}

#[test]
fn bound_qp_matrix_free_on_an_ill_conditioned_smoothing_problem() {
    // H = μ I + D₂ᵀD₂ (1D second-difference squared, n = 300): condition number ~ 16/μ = 1.6e5.
    // The matrix-free answer must satisfy KKT and agree with the dense active-set answer.
    let n = 300;
    let mu = 1e-4;
    let mut rng = Pcg64::seed_from_u64(3);
    let b: Vec<f64> = (0..n)
        .map(|i| (i as f64 * 0.05).sin() * 1e-3 + 1e-4 * gaussian(&mut rng))
        .collect();
    let lap = |v: &[f64], out: &mut [f64]| {
        for i in 0..n {
            let l = if i > 0 { v[i - 1] } else { v[i] };
            let r = if i + 1 < n { v[i + 1] } else { v[i] };
            out[i] = 2.0 * v[i] - l - r;
        }
    };
    let hmul = |v: &[f64], out: &mut [f64]| {
        let mut t = vec![0.0; n];
        lap(v, &mut t);
        lap(&t, out);
        for i in 0..n {
            out[i] += mu * v[i];
        }
    };
    let opts = QpOptions {
        // 1e-8 of |b|∞ ≈ 1e-11: above the rounding of H x (|x| ≲ 1e2, entries ≤ 16).
        tol: 1e-11,
        max_iter: 5000,
        max_cg: 400,
    };
    let r = bound_qp(hmul, &b, &vec![0.0; n], &opts).unwrap();
    assert!(r.converged, "kkt {} after {} its", r.kkt, r.iterations);
    let mut hd = DMatrix::zeros(n, n);
    let mut e = vec![0.0; n];
    let mut col = vec![0.0; n];
    for j in 0..n {
        e[j] = 1.0;
        hmul(&e, &mut col);
        e[j] = 0.0;
        for i in 0..n {
            hd[(i, j)] = col[i];
        }
    }
    let x = nnls(
        &hd,
        &DVector::from_column_slice(&b),
        &NnlsOptions::default(),
    )
    .unwrap();
    let f = |x: &[f64]| {
        let mut hx = vec![0.0; n];
        hmul(x, &mut hx);
        0.5 * x.iter().zip(&hx).map(|(a, c)| a * c).sum::<f64>()
            - b.iter().zip(x).map(|(a, c)| a * c).sum::<f64>()
    };
    let (fa, fb) = (f(x.as_slice()), f(&r.x));
    // Optimal values agree to 1e-6 relative: both stop on KKT residuals far below that
    // scale of the objective.
    assert!((fa - fb).abs() <= 1e-6 * fa.abs(), "{fa} vs {fb}");
    eprintln!(
        "its {} matvecs {} cond {:e}",
        r.iterations, r.matvecs, r.cond_lower_bound
    );
    assert!(
        r.cond_lower_bound > 1e3,
        "cond estimate {}",
        r.cond_lower_bound
    );
}

#[test]
fn degenerate_inputs_give_answers_or_errors_not_panics() {
    // Zero matrix and zero vector: x = 0 is optimal.
    let z = DMatrix::zeros(3, 3);
    let x = nnls(&z, &DVector::zeros(3), &NnlsOptions::default()).unwrap();
    assert_eq!(x.amax(), 0.0);
    // NaN input: an error, not a panic or a NaN answer.
    let mut h = DMatrix::identity(2, 2);
    h[(0, 1)] = f64::NAN;
    assert!(nnls(&h, &DVector::zeros(2), &NnlsOptions::default()).is_err());
    assert!(bound_qp_dense(
        &DMatrix::identity(2, 2),
        &DVector::from_vec(vec![f64::NAN, 1.0]),
        &[0.0, 0.0],
        &QpOptions::default()
    )
    .is_err());
    // Duplicate columns (singular H): a KKT point still comes back.
    let a = DMatrix::from_row_slice(3, 2, &[1.0, 1.0, 2.0, 2.0, 0.5, 0.5]);
    let y = DVector::from_vec(vec![1.0, 2.0, 0.5]);
    let (h, b) = (a.transpose() * &a, a.transpose() * y);
    let x = nnls(&h, &b, &NnlsOptions::default()).unwrap();
    let g = &h * &x - &b;
    assert!(kkt_violation(g.as_slice(), x.as_slice()) < 1e-10);
    assert!((x.sum() - 1.0).abs() < 1e-10);
}
