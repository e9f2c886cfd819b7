//! Initial materials: k-means on hue/saturation features of colours with known clusters.

#![allow(clippy::needless_range_loop)]

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use relight_cpc::solve::cluster::initial_materials;

/// Three materials (red, green, blue-grey), each shaded by a random brightness in
/// [0.2, 1] and jittered by 2% per channel: shading must not split a material.
fn three_materials(n_each: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<usize>) {
    let base = [[0.8, 0.1, 0.1], [0.1, 0.7, 0.15], [0.3, 0.35, 0.6]];
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut cols = Vec::new();
    let mut truth = Vec::new();
    for i in 0..3 * n_each {
        let m = i % 3;
        let shade = 0.2 + 0.8 * rng.random::<f64>();
        let c = base[m].map(|v| v * shade * (1.0 + 0.02 * (rng.random::<f64>() - 0.5)));
        cols.push(c);
        truth.push(m);
    }
    (cols, truth)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[test]
fn recovers_known_clusters_with_median_albedo() {
    let (cols, truth) = three_materials(200, 1);
    let seen = vec![true; cols.len()];
    let im = initial_materials(&cols, &seen, 3, 42).unwrap();
    assert_eq!(im.albedo.len(), 3);
    // A bijection between found and true clusters with every vertex assigned correctly.
    let mut map = [usize::MAX; 3];
    for (x, &t) in truth.iter().enumerate() {
        if map[t] == usize::MAX {
            map[t] = im.labels[x];
        }
        assert_eq!(im.labels[x], map[t], "vertex {x}");
    }
    let mut used = map.to_vec();
    used.sort();
    used.dedup();
    assert_eq!(used.len(), 3);
    // Median colour per cluster, computed here from the truth labels.
    for t in 0..3 {
        for c in 0..3 {
            let want = median(
                cols.iter()
                    .zip(&truth)
                    .filter(|(_, &m)| m == t)
                    .map(|(v, _)| v[c])
                    .collect(),
            );
            assert!((im.albedo[map[t]][c] - want).abs() < 1e-12);
        }
    }
    // Weights: rows sum to one, the largest on the vertex's own cluster, near one-hot for
    // these well-separated clusters (spread 0.05 vs centre distances ≳ 1).
    for x in 0..cols.len() {
        let w = &im.weights[x * 3..x * 3 + 3];
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(w[im.labels[x]] > 0.99, "vertex {x}: {w:?}");
    }
}

#[test]
fn deterministic_for_a_seed() {
    let (cols, _) = three_materials(100, 2);
    let seen = vec![true; cols.len()];
    let a = initial_materials(&cols, &seen, 4, 9).unwrap();
    let b = initial_materials(&cols, &seen, 4, 9).unwrap();
    assert_eq!(a.labels, b.labels);
    assert_eq!(a.weights, b.weights);
    assert_eq!(a.albedo, b.albedo);
}

#[test]
fn identical_colours_unseen_vertices_and_too_many_clusters() {
    // All colours identical: one material, no panic, no NaN.
    let cols = vec![[0.5, 0.4, 0.3]; 50];
    let mut seen = vec![true; 50];
    seen[7] = false;
    let im = initial_materials(&cols, &seen, 6, 1).unwrap();
    assert_eq!(im.albedo.len(), 1);
    assert!(im.weights.iter().all(|w| (w - 1.0).abs() < 1e-12));
    // Two distinct colours, k = 5: at most two non-empty materials, each used.
    let cols: Vec<[f64; 3]> = (0..40)
        .map(|i| {
            if i < 30 {
                [0.9, 0.1, 0.1]
            } else {
                [0.1, 0.1, 0.9]
            }
        })
        .collect();
    let mut seen = vec![true; 40];
    seen[0] = false;
    let im = initial_materials(&cols, &seen, 5, 3).unwrap();
    assert_eq!(im.albedo.len(), 2);
    let kk = im.albedo.len();
    for c in 0..kk {
        assert!(im.labels.contains(&c), "cluster {c} empty");
    }
    // The unseen vertex: uniform weights, the label of the larger (red) cluster.
    assert!(im.weights[..kk].iter().all(|&w| (w - 0.5).abs() < 1e-12));
    assert_eq!(im.labels[0], im.labels[1]);
    assert!(im.weights.iter().all(|w| w.is_finite()));
    // Nothing seen, k = 0, NaN colours: errors.
    assert!(initial_materials(&cols, &[false; 40], 2, 0).is_err());
    assert!(initial_materials(&cols, &[true; 40], 0, 0).is_err());
    let mut bad = cols.clone();
    bad[3] = [f64::NAN, 0.0, 0.0];
    assert!(initial_materials(&bad, &[true; 40], 2, 0).is_err());
}
