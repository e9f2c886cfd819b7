//! The ablation's starts (`ABLATION_START`, module docs of `benches/ablation.rs`): the
//! paper's k-means start, oracle starts with parts of the truth, and alternatives.

use super::*;

/// The fit's start: the paper's (k-means), or with `ABLATION_START=truth` the TRUE
/// materials (a diagnosis: does the alternation leave the truth?), or with
/// `ABLATION_START=gloss` the paper's with every glossy lobe at
/// [`relight_cpc::solve::starts::GLOSS_FRACTION`] of the mean Lambertian weight, or with
/// `ABLATION_START=open` the paper's clustering of [`open_corrected_colours`]; the oracle
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
        Ok("open") => {
            let (mean, seen) = open_corrected_colours(case);
            let init =
                relight_cpc::solve::cluster::initial_materials(&mean, &seen, case.lambda.len(), 1)
                    .expect("k-means start");
            Materials0::from_initial(&init, case.basis.len(), 0)
        }
        Ok("gloss") => relight_cpc::solve::starts::uniform_gloss(
            &init,
            0,
            relight_cpc::solve::starts::GLOSS_FRACTION,
        ),
        _ => init,
    }
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
