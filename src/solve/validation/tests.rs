//! Early stopping's splits, scores and terms against brute force and separate code paths.

use super::*;

/// `n_vertices` vertices with `per_vertex` observations each, every fifth with `α = 0`.
fn grid_obs(n_vertices: usize, per_vertex: usize) -> Observations {
    let mut obs = Observations::default();
    for x in 0..n_vertices {
        for k in 0..per_vertex {
            let p = obs.vertex.len();
            obs.vertex.push(x as u32);
            obs.photo.push(k as u32);
            obs.rgb.push([0.5; 3]);
            obs.weight.push(if p % 5 == 4 { 0.0 } else { 1.0 });
            obs.dir.push([0.0, 0.0, 1.0]);
        }
    }
    obs
}

/// The blocked split holds back whole vertices (no held-back vertex keeps a fitted
/// `α > 0` observation), never an `α = 0` one, and about `fraction` of the `α > 0`
/// observations: 2000 blocks drawn with p = 0.1 give a block count with standard
/// deviation sqrt(2000 · 0.09) ≈ 13.4 of 200, i.e. 0.0067 in the fraction, so ±0.03
/// (4.5 σ) fails only for a wrong draw.
#[test]
fn blocked_split_holds_back_whole_vertices_at_the_fraction() {
    let (nv, block, fraction) = (64 * 2000, 64, 0.1);
    let obs = grid_obs(nv, 3);
    let held = validation_split_blocked(&obs, nv, fraction, block, 7);
    assert!(held.windows(2).all(|w| w[0] < w[1]), "not sorted / unique");
    let mut held_vertex = vec![false; nv];
    for &p in &held {
        assert!(obs.weight[p] > 0.0, "held-back observation {p} has α = 0");
        held_vertex[obs.vertex[p] as usize] = true;
    }
    let mut is_held = vec![false; obs.len()];
    for &p in &held {
        is_held[p] = true;
    }
    for p in 0..obs.len() {
        let x = obs.vertex[p] as usize;
        assert!(
            !(held_vertex[x] && obs.weight[p] > 0.0 && !is_held[p]),
            "vertex {x} is held back but observation {p} is fitted"
        );
        // Whole blocks: a vertex is held back exactly when its block's first one is.
        assert_eq!(held_vertex[x], held_vertex[x / block * block], "vertex {x}");
    }
    let usable = obs.weight.iter().filter(|&&a| a > 0.0).count();
    let got = held.len() as f64 / usable as f64;
    assert!(
        (got - fraction).abs() <= 0.03,
        "held-back fraction {got:.4}"
    );
    // A different seed draws different blocks.
    assert_ne!(held, validation_split_blocked(&obs, nv, fraction, block, 8));
}

/// The photo-half split holds back exactly the `α > 0` observations of the chosen
/// photos at vertices marked right, and nothing of the other photos. The rule is
/// deterministic (no draw), so the check is exact: with `grid_obs` every vertex is seen
/// by photos 0..4, photos 1 and 3 are chosen with vertices `x ≥ nv/2` (resp. odd `x`) on
/// the right, and the count is recomputed by brute force.
#[test]
fn photo_halves_split_holds_back_right_halves_of_chosen_photos() {
    let nv = 40;
    let obs = grid_obs(nv, 4);
    let halves = PhotoHalves {
        right: vec![
            (1, (0..nv).map(|x| x >= nv / 2).collect()),
            (3, (0..nv).map(|x| x % 2 == 1).collect()),
        ],
    };
    let held = photo_halves_split(&obs, &halves);
    assert!(held.windows(2).all(|w| w[0] < w[1]), "not sorted / unique");
    for &p in &held {
        let (k, x) = (obs.photo[p], obs.vertex[p] as usize);
        assert!(obs.weight[p] > 0.0, "held-back observation {p} has α = 0");
        assert!(k == 1 || k == 3, "observation {p} of unchosen photo {k}");
        assert!(
            (k == 1 && x >= nv / 2) || (k == 3 && x % 2 == 1),
            "observation {p} (photo {k}, vertex {x}) is not in the right half"
        );
    }
    let expected = (0..obs.len())
        .filter(|&p| {
            let (k, x) = (obs.photo[p], obs.vertex[p] as usize);
            obs.weight[p] > 0.0 && ((k == 1 && x >= nv / 2) || (k == 3 && x % 2 == 1))
        })
        .count();
    assert_eq!(held.len(), expected);
    assert!(photo_halves_split(&obs, &PhotoHalves::default()).is_empty());
}

/// [`grid_obs`] as one photo's, with a one-lobe transport on a 2 × 2 map: observation
/// `p` reads texel `p mod 4` with the value `base + step · p`.
fn one_photo(
    n_vertices: usize,
    per_vertex: usize,
    base: f64,
    step: f64,
) -> (Observations, crate::transport::Transport) {
    let mut obs = grid_obs(n_vertices, per_vertex);
    let n = obs.len();
    obs.photo_ranges = std::iter::once(0..n).collect();
    obs.photo.iter_mut().for_each(|k| *k = 0);
    let t = crate::transport::Transport {
        n_global: 2,
        n_basis: 1,
        n_obs: n,
        offsets: (0..=n).collect(),
        index: (0..n).map(|p| (p % 4) as u16).collect(),
        value: (0..n)
            .map(|p| crate::transport::TransportValue::from_f64(base + step * p as f64))
            .collect(),
    };
    (obs, t)
}

/// `training_score` is the relative RMSE of the prediction: with every observation the
/// model's own prediction times `1 + e` it is `e / (1 + e)` exactly (the residual is
/// `e ŷ`, the observation `(1 + e) ŷ`), whatever the transport. The prediction comes
/// from [`crate::solve::predict`], a separate code path; the tolerance 1e-6 is the
/// `f32` storage of the observations (relative rounding 6e-8).
#[test]
fn training_score_is_the_relative_rmse_of_a_scaled_prediction() {
    use crate::solve::{predict, Estimate};
    use crate::transport::Transport;
    let (nv, per) = (6, 3);
    let (mut obs, t) = one_photo(nv, per, 0.5, 0.1);
    let n = obs.len();
    let light = [
        vec![1.0, 2.0, 0.5, 3.0],
        vec![0.7; 4],
        vec![1.5, 0.2, 0.9, 1.1],
    ];
    let lambda = vec![vec![[0.8, 0.5, 0.3]], vec![[0.2, 0.6, 0.9]]];
    let weights: Vec<f64> = (0..nv * 2).map(|i| 0.1 + 0.15 * i as f64).collect();
    let est = Estimate::from_parts(vec![light.clone()], lambda.clone(), weights.clone());
    fn problem_of<'a>(obs: &'a Observations, t: &'a Transport, nv: usize) -> Problem<'a> {
        Problem {
            obs,
            transport: t,
            n_vertices: nv,
            n_photos: 1,
        }
    }
    let pred = predict(&problem_of(&obs, &t, nv), &est);
    let beta = crate::solve::beta_per_vertex(&lambda, &weights, nv);
    for e in [0.0, 0.1, -0.3] {
        for p in 0..n {
            obs.rgb[p] = pred[p].map(|v| ((1.0 + e) * v) as f32);
        }
        let got = training_score(
            &problem_of(&obs, &t, nv),
            &beta,
            std::slice::from_ref(&light),
        );
        let want = (e / (1.0_f64 + e)).abs();
        assert!((got - want).abs() <= 1e-6, "e = {e}: {got} against {want}");
    }
}

/// `validation_terms` are each observation's `α Σ_c (y − ŷ)²`: with every observation
/// the model's prediction (from [`crate::solve::predict`], a separate code path) times
/// `1 + e`, the term is `α e² Σ_c ŷ_c²` exactly, on any subset in its order; the
/// tolerance 1e-6 relative covers the `f32` storage of the observations (rounding
/// 6e-8 of `1.2 ŷ` is 3.6e-7 of the residual `0.2 ŷ`, 7.2e-7 of its square).
#[test]
fn validation_terms_are_each_observations_weighted_squared_residual() {
    use crate::solve::{predict, Estimate};
    let (nv, per) = (5, 4);
    let (obs, t) = one_photo(nv, per, 0.3, 0.05);
    let n = obs.len();
    let light = [
        vec![1.0, 0.4, 2.0, 0.6],
        vec![0.9; 4],
        vec![0.3, 1.2, 0.8, 1.6],
    ];
    let lambda = vec![vec![[0.7, 0.4, 0.2]]];
    let weights: Vec<f64> = (0..nv).map(|i| 0.5 + 0.2 * i as f64).collect();
    let est = Estimate::from_parts(vec![light.clone()], lambda.clone(), weights.clone());
    let problem = Problem {
        obs: &obs,
        transport: &t,
        n_vertices: nv,
        n_photos: 1,
    };
    let pred = predict(&problem, &est);
    let e = 0.2;
    let mut scaled = obs.clone();
    for p in 0..n {
        scaled.rgb[p] = pred[p].map(|v| ((1.0 + e) * v) as f32);
    }
    let problem = Problem {
        obs: &scaled,
        ..problem
    };
    let beta = crate::solve::beta_per_vertex(&lambda, &weights, nv);
    let idx: Vec<usize> = (0..n).rev().step_by(3).collect();
    let terms = validation_terms(&problem, &scaled, std::slice::from_ref(&light), &beta, &idx);
    assert_eq!(terms.len(), idx.len());
    for (&p, got) in idx.iter().zip(&terms) {
        let want = scaled.weight[p] as f64 * e * e * pred[p].iter().map(|v| v * v).sum::<f64>();
        assert!(
            (got - want).abs() <= 1e-6 * want.max(1e-12),
            "p = {p}: {got} against {want}"
        );
    }
}

/// `left_by_view` cuts each photo by the plane through its observed vertices' centroid
/// spanned by the mean viewing direction and world `y`: vertices on a line along `x`
/// seen from `+z` split at the centroid (left = `x` below it, since `z × y = −x`); seen
/// from `+y` (within 10° of up) the plane is spanned by `y` and `z` instead. Exact
/// (no vertex lies on a plane).
#[test]
fn left_by_view_splits_each_photo_at_its_centroid() {
    let positions: Vec<crate::Vec3> = (0..6)
        .map(|i| crate::Vec3::new(i as f64 + 0.5, 0.1 * i as f64, 0.0))
        .collect();
    let mut obs = Observations::default();
    for (k, dir) in [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]].iter().enumerate() {
        let lo = obs.len();
        for x in 0..6 {
            obs.vertex.push(x);
            obs.photo.push(k as u32);
            obs.rgb.push([0.5; 3]);
            obs.weight.push(1.0);
            obs.dir.push(*dir);
        }
        obs.photo_ranges.push(lo..obs.len());
    }
    let left = left_by_view(&obs, &positions);
    // Photo 0: centroid x = 3, right = z × y = −x, so left is x > 3.
    assert_eq!(&left[..6], &[false, false, false, true, true, true]);
    // Photo 1: d = y, right = y × z = x, so left is x < 3.
    assert_eq!(&left[6..], &[true, true, true, false, false, false]);
}

/// The fit's copy reads an overexposed observation as a bound only when asked, with the
/// paper's map, and at a vertex some un-clipped observation also reads: vertex 0 has one
/// value and one bound, vertex 1 only a bound (nothing would hold its weights from above).
#[test]
fn bounds_join_the_fit_only_where_a_value_also_reads_the_vertex() {
    let mut obs = grid_obs(2, 2);
    obs.weight = vec![1.0, 0.0, 0.0, 0.0];
    obs.clipped = vec![0, 0b001, 0b011, 0];
    obs.bound_weight = vec![0.0, 0.7, 0.9, 0.0];
    obs.photo_ranges = std::iter::once(0..4).collect();
    let t = crate::transport::Transport::default();
    let problem = Problem {
        obs: &obs,
        transport: &t,
        n_vertices: 2,
        n_photos: 1,
    };
    let weights = |opts: &EstimateOptions| {
        let held = HeldBack::new(&problem, opts);
        held.fit_problem(&problem).obs.weight.clone()
    };
    let base = EstimateOptions {
        validation_fraction: 0.0,
        ..EstimateOptions::default()
    };
    assert_eq!(weights(&base), vec![1.0, 0.0, 0.0, 0.0], "off by default");
    let on = EstimateOptions {
        clipped_bounds: true,
        ..base.clone()
    };
    assert_eq!(weights(&on), vec![1.0, 0.7, 0.0, 0.0]);
    // Every light model reads them: the shared light and the sun and sky as the paper's map.
    let shared = EstimateOptions {
        light_groups: Some(crate::solve::options::LightGroups {
            group: vec![0],
            source: "test".into(),
        }),
        ..on.clone()
    };
    let sky = EstimateOptions {
        light_sky: Some(crate::solve::light::sky::SkyOptions::default()),
        ..on.clone()
    };
    for opts in [&shared, &sky] {
        assert_eq!(weights(opts), vec![1.0, 0.7, 0.0, 0.0]);
    }
}
