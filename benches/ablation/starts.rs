//! The ablation's starts (`ABLATION_START`, module docs of `benches/ablation.rs`): the
//! paper's k-means start, oracle starts with parts of the truth, and alternatives.

use super::*;

/// The fit's start: the paper's (k-means), or with `ABLATION_START=truth` the TRUE
/// materials (a diagnosis: does the alternation leave the truth?), or with
/// `ABLATION_START=gloss` the paper's with every glossy lobe at
/// [`relight_cpc::solve::starts::GLOSS_FRACTION`] of the mean Lambertian weight, or with
/// `ABLATION_START=open` the paper's clustering of [`open_corrected_colours`], or with
/// `ABLATION_START=matched` the paper's with the albedo ratios of [`matched_ratios`], or with
/// `ABLATION_START=k1` the paper's clustering of [`k1_corrected_colours`], or with
/// `ABLATION_START=k1-albedo` the paper's clusters with each material's Lambertian weight
/// the median of those colours over its vertices (both measured and not kept, section 14
/// of `bench-results/estimator-ablation-iterations.md`); the oracle
/// starts `truth-diffuse` (the TRUE materials without their glossy lobes) and
/// `kmeans-true-albedo` (the k-means weights, the TRUE Lambertian weights) say which part
/// of the start matters.
pub fn fit_start(case: &Case) -> Materials0 {
    let init = start(case, &case.train.obs, case.lambda.len()).expect("k-means start");
    match std::env::var("ABLATION_START").as_deref() {
        Ok("truth") => case.true_materials(),
        Ok("truth-diffuse") => {
            // The TRUE weights and Lambertian weights, every glossy lobe 0.
            let mut m = case.true_materials();
            for row in &mut m.lambda {
                for v in row.iter_mut().skip(1) {
                    *v = [0.0; 3];
                }
            }
            m
        }
        Ok("kmeans-true-albedo") => {
            // The k-means start's weights with each cluster's Lambertian weight replaced by
            // the TRUE one of the material it stands for (best order).
            let mut m = init;
            let (_, seen) = relight_cpc::run::mean_colours(&case.train.obs, case.nv);
            let est = estimate_of(&m);
            let (_, _, perm) = metrics::best_order(case, &est, &seen);
            for (k, row) in m.lambda.iter_mut().enumerate() {
                row[0] = case.lambda[perm[k]][0];
            }
            m
        }
        Ok("open") => clustered(case, open_corrected_colours(case)),
        Ok("k1") => clustered(case, k1_corrected_colours(case)),
        Ok("k1-albedo") => {
            // The k-means clusters and weights; each material's Lambertian weight the
            // median of `k1_corrected_colours` over the vertices labelled with it.
            let (mean, seen) = k1_corrected_colours(case);
            let mut m = init;
            let kk = m.lambda.len();
            for (k, row) in m.lambda.iter_mut().enumerate() {
                let members: Vec<usize> = (0..case.nv)
                    .filter(|&x| {
                        seen[x] && (0..kk).all(|j| m.weights[x * kk + j] <= m.weights[x * kk + k])
                    })
                    .collect();
                if members.is_empty() {
                    continue;
                }
                for c in 0..3 {
                    let mut v: Vec<f64> = members.iter().map(|&x| mean[x][c]).collect();
                    v.sort_by(f64::total_cmp);
                    row[0][c] = v[v.len() / 2];
                }
                eprintln!("k1-albedo: material {k}: {:?}", row[0]);
            }
            m
        }
        Ok("matched") => {
            let mut m = init;
            matched_ratios(case, &mut m);
            m
        }
        Ok("gloss") => relight_cpc::solve::starts::uniform_gloss(
            &init,
            0,
            relight_cpc::solve::starts::GLOSS_FRACTION,
        ),
        _ => init,
    }
}

/// The paper's start (k-means, Lambertian only) on per-vertex colours other than the mean
/// ones: `(colours, seen)`.
fn clustered(case: &Case, (colours, seen): (Vec<[f64; 3]>, Vec<bool>)) -> Materials0 {
    let init =
        relight_cpc::solve::cluster::initial_materials(&colours, &seen, case.lambda.len(), 1)
            .expect("k-means start");
    Materials0::from_initial(&init, case.basis.len(), 0)
}

/// A bare [`Estimate`] holding materials `m` (for the metrics that read one).
fn estimate_of(m: &Materials0) -> Estimate {
    Estimate::from_parts(Vec::new(), m.lambda.clone(), m.weights.clone())
}

/// Per vertex `Σ_p α_p y_p / Σ_p α_p o_p` over its training observations, `o_p` the
/// Lambertian response of the observation to a white map of radiance 1 (its
/// cosine-weighted unoccluded fraction): the mean colour with the occlusion part of the
/// shading divided out.
fn open_corrected_colours(case: &Case) -> (Vec<[f64; 3]>, Vec<bool>) {
    let white = vec![(0..case.basis.len())
        .map(|b| if b == 0 { [1.0; 3] } else { [0.0; 3] })
        .collect::<Vec<_>>()];
    let maps: Vec<[Vec<f64>; 3]> = case
        .train
        .lights
        .iter()
        .map(|l| [0, 1, 2].map(|c| vec![1.0; l[c].len()]))
        .collect();
    let open = predict_with(&case.train, case.nv, &white, &vec![1.0; case.nv], &maps);
    let obs = &case.train.obs;
    let mut num = vec![[0.0; 3]; case.nv];
    let mut den = vec![0.0; case.nv];
    for p in 0..obs.len() {
        let a = obs.weight[p] as f64;
        if a <= 0.0 {
            continue;
        }
        let x = obs.vertex[p] as usize;
        for c in 0..3 {
            num[x][c] += a * obs.rgb[p][c] as f64;
        }
        den[x] += a * open[p][0];
    }
    let seen: Vec<bool> = den.iter().map(|&d| d > 0.0).collect();
    let mean = (0..case.nv)
        .map(|x| {
            if seen[x] {
                num[x].map(|v| v / den[x])
            } else {
                [0.0; 3]
            }
        })
        .collect();
    (mean, seen)
}

/// Per vertex and channel the least-squares Lambertian albedo under the lights of a
/// one-material fit (`ABLATION_K1_ITERS` outer iterations, default 4): `a_c(x) = Σ_p α_p
/// r_{p,c} s_{p,c} / Σ_p α_p s_{p,c}²`, `s` the Lambertian response to the fitted map and
/// `r` the photo minus the fit's glossy part: the mean colour with the fitted shading
/// divided out.
fn k1_corrected_colours(case: &Case) -> (Vec<[f64; 3]>, Vec<bool>) {
    let problem = case.train.problem(case.nv);
    let init = start(case, &case.train.obs, 1).expect("one-material start");
    let o = EstimateOptions {
        max_outer: env_or("ABLATION_K1_ITERS", 4),
        ..base_options()
    };
    let est = estimate(&problem, init, &o, &mut |_, _| {}).unwrap();
    let nb = case.basis.len();
    let beta = relight_cpc::solve::beta_per_vertex(&est.lambda, &est.weights, case.nv);
    let s = relight_cpc::solve::basis_responses(&problem, &est.lights);
    let obs = &case.train.obs;
    let mut num = vec![[0.0; 3]; case.nv];
    let mut den = vec![[0.0; 3]; case.nv];
    for p in 0..obs.len() {
        let a = obs.weight[p] as f64;
        if a <= 0.0 {
            continue;
        }
        let x = obs.vertex[p] as usize;
        for c in 0..3 {
            let gloss: f64 = (1..nb)
                .map(|b| beta[x * nb + b][c] * s[p * nb + b][c])
                .sum();
            let r = obs.rgb[p][c] as f64 - gloss;
            num[x][c] += a * r * s[p * nb][c];
            den[x][c] += a * s[p * nb][c] * s[p * nb][c];
        }
    }
    let seen: Vec<bool> = den.iter().map(|d| d.iter().all(|&v| v > 0.0)).collect();
    let mean = (0..case.nv)
        .map(|x| {
            if seen[x] {
                [0, 1, 2].map(|c| (num[x][c] / den[x][c]).max(0.0))
            } else {
                [0.0; 3]
            }
        })
        .collect();
    (mean, seen)
}

/// The Lambertian weights of materials `k ≥ 1` rescaled per channel to the albedo ratios of
/// matched-shading pairs: two observations in one photo whose Lambertian transport rows
/// are nearly parallel (same normal and visibility, so the same diffuse irradiance under
/// any light) of vertices labelled with different materials give `y_p / y_q = ρ_A / ρ_B`;
/// the median log ratio per material pair and channel, then least squares over the pairs
/// for each material's log albedo relative to material 0's. Pairs: each observation's most
/// parallel partner of a later material in its photo, kept when the cosine is at least
/// `ABLATION_MATCH_COS` (default 0.995); vertices labelled when one material holds more
/// than 90% of their start weights.
fn matched_ratios(case: &Case, m: &mut Materials0) {
    let kk = m.lambda.len();
    if kk < 2 {
        return;
    }
    let min_cos: f64 = crate::env_or("ABLATION_MATCH_COS", 0.995);
    let label = pure_labels(&m.weights, kk, case.nv);
    let logs = pair_log_ratios(case, &label, kk, min_cos);
    for c in 0..3 {
        let Some(rel) = log_albedos(&logs, kk, c) else {
            continue;
        };
        let base = m.lambda[0][0][c];
        for k in 1..kk {
            let before = m.lambda[k][0][c];
            m.lambda[k][0][c] = base * rel[k - 1].exp();
            eprintln!(
                "matched: material {k} channel {c}: {before:.4} -> {:.4}",
                m.lambda[k][0][c]
            );
        }
    }
}

/// Each vertex's material when one holds more than 90% of its start weights.
fn pure_labels(weights: &[f64], kk: usize, nv: usize) -> Vec<Option<usize>> {
    (0..nv)
        .map(|x| {
            let w = &weights[x * kk..(x + 1) * kk];
            let (k, &best) = w
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .unwrap();
            let sum: f64 = w.iter().map(|v| v.max(0.0)).sum();
            (sum > 0.0 && best / sum > 0.9).then_some(k)
        })
        .collect()
}

/// `log(y_p / y_q)` per channel of every matched pair, listed under its material pair
/// `a · K + b` (`a < b`, `p` of material `a`): `q` is `p`'s most parallel partner of a
/// later material in the same photo (Lambert rows' cosine at least `min_cos`).
fn pair_log_ratios(
    case: &Case,
    label: &[Option<usize>],
    kk: usize,
    min_cos: f64,
) -> Vec<Vec<[f64; 3]>> {
    let obs = &case.train.obs;
    let tr = &case.train.transport;
    let unit_lambert_row = |p: usize| {
        let mut d = vec![0.0; tr.n_global * tr.n_global];
        let (idx, val) = tr.row(p, 0);
        for (&i, &v) in idx.iter().zip(val) {
            d[i as usize] = f64::from(v);
        }
        let n = d.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
        d.iter_mut().for_each(|v| *v /= n);
        d
    };
    let mut logs: Vec<Vec<[f64; 3]>> = vec![Vec::new(); kk * kk];
    for range in &obs.photo_ranges {
        let ps: Vec<(usize, usize)> = range
            .clone()
            .filter(|&p| obs.weight[p] > 0.0 && obs.rgb[p].iter().all(|&v| v > 0.02))
            .filter_map(|p| label[obs.vertex[p] as usize].map(|k| (p, k)))
            .collect();
        let dense: Vec<Vec<f64>> = ps.iter().map(|&(p, _)| unit_lambert_row(p)).collect();
        for (i, &(p, a)) in ps.iter().enumerate() {
            let best = ps
                .iter()
                .enumerate()
                .filter(|(_, &(_, b))| b > a)
                .map(|(j, &(q, b))| {
                    let c: f64 = dense[i].iter().zip(&dense[j]).map(|(x, y)| x * y).sum();
                    (c, q, b)
                })
                .filter(|&(c, _, _)| c >= min_cos)
                // The first of equal cosines.
                .reduce(|best, x| if x.0 > best.0 { x } else { best });
            if let Some((_, q, b)) = best {
                let r = [0, 1, 2].map(|c| (obs.rgb[p][c] as f64 / obs.rgb[q][c] as f64).ln());
                logs[a * kk + b].push(r);
            }
        }
    }
    logs
}

/// Least squares for channel `c`'s `l_k = log ρ_k − log ρ_0` (`k ≥ 1`, `l_0 = 0`) from
/// `l_b − l_a = median log(ρ_b / ρ_a)` over each material pair with matches, weighted by
/// the square root of its count; `None` when the system is singular.
fn log_albedos(logs: &[Vec<[f64; 3]>], kk: usize, c: usize) -> Option<Vec<f64>> {
    let n = kk - 1;
    let mut ata = vec![0.0; n * n];
    let mut atb = vec![0.0; n];
    for a in 0..kk {
        for b in a + 1..kk {
            let v = &logs[a * kk + b];
            if v.is_empty() {
                continue;
            }
            let mut xs: Vec<f64> = v.iter().map(|r| -r[c]).collect();
            xs.sort_by(f64::total_cmp);
            let med = xs[xs.len() / 2];
            let w = (xs.len() as f64).sqrt();
            eprintln!(
                "matched: pair {a}-{b} channel {c}: {} pairs, median log ratio {med:.3}",
                xs.len()
            );
            // The row: +1 at b, −1 at a (unknown k − 1 for k ≥ 1; b ≥ 1 always).
            let mut row = vec![0.0; n];
            row[b - 1] += 1.0;
            if a >= 1 {
                row[a - 1] -= 1.0;
            }
            for i in 0..n {
                atb[i] += w * row[i] * med;
                for j in 0..n {
                    ata[i * n + j] += w * row[i] * row[j];
                }
            }
        }
    }
    let mat =
        nalgebra::DMatrix::from_row_slice(n, n, &ata) + nalgebra::DMatrix::identity(n, n) * 1e-9;
    let sol = mat.lu().solve(&nalgebra::DVector::from_vec(atb))?;
    Some(sol.iter().copied().collect())
}
