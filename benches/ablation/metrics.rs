//! The ablation's metrics of one fit against the case's truth (module docs of
//! `benches/ablation.rs`: definitions): material accuracy, the diffuse albedo ratios and
//! the held-out half protocol.

use crate::synth_case::*;
use relight_cpc::report::metrics::{channel_scales, upper_median, PURE_OFF, PURE_WEIGHT};
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

/// The index of the largest of a vertex's weights `w` (the last of equals, as `max_by`).
fn argmax(w: &[f64]) -> usize {
    (0..w.len())
        .max_by(|&a, &b| w[a].total_cmp(&w[b]))
        .unwrap_or(0)
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
    best_order_of(case, &est.weights, seen)
}

/// [`best_order`] of any blending weights `weights` (`n_vertices × K`).
pub fn best_order_of(case: &Case, weights: &[f64], seen: &[bool]) -> (f64, f64, Vec<usize>) {
    let k = case.lambda.len();
    let mut best = (0.0, 0.0, (0..k).collect());
    for perm in permutations(k) {
        let (mut ok, mut n, mut okp, mut np) = (0, 0, 0, 0);
        for x in (0..case.nv).filter(|&x| seen[x]) {
            let t = argmax(&case.weights[x * k..(x + 1) * k]);
            let hit = perm[argmax(&weights[x * k..(x + 1) * k])] == t;
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
    let signed = signed_ratio_errors(case, lambda, weights, seen);
    [0, 1, 2].map(|c| signed.iter().map(|e| e[c].abs()).fold(0.0, f64::max))
}

/// Per material `j ≥ 1` and channel, the signed diffuse albedo ratio error against
/// material 0 (the fitted ratio of the pure vertices' medians over the true one, minus 1).
pub fn signed_ratio_errors(
    case: &Case,
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    seen: &[bool],
) -> Vec<[f64; 3]> {
    let k = case.lambda.len();
    let nb = case.basis.len();
    let beta = beta_per_vertex(lambda, weights, case.nv);
    let medians: Vec<[f64; 3]> = (0..k)
        .map(|t| pure_medians(&beta, nb, &pure_seen(case, seen, t)))
        .collect();
    (1..k)
        .map(|j| {
            [0, 1, 2].map(|c| {
                let r_true = case.lambda[j][0][c] / case.lambda[0][0][c];
                medians[j][c] / medians[0][c] / r_true - 1.0
            })
        })
        .collect()
}

/// `ABLATION_LAMBDA=1`: each fitted material's `λ` per lobe, every channel `c` scaled by
/// `s_c = Σ_k λ*_{k,0,c} λ_{k,0,c} / Σ_k λ_{k,0,c}²` ([`channel_scales`] of the diffuse
/// colours against the truth's: the per-channel scale no photo fixes), beside its true
/// material's (the best order of [`best_order`]). Every row's `λ` is over the case's lobes
/// (the `defaults` row's expanded from the pilot's).
pub fn scaled_lambda(case: &Case, est: &Estimate, seen: &[bool]) -> String {
    let (_, _, perm) = best_order(case, est, seen);
    let diffuse = |l: &Vec<[f64; 3]>| l[0].map(|v| v as f32);
    let truth: Vec<[f32; 3]> = perm.iter().map(|&t| diffuse(&case.lambda[t])).collect();
    let fitted: Vec<[f32; 3]> = est.lambda.iter().map(diffuse).collect();
    let scale = channel_scales(&truth, &fitted, &vec![true; fitted.len()]);
    let mut out = String::new();
    for (k, l) in est.lambda.iter().enumerate() {
        let scaled: Vec<[f64; 3]> = l
            .iter()
            .map(|b| [0, 1, 2].map(|c| b[c] * scale[c]))
            .collect();
        out += &format!(
            "  λ of material {k}, scaled: {scaled:.3?}; the truth's: {:?}\n",
            case.lambda[perm[k]]
        );
    }
    out
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

/// `ABLATION_ACCURACY_MISSES=1`: where the material accuracy's misses are, over the seen
/// vertices under the best order ([`best_order`]). Each miss is counted by its true largest
/// weight (< 0.55, < 0.6, < 0.75, < 0.95, pure) and by whether the fit's largest weight
/// sits on a material the truth blends at that vertex (true weight > 0.05: a swap within
/// the blend) or on one it does not (outside its support). `third` counts the seen
/// vertices whose normalised fitted weights put more than 0.1 on a material with true
/// weight below 0.02.
pub fn accuracy_misses(case: &Case, est: &Estimate, seen: &[bool]) -> String {
    let k = case.lambda.len();
    let (_, _, perm) = best_order(case, est, seen);
    let edges = [0.55, 0.6, 0.75, 0.95, f64::INFINITY];
    let mut swap = [0usize; 5];
    let mut outside = [0usize; 5];
    let mut total = [0usize; 5];
    let (mut third, mut n) = (0usize, 0usize);
    for x in (0..case.nv).filter(|&x| seen[x]) {
        n += 1;
        let tw = &case.weights[x * k..(x + 1) * k];
        let ew = &est.weights[x * k..(x + 1) * k];
        let sum: f64 = ew.iter().sum::<f64>().max(1e-12);
        let t = argmax(tw);
        let bucket = edges.iter().position(|&e| tw[t] < e).unwrap_or(4);
        total[bucket] += 1;
        let e = perm[argmax(ew)];
        if e != t {
            if tw[e] > 0.05 {
                swap[bucket] += 1;
            } else {
                outside[bucket] += 1;
            }
        }
        if (0..k).any(|j| ew[j] / sum > 0.1 && tw[perm[j]] < 0.02) {
            third += 1;
        }
    }
    let names = ["<0.55", "<0.6", "<0.75", "<0.95", "pure"];
    let cells: Vec<String> = (0..5)
        .map(|b| {
            format!(
                "{}: {} of {} missed ({} swap, {} outside)",
                names[b],
                swap[b] + outside[b],
                total[b],
                swap[b],
                outside[b]
            )
        })
        .collect();
    format!(
        "seen {n}; {}; a third material > 0.1 at {third}",
        cells.join("; ")
    )
}

/// `ABLATION_ACCURACY_MISSES=1`: for each pair of materials the truth blends, the median
/// fitted share `ŵ_a / (ŵ_a + ŵ_b)` (under the best order) over the seen vertices binned
/// by the true share `w_a / (w_a + w_b)` in tenths, where the two carry ≥ 0.95 of the true
/// weight: a shift of the fitted boundary shows as medians off the bins' centres.
pub fn blend_shares(case: &Case, est: &Estimate, seen: &[bool]) -> String {
    let k = case.lambda.len();
    let (_, _, perm) = best_order(case, est, seen);
    let mut inv = vec![0; k];
    for (e, &t) in perm.iter().enumerate() {
        inv[t] = e;
    }
    let mut out = Vec::new();
    for a in 0..k {
        for b in a + 1..k {
            let mut bins: Vec<Vec<(f64, f64)>> = vec![Vec::new(); 10];
            for x in (0..case.nv).filter(|&x| seen[x]) {
                let tw = &case.weights[x * k..(x + 1) * k];
                let (ta, tb) = (tw[a], tw[b]);
                if ta + tb < 0.95 || ta < 0.02 || tb < 0.02 {
                    continue;
                }
                let ew = &est.weights[x * k..(x + 1) * k];
                let (ea, eb) = (ew[inv[a]], ew[inv[b]]);
                if ea + eb <= 0.0 {
                    continue;
                }
                let bin = ((ta / (ta + tb)) * 10.0).floor().min(9.0) as usize;
                bins[bin].push((ea / (ea + eb), ea + eb));
            }
            if bins.iter().all(|b| b.is_empty()) {
                continue;
            }
            let cells: Vec<String> = bins
                .iter_mut()
                .enumerate()
                .filter(|(_, v)| !v.is_empty())
                .map(|(i, v)| {
                    v.sort_by(|p, q| p.0.total_cmp(&q.0));
                    let sum: f64 = v.iter().map(|e| e.1).sum();
                    format!(
                        "{:.2}: {:.2} (n {}, mean sum {:.2})",
                        (i as f64 + 0.5) / 10.0,
                        v[v.len() / 2].0,
                        v.len(),
                        sum / v.len() as f64
                    )
                })
                .collect();
            out.push(format!("{a}-{b}: {}", cells.join(", ")));
        }
    }
    for t in 0..k {
        let mut v: Vec<f64> = (0..case.nv)
            .filter(|&x| seen[x] && case.weights[x * k + t] >= 0.95)
            .map(|x| est.weights[x * k + inv[t]])
            .collect();
        v.sort_by(f64::total_cmp);
        if !v.is_empty() {
            let q = |f: f64| v[((v.len() - 1) as f64 * f) as usize];
            out.push(format!(
                "pure {t}: fitted weight quartiles {:.2} / {:.2} / {:.2} / {:.2} / {:.2} (n {})",
                q(0.0),
                q(0.25),
                q(0.5),
                q(0.75),
                q(1.0),
                v.len()
            ));
        }
    }
    out.join("; ")
}

/// `ABLATION_TAIL=1` (`bench-results/light-prior-many-photos.md`, section 3): per true
/// material, the share of its seen pure vertices ([`pure_seen`]) whose diffuse albedo `β`
/// is more than [`PURE_OFF`] (10%) off the material's median `β` in some channel, over those whose
/// normal faces down (its up component in the map frame below −0.5) and over the others.
pub fn tail_shares(
    case: &Case,
    lambda: &[Vec<[f64; 3]>],
    weights: &[f64],
    seen: &[bool],
) -> String {
    let k = case.lambda.len();
    let nb = case.basis.len();
    let beta = beta_per_vertex(lambda, weights, case.nv);
    let mut out = Vec::new();
    for t in 0..k {
        let pure = pure_seen(case, seen, t);
        let median = pure_medians(&beta, nb, &pure);
        let off = |x: usize| (0..3).any(|c| (beta[x * nb][c] / median[c] - 1.0).abs() > PURE_OFF);
        let share = |down: bool| {
            let set: Vec<usize> = pure
                .iter()
                .copied()
                .filter(|&x| (case.normals_env[x].z < -0.5) == down)
                .collect();
            let n = set.iter().filter(|&&x| off(x)).count();
            format!(
                "{:.0}% of {}",
                100.0 * n as f64 / set.len().max(1) as f64,
                set.len()
            )
        };
        out.push(format!(
            "material {t}: down {}, others {}",
            share(true),
            share(false)
        ));
    }
    out.join("; ")
}

/// The seen vertices of true material `t` alone (true weight ≥ [`PURE_WEIGHT`], as the
/// run's report counts them).
fn pure_seen(case: &Case, seen: &[bool], t: usize) -> Vec<usize> {
    let k = case.lambda.len();
    (0..case.nv)
        .filter(|&x| seen[x] && case.weights[x * k + t] >= PURE_WEIGHT)
        .collect()
}

/// Per channel, the [`upper_median`] of the Lambertian `β` (row stride `nb`) over `pure`.
fn pure_medians(beta: &[[f64; 3]], nb: usize, pure: &[usize]) -> [f64; 3] {
    [0, 1, 2].map(|c| upper_median(pure.iter().map(|&x| beta[x * nb][c]).collect()))
}

/// `ABLATION_ACCURACY_MISSES=1`: the material accuracy over the seen vertices with each
/// estimated material's weights scaled by `s_k` before the argmax: (a) `s` the least-squares
/// scales that make the weights sum to one, `min_s Σ_x (Σ_k s_k ŵ_{x,k} − 1)²`, over the seen
/// vertices (needs no truth); (b) the best `s` on a grid (`s_0 = 1`, the others in
/// `e^{±0.3}`, 41 steps each; an oracle, the ceiling of any rescaling).
pub fn rescaled_accuracy(case: &Case, est: &Estimate, seen: &[bool]) -> String {
    let k = case.lambda.len();
    let (a0, _, perm) = best_order(case, est, seen);
    let xs: Vec<usize> = (0..case.nv).filter(|&x| seen[x]).collect();
    let acc = |s: &[f64]| -> f64 {
        let hits = xs
            .iter()
            .filter(|&&x| {
                let w: Vec<f64> = (0..k).map(|j| s[j] * est.weights[x * k + j]).collect();
                perm[argmax(&w)] == argmax(&case.weights[x * k..(x + 1) * k])
            })
            .count();
        hits as f64 / xs.len().max(1) as f64
    };
    let mut a = nalgebra::DMatrix::<f64>::zeros(k, k);
    let mut b = nalgebra::DVector::<f64>::zeros(k);
    for &x in &xs {
        let w = nalgebra::DVector::from_column_slice(&est.weights[x * k..(x + 1) * k]);
        a += &w * w.transpose();
        b += &w;
    }
    let sum_one: Vec<f64> = a
        .lu()
        .solve(&b)
        .map_or(vec![1.0; k], |s| s.iter().copied().collect());
    let grid: Vec<f64> = (0..41).map(|i| (-0.3 + 0.015 * i as f64).exp()).collect();
    let mut best = (a0, vec![1.0; k]);
    let mut s = vec![1.0; k];
    let mut visit = |s: &[f64]| {
        let v = acc(s);
        if v > best.0 {
            best = (v, s.to_vec());
        }
    };
    match k {
        2 => grid.iter().for_each(|&g| visit(&[1.0, g])),
        3 => {
            for &g1 in &grid {
                for &g2 in &grid {
                    s[1] = g1;
                    s[2] = g2;
                    visit(&s);
                }
            }
        }
        _ => {}
    }
    format!(
        "as fitted {a0:.4}; sum-to-one scales {:?}: {:.4}; best scales {:?}: {:.4}",
        sum_one
            .iter()
            .map(|v| (v * 1000.0).round() / 1000.0)
            .collect::<Vec<_>>(),
        acc(&sum_one),
        best.1
            .iter()
            .map(|v| (v * 1000.0).round() / 1000.0)
            .collect::<Vec<_>>(),
        best.0
    )
}

/// The exact data plus the photos' own residual `y − ŷ` with a random sign per observation
/// and channel: noise of the photos' size and place with its systematic part removed.
pub fn flipped_residuals(
    photos: &relight_cpc::observe::Observations,
    exact: &relight_cpc::observe::Observations,
) -> relight_cpc::observe::Observations {
    let mut out = exact.clone();
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    for (p, y) in out.rgb.iter_mut().enumerate() {
        for c in 0..3 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let sign = if state & 1 == 0 { 1.0 } else { -1.0 };
            y[c] += sign * (photos.rgb[p][c] - exact.rgb[p][c]);
        }
    }
    out
}

/// `w` (`V × K`, each row summing to 1 or 0) mixed with its neighbours' mean by `s`.
pub fn smoothed(
    w: &[f64],
    graph: &relight_cpc::solve::materials::propagate::VertexGraph,
    kk: usize,
    s: f64,
) -> Vec<f64> {
    let mut out = w.to_vec();
    for x in 0..w.len() / kk {
        let nb = graph.neighbours(x);
        if nb.is_empty() {
            continue;
        }
        for k in 0..kk {
            let mean = nb.iter().map(|&y| w[y as usize * kk + k]).sum::<f64>() / nb.len() as f64;
            out[x * kk + k] = (1.0 - s) * w[x * kk + k] + s * mean;
        }
    }
    out
}
