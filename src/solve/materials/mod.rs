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

pub mod bilinear;
pub mod brightness;
pub mod coarse_light;
pub mod coarse_light_blend;
pub mod coarse_light_shiny;
pub mod irradiance;
pub mod propagate;
pub mod reanchor;
pub mod support;

#[cfg(test)]
pub(crate) mod test_normals {
    use crate::Vec3;

    /// `n` unit normals spread over the sphere (a Fibonacci lattice), those with
    /// `z ∈ [lo, hi]`: the surfaces of the ratio models' tests.
    pub(crate) fn normals(n: usize, lo: f64, hi: f64) -> Vec<Vec3> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let phi = golden * i as f64;
                Vec3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .filter(|v| v.z >= lo && v.z <= hi)
            .collect()
    }
}

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

/// How the λ step couples the channels, and the entries it holds at zero.
#[derive(Debug, Clone, Copy, Default)]
pub struct LambdaCoupling<'a> {
    /// `Some(l)`: every basis but `l` shares one weight per material across R, G and B
    /// (module docs); `None`: the channels are independent (the paper).
    pub achromatic_except: Option<usize>,
    /// `pruned[k·B + b]`: `λ_{k,b,·}` held at zero ([`crate::solve::lobe_prune`]); empty:
    /// none.
    pub pruned: &'a [bool],
}

impl<'a> LambdaCoupling<'a> {
    /// The coupling the options ask for, with the entries `pruned` held at zero.
    pub fn of(opts: &EstimateOptions, pruned: &'a [bool]) -> Self {
        LambdaCoupling {
            achromatic_except: opts.achromatic_specular.then_some(opts.lambert_basis),
            pruned,
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
    coupling: LambdaCoupling<'_>,
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
        hold_at_zero(&mut sys[c], coupling.pruned, maxd[c]);
    }
    let sol = match coupling.achromatic_except {
        // With the Lambertian lobe alone nothing is tied: the channels stay independent.
        Some(lb) if nb > 1 => {
            let tied: Vec<bool> = (0..m).map(|i| i % nb != lb).collect();
            solve_tied(&sys, &tied)?
        }
        _ => {
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

/// Entry `i`'s row and column of `(M, r)` replaced by `d λ_i = 0` wherever `pruned[i]`
/// (`d > 0` keeps the system's scale), so the NNLS returns `λ_i = 0` and the other entries
/// as if `λ_i` were fixed there.
fn hold_at_zero((mat, rhs): &mut ChannelSystem, pruned: &[bool], d: f64) {
    for (i, _) in pruned.iter().enumerate().filter(|(_, &p)| p) {
        mat.row_mut(i).fill(0.0);
        mat.column_mut(i).fill(0.0);
        mat[(i, i)] = if d > 0.0 { d } else { 1.0 };
        rhs[i] = 0.0;
    }
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

/// How evenly a vertex's weights `w` blend materials: `b = min(1, 2 (1 − max_k w_k / Σ_k w_k))`,
/// 0 at a pure vertex (one material), 1 where the largest share is ½ or less; 1 when the
/// weights are all 0 (no material yet: the tie stays whole).
pub fn blend_share(w: &[f64]) -> f64 {
    let sum: f64 = w.iter().sum();
    if sum <= 0.0 {
        return 1.0;
    }
    let largest = w.iter().copied().fold(0.0, f64::max);
    (2.0 * (1.0 - largest / sum)).clamp(0.0, 1.0)
}

/// The sum-to-one prior's weights on blended vertices ([`crate::solve::SumScope::Blends`]):
/// `γ_x max(b_x, floor)` with `b_x` the [`blend_share`] of vertex `x`'s row of `weights`
/// (row-major `V × K`).
pub fn blend_scaled_gamma(gamma: &[f64], weights: &[f64], kk: usize, floor: f64) -> Vec<f64> {
    gamma
        .iter()
        .enumerate()
        .map(|(x, &g)| g * blend_share(&weights[x * kk..(x + 1) * kk]).max(floor))
        .collect()
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

/// The neighbour prior's pull of [`weights_step`]: per vertex `η_x`, and the graph.
#[derive(Clone, Copy)]
pub struct NeighbourPull<'a> {
    pub eta: &'a [f64],
    pub graph: &'a propagate::VertexGraph,
}

impl NeighbourPull<'_> {
    /// `w̄_N(x)`, the mean of `x`'s neighbours' weights (`None` without neighbours).
    pub fn mean(&self, x: usize, weights: &[f64], kk: usize) -> Option<Vec<f64>> {
        // Only neighbours with fitted weights (η > 0): the others keep their start.
        let nb = self
            .graph
            .neighbours(x)
            .iter()
            .map(|&y| y as usize)
            .filter(|&y| self.eta[y] > 0.0);
        let mut m = vec![0.0; kk];
        let mut count = 0usize;
        for y in nb {
            count += 1;
            for k in 0..kk {
                m[k] += weights[y * kk + k];
            }
        }
        (count > 0).then(|| m.into_iter().map(|v| v / count as f64).collect())
    }

    /// `Σ_x η_x ‖w(x) − w̄_N(x)‖²`.
    pub fn penalty(&self, weights: &[f64], kk: usize) -> f64 {
        (0..self.eta.len())
            .filter(|&x| self.eta[x] > 0.0)
            .filter_map(|x| {
                let m = self.mean(x, weights, kk)?;
                Some(
                    self.eta[x]
                        * (0..kk)
                            .map(|k| (weights[x * kk + k] - m[k]).powi(2))
                            .sum::<f64>(),
                )
            })
            .sum()
    }
}

/// What [`weights_step`] adds to each vertex's data term, and how it picks a vertex's
/// materials.
#[derive(Clone, Copy, Default)]
pub struct WeightsRules<'a> {
    /// `γ_x` of the sum-to-one prior ([`sum_weights_gamma`]), when on.
    pub gamma: Option<&'a [f64]>,
    /// The neighbour prior, when on.
    pub pull: Option<NeighbourPull<'a>>,
    /// The multiple of BIC's penalty by which each vertex drops materials
    /// ([`EstimateOptions::weights_bic`], [`support`]); 0 = off: NNLS keeps every
    /// material that lowers the vertex's term at all (the paper).
    pub bic: f64,
}

/// Every fitted vertex's weights through [`support::select_support`], each with the
/// penalty `bic · σ² ln n_x`: `σ²` the data term per weighted observation over all fitted
/// vertices (at their NNLS weights), `n_x` the vertex's weighted observations.
fn select_supports(fits: &mut [Option<VertexFit>], bic: f64) {
    let (sse, n) = fits
        .iter()
        .flatten()
        .fold((0.0, 0usize), |(s, n), f| (s + f.sse, n + f.n));
    let sigma2 = sse / n.max(1) as f64;
    fits.par_iter_mut().flatten().for_each(|f| {
        let penalty = bic * sigma2 * (f.n.max(2) as f64).ln();
        f.w = support::select_support(&f.mat, &f.rhs, &f.w, penalty);
    });
}

/// Material step, w part (Eq. 12): per vertex, NNLS over its observations in all channels,
/// plus the sum-to-one prior `γ_x (Σ_k w_k − 1)²` when `rules.gamma` is given (its normal
/// equations gain `γ_x 1 1ᵀ` and `γ_x 1`, [`sum_weights_gamma`]), and the neighbour prior
/// when `rules.pull` is given (`η_x I` and `η_x w̄_N(x)`, the neighbours' mean at the step's
/// start: [`NeighbourPull`]); with `rules.bic > 0` each vertex then drops the materials
/// BIC finds it does not need ([`select_supports`]). Vertices without weighted
/// observations keep their weights (after the fit, `run` gives the ones no training photo
/// sees their seen neighbours' materials: [`propagate`]). Returns the new weights, the largest finite condition
/// number and the count of singular systems.
pub fn weights_step(
    problem: &Problem,
    s: &[[f64; 3]],
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    dw: &[[f64; 3]],
    rules: WeightsRules,
) -> Result<WeightsStep> {
    let kk = lambda.len();
    let (off, list) = by_vertex(problem.obs, problem.n_vertices);
    let data = WeightsData {
        problem,
        s,
        lambda,
        dw,
    };
    let mut fits: Vec<Option<VertexFit>> = (0..problem.n_vertices)
        .into_par_iter()
        .map(|x| data.fit_vertex(x, &list[off[x]..off[x + 1]], weights, rules))
        .collect::<Result<_>>()?;
    if rules.bic > 0.0 {
        select_supports(&mut fits, rules.bic);
    }
    let mut out = Vec::with_capacity(weights.len());
    let (mut cmax, mut singular) = (0.0_f64, 0usize);
    for (x, f) in fits.into_iter().enumerate() {
        // Vertices without weighted observations keep their weights (condition 0).
        let (w, c) = f.map_or_else(
            || (weights[x * kk..(x + 1) * kk].to_vec(), 0.0),
            |f| (f.w, f.cond),
        );
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

/// What the data term of [`weights_step`] reads: the transport responses `s` (per
/// observation and basis), the materials `λ` and the observations' weights `dw`.
struct WeightsData<'a> {
    problem: &'a Problem<'a>,
    s: &'a [[f64; 3]],
    lambda: &'a [Vec<[f64; 3]>],
    dw: &'a [[f64; 3]],
}

impl WeightsData<'_> {
    /// Vertex `x`'s NNLS weights over its observations `ps`, with the priors of `rules`
    /// (`weights`: the step's start, for the neighbours' mean); `None` when no observation
    /// has weight. Its data term's value is kept for [`select_supports`] only when
    /// `rules.bic > 0`.
    fn fit_vertex(
        &self,
        x: usize,
        ps: &[usize],
        weights: &[f64],
        rules: WeightsRules,
    ) -> Result<Option<VertexFit>> {
        let Some(sys) = self.normal_equations(ps) else {
            return Ok(None);
        };
        let kk = self.lambda.len();
        let data_term = (rules.bic > 0.0).then(|| (sys.mat.clone(), sys.rhs.clone()));
        let (mut mat, mut rhs) = (sys.mat, sys.rhs);
        if let Some(g) = rules.gamma.map(|g| g[x]).filter(|&g| g > 0.0) {
            add_sum_prior(&mut mat, &mut rhs, g);
        }
        if let Some(pl) = rules.pull.filter(|pl| pl.eta[x] > 0.0) {
            if let Some(m) = pl.mean(x, weights, kk) {
                for i in 0..kk {
                    rhs[i] += pl.eta[x] * m[i];
                    mat[(i, i)] += pl.eta[x];
                }
            }
        }
        let cond = condition_number(&mat);
        let sol = nnls(&mat, &rhs, &NnlsOptions::default()).map_err(|e| Error::Numeric {
            stage: format!("material step (w, vertex {x})"),
            message: e.to_string(),
        })?;
        let w: Vec<f64> = sol.iter().copied().collect();
        let sse = data_term.map_or(0.0, |(m, r)| {
            (support::quadratic(&m, &r, &w) + sys.yy).max(0.0)
        });
        Ok(Some(VertexFit {
            w,
            cond,
            sse,
            n: sys.n,
            mat,
            rhs,
        }))
    }

    /// One vertex's data term `Σ_{p,c} d_{p,c} (a_{p,c}ᵀ w − y_{p,c})²` as normal equations
    /// `(Σ d a aᵀ, Σ d a y)`, with `a_{p,c,k} = Σ_b λ_{k,b,c} s_{p,b,c}` over its observations
    /// `ps`; `None` when none of them has weight.
    fn normal_equations(&self, ps: &[usize]) -> Option<VertexSystem> {
        let nb = self.problem.transport.n_basis;
        let kk = self.lambda.len();
        let mut mat = DMatrix::<f64>::zeros(kk, kk);
        let mut rhs = DVector::<f64>::zeros(kk);
        let mut a = vec![0.0; kk];
        let (mut yy, mut n) = (0.0, 0usize);
        for &p in ps {
            for c in 0..3 {
                let d = self.dw[p][c];
                if d == 0.0 {
                    continue;
                }
                n += 1;
                for k in 0..kk {
                    a[k] = (0..nb)
                        .map(|b| self.lambda[k][b][c] * self.s[p * nb + b][c])
                        .sum();
                }
                let yc = self.problem.obs.rgb[p][c] as f64;
                yy += d * yc * yc;
                for i in 0..kk {
                    rhs[i] += d * a[i] * yc;
                    for j in 0..kk {
                        mat[(i, j)] += d * a[i] * a[j];
                    }
                }
            }
        }
        (n > 0).then_some(VertexSystem { mat, rhs, yy, n })
    }
}

/// One vertex's data term as normal equations ([`WeightsData::normal_equations`]):
/// `F_x(w) = wᵀ mat w − 2 wᵀ rhs + yy` over its `n` weighted observations (per channel).
struct VertexSystem {
    mat: DMatrix<f64>,
    rhs: DVector<f64>,
    yy: f64,
    n: usize,
}

/// One vertex's weights from [`weights_step`]: the solution, its system's condition number,
/// its data term `sse` over `n` weighted observations (0 unless BIC is on), and the system
/// with the priors.
struct VertexFit {
    w: Vec<f64>,
    cond: f64,
    sse: f64,
    n: usize,
    mat: DMatrix<f64>,
    rhs: DVector<f64>,
}

/// The sum-to-one prior `γ (Σ_k w_k − 1)²` added to normal equations: `γ 1 1ᵀ` and `γ 1`.
fn add_sum_prior(mat: &mut DMatrix<f64>, rhs: &mut DVector<f64>, g: f64) {
    for i in 0..rhs.len() {
        rhs[i] += g;
        for j in 0..rhs.len() {
            mat[(i, j)] += g;
        }
    }
}

/// The 2-norm condition number of a symmetric positive semi-definite `mat`, infinite when
/// its smallest eigenvalue is below `10⁻¹⁴` of its largest (or it is 0).
fn condition_number(mat: &DMatrix<f64>) -> f64 {
    let ev = mat.clone().symmetric_eigenvalues();
    let (lo, hi) = ev
        .iter()
        .fold((f64::INFINITY, 0.0_f64), |(l, h), &v| (l.min(v), h.max(v)));
    if lo > 1e-14 * hi && hi > 0.0 {
        hi / lo
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests;
