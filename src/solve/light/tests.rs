//! Tests of the lighting step on a stratified sample of a photo's observations.

use rand::{Rng, SeedableRng};

use crate::observe::Observations;
use crate::solve::light::photo::{
    lighting_sample, lighting_step_full, lighting_step_on, lighting_step_warm,
};
use crate::solve::light::system::row_dot;
use crate::solve::options::{EstimateOptions, Robust};
use crate::solve::problem::{basis_responses, haar3, predict_from, Problem};
use crate::transport::{HaarIndex, Transport, TransportValue};

/// The problem of one photo whose observations are `obs` (one per vertex) under `t`.
pub(super) fn one_photo<'a>(obs: &'a Observations, t: &'a Transport) -> Problem<'a> {
    Problem {
        obs,
        transport: t,
        n_vertices: obs.len(),
        n_photos: 1,
    }
}

/// The smooth light [`planted_photo`] plants on an `n²` map, texels per channel:
/// `1 + ½ sin(u + c)` with `u` the texel's column over `n`.
pub(super) fn planted_light(n: usize) -> [Vec<f64>; 3] {
    [0, 1, 2].map(|c| {
        (0..n * n)
            .map(|t| 1.0 + 0.5 * ((t % n) as f64 / n as f64 + c as f64).sin())
            .collect()
    })
}

/// One photo of `rows` observations (vertex = observation) over an `n²` map: each row
/// 24 random Haar coefficients of the low levels (the first `n²/4`), positive values;
/// `y` from a known smooth light plus Gaussian-like noise (`σ` relative).
pub(super) fn planted_photo(
    rows: usize,
    n: usize,
    noise: f64,
    seed: u64,
) -> (Observations, Transport) {
    planted_photo_under(&planted_light(n), rows, n, noise, seed)
}

/// [`planted_photo`] under the texels `texels` (per channel).
pub(super) fn planted_photo_under(
    texels: &[Vec<f64>; 3],
    rows: usize,
    n: usize,
    noise: f64,
    seed: u64,
) -> (Observations, Transport) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let n2 = n * n;
    let light: Vec<[f64; 3]> = haar3(texels, n);
    let mut t = Transport {
        n_global: n,
        n_basis: 1,
        n_obs: rows,
        offsets: vec![0],
        ..Default::default()
    };
    let mut obs = Observations::default();
    for p in 0..rows {
        let mut idx: Vec<HaarIndex> = (0..24)
            .map(|_| rng.random_range(0..n2 / 4) as HaarIndex)
            .collect();
        idx.sort_unstable();
        idx.dedup();
        // Values as stored (half precision), so `clean` is the rows' exact response.
        let val: Vec<f32> = idx
            .iter()
            .map(|_| TransportValue::from_f32(rng.random_range(0.1..1.0)).to_f32())
            .collect();
        let clean = row_dot(
            &idx,
            &val.iter().map(|&v| [v; 3]).collect::<Vec<_>>(),
            &light,
        );
        t.index.extend(&idx);
        t.value
            .extend(val.iter().map(|&v| TransportValue::from_f32(v)));
        t.offsets.push(t.index.len());
        obs.vertex.push(p as u32);
        obs.photo.push(0);
        // Sum of 4 uniforms on [-1, 1]: mean 0, variance 4/3.
        let mut e =
            || (0..4).map(|_| rng.random_range(-1.0..1.0)).sum::<f64>() / (4.0_f64 / 3.0).sqrt();
        obs.rgb
            .push(clean.map(|v| (v * (1.0 + noise * e())) as f32));
        obs.weight.push(1.0);
        obs.dir.push([0.0, 0.0, 1.0]);
    }
    let all = 0..rows;
    obs.photo_ranges = vec![all];
    (obs, t)
}

#[test]
fn a_lighting_sample_leaves_the_map_where_all_observations_put_it() {
    // 6,000 observations, 3 × 256 unknowns of which the rows reach the 64 coarsest
    // Haar levels: the full fit against fits on 1,500 sampled rows (four seeds), all to
    // the KKT tolerance. With 2% noise the full fit's own error against the truth is
    // the yardstick: a sample of a quarter of the rows has about twice the variance
    // (√4 = 2 × the standard error), so the sampled map must stay within 3 × the full
    // fit's distance from the truth of the full map, and its predictions of the rows
    // it never saw must be as good as of those it saw (ratio < 1.1, the run's check).
    let n = 16;
    let (obs, t) = planted_photo(6000, n, 0.02, 11);
    let problem = one_photo(&obs, &t);
    let beta = vec![[1.0; 3]; obs.len()];
    let opts = EstimateOptions {
        robust: Robust::None,
        irls_iters: 1,
        smoothness: 1e-4,
        qp_rel_tol: 1e-9,
        qp_max_iter: 500,
        ..EstimateOptions::default()
    };
    let full = lighting_step_full(&problem, &beta, 0, None, None, &opts).unwrap();
    // Only the coefficients the rows reach are determined by the data.
    let dist = |a: &[Vec<f64>; 3], b: &[Vec<f64>; 3]| reached_distance(a, b, n);
    let truth = planted_light(n);
    let full_err = dist(&full.light, &truth);
    assert!(full_err < 0.05, "the full fit itself: {full_err}");
    for seed in 1..=4 {
        let sampled_opts = EstimateOptions {
            lighting_sample: 1500,
            validation_seed: seed,
            ..opts.clone()
        };
        let sample = lighting_sample(&problem, 0, &sampled_opts, None).unwrap();
        assert_eq!(sample.index.len(), 1500);
        let r =
            lighting_step_on(&problem, &beta, 0, None, None, &sampled_opts, Some(&sample)).unwrap();
        assert_eq!(
            r.irls_weights.len(),
            obs.len(),
            "weights for every observation"
        );
        let moved = dist(&r.light, &full.light);
        assert!(
            moved < 3.0 * full_err,
            "seed {seed}: moved {moved}, full fit's error {full_err}"
        );
        let pred = predict_from(
            &problem,
            &beta,
            &basis_responses(&problem, std::slice::from_ref(&r.light)),
        );
        let check = crate::solve::subsample::sample_check(
            &pred,
            &obs.rgb,
            &obs.weight,
            &obs.photo_ranges,
            &[Some(sample)],
            1500,
        );
        assert_eq!(check.in_sample + check.out_of_sample, obs.len());
        assert!(check.ratio < 1.1, "seed {seed}: {check:?}");
    }
}

/// Relative distance of two maps on the Haar coefficients the planted rows reach (the
/// first `n²/4`; the others are set by the prior alone).
fn reached_distance(a: &[Vec<f64>; 3], b: &[Vec<f64>; 3], n: usize) -> f64 {
    let (ha, hb) = (haar3(a, n), haar3(b, n));
    let (mut d, mut s) = (0.0, 0.0);
    for m in 0..n * n / 4 {
        for c in 0..3 {
            d += (ha[m][c] - hb[m][c]).powi(2);
            s += hb[m][c].powi(2);
        }
    }
    (d / s).sqrt()
}

#[test]
fn warm_irls_passes_continue_to_the_robust_fit() {
    // 3,000 observations with 1% noise, every 8th one a gross outlier (radiance × 4). The
    // plain least-squares fit is pulled off the planted light; IRLS continued one warm
    // pass at a time (each from the previous pass's light, as the alternation runs it)
    // must reach the robust fit: within 1.5 × the distance from the planted light of a
    // fit restarted from unit weights with 8 passes, and at least 3 × closer than the
    // least-squares start (both thresholds leave room for the noise, which is the same
    // draw for every fit).
    let n = 16;
    let (mut obs, t) = planted_photo(3000, n, 0.01, 5);
    for rgb in obs.rgb.iter_mut().step_by(8) {
        *rgb = rgb.map(|v| 4.0 * v);
    }
    let problem = one_photo(&obs, &t);
    let beta = vec![[1.0; 3]; obs.len()];
    let robust = EstimateOptions {
        smoothness: 1e-4,
        irls_iters: 8,
        qp_rel_tol: 1e-9,
        qp_max_iter: 500,
        ..EstimateOptions::default()
    };
    let plain = EstimateOptions {
        robust: Robust::None,
        irls_iters: 1,
        ..robust.clone()
    };
    let truth = planted_light(n);
    let ls = lighting_step_full(&problem, &beta, 0, None, None, &plain).unwrap();
    let restarted = lighting_step_full(&problem, &beta, 0, None, None, &robust).unwrap();
    let mut light = ls.light.clone();
    for _ in 0..8 {
        let r = lighting_step_warm(
            &problem,
            &beta,
            0,
            Some(&light),
            Some(restarted.mu),
            &robust,
            None,
            true,
        )
        .unwrap();
        assert_eq!(r.qps, 1, "one pass per warm step");
        light = r.light;
    }
    let (e_ls, e_restart, e_warm) = (
        reached_distance(&ls.light, &truth, n),
        reached_distance(&restarted.light, &truth, n),
        reached_distance(&light, &truth, n),
    );
    assert!(
        e_warm < 1.5 * e_restart,
        "warm {e_warm}, restarted {e_restart}"
    );
    assert!(3.0 * e_warm < e_ls, "warm {e_warm}, least squares {e_ls}");
}

#[test]
fn clipped_channels_read_as_bounds_recover_the_light_clipping_hides() {
    // Noise-free rows; every channel value above the 80th percentile clipped to it (a
    // photo's overexposure). Read as exact values, the clipped rows pull the map down;
    // read as lower bounds (the one-sided term, its active set re-read as each lighting
    // step starts from the last one's light, as the alternation runs it) the fit must come
    // back to the planted light, which satisfies every bound and fits every other row
    // exactly: within 5% of the exact reading's distance from it, and no clipped channel
    // predicted more than 0.5% below its bound (the QP's tolerance and the Laplacian's
    // pull are far below both).
    let n = 16;
    let (mut obs, t) = planted_photo(3000, n, 0.0, 5);
    let mut all: Vec<f32> = obs.rgb.iter().flatten().copied().collect();
    all.sort_by(f32::total_cmp);
    let level = all[all.len() * 8 / 10];
    for rgb in obs.rgb.iter_mut() {
        let mask = (0..3)
            .filter(|&c| rgb[c] > level)
            .fold(0u8, |m, c| m | 1 << c);
        for c in (0..3).filter(|&c| mask & 1 << c != 0) {
            rgb[c] = level;
        }
        obs.clipped.push(mask);
        obs.bound_weight.push(if mask != 0 { 1.0 } else { 0.0 });
    }
    let beta = vec![[1.0; 3]; obs.len()];
    let opts = EstimateOptions {
        robust: Robust::None,
        irls_iters: 1,
        smoothness: 1e-6,
        qp_rel_tol: 1e-10,
        qp_max_iter: 1000,
        ..EstimateOptions::default()
    };
    let truth = planted_light(n);
    let exact_reading = Observations {
        clipped: Vec::new(),
        bound_weight: Vec::new(),
        ..obs.clone()
    };
    let problem = one_photo(&exact_reading, &t);
    let naive = lighting_step_full(&problem, &beta, 0, None, None, &opts).unwrap();
    let naive_err = reached_distance(&naive.light, &truth, n);
    let problem = one_photo(&obs, &t);
    let mut light = None;
    for _ in 0..15 {
        let start = light.as_ref();
        let r = lighting_step_warm(&problem, &beta, 0, start, None, &opts, None, false).unwrap();
        light = Some(r.light);
    }
    let light = light.unwrap();
    let err = reached_distance(&light, &truth, n);
    assert!(
        naive_err > 0.05,
        "clipping must bias the exact reading: {naive_err}"
    );
    assert!(
        err < 0.05 * naive_err,
        "bounds {err} against exact reading {naive_err}"
    );
    let pred = predict_from(
        &problem,
        &beta,
        &basis_responses(&problem, std::slice::from_ref(&light)),
    );
    for (p, (&mask, pred)) in obs.clipped.iter().zip(&pred).enumerate() {
        for c in (0..3).filter(|&c| mask & 1 << c != 0) {
            let short = (level as f64 - pred[c]) / level as f64;
            assert!(short < 0.005, "observation {p} channel {c}: {short} below");
        }
    }
}

#[test]
fn the_chroma_prior_pools_noise_across_channels_when_the_light_has_one_colour() {
    // A light whose channels are one smooth shape times three gains: the chroma prior
    // costs nothing at the truth, so it can only pull each channel's noise toward what
    // the other two say. 5% independent noise per channel on 200 rows: the fit with the
    // prior (κ = 1000) must land closer to the truth on the coefficients the rows reach
    // than the Laplacian alone, by at least 10% (pooling three channels could at best
    // cut the noise part by √3; measured 23% at this seed, 25–27% at seeds 1–3).
    let n = 16;
    let shape = planted_light(n)[0].clone();
    let gains = [1.2, 1.0, 0.6];
    let truth = gains.map(|g| shape.iter().map(|v| g * v).collect::<Vec<f64>>());
    let (obs, t) = planted_photo_under(&truth, 200, n, 0.05, 5);
    let problem = one_photo(&obs, &t);
    let beta = vec![[1.0; 3]; obs.len()];
    let fit = |kappa: f64| {
        let opts = EstimateOptions {
            robust: Robust::None,
            irls_iters: 2,
            smoothness: 1e-4,
            chroma_smoothness: kappa,
            qp_rel_tol: 1e-9,
            qp_max_iter: 500,
            ..EstimateOptions::default()
        };
        lighting_step_full(&problem, &beta, 0, None, None, &opts).unwrap()
    };
    let plain = reached_distance(&fit(0.0).light, &truth, n);
    let pooled = reached_distance(&fit(1000.0).light, &truth, n);
    assert!(
        pooled < 0.9 * plain,
        "with the prior {pooled}, without {plain}"
    );
}

#[test]
fn the_background_pins_the_texels_it_shows() {
    // The rows reach only the 64 coarsest Haar coefficients of a 16² map, so detail finer
    // than 2 × 2 texels is invisible to them: the planted light has every other texel of
    // one row 40% brighter, which the free fit (the paper's Laplacian, 1e-4) smooths out
    // (more than 5% off there). Those 12 texels' background (50 pixels a texel at γ = 1,
    // exact values) must bring each within 1% of the planted map, and the rows' fit must
    // not suffer: their relative RMSE no more than 0.01 above the free fit's (measured:
    // 22% off free, 0.05% pinned; rows 8.4e-5 both).
    let n = 16;
    let mut truth = planted_light(n);
    for ch in truth.iter_mut() {
        for i in (3..14).step_by(2) {
            ch[5 * n + i] *= 1.4;
        }
    }
    let (obs, t) = planted_photo_under(&truth, 300, n, 0.0, 3);
    let problem = one_photo(&obs, &t);
    let beta = vec![[1.0; 3]; obs.len()];
    let shown: Vec<usize> = (2..14).map(|i| 5 * n + i).collect();
    let texels = shown
        .iter()
        .map(|&t| crate::observe::background::BackgroundTexel {
            texel: t as u32,
            pixels: 50,
            mean: [0, 1, 2].map(|c| truth[c][t] as f32),
        })
        .collect();
    let term = crate::solve::light::background::BackgroundTerm {
        weight: 1.0,
        n_global: n,
        photos: vec![texels],
    };
    let fit = |background| {
        let opts = EstimateOptions {
            robust: Robust::None,
            smoothness: 1e-4,
            qp_rel_tol: 1e-10,
            qp_max_iter: 1000,
            background,
            ..EstimateOptions::default()
        };
        lighting_step_full(&problem, &beta, 0, None, None, &opts)
            .unwrap()
            .light
    };
    let worst = |light: &[Vec<f64>; 3]| {
        let rel = |c: usize, t: usize| (light[c][t] / truth[c][t] - 1.0).abs();
        shown
            .iter()
            .flat_map(|&t| (0..3).map(move |c| (c, t)))
            .map(|(c, t)| rel(c, t))
            .fold(0.0, f64::max)
    };
    // The rows' RMSE against their clean values, relative to their RMS.
    let rows_rmse = |light: &[Vec<f64>; 3]| {
        let s = basis_responses(&problem, std::slice::from_ref(light));
        let pred = predict_from(&problem, &beta, &s);
        let (mut e, mut y2) = (0.0, 0.0);
        for (p, y) in pred.iter().zip(&obs.rgb) {
            for c in 0..3 {
                e += (p[c] - f64::from(y[c])).powi(2);
                y2 += f64::from(y[c]).powi(2);
            }
        }
        (e / y2).sqrt()
    };
    let free = fit(None);
    let pinned = fit(Some(std::sync::Arc::new(term)));
    assert!(
        worst(&free) > 0.05,
        "the free fit is already at the truth: {}",
        worst(&free)
    );
    assert!(worst(&pinned) < 0.01, "pinned {}", worst(&pinned));
    let (r_free, r_pinned) = (rows_rmse(&free), rows_rmse(&pinned));
    assert!(
        r_pinned < r_free + 0.01,
        "rows: pinned {r_pinned}, free {r_free}"
    );
}
