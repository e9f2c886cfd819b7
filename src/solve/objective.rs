//! The objective `F` of Eq. 9 (data term `Σ α ω r²` plus the light model's prior plus the
//! ridge `Σ r_c λ²`, plus the blending weights' sum-to-one prior when on,
//! [`crate::solve::EstimateOptions::weights_sum`]), the train RMSE, and the scale `Σ_x Σ_b β_{x,b,c}` that the gauge
//! holds fixed.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use crate::solve::problem::{basis_responses, beta_per_vertex, predict_from, Problem, CHUNK};

/// Data term, train RMSE: `(Σ α ω r², RMSE over α > 0)`.
pub(crate) fn data_fit(problem: &Problem, pred: &[[f64; 3]], omega: &[[f32; 3]]) -> (f64, f64) {
    let obs = problem.obs;
    let np = obs.vertex.len();
    let parts: Vec<(f64, f64, usize)> = (0..np.div_ceil(CHUNK))
        .into_par_iter()
        .map(|ci| {
            let (mut f, mut sq, mut cnt) = (0.0, 0.0, 0usize);
            for p in ci * CHUNK..((ci + 1) * CHUNK).min(np) {
                let a = obs.weight[p] as f64;
                if a <= 0.0 {
                    continue;
                }
                cnt += 1;
                for c in 0..3 {
                    let r = obs.rgb[p][c] as f64 - pred[p][c];
                    f += a * omega[p][c] as f64 * r * r;
                    sq += r * r;
                }
            }
            (f, sq, cnt)
        })
        .collect();
    let (mut f, mut sq, mut cnt) = (0.0, 0.0, 0usize);
    for (a, b, c) in parts {
        f += a;
        sq += b;
        cnt += c;
    }
    (
        f,
        if cnt > 0 {
            (sq / (3 * cnt) as f64).sqrt()
        } else {
            0.0
        },
    )
}

/// The data term `Σ α ω r²` per channel.
pub(crate) fn channel_data_fit(
    problem: &Problem,
    pred: &[[f64; 3]],
    omega: &[[f32; 3]],
) -> [f64; 3] {
    let obs = problem.obs;
    let mut f = [0.0; 3];
    for p in 0..obs.vertex.len() {
        let a = obs.weight[p] as f64;
        if a <= 0.0 {
            continue;
        }
        for c in 0..3 {
            let r = obs.rgb[p][c] as f64 - pred[p][c];
            f[c] += a * omega[p][c] as f64 * r * r;
        }
    }
    f
}

/// A state the objective is evaluated at: the light model's maps and its prior's value,
/// and the materials.
pub(crate) struct Point<'a> {
    /// Per photo and channel, the map texels.
    pub(crate) maps: &'a [[Vec<f64>; 3]],
    /// `lambda[k][b][c]`.
    pub(crate) lambda: &'a [Vec<[f64; 3]>],
    /// Row-major `V × K`.
    pub(crate) weights: &'a [f64],
    /// The priors' terms: the light model's ([`crate::solve::light::LightModel::penalty`])
    /// plus the weights' sum-to-one prior.
    pub(crate) prior: f64,
}

/// `F` and the train RMSE of a [`Point`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Objective {
    /// `F` (module docs).
    pub(crate) value: f64,
    /// RMSE over the observations with `α > 0`, all channels.
    pub(crate) train_rmse: f64,
}

/// Objective `F` (module docs) and train RMSE at `at`; `s` = its basis responses when
/// already computed.
pub(crate) fn evaluate(
    problem: &Problem,
    at: &Point,
    ridge: Option<[f64; 3]>,
    omega: &[[f32; 3]],
    s: Option<&[[f64; 3]]>,
) -> Objective {
    let owned;
    let s = match s {
        Some(s) => s,
        None => {
            owned = basis_responses(problem, at.maps);
            &owned
        }
    };
    let beta = beta_per_vertex(at.lambda, at.weights, problem.n_vertices);
    let pred = predict_from(problem, &beta, s);
    let (data, rmse) = data_fit(problem, &pred, omega);
    let rid: f64 = ridge.map_or(0.0, |r| {
        at.lambda
            .iter()
            .flatten()
            .map(|v| (0..3).map(|c| r[c] * v[c] * v[c]).sum::<f64>())
            .sum()
    });
    Objective {
        value: data + at.prior + rid,
        train_rmse: rmse,
    }
}

/// Per channel `Σ_x Σ_b β_{x,b,c} = Σ_k (Σ_x w_k(x)) (Σ_b λ_{k,b,c})`: the scale that
/// [`crate::solve::EstimateOptions::fix_gauge`] holds fixed.
pub(crate) fn gauge(lambda: &[Vec<[f64; 3]>], weights: &[f64], n_vertices: usize) -> [f64; 3] {
    let kk = lambda.len();
    let mut g = [0.0; 3];
    for (k, lk) in lambda.iter().enumerate() {
        let wsum: f64 = (0..n_vertices).map(|x| weights[x * kk + k]).sum();
        for c in 0..3 {
            g[c] += wsum * lk.iter().map(|v| v[c]).sum::<f64>();
        }
    }
    g
}
