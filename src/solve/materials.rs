//! The material step (paper Sec. 5.2, Eq. 11–12): with the basis responses
//! `s_{p,b,c} = ⟨g_{p,b}, W x_{I,c}⟩` fixed, `λ` per channel from all observations jointly
//! (`K·B` unknowns, design row `w_k(x_p) s_{p,b,c}`, ridge `β_λ`), then `w(x)` per vertex
//! from its observations in all three channels (`K` unknowns, row
//! `Σ_b λ_{k,b,c} s_{p,b,c}`). Both are small dense NNLS problems solved exactly by the
//! active-set [`crate::solve::qp::nnls`], so each minimises `F` over its block.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::observe::Observations;
use crate::solve::options::{EstimateOptions, Robust};
use crate::solve::problem::{Problem, CHUNK};
use crate::solve::qp::{nnls, NnlsOptions};
use crate::{Error, Result};

/// The λ part of the material step.
#[derive(Debug, Clone)]
pub struct LambdaStep {
    /// `lambda[k][b][c]` (`K × B × 3`).
    pub lambda: Vec<Vec<[f64; 3]>>,
    /// Per channel, the condition number of the system (with ridge).
    pub cond: [f64; 3],
    /// Per channel, the system's largest diagonal entry (before the ridge).
    pub max_diag: [f64; 3],
}

/// The w part of the material step.
#[derive(Debug, Clone)]
pub struct WeightsStep {
    /// Row-major `V × K`.
    pub weights: Vec<f64>,
    /// The largest finite condition number over the vertices' systems.
    pub cond_max: f64,
    /// How many vertices' systems were singular.
    pub singular: usize,
}

/// The data weights of the material step, per observation and channel.
pub(crate) struct DataWeights {
    /// `α_p ω_{p,c}` for the λ step (or `α_p` / 0 by the cut with `materials_cut_only`).
    pub(crate) lambda: Vec<[f64; 3]>,
    /// The same with observations below the cut left out, for the w step.
    pub(crate) weights: Vec<[f64; 3]>,
}

/// The material step's data weights from the lighting step's IRLS weights `omega`: with
/// Huber IRLS and [`EstimateOptions::weights_reject`], an observation whose weight is below
/// `k / weights_reject` (a residual beyond `weights_reject · σ`) is left out of the w step.
pub(crate) fn data_weights(
    problem: &Problem,
    omega: &[[f32; 3]],
    opts: &EstimateOptions,
) -> DataWeights {
    let np = problem.obs.vertex.len();
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
    DataWeights {
        lambda: dw,
        weights: dw_w,
    }
}

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
    Ok(LambdaStep {
        lambda,
        cond,
        max_diag: maxd,
    })
}

/// Observations of each vertex (CSR over vertices): `(offsets, obs indices)`.
pub(crate) fn by_vertex(obs: &Observations, n_vertices: usize) -> (Vec<usize>, Vec<usize>) {
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

/// The weights of the sum-to-one prior ([`EstimateOptions::weights_sum`] `= tau`): per
/// vertex `γ_x = tau · Σ_{p ∈ x} α_p Σ_c y_{p,c}²` over its fitted observations. Scaling
/// every weight of a vertex by `1 + δ` scales its predictions by `1 + δ`; near a fit that
/// costs `δ² Σ α ‖y‖²` in the data term, and the prior charges `γ_x δ²` when the weights
/// summed to one, so `tau` is the ratio of the two.
pub fn sum_weights_gamma(obs: &Observations, n_vertices: usize, tau: f64) -> Vec<f64> {
    let mut gamma = vec![0.0; n_vertices];
    for p in 0..obs.len() {
        let a = obs.weight[p] as f64;
        if a > 0.0 {
            let y2: f64 = obs.rgb[p].iter().map(|&v| (v as f64).powi(2)).sum();
            gamma[obs.vertex[p] as usize] += tau * a * y2;
        }
    }
    gamma
}

/// The sum-to-one prior's value `Σ_x γ_x (Σ_k w_k(x) − 1)²` (`weights` row-major `V × K`).
pub fn sum_weights_penalty(gamma: &[f64], weights: &[f64], kk: usize) -> f64 {
    gamma
        .iter()
        .enumerate()
        .filter(|(_, &g)| g > 0.0)
        .map(|(x, g)| g * (weights[x * kk..(x + 1) * kk].iter().sum::<f64>() - 1.0).powi(2))
        .sum()
}

/// Material step, w part (Eq. 12): per vertex, NNLS over its observations in all channels,
/// plus the sum-to-one prior `γ_x (Σ_k w_k − 1)²` when `gamma` is given (its normal
/// equations gain `γ_x 1 1ᵀ` and `γ_x 1`, [`sum_weights_gamma`]). Vertices without weighted
/// observations keep their weights. Returns the new weights, the largest finite condition
/// number and the count of singular systems.
pub fn weights_step(
    problem: &Problem,
    s: &[[f64; 3]],
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    dw: &[[f64; 3]],
    gamma: Option<&[f64]>,
) -> Result<WeightsStep> {
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
            if let Some(g) = gamma.map(|g| g[x]).filter(|&g| g > 0.0) {
                for i in 0..kk {
                    rhs[i] += g;
                    for j in 0..kk {
                        mat[(i, j)] += g;
                    }
                }
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
    Ok(WeightsStep {
        weights: out,
        cond_max: cmax,
        singular,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::Transport;

    /// One vertex's data for the `w` step: observations, transport (only its basis count
    /// is read), basis responses `s` and materials `λ`.
    struct OneVertex {
        obs: Observations,
        transport: Transport,
        s: Vec<[f64; 3]>,
        lambda: Vec<Vec<[f64; 3]>>,
    }

    /// One vertex seen by four observations, two materials of one basis: the `w` step's
    /// normal equations are 2 × 2, so the prior's minimiser has a closed form.
    fn one_vertex() -> OneVertex {
        let mut obs = Observations::default();
        let s = vec![
            [1.0, 0.8, 0.6],
            [0.5, 0.9, 1.2],
            [1.5, 0.4, 0.7],
            [0.9, 1.1, 0.3],
        ];
        let rgb = [
            [0.9, 0.7, 0.5],
            [0.6, 0.8, 0.9],
            [1.1, 0.5, 0.6],
            [0.7, 0.9, 0.4],
        ];
        for (p, y) in rgb.iter().enumerate() {
            obs.vertex.push(0);
            obs.photo.push(p as u32);
            obs.rgb.push(*y);
            obs.weight.push(1.0);
            obs.dir.push([0.0, 0.0, 1.0]);
            obs.photo_ranges.push(p..p + 1);
        }
        let t = Transport {
            n_global: 2,
            n_basis: 1,
            n_obs: 4,
            offsets: vec![0; 5],
            ..Default::default()
        };
        let lambda = vec![vec![[0.8, 0.4, 0.2]], vec![[0.2, 0.4, 0.7]]];
        OneVertex {
            obs,
            transport: t,
            s,
            lambda,
        }
    }

    /// `(M, b)` of the plain `w` step: `M = Σ a aᵀ`, `b = Σ a y` over observations and
    /// channels, `a_k = λ_{k,c} s_{p,c}`.
    fn normal_equations(
        obs: &Observations,
        s: &[[f64; 3]],
        lambda: &[Vec<[f64; 3]>],
    ) -> ([[f64; 2]; 2], [f64; 2]) {
        let (mut m, mut b) = ([[0.0; 2]; 2], [0.0; 2]);
        for p in 0..obs.len() {
            for c in 0..3 {
                let a = [lambda[0][0][c] * s[p][c], lambda[1][0][c] * s[p][c]];
                for i in 0..2 {
                    b[i] += a[i] * obs.rgb[p][c] as f64;
                    for j in 0..2 {
                        m[i][j] += a[i] * a[j];
                    }
                }
            }
        }
        (m, b)
    }

    fn solve2(m: [[f64; 2]; 2], b: [f64; 2]) -> [f64; 2] {
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        [
            (m[1][1] * b[0] - m[0][1] * b[1]) / det,
            (m[0][0] * b[1] - m[1][0] * b[0]) / det,
        ]
    }

    #[test]
    fn sum_to_one_prior_matches_the_closed_form_and_its_hard_limit() {
        let OneVertex {
            obs,
            transport: t,
            s,
            lambda,
        } = one_vertex();
        let problem = Problem {
            obs: &obs,
            transport: &t,
            n_vertices: 1,
            n_photos: 4,
        };
        let dw = vec![[1.0; 3]; 4];
        let w0 = vec![0.5, 0.5];
        // γ by hand: Σ_p Σ_c y² of the four observations.
        let y2: f64 = obs.rgb.iter().flatten().map(|&v| (v as f64).powi(2)).sum();
        let gamma = sum_weights_gamma(&obs, 1, 0.3);
        assert!((gamma[0] - 0.3 * y2).abs() < 1e-12 * y2);
        let (m, b) = normal_equations(&obs, &s, &lambda);
        // Soft prior: (M + γ 1 1ᵀ) w = b + γ 1. Both weights come out positive here, so
        // the NNLS solution is the unconstrained one: equal to rounding (1e-10 relative
        // covers the active-set solver's Cholesky on a 2 × 2 system).
        let g = gamma[0];
        let soft = solve2(
            [[m[0][0] + g, m[0][1] + g], [m[1][0] + g, m[1][1] + g]],
            [b[0] + g, b[1] + g],
        );
        assert!(soft.iter().all(|&v| v > 0.0), "{soft:?}");
        let w = weights_step(&problem, &s, &lambda, &w0, &dw, Some(&gamma)).unwrap();
        for k in 0..2 {
            assert!(
                (w.weights[k] - soft[k]).abs() < 1e-10,
                "{:?} vs {soft:?}",
                w.weights
            );
        }
        // Off: the plain least squares, whose weights do not sum to one.
        let free = solve2(m, b);
        let w = weights_step(&problem, &s, &lambda, &w0, &dw, None).unwrap();
        for k in 0..2 {
            assert!((w.weights[k] - free[k]).abs() < 1e-10);
        }
        assert!((free[0] + free[1] - 1.0).abs() > 0.05, "{free:?}");
        // The hard limit (τ = 10⁸): least squares on the line w₀ + w₁ = 1, by Lagrange:
        // w = M⁻¹ (b − ν 1) with ν chosen so that 1ᵀ w = 1. The soft solution is within
        // O(1/γ) of it: |M| ≈ 1, γ ≈ 10⁸ ⇒ 1e-6 is ample.
        let (mi_b, mi_1) = (solve2(m, b), solve2(m, [1.0, 1.0]));
        let nu = (mi_b[0] + mi_b[1] - 1.0) / (mi_1[0] + mi_1[1]);
        let hard = [mi_b[0] - nu * mi_1[0], mi_b[1] - nu * mi_1[1]];
        let gamma = sum_weights_gamma(&obs, 1, 1e8);
        let w = weights_step(&problem, &s, &lambda, &w0, &dw, Some(&gamma)).unwrap();
        for k in 0..2 {
            assert!(
                (w.weights[k] - hard[k]).abs() < 1e-6,
                "{:?} vs {hard:?}",
                w.weights
            );
        }
        // The penalty's value at a point off the line, by hand.
        let p = sum_weights_penalty(&[2.0, 0.0], &[0.7, 0.6, 5.0, 5.0], 2);
        assert!((p - 2.0 * 0.3f64.powi(2)).abs() < 1e-15);
    }
}
