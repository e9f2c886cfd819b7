//! The material step (paper Sec. 5.2, Eq. 11–12): with the basis responses
//! `s_{p,b,c} = ⟨g_{p,b}, W x_{I,c}⟩` fixed, `λ` per channel from all observations jointly
//! (`K·B` unknowns, design row `w_k(x_p) s_{p,b,c}`, ridge `β_λ`), then `w(x)` per vertex
//! from its observations in all three channels (`K` unknowns, row
//! `Σ_b λ_{k,b,c} s_{p,b,c}`). Both are small dense NNLS problems solved exactly by the
//! active-set [`crate::solve::qp::nnls`], so each minimises `F` over its block.
//!
//! **Achromatic specular lobes** ([`EstimateOptions::achromatic_specular`], not in the
//! paper): a dielectric's specular reflection is the Fresnel reflection at its surface,
//! whose index of refraction barely depends on wavelength over the visible range, so the
//! specular lobes reflect the light's colour and the material's colour lives in its
//! diffuse lobe (the dichromatic reflection model, Shafer 1985, "Using color to separate
//! reflection components"). With the option every basis other than
//! [`EstimateOptions::lambert_basis`] has one weight per material shared by R, G and B:
//! `λ_{k,b,c} = σ_{k,b}`. The three channels' λ systems `(M_c + ρ_c I) λ_c = r_c` then
//! become one NNLS over `z` (`K·(B−1)·3 + K·(B−1)` unknowns, [`solve_tied`]):
//! `λ_c = P_c z` with `P_c` the 0/1 map of channel `c`'s unknowns onto `z`, so
//! `(Σ_c P_cᵀ (M_c + ρ_c I) P_c) z = Σ_c P_cᵀ r_c`, the exact minimiser of the same data
//! term and ridge on the constrained set. `F` is invariant to a per-channel scale of λ
//! against the lights (normalise's module docs): the constraint fixes that gauge (the
//! lights carry the illuminant's colour) and otherwise ties the specular colour of all
//! materials together, which is what it adds with two or more glossy materials.

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

/// How the λ step couples the channels.
#[derive(Debug, Clone, Copy, Default)]
pub struct LambdaCoupling {
    /// `Some(l)`: every basis but `l` shares one weight per material across R, G and B
    /// (module docs); `None`: the channels are independent (the paper).
    pub achromatic_except: Option<usize>,
}

impl LambdaCoupling {
    /// The coupling the options ask for.
    pub fn of(opts: &EstimateOptions) -> Self {
        LambdaCoupling {
            achromatic_except: opts.achromatic_specular.then_some(opts.lambert_basis),
        }
    }
}

/// One channel's λ normal equations `(M, r)` (`K·B` unknowns, index `k·B + b`).
type ChannelSystem = (DMatrix<f64>, DVector<f64>);

/// Material step, λ part: per channel, NNLS over all observations (`K·B` unknowns) with
/// ridge `ridge[c]` (absolute), or one NNLS over the three channels with the specular
/// weights shared ([`LambdaCoupling`]). Returns λ and each channel system's condition
/// number and largest diagonal entry (before the ridge).
#[allow(clippy::too_many_arguments)]
pub fn lambda_step(
    problem: &Problem,
    s: &[[f64; 3]],
    weights: &[f64],
    n_materials: usize,
    dw: &[[f64; 3]],
    ridge: Option<[f64; 3]>,
    rel_ridge: f64,
    coupling: LambdaCoupling,
) -> Result<LambdaStep> {
    let nb = problem.transport.n_basis;
    let kk = n_materials;
    let mut sys = lambda_systems(problem, s, weights, kk, dw);
    let m = kk * nb;
    let mut lambda = vec![vec![[0.0; 3]; nb]; kk];
    let mut cond = [0.0; 3];
    let mut maxd = [0.0; 3];
    for c in 0..3 {
        let (mat, _) = &mut sys[c];
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
    }
    let sol = match coupling.achromatic_except {
        Some(lb) => {
            let tied: Vec<bool> = (0..m).map(|i| i % nb != lb).collect();
            solve_tied(&sys, &tied)?
        }
        None => {
            let mut out = vec![[0.0; 3]; m];
            for c in 0..3 {
                let x = nnls(&sys[c].0, &sys[c].1, &NnlsOptions::default()).map_err(|e| {
                    Error::Numeric {
                        stage: format!("material step (λ, channel {c})"),
                        message: e.to_string(),
                    }
                })?;
                for i in 0..m {
                    out[i][c] = x[i];
                }
            }
            out
        }
    };
    for k in 0..kk {
        for b in 0..nb {
            lambda[k][b] = sol[k * nb + b];
        }
    }
    Ok(LambdaStep {
        lambda,
        cond,
        max_diag: maxd,
    })
}

/// The three channels' λ systems `(M_c, r_c)` (ridge included) solved as one NNLS with
/// the unknowns where `tied[i]` shared by R, G and B (module docs: `Σ_c P_cᵀ M_c P_c`).
/// Returns `λ[i][c]`.
pub fn solve_tied(sys: &[ChannelSystem; 3], tied: &[bool]) -> Result<Vec<[f64; 3]>> {
    let m = tied.len();
    // var[c][i]: the index in z of channel c's unknown i.
    let mut var = [vec![0usize; m], vec![0usize; m], vec![0usize; m]];
    let mut n = 0;
    for i in 0..m {
        for c in 0..3 {
            var[c][i] = if tied[i] && c > 0 { var[0][i] } else { n };
            if !(tied[i] && c > 0) {
                n += 1;
            }
        }
    }
    let mut mat = DMatrix::<f64>::zeros(n, n);
    let mut rhs = DVector::<f64>::zeros(n);
    for c in 0..3 {
        let (mc, rc) = &sys[c];
        for i in 0..m {
            rhs[var[c][i]] += rc[i];
            for j in 0..m {
                mat[(var[c][i], var[c][j])] += mc[(i, j)];
            }
        }
    }
    let z = nnls(&mat, &rhs, &NnlsOptions::default()).map_err(|e| Error::Numeric {
        stage: "material step (λ, achromatic specular)".into(),
        message: e.to_string(),
    })?;
    Ok((0..m).map(|i| [0, 1, 2].map(|c| z[var[c][i]])).collect())
}

/// The λ normal equations per channel, without ridge: `M_c = Σ_p dw_{p,c} a aᵀ`,
/// `r_c = Σ_p dw_{p,c} a y_{p,c}`, `a_{k·B+b} = w_k(x_p) s_{p,b,c}`.
fn lambda_systems(
    problem: &Problem,
    s: &[[f64; 3]],
    weights: &[f64],
    kk: usize,
    dw: &[[f64; 3]],
) -> [ChannelSystem; 3] {
    let nb = problem.transport.n_basis;
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
    for (mat, _) in sys.iter_mut() {
        for i in 0..m {
            for j in 0..i {
                mat[(j, i)] = mat[(i, j)];
            }
        }
    }
    sys
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

    /// A small two-material, two-lobe (Lambert + specular) problem: `V` vertices with
    /// positive blends, each seen by `per` observations with pseudo-random positive basis
    /// responses per channel; `y` = the truth's prediction times `1 + noise · u`, `u` in
    /// [−1, 1] pseudo-random.
    struct TiedCase {
        obs: Observations,
        transport: Transport,
        s: Vec<[f64; 3]>,
        weights: Vec<f64>,
    }

    /// The truth of [`tied_case`]: colour in the diffuse lobe, achromatic specular weights.
    const TRUTH: [[[f64; 3]; 2]; 2] = [
        [[0.8, 0.45, 0.2], [0.25, 0.25, 0.25]],
        [[0.2, 0.3, 0.6], [0.15, 0.15, 0.15]],
    ];

    fn tied_case(noise: f64) -> TiedCase {
        let (nv, per, nb) = (6, 8, 2);
        let mut state = 12345u64;
        let mut rand = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let weights: Vec<f64> = (0..nv * 2).map(|_| 0.2 + 0.8 * rand()).collect();
        let mut obs = Observations::default();
        let mut s = Vec::new();
        for x in 0..nv {
            for _ in 0..per {
                let p = obs.vertex.len();
                let sp: Vec<[f64; 3]> = (0..nb).map(|_| [0, 1, 2].map(|_| 0.1 + rand())).collect();
                let y = [0, 1, 2].map(|c| {
                    let clean: f64 = (0..2)
                        .map(|k| {
                            weights[x * 2 + k]
                                * (0..nb).map(|b| TRUTH[k][b][c] * sp[b][c]).sum::<f64>()
                        })
                        .sum();
                    (clean * (1.0 + noise * (2.0 * rand() - 1.0))) as f32
                });
                s.extend(sp);
                obs.vertex.push(x as u32);
                obs.photo.push(0);
                obs.rgb.push(y);
                obs.weight.push(1.0);
                obs.dir.push([0.0, 0.0, 1.0]);
                obs.photo_ranges.push(p..p + 1);
            }
        }
        let n = obs.vertex.len();
        let transport = Transport {
            n_global: 2,
            n_basis: nb,
            n_obs: n,
            offsets: vec![0; n * nb + 1],
            ..Default::default()
        };
        TiedCase {
            obs,
            transport,
            s,
            weights,
        }
    }

    fn lambda_of(case: &TiedCase, coupling: LambdaCoupling) -> Vec<Vec<[f64; 3]>> {
        let problem = Problem {
            obs: &case.obs,
            transport: &case.transport,
            n_vertices: 6,
            n_photos: case.obs.photo_ranges.len(),
        };
        let dw = vec![[1.0; 3]; case.obs.len()];
        let l = lambda_step(
            &problem,
            &case.s,
            &case.weights,
            2,
            &dw,
            Some([0.0; 3]),
            0.0,
            coupling,
        )
        .unwrap();
        l.lambda
    }

    const TIED: LambdaCoupling = LambdaCoupling {
        achromatic_except: Some(0),
    };

    #[test]
    fn achromatic_step_recovers_an_achromatic_truth_without_noise() {
        let case = tied_case(0.0);
        let lam = lambda_of(&case, TIED);
        // The observations are stored as f32 (relative rounding 6e-8) and the system is
        // well conditioned (responses in [0.1, 1.1], blends in [0.2, 1]): 1e-5 absolute on
        // weights of 0.15–0.8 leaves a margin of ~100 over the rounding's effect.
        for k in 0..2 {
            for b in 0..2 {
                for c in 0..3 {
                    let d = (lam[k][b][c] - TRUTH[k][b][c]).abs();
                    assert!(
                        d < 1e-5,
                        "λ[{k}][{b}][{c}] {} vs {}",
                        lam[k][b][c],
                        TRUTH[k][b][c]
                    );
                }
            }
        }
    }

    /// The tied NNLS against the least squares of the reduced design solved directly
    /// (SVD of the stacked rows, one per observation and channel, columns: the 2 × 3
    /// diffuse weights and the 2 shared specular ones).
    #[test]
    fn achromatic_step_is_the_least_squares_of_the_reduced_design() {
        let case = tied_case(0.05);
        let lam = lambda_of(&case, TIED);
        let free = lambda_of(&case, LambdaCoupling::default());
        let np = case.obs.len();
        let mut a = DMatrix::<f64>::zeros(np * 3, 8);
        let mut y = DVector::<f64>::zeros(np * 3);
        for p in 0..np {
            let x = case.obs.vertex[p] as usize;
            for c in 0..3 {
                let r = p * 3 + c;
                for k in 0..2 {
                    let w = case.weights[x * 2 + k];
                    a[(r, k * 3 + c)] = w * case.s[p * 2][c];
                    a[(r, 6 + k)] = w * case.s[p * 2 + 1][c];
                }
                y[r] = case.obs.rgb[p][c] as f64;
            }
        }
        let z = a.clone().svd(true, true).solve(&y, 1e-14).unwrap();
        // Every z is positive, so the NNLS optimum is the unconstrained one; both are
        // solved in f64 on a system with condition number ~10²: 1e-9 is ample.
        assert!(z.iter().all(|&v| v > 0.0), "{z}");
        for k in 0..2 {
            for c in 0..3 {
                assert!((lam[k][0][c] - z[k * 3 + c]).abs() < 1e-9, "{lam:?} vs {z}");
                assert!((lam[k][1][c] - z[6 + k]).abs() < 1e-9, "{lam:?} vs {z}");
            }
        }
        // The constraint binds: the free channels' specular weights differ by more than
        // the 5% noise allows to vanish (> 1e-3), and fit the data at least as well.
        let spread = |l: &[[f64; 3]]| {
            let v = l[1];
            v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
        };
        assert!(
            spread(&free[0]) > 1e-3 || spread(&free[1]) > 1e-3,
            "{free:?}"
        );
        let sse = |l: &[Vec<[f64; 3]>]| {
            let mut e = 0.0;
            for p in 0..np {
                let x = case.obs.vertex[p] as usize;
                for c in 0..3 {
                    let pred: f64 = (0..2)
                        .map(|k| {
                            case.weights[x * 2 + k]
                                * (0..2)
                                    .map(|b| l[k][b][c] * case.s[p * 2 + b][c])
                                    .sum::<f64>()
                        })
                        .sum();
                    e += (pred - case.obs.rgb[p][c] as f64).powi(2);
                }
            }
            e
        };
        assert!(sse(&free) <= sse(&lam) * (1.0 + 1e-12));
    }
}
