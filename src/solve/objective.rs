//! The objective `F` of Eq. 9 (data term `Σ α ω r²` plus the light model's prior plus the
//! ridge `Σ r_c λ²`, plus the blending weights' sum-to-one prior when on,
//! [`crate::solve::EstimateOptions::weights_sum`]), the train RMSE, and the scale `Σ_x Σ_b β_{x,b,c}` that the gauge
//! holds fixed.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use crate::solve::problem::{basis_responses, beta_per_vertex, predict_from, Problem, CHUNK};

/// The residual `r = y − ŷ` of observation `p`'s channel `c`; of a channel read as a lower
/// bound ([`crate::observe::Observations::clipped`], weighted only when the fit reads
/// bounds), the shortfall `max(0, y − ŷ)`: a prediction above a bound is no error.
fn residual(obs: &crate::observe::Observations, p: usize, c: usize, pred: f64) -> f64 {
    let r = obs.rgb[p][c] as f64 - pred;
    if obs.clipped.get(p).is_some_and(|m| m & (1 << c) != 0) {
        r.max(0.0)
    } else {
        r
    }
}

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
                    let r = residual(obs, p, c, pred[p][c]);
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
            let r = residual(obs, p, c, pred[p][c]);
            f[c] += a * omega[p][c] as f64 * r * r;
        }
    }
    f
}

/// Per observation and channel, the weighted residual `√(α_p ω_{p,c}) r_{p,c}` whose squares
/// sum to the data term of [`channel_data_fit`] (0 where `α_p ≤ 0`).
pub(crate) fn weighted_residuals(
    problem: &Problem,
    pred: &[[f64; 3]],
    omega: &[[f32; 3]],
) -> Vec<[f64; 3]> {
    let obs = problem.obs;
    (0..obs.vertex.len())
        .into_par_iter()
        .map(|p| {
            let a = obs.weight[p] as f64;
            if a <= 0.0 {
                return [0.0; 3];
            }
            [0, 1, 2].map(|c| (a * omega[p][c] as f64).sqrt() * residual(obs, p, c, pred[p][c]))
        })
        .collect()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observe::Observations;
    use crate::transport::Transport;

    /// Two observations of value 0.5 in every channel, of weights 1 and 2, one photo.
    fn two(clipped: Vec<u8>, bound_weight: Vec<f32>) -> Observations {
        Observations {
            vertex: vec![0, 1],
            photo: vec![0, 0],
            rgb: vec![[0.5; 3]; 2],
            weight: vec![1.0, 2.0],
            dir: vec![[0.0, 0.0, 1.0]; 2],
            photo_ranges: std::iter::once(0..2).collect(),
            clipped,
            bound_weight,
        }
    }

    fn problem_of<'a>(obs: &'a Observations, t: &'a Transport) -> Problem<'a> {
        Problem {
            obs,
            transport: t,
            n_vertices: 2,
            n_photos: 1,
        }
    }

    /// The second observation's red channel a lower bound: predicted 0.8 there the bound is
    /// met (no error), predicted 0.2 it falls 0.3 short, as a value would; green and blue
    /// are values either way.
    #[test]
    fn a_bound_met_is_no_error_and_a_bound_missed_counts_its_shortfall() {
        let obs = two(vec![0, 0b001], vec![0.0, 2.0]);
        let t = Transport::default();
        let problem = problem_of(&obs, &t);
        let omega = vec![[1.0_f32; 3]; 2];
        let met = [[0.4, 0.5, 0.5], [0.8, 0.5, 0.5]];
        let (f, rmse) = data_fit(&problem, &met, &omega);
        // Only the first observation's red misses, by 0.1: F = 1 · 0.01; RMSE over 6 terms.
        assert!((f - 0.01).abs() < 1e-12, "{f}");
        assert!((rmse - (0.01_f64 / 6.0).sqrt()).abs() < 1e-12, "{rmse}");
        let missed = [[0.4, 0.5, 0.5], [0.2, 0.6, 0.5]];
        let per_channel = channel_data_fit(&problem, &missed, &omega);
        // Red: 0.01 + 2 · 0.09; green: 2 · 0.01; blue: 0.
        let want = [0.01 + 2.0 * 0.09, 2.0 * 0.01, 0.0];
        for c in 0..3 {
            assert!((per_channel[c] - want[c]).abs() < 1e-12, "{per_channel:?}");
        }
    }

    /// A problem whose clipped channels do not cover every observation is refused, with the
    /// counts named (a derived set of observations that dropped them half-way).
    #[test]
    fn clipped_channels_must_cover_every_observation() {
        let obs = two(vec![1], vec![1.0]);
        let t = Transport::default();
        let err = problem_of(&obs, &t).validate().unwrap_err().to_string();
        assert!(err.contains("clipped channels (1)"), "{err}");
    }
}
