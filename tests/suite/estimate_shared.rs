//! The shared light model ([`relight_cpc::solve::light::shared`]) on a planted problem
//! whose photos come in groups under one true map each, seen through known per-photo
//! exposure and white-balance gains: the fit must recover the gains' ratios inside a
//! group, and predict observations it never fitted at least as well as the paper's free
//! map per photo.

#![allow(clippy::needless_range_loop)]

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use relight_cpc::observe::Observations;
use relight_cpc::solve::light::shared::LightGroups;
use relight_cpc::solve::{
    beta_per_vertex, estimate, predict, Estimate, EstimateOptions, Materials0, Problem, Robust,
};
use relight_cpc::sphere::haar;
use relight_cpc::transport::{Transport, TransportValue};

const N: usize = 8; // map side: 64 texels per channel
const B: usize = 2; // a wide ("diffuse") and a narrow ("glossy") lobe
const K: usize = 2;

/// The planted scene: observations, transport, the truth, and which observations are held
/// out (weight 0: never fitted, scored against the clean truth).
pub(crate) struct SharedPlanted {
    pub(crate) obs: Observations,
    pub(crate) transport: Transport,
    pub(crate) group: Vec<usize>,
    /// True gains `a_{I,c}` per photo.
    pub(crate) gains: Vec<[f64; 3]>,
    pub(crate) lambda: Vec<Vec<[f64; 3]>>,
    pub(crate) weights: Vec<f64>,
    pub(crate) clean: Vec<[f64; 3]>,
    pub(crate) held_out: Vec<bool>,
    pub(crate) v: usize,
}

fn gaussian(rng: &mut Pcg64) -> f64 {
    let u: f64 = rng.random::<f64>().max(1e-300);
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

/// A smooth sky gradient plus a bright sun block, one per group.
fn group_map(rng: &mut Pcg64, g: usize) -> [Vec<f64>; 3] {
    let (si, sj) = (rng.random_range(0..N - 1), rng.random_range(0..N - 1));
    [0, 1, 2].map(|c| {
        (0..N * N)
            .map(|t| {
                let (u, v) = ((t % N) as f64 / N as f64, (t / N) as f64 / N as f64);
                let sky = 0.3 + 0.2 * (u + 0.3 * c as f64 + g as f64).sin() * v;
                let sun = (t / N == sj && (t % N == si || t % N == si + 1)) as u8 as f64;
                sky + 3.0 * sun
            })
            .collect()
    })
}

/// One observation's transport rows (texel-domain non-negative lobes, Haar-transformed):
/// pushed onto `index`, `value`, `offsets`.
fn push_rows(
    rng: &mut Pcg64,
    index: &mut Vec<u16>,
    value: &mut Vec<TransportValue>,
    offsets: &mut Vec<usize>,
) {
    let (ci, cj) = (
        rng.random_range(0..N) as isize,
        rng.random_range(0..N) as isize,
    );
    for b in 0..B {
        let mut g = vec![0.0; N * N];
        let r: isize = if b == 0 { 2 } else { 0 };
        for dj in -r..=r {
            for di in -r..=r {
                let ii = (ci + di).rem_euclid(N as isize) as usize;
                let jj = (cj + dj).rem_euclid(N as isize) as usize;
                g[jj * N + ii] += 1.0 / (1 + di.abs() + dj.abs()) as f64;
            }
        }
        for _ in 0..3 {
            g[rng.random_range(0..N * N)] += 0.2 * rng.random::<f64>();
        }
        let scale = if b == 0 { 0.05 } else { 0.4 };
        g.iter_mut().for_each(|v| *v *= scale);
        haar::forward(&mut g, N);
        for (m, &v) in g.iter().enumerate() {
            if v.abs() > 1e-12 {
                index.push(m as u16);
                value.push(TransportValue::from_f64(v));
            }
        }
        offsets.push(index.len());
    }
}

/// `groups` groups of `per_group` photos; photo gains: exposure in [0.5, 2] (log-uniform)
/// times a white balance in [0.85, 1.15] on red and blue (green 1), as the synthetic
/// workspaces draw them; `noise` relative Gaussian noise; 20% of observations held out.
pub(crate) fn shared_planted(
    seed: u64,
    noise: f64,
    nv: usize,
    groups: usize,
    per_group: usize,
) -> SharedPlanted {
    let mut rng = Pcg64::seed_from_u64(seed);
    let maps: Vec<[Vec<f64>; 3]> = (0..groups).map(|g| group_map(&mut rng, g)).collect();
    let photos = groups * per_group;
    let group: Vec<usize> = (0..photos).map(|i| i / per_group).collect();
    let gains: Vec<[f64; 3]> = (0..photos)
        .map(|_| {
            let e = (rng.random_range(-1.0..1.0) * std::f64::consts::LN_2).exp();
            let (r, b) = (rng.random_range(0.85..1.15), rng.random_range(0.85..1.15));
            [e * r, e, e * b]
        })
        .collect();
    let lambda = vec![
        vec![[0.8, 0.35, 0.2], [0.3, 0.3, 0.3]],
        vec![[0.15, 0.45, 0.7], [0.05, 0.05, 0.05]],
    ];
    let mut weights = vec![0.0; nv * K];
    for x in 0..nv {
        if x % 10 == 9 {
            weights[x * K] = 0.6;
            weights[x * K + 1] = 0.4;
        } else {
            weights[x * K + x % K] = 1.0;
        }
    }
    let mut obs = Observations::default();
    let (mut offsets, mut index, mut value) = (vec![0usize], Vec::new(), Vec::new());
    let mut held_out = Vec::new();
    for i in 0..photos {
        let start = obs.vertex.len();
        for x in 0..nv {
            if rng.random::<f64>() < 0.02 {
                continue;
            }
            obs.vertex.push(x as u32);
            obs.photo.push(i as u32);
            obs.dir.push([0.0, 0.0, 1.0]);
            let out = rng.random::<f64>() < 0.2;
            held_out.push(out);
            let w = (0.5 + 0.5 * rng.random::<f64>()) as f32;
            obs.weight.push(if out { 0.0 } else { w });
            obs.rgb.push([0.0; 3]);
            push_rows(&mut rng, &mut index, &mut value, &mut offsets);
        }
        obs.photo_ranges.push(start..obs.vertex.len());
    }
    let transport = Transport {
        n_global: N,
        n_basis: B,
        n_obs: obs.vertex.len(),
        offsets,
        index,
        value,
    };
    let beta = beta_per_vertex(&lambda, &weights, nv);
    let hmaps: Vec<[Vec<f64>; 3]> = maps
        .iter()
        .map(|m| {
            m.clone().map(|mut c| {
                haar::forward(&mut c, N);
                c
            })
        })
        .collect();
    let mut clean = Vec::with_capacity(obs.vertex.len());
    for p in 0..obs.vertex.len() {
        let (x, i) = (obs.vertex[p] as usize, obs.photo[p] as usize);
        let mut y = [0.0; 3];
        for b in 0..B {
            for c in 0..3 {
                let r = transport.response(p, b, &hmaps[group[i]][c]);
                y[c] += gains[i][c] * beta[x * B + b][c] * r;
            }
        }
        clean.push(y);
    }
    let mean_level = clean.iter().flatten().sum::<f64>() / (3 * clean.len()) as f64;
    for (o, y) in obs.rgb.iter_mut().zip(&clean) {
        *o = y.map(|v| (v + noise * mean_level * gaussian(&mut rng)) as f32);
    }
    SharedPlanted {
        obs,
        transport,
        group,
        gains,
        lambda,
        weights,
        clean,
        held_out,
        v: nv,
    }
}

pub(crate) fn problem(p: &SharedPlanted) -> Problem<'_> {
    Problem {
        obs: &p.obs,
        transport: &p.transport,
        n_vertices: p.v,
        n_photos: p.group.len(),
    }
}

/// The start of `estimate_planted`: true Lambertian colours ×(1 ± 20%), no glossy
/// weight, blurred blending weights.
pub(crate) fn start(p: &SharedPlanted) -> Materials0 {
    let lambda = p
        .lambda
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let f = if k == 0 { 1.2 } else { 0.8 };
            vec![l[0].map(|v| v * f), [0.0; 3]]
        })
        .collect();
    let weights = p.weights.iter().map(|w| 0.8 * w + 0.1).collect();
    Materials0 { lambda, weights }
}

/// Relative RMSE against the clean truth over the held-out (or the fitted) observations.
pub(crate) fn clean_error(p: &SharedPlanted, est: &Estimate, held_out: bool) -> f64 {
    let pred = predict(&problem(p), est);
    let (mut se, mut lvl, mut n) = (0.0, 0.0, 0.0);
    for q in 0..pred.len() {
        if p.held_out[q] != held_out {
            continue;
        }
        for c in 0..3 {
            se += (pred[q][c] - p.clean[q][c]).powi(2);
            lvl += p.clean[q][c];
            n += 1.0;
        }
    }
    (se / n).sqrt() / (lvl / n)
}

/// Worst relative error of the Lambertian albedo ratio between the two materials,
/// `(λ_0,c / λ_1,c) / (true ratio) − 1` over channels: free of the global per-channel scale.
pub(crate) fn albedo_ratio_error(p: &SharedPlanted, est: &Estimate) -> f64 {
    (0..3)
        .map(|c| {
            let fit = est.lambda[0][0][c] / est.lambda[1][0][c];
            let truth = p.lambda[0][0][c] / p.lambda[1][0][c];
            (fit / truth - 1.0).abs()
        })
        .fold(0.0, f64::max)
}

pub(crate) fn opts(groups: Option<&[usize]>) -> EstimateOptions {
    EstimateOptions {
        max_outer: 30,
        rel_tol: 1e-7,
        smoothness: 1e-6,
        robust: Robust::None,
        qp_rel_tol: 1e-9,
        material_sweeps: 4,
        light_groups: groups.map(|g| LightGroups::from_labels(g, "planted".into())),
        ..EstimateOptions::default()
    }
}

#[test]
fn shared_light_recovers_gain_ratios_and_predicts_unseen_observations() {
    // 2 groups × 4 photos, 150 vertices, 1% noise, 20% of observations never fitted.
    let p = shared_planted(7, 0.01, 150, 2, 4);
    let fit = |groups: Option<&[usize]>| {
        estimate(&problem(&p), start(&p), &opts(groups), &mut |_, _| {}).unwrap()
    };
    let shared = fit(Some(&p.group));
    let paper = fit(None);
    // Recovered gains: a photo's map is a_I m_g, so a_{I,c} / a_{J,c} in one group is the
    // ratio of the two photos' maps at any texel where the map is non-zero; compare it
    // with the truth for every pair of photos in a group. The ratio of two photos'
    // brightness is fixed by ~120 fitted observations each with 1% noise (standard error
    // ≈ 0.1%), and free of the albedo/light scale (it cancels in a ratio); 2% leaves room
    // for the fit's own bias at 30 iterations.
    for i in 0..p.group.len() {
        for j in 0..p.group.len() {
            if i == j || p.group[i] != p.group[j] {
                continue;
            }
            for c in 0..3 {
                let (mi, mj) = (&shared.lights[i][c], &shared.lights[j][c]);
                let t = (0..mi.len())
                    .max_by(|&a, &b| mj[a].total_cmp(&mj[b]))
                    .unwrap();
                let fit = mi[t] / mj[t];
                let truth = p.gains[i][c] / p.gains[j][c];
                assert!(
                    (fit / truth - 1.0).abs() < 0.02,
                    "photos {i}, {j} channel {c}: gain ratio {fit} vs true {truth}"
                );
            }
        }
    }
    // Held-out: with 4 photos under each map the shared model has a quarter of the
    // paper's light unknowns, so on observations neither saw it must predict at least as
    // well (no tolerance: the comparison is the claim).
    let (e_shared, e_paper) = (
        clean_error(&p, &shared, true),
        clean_error(&p, &paper, true),
    );
    eprintln!(
        "held-out vs clean truth: shared {e_shared:.5}, paper {e_paper:.5}; albedo ratio error shared {:.4}, paper {:.4}",
        albedo_ratio_error(&p, &shared),
        albedo_ratio_error(&p, &paper)
    );
    assert!(e_shared <= e_paper, "shared {e_shared} vs paper {e_paper}");
    assert!(shared.lights.iter().flatten().flatten().all(|&v| v >= 0.0));
}

#[test]
fn grey_world_anchor_sets_the_mean_albedo_and_keeps_the_predictions() {
    // The anchor only moves the per-channel scale between λ and the light, which `F`
    // cannot see: the predictions of the two fits (same data, same path up to the final
    // normalisation) agree to rounding (1e-9 relative), and the grey-world fit's mean
    // diffuse albedo over the vertices is 0.5 per channel (to rounding, 1e-12).
    use relight_cpc::solve::normalise::{ScaleAnchor, GREY_WORLD_ALBEDO};
    let p = shared_planted(9, 0.01, 100, 2, 3);
    let fit = |anchor: ScaleAnchor| {
        let o = EstimateOptions {
            max_outer: 5,
            scale_anchor: anchor,
            ..opts(Some(&p.group))
        };
        estimate(&problem(&p), start(&p), &o, &mut |_, _| {}).unwrap()
    };
    let (start_fit, grey) = (fit(ScaleAnchor::Start), fit(ScaleAnchor::GreyWorld));
    assert!(
        grey.normalisation.contains("grey-world"),
        "{}",
        grey.normalisation
    );
    let (a, b) = (
        predict(&problem(&p), &start_fit),
        predict(&problem(&p), &grey),
    );
    let scale = a.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
    for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
        assert!((x - y).abs() <= 1e-9 * scale, "{x} vs {y}");
    }
    let beta = beta_per_vertex(&grey.lambda, &grey.weights, p.v);
    for c in 0..3 {
        let mean = (0..p.v).map(|x| beta[x * B][c]).sum::<f64>() / p.v as f64;
        assert!(
            (mean - GREY_WORLD_ALBEDO).abs() < 1e-12,
            "channel {c}: {mean}"
        );
    }
}

#[test]
fn the_ratio_step_runs_under_the_shared_light() {
    // The ratio step needs a light model whose channels are separable and whose parameters
    // mix (`LightModel::channel_penalty`, `combine`). The shared model has both, so every
    // round asked for tries its move (one direction with two materials) until the step's
    // patience ends it, and none is left unsupported; without them the step was skipped
    // in silence (its effect on rendered scenes: bench-results/shared-skies.md).
    let p = shared_planted(7, 0.01, 150, 2, 4);
    let o = EstimateOptions {
        ratio_steps: 4,
        max_outer: 4,
        ..opts(Some(&p.group))
    };
    let est = estimate(&problem(&p), start(&p), &o, &mut |_, _| {}).unwrap();
    let m = &est.ratio_moves;
    assert_eq!(m.unsupported, 0, "{m:?}");
    let rounds = m.stopped_after.unwrap_or(4);
    assert_eq!(m.tried, rounds, "{m:?}");
}
