//! The ablation's metrics of one fit against the case's truth (module docs of
//! `benches/ablation.rs`: definitions): material accuracy, the diffuse albedo ratios and
//! the held-out half protocol.

use crate::synth_case::*;
use relight_cpc::solve::{beta_per_vertex, fit_light_frozen, Estimate, EstimateOptions};

/// All permutations of `0..k` (k ≤ 4).
pub fn permutations(k: usize) -> Vec<Vec<usize>> {
    if k == 0 {
        return vec![Vec::new()];
    }
    let mut out = Vec::new();
    for p in permutations(k - 1) {
        for i in 0..k {
            let mut q = p.clone();
            q.insert(i, k - 1);
            out.push(q);
        }
    }
    out
}

/// Material accuracy (all seen, pure seen) over the best order of the estimated materials.
pub fn assignment(case: &Case, est: &Estimate, seen: &[bool]) -> (f64, f64) {
    let (a, p, _) = best_order(case, est, seen);
    (a, p)
}

/// The order of the estimated materials with the best material accuracy: (accuracy over
/// all seen vertices, over the pure ones, `perm` with estimated material `k` = true
/// material `perm[k]`).
pub fn best_order(case: &Case, est: &Estimate, seen: &[bool]) -> (f64, f64, Vec<usize>) {
    let k = case.lambda.len();
    let argmax = |w: &[f64]| (0..w.len()).max_by(|&a, &b| w[a].total_cmp(&w[b])).unwrap();
    let mut best = (0.0, 0.0, (0..k).collect());
    for perm in permutations(k) {
        let (mut ok, mut n, mut okp, mut np) = (0, 0, 0, 0);
        for x in (0..case.nv).filter(|&x| seen[x]) {
            let t = argmax(&case.weights[x * k..(x + 1) * k]);
            let hit = perm[argmax(&est.weights[x * k..(x + 1) * k])] == t;
            n += 1;
            ok += usize::from(hit);
            if case.weights[x * k + t] >= 0.95 {
                np += 1;
                okp += usize::from(hit);
            }
        }
        let a = ok as f64 / n.max(1) as f64;
        if a > best.0 {
            best = (a, okp as f64 / np.max(1) as f64, perm);
        }
    }
    best
}

/// Per channel, the worst relative error of the diffuse ratios `β_{j,L,c} / β_{0,L,c}`
/// (module docs).
pub fn ratio_errors(
    case: &Case,
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    seen: &[bool],
) -> [f64; 3] {
    let k = case.lambda.len();
    let nb = case.basis.len();
    let beta = beta_per_vertex(lambda, weights, case.nv);
    let median = |mut v: Vec<f64>| -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    let pure = |t: usize, c: usize| -> f64 {
        median(
            (0..case.nv)
                .filter(|&x| seen[x] && case.weights[x * k + t] >= 0.95)
                .map(|x| beta[x * nb][c])
                .collect(),
        )
    };
    [0, 1, 2].map(|c| {
        (1..k)
            .map(|j| {
                let r_true = case.lambda[j][0][c] / case.lambda[0][0][c];
                (pure(j, c) / pure(0, c) / r_true - 1.0).abs()
            })
            .fold(0.0, f64::max)
    })
}

/// The held-out split's observations cut in two per photo by the plane through the
/// observed vertices' centroid spanned by the mean viewing direction and the world up
/// axis: `true` = left (the light is fitted there), `false` = right (evaluated).
pub fn left_half(case: &Case) -> Vec<bool> {
    relight_cpc::solve::validation::left_by_view(&case.held.obs, &case.positions)
}

/// The half protocol's error for reflectance `(lambda, weights)` (module docs).
pub fn half_error(case: &Case, lambda: &[Vec<[f64; 3]>], weights: &[f64], left: &[bool]) -> f64 {
    let mut fit_obs = case.held.obs.clone();
    let mut eval_obs = case.held.obs.clone();
    for p in 0..left.len() {
        if left[p] {
            eval_obs.weight[p] = 0.0;
        } else {
            fit_obs.weight[p] = 0.0;
        }
    }
    let problem = relight_cpc::solve::Problem {
        obs: &fit_obs,
        transport: &case.held.transport,
        n_vertices: case.nv,
        n_photos: fit_obs.photo_ranges.len(),
    };
    let beta = beta_per_vertex(lambda, weights, case.nv);
    let opts = EstimateOptions {
        lighting_sample: 0,
        ..EstimateOptions::default()
    };
    let lights: Vec<[Vec<f64>; 3]> = (0..problem.n_photos)
        .map(|i| fit_light_frozen(&problem, &beta, i, None, &opts).unwrap())
        .collect();
    let pred = predict_with(&case.held, case.nv, lambda, weights, &lights);
    rel_rmse_per_channel(&eval_obs, &pred)
}
