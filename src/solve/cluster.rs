//! Initial materials (paper Sec. 5.2, last paragraph): cluster the per-vertex mean colours.
//!
//! Each seen vertex's mean linear RGB colour goes to HSV (`H ∈ [0,1)`, `S = (max−min)/max`,
//! `V = max`; `H = 0` for greys) and then to the feature `(cos 2πH, sin 2πH, S)` — hue on
//! the unit circle so that red at `H ≈ 0` and `H ≈ 1` are close, brightness left out so
//! shading does not split a material. k-means (linfa-clustering, Lloyd iterations) from a
//! seeded k-means++ start (several starts, the lowest inertia kept) gives K clusters; each is
//! a material whose Lambertian weight is the component-wise median colour of its members.
//!
//! Blending weights from the distances `d_k(x)` to the centroids:
//! `w_k(x) ∝ exp(−d_k² / (2 s²))`, normalised to sum to one, with `s` the root-mean-square
//! distance of the vertices to their own centroid (floored at 0.05 so that tight clusters
//! still give near one-hot weights rather than NaN). Vertices seen by no photo get uniform
//! weights and the label of the largest cluster.
//!
//! When the colours have fewer than `k` distinct features, fewer materials are returned
//! (`albedo.len()` is the count); a cluster that k-means leaves empty is dropped likewise.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use crate::stats::median;
use crate::{Error, Result};
use linfa::prelude::*;
use linfa::DatasetBase;
use linfa_clustering::{KMeans, KMeansInit};
use ndarray::Array2;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// The clustering result: the start of the material estimation.
#[derive(Debug, Clone)]
pub struct InitialMaterials {
    /// Cluster of every vertex (`V` entries; unseen vertices: the largest cluster).
    pub labels: Vec<usize>,
    /// Median linear RGB colour of every cluster (`K` entries): its Lambertian weight.
    pub albedo: Vec<[f64; 3]>,
    /// Blending weights `w_k(x)`, row-major `V × K`, each row summing to one.
    pub weights: Vec<f64>,
    /// Cluster centres in feature space `(cos 2πH, sin 2πH, S)`.
    pub centroids: Vec<[f64; 3]>,
}

/// HSV of a linear RGB colour: `(H ∈ [0,1), S ∈ [0,1], V)`; `H = 0` when `S = 0`.
pub fn rgb_to_hsv(rgb: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = rgb.map(|v| v.max(0.0));
    let max = r.max(g).max(b);
    let min = r.min(g).min(b);
    let delta = max - min;
    let s = if max > 0.0 { delta / max } else { 0.0 };
    let h = if delta <= 0.0 {
        0.0
    } else if max == r {
        ((g - b) / delta).rem_euclid(6.0) / 6.0
    } else if max == g {
        ((b - r) / delta + 2.0) / 6.0
    } else {
        ((r - g) / delta + 4.0) / 6.0
    };
    [h.rem_euclid(1.0), s, max]
}

/// The clustering feature `(cos 2πH, sin 2πH, S)` of a linear RGB colour.
pub fn hue_feature(rgb: [f64; 3]) -> [f64; 3] {
    let [h, s, _] = rgb_to_hsv(rgb);
    let a = 2.0 * std::f64::consts::PI * h;
    [a.cos(), a.sin(), s]
}

fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum()
}

/// k-means++ seeding (Arthur & Vassilvitskii 2007) over distinct points, seeded.
fn kmeans_pp(points: &[[f64; 3]], k: usize, rng: &mut Pcg64) -> Vec<[f64; 3]> {
    let mut centres = vec![points[rng.random_range(0..points.len())]];
    let mut d2: Vec<f64> = points.iter().map(|p| dist2(p, &centres[0])).collect();
    while centres.len() < k {
        let total: f64 = d2.iter().sum();
        if total <= 0.0 {
            break;
        }
        let mut t = rng.random::<f64>() * total;
        let mut pick = points.len() - 1;
        for (i, &d) in d2.iter().enumerate() {
            if t < d {
                pick = i;
                break;
            }
            t -= d;
        }
        let c = points[pick];
        centres.push(c);
        for (i, p) in points.iter().enumerate() {
            d2[i] = d2[i].min(dist2(p, &c));
        }
    }
    centres
}

/// Initial materials from per-vertex mean linear colours (`mean_rgb`, `V` entries; only
/// vertices with `seen[x]` count), at most `k` clusters, deterministic for a given `seed`.
/// Steps: hue features of the seen vertices, k-means (best of 8 k-means++ starts), empty
/// clusters dropped, each cluster's median colour, soft weights from the distances.
///
/// Errors: `Config` when `k == 0` or the slices differ in length; `Numeric` when no vertex
/// is seen or a seen colour is not finite.
pub fn initial_materials(
    mean_rgb: &[[f64; 3]],
    seen: &[bool],
    k: usize,
    seed: u64,
) -> Result<InitialMaterials> {
    let idx = seen_vertices(mean_rgb, seen, k)?;
    let feats: Vec<[f64; 3]> = idx.iter().map(|&x| hue_feature(mean_rgb[x])).collect();
    let centres = kmeans_best_of(&feats, k, seed)?;
    // Assign, drop empty clusters, re-assign.
    let mut count = vec![0usize; centres.len()];
    for f in &feats {
        count[nearest(f, &centres)] += 1;
    }
    let centres: Vec<[f64; 3]> = centres
        .into_iter()
        .zip(&count)
        .filter(|(_, &n)| n > 0)
        .map(|(c, _)| c)
        .collect();
    let member: Vec<usize> = feats.iter().map(|f| nearest(f, &centres)).collect();
    let albedo = cluster_medians(mean_rgb, &idx, &member, centres.len());
    let (labels, weights) = soft_weights(mean_rgb.len(), &idx, &feats, &member, &centres);
    Ok(InitialMaterials {
        labels,
        albedo,
        weights,
        centroids: centres,
    })
}

/// The seen vertices, after checking `k ≥ 1`, the lengths and the colours.
fn seen_vertices(mean_rgb: &[[f64; 3]], seen: &[bool], k: usize) -> Result<Vec<usize>> {
    if k == 0 {
        return Err(Error::Internal(
            "the number of materials must be at least 1".into(),
        ));
    }
    if mean_rgb.len() != seen.len() {
        return Err(Error::Internal(format!(
            "{} vertex colours but {} seen flags",
            mean_rgb.len(),
            seen.len()
        )));
    }
    let idx: Vec<usize> = (0..seen.len()).filter(|&x| seen[x]).collect();
    if idx.is_empty() {
        return Err(Error::Numeric {
            stage: "initial materials".into(),
            message: "no vertex is seen by any photo".into(),
        });
    }
    if let Some(&x) = idx
        .iter()
        .find(|&&x| mean_rgb[x].iter().any(|v| !v.is_finite()))
    {
        return Err(Error::Numeric {
            stage: "initial materials".into(),
            message: format!("vertex {x} has a non-finite mean colour {:?}", mean_rgb[x]),
        });
    }
    Ok(idx)
}

/// k-means on `feats` (linfa), from 8 k-means++ starts over the distinct features, the
/// centroids of the lowest inertia kept; at most `k` centres (as many as there are
/// distinct features).
fn kmeans_best_of(feats: &[[f64; 3]], k: usize, seed: u64) -> Result<Vec<[f64; 3]>> {
    // Distinct features (bitwise), in first-seen order: k-means++ cannot place more centres
    // than there are distinct points.
    let mut distinct: Vec<[f64; 3]> = feats.to_vec();
    distinct.sort_by(|a, b| {
        a.iter()
            .zip(b)
            .map(|(x, y)| x.total_cmp(y))
            .find(|o| o.is_ne())
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    distinct.dedup();
    let k_eff = k.min(distinct.len());

    let records = Array2::from_shape_fn((feats.len(), 3), |(i, j)| feats[i][j]);
    let data = DatasetBase::from(records.clone());
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut best: Option<(f64, Vec<[f64; 3]>)> = None;
    for _ in 0..8 {
        let start = kmeans_pp(&distinct, k_eff, &mut rng);
        let kk = start.len();
        let init = Array2::from_shape_fn((kk, 3), |(i, j)| start[i][j]);
        let model = KMeans::params(kk)
            .init_method(KMeansInit::Precomputed(init))
            .n_runs(1)
            .max_n_iterations(300)
            .tolerance(1e-10)
            .fit(&data)
            .map_err(|e| Error::Numeric {
                stage: "initial materials (k-means)".into(),
                message: e.to_string(),
            })?;
        let c = model.centroids();
        let centres: Vec<[f64; 3]> = (0..kk).map(|i| [c[(i, 0)], c[(i, 1)], c[(i, 2)]]).collect();
        let inertia: f64 = feats
            .iter()
            .map(|f| {
                centres
                    .iter()
                    .map(|c| dist2(f, c))
                    .fold(f64::INFINITY, f64::min)
            })
            .sum();
        if centres.iter().flatten().all(|v| v.is_finite())
            && best.as_ref().is_none_or(|(bi, _)| inertia < *bi)
        {
            best = Some((inertia, centres));
        }
    }
    best.map(|(_, centres)| centres)
        .ok_or_else(|| Error::Numeric {
            stage: "initial materials (k-means)".into(),
            message: "k-means produced no finite centroids".into(),
        })
}

/// Index of the centre nearest `f` (the first of equals).
fn nearest(f: &[f64; 3], cs: &[[f64; 3]]) -> usize {
    let mut bi = 0;
    for (i, c) in cs.iter().enumerate() {
        if dist2(f, c) < dist2(f, &cs[bi]) {
            bi = i;
        }
    }
    bi
}

/// Each cluster's median colour per channel over its member vertices (`idx[i]` in
/// cluster `member[i]`).
fn cluster_medians(
    mean_rgb: &[[f64; 3]],
    idx: &[usize],
    member: &[usize],
    kk: usize,
) -> Vec<[f64; 3]> {
    let mut albedo = vec![[0.0; 3]; kk];
    for (c, alb) in albedo.iter_mut().enumerate() {
        for (ch, a) in alb.iter_mut().enumerate() {
            let mut vals: Vec<f64> = idx
                .iter()
                .zip(member)
                .filter(|(_, &m)| m == c)
                .map(|(&x, _)| mean_rgb[x][ch])
                .collect();
            // Every cluster kept has members (empty ones are dropped).
            *a = median(&mut vals).unwrap_or(0.0);
        }
    }
    albedo
}

/// Per vertex its label and soft weights `w_c ∝ exp(−d_c² / 2s²)` from its feature's
/// squared distances to the centres, `s²` the mean squared distance to the own centre
/// (at least 0.05²); unseen vertices get uniform weights and the largest cluster's label.
fn soft_weights(
    nv: usize,
    idx: &[usize],
    feats: &[[f64; 3]],
    member: &[usize],
    centres: &[[f64; 3]],
) -> (Vec<usize>, Vec<f64>) {
    let kk = centres.len();
    let spread2 = feats
        .iter()
        .zip(member)
        .map(|(f, &m)| dist2(f, &centres[m]))
        .sum::<f64>()
        / feats.len() as f64;
    let s2 = spread2.max(0.05 * 0.05);
    let mut weights = vec![1.0 / kk as f64; nv * kk];
    let mut count = vec![0usize; kk];
    for &m in member {
        count[m] += 1;
    }
    let largest = (0..kk)
        .max_by_key(|&c| (count[c], usize::MAX - c))
        .unwrap_or(0);
    let mut labels = vec![largest; nv];
    for ((&x, f), &m) in idx.iter().zip(feats).zip(member) {
        labels[x] = m;
        let d2: Vec<f64> = centres.iter().map(|c| dist2(f, c)).collect();
        let dmin = d2.iter().copied().fold(f64::INFINITY, f64::min);
        // Shift by the nearest distance so the largest weight is exp(0) = 1: no underflow.
        let e: Vec<f64> = d2
            .iter()
            .map(|d| (-(d - dmin) / (2.0 * s2)).exp())
            .collect();
        let sum: f64 = e.iter().sum();
        for c in 0..kk {
            weights[x * kk + c] = e[c] / sum;
        }
    }
    (labels, weights)
}

/// Where the start's blending weights come from (`--start-weights`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StartWeights {
    /// From the hue distances to the cluster centres (the paper's clustering).
    Clustered,
    /// Unmixed from each vertex's mean colour ([`unmixed_weights`]).
    Unmixed,
    /// Both starts fitted, the one with the lower validation score kept (one more fit).
    Both,
}

impl StartWeights {
    /// The flag's word: `clustered`, `unmixed` or `both`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "clustered" => Ok(StartWeights::Clustered),
            "unmixed" => Ok(StartWeights::Unmixed),
            "both" => Ok(StartWeights::Both),
            _ => Err(Error::Config(format!(
                "--start-weights {s}: expected clustered, unmixed or both"
            ))),
        }
    }
}

/// The start's blending weights unmixed from each seen vertex's mean colour `c_x` over the
/// materials' colours `a_k` (`init.albedo`), not in the paper: a vertex where two materials
/// blend shows `c_x = s_x Σ_k w_k a_k` (its shading `s_x`), so
/// `v = argmin_{v ≥ 0} ‖Σ_k v_k a_k − c_x‖²` (non-negative least squares, Lawson–Hanson)
/// gives `w = v / Σ_k v_k`, where the clustered weights ([`initial_materials`]) come from
/// hue distances alone. Returns the weights (row-major `V × K`) and each vertex's largest;
/// a vertex unseen, or whose `v` is 0, keeps its clustered weights.
pub fn unmixed_weights(
    init: &InitialMaterials,
    mean_rgb: &[[f64; 3]],
    seen: &[bool],
) -> (Vec<f64>, Vec<usize>) {
    use crate::solve::qp::{nnls, NnlsOptions};
    use nalgebra::{DMatrix, DVector};
    let kk = init.albedo.len();
    let a = DMatrix::from_fn(3, kk, |c, k| init.albedo[k][c]);
    let ata = a.transpose() * &a;
    let mut weights = init.weights.clone();
    let mut labels = init.labels.clone();
    for x in (0..seen.len()).filter(|&x| seen[x]) {
        let atb = a.transpose() * DVector::from_row_slice(&mean_rgb[x]);
        let Ok(v) = nnls(&ata, &atb, &NnlsOptions::default()) else {
            continue;
        };
        let total = v.sum();
        if !(total > 0.0 && total.is_finite()) {
            continue;
        }
        for k in 0..kk {
            weights[x * kk + k] = v[k] / total;
        }
        labels[x] = (0..kk).max_by(|&i, &j| v[i].total_cmp(&v[j])).unwrap_or(0);
    }
    (weights, labels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unmixing_recovers_a_shaded_blend_of_the_materials_colours() {
        // c = s (w a + (1 − w) b) with any shading s > 0: NNLS finds v = s (w, 1 − w)
        // exactly (two independent colours in RGB), so w comes back to rounding (1e-9:
        // the normal equations square a condition number of order 10). A colour outside
        // the cone of a and b gets its nearest non-negative mix; an unseen vertex keeps
        // its clustered weights.
        let (a, b) = ([0.8, 0.45, 0.2], [0.2, 0.3, 0.6]);
        let blends = [(1.0, 0.3), (0.7, 0.05), (0.2, 0.55), (1.7, 1.0)];
        let mut mean_rgb: Vec<[f64; 3]> = blends
            .iter()
            .map(|&(s, w)| [0, 1, 2].map(|c| s * (w * a[c] + (1.0 - w) * b[c])))
            .collect();
        mean_rgb.push([1.0, 0.0, 0.0]);
        mean_rgb.push([0.5, 0.5, 0.5]);
        let n = mean_rgb.len();
        let mut seen = vec![true; n];
        seen[n - 1] = false;
        let init = InitialMaterials {
            labels: vec![0; n],
            albedo: vec![a, b],
            weights: vec![0.5; 2 * n],
            centroids: vec![[0.0; 3]; 2],
        };
        let (w, labels) = unmixed_weights(&init, &mean_rgb, &seen);
        for (x, &(_, wa)) in blends.iter().enumerate() {
            assert!(
                (w[2 * x] - wa).abs() < 1e-9,
                "vertex {x}: {} vs {wa}",
                w[2 * x]
            );
            assert!((w[2 * x] + w[2 * x + 1] - 1.0).abs() < 1e-12);
            assert_eq!(labels[x], usize::from(wa < 0.5));
        }
        // Pure red lies outside the cone: the mix nearest it is mostly the orange colour.
        assert!(w[2 * 4] > 0.5 && w[2 * 4 + 1] >= 0.0 && labels[4] == 0);
        assert_eq!(&w[2 * 5..], &[0.5, 0.5]);
    }

    #[test]
    fn hsv_of_primaries_and_greys() {
        // Closed forms: red H=0, green 1/3, blue 2/3, grey S=0.
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        let r = rgb_to_hsv([1.0, 0.0, 0.0]);
        assert!(close(r[0], 0.0) && close(r[1], 1.0) && close(r[2], 1.0));
        assert!(close(rgb_to_hsv([0.0, 0.5, 0.0])[0], 1.0 / 3.0));
        assert!(close(rgb_to_hsv([0.0, 0.0, 0.2])[0], 2.0 / 3.0));
        let g = rgb_to_hsv([0.3, 0.3, 0.3]);
        assert!(close(g[0], 0.0) && close(g[1], 0.0));
        assert_eq!(rgb_to_hsv([0.0; 3]), [0.0, 0.0, 0.0]);
        // Magenta-ish red just below H = 1 lies close to red on the hue circle.
        let f1 = hue_feature([1.0, 0.0, 0.05]);
        let f0 = hue_feature([1.0, 0.05, 0.0]);
        assert!(dist2(&f0, &f1) < 0.02);
    }
}
