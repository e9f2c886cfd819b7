//! Transient occluders (a person, a car, scaffolding in some of the photos): a per-photo,
//! spatially coherent outlier mask over the observations, from the residuals `r = y − ŷ`
//! of a fit.
//!
//! **Score.** Per channel `c`, the robust scale of IRLS ([`crate::solve::Robust`]) over
//! ALL photos' observations with `α > 0`: `σ_c = max(1.4826 · median_p |r_{p,c}|,
//! floor · rms_p(y_{p,c}))`; the observation's score is `s_p = max_c |r_{p,c}| / σ_c`.
//! One scale for all photos, not IRLS's per-photo one: an occluder covering a fifth of a
//! photo inflates that photo's own median residual and would hide itself.
//!
//! **Excess over the vertex's consensus.** The mask thresholds `e_p = max(0, s_p − m_x)`,
//! `m_x` the median score of vertex `x`'s observations over all photos (α > 0): an
//! observation counts as an outlier only where it disagrees with what the other photos of
//! the same vertex agree on. Where the fit is wrong at `x` in every photo (its
//! reflectance pulled by an occluder in some of them, a highlight it cannot make yet), the
//! excess stays small in the clean photos; a vertex seen once has no excess.
//!
//! **Mask** (per photo, hysteresis over the mesh's vertex graph, as in Canny's edge
//! linking, "A Computational Approach to Edge Detection", PAMI 1986):
//! 1. *seeds*: `s_p ≥ seed` and at least `min_neighbours` of the vertex's mesh neighbours
//!    observed in the same photo also score `≥ seed`. A lone large residual (noise, a glint)
//!    is left to IRLS; an occluder covers a patch of neighbouring vertices;
//! 2. *growth*: `rings` times, every observation of the photo with `s ≥ grow` next to a
//!    masked one joins (the occluder's blurred rim, partly mixed with the object).
//!
//! IRLS alone (per observation, Huber) bounds each outlier's influence but keeps it in the
//! lighting and material steps, and misses the rim; masked observations get `α = 0`.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use super::Observations;
use crate::stats::median;

/// Tunables of the mask (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutlierOptions {
    /// Seed threshold on the score (robust scales).
    pub seed: f64,
    /// Growth threshold on the score.
    pub grow: f64,
    /// Neighbours above `seed` a seed needs.
    pub min_neighbours: usize,
    /// Growth rings.
    pub rings: usize,
    /// Floor of the scale relative to the photo's RMS radiance per channel.
    pub floor: f64,
}

impl OutlierOptions {
    /// `seed` 5 and `grow` 2.5 robust scales, 2 neighbours, 2 rings, and `floor` (the run
    /// passes the estimator's robust floor, [`crate::solve::ROBUST_FLOOR`] by default, so
    /// that a seed is at least a fixed fraction of the photos' RMS radiance off). Measured
    /// on the built-in example with planted occluders (`tests/suite/realphoto_effects.rs`):
    /// at these thresholds the pass masks 9% of the clean photos' object pixels, the short
    /// pilot's own misfit at shadows and highlights.
    pub fn with_floor(floor: f64) -> Self {
        OutlierOptions {
            seed: 5.0,
            grow: 2.5,
            min_neighbours: 2,
            rings: 2,
            floor,
        }
    }
}

/// Vertex adjacency of a triangle mesh, compressed rows: the neighbours of `x` are
/// `list[start[x]..start[x + 1]]`, sorted, without repeats.
#[derive(Debug, Clone)]
pub struct Adjacency {
    pub start: Vec<usize>,
    pub list: Vec<u32>,
}

impl Adjacency {
    /// From faces over `n_vertices` vertices (indices out of range are skipped).
    pub fn from_faces(faces: &[[u32; 3]], n_vertices: usize) -> Self {
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); n_vertices];
        for f in faces {
            for j in 0..3 {
                let (a, b) = (f[j] as usize, f[(j + 1) % 3] as usize);
                if a < n_vertices && b < n_vertices && a != b {
                    lists[a].push(b as u32);
                    lists[b].push(a as u32);
                }
            }
        }
        let mut start = Vec::with_capacity(n_vertices + 1);
        let mut list = Vec::new();
        start.push(0);
        for mut l in lists {
            l.sort_unstable();
            l.dedup();
            list.extend(l);
            start.push(list.len());
        }
        Adjacency { start, list }
    }

    /// Neighbours of `x`.
    pub fn of(&self, x: usize) -> &[u32] {
        &self.list[self.start[x]..self.start[x + 1]]
    }
}

/// The score `s_p` of every observation (module docs); 0 where `α = 0`.
pub fn scores(obs: &Observations, pred: &[[f64; 3]], floor: f64) -> Vec<f32> {
    let mut out = vec![0.0f32; obs.len()];
    {
        let used: Vec<usize> = (0..obs.len()).filter(|&p| obs.weight[p] > 0.0).collect();
        if used.is_empty() {
            return out;
        }
        let mut sigma = [0.0f64; 3];
        for (c, s) in sigma.iter_mut().enumerate() {
            let mut ab: Vec<f64> = used
                .iter()
                .map(|&p| (obs.rgb[p][c] as f64 - pred[p][c]).abs())
                .collect();
            let mad = 1.4826 * median(&mut ab).unwrap_or(0.0);
            let rms = (used
                .iter()
                .map(|&p| (obs.rgb[p][c] as f64).powi(2))
                .sum::<f64>()
                / used.len() as f64)
                .sqrt();
            *s = mad.max(floor * rms);
        }
        for &p in &used {
            let s = (0..3)
                .map(|c| {
                    let r = (obs.rgb[p][c] as f64 - pred[p][c]).abs();
                    if sigma[c] > 0.0 {
                        r / sigma[c]
                    } else if r > 0.0 {
                        f64::INFINITY
                    } else {
                        0.0
                    }
                })
                .fold(0.0, f64::max);
            out[p] = s.min(f32::MAX as f64) as f32;
        }
    }
    out
}

/// `e_p = max(0, s_p − m_x)` (module docs), 0 where `α = 0`.
pub fn excess_over_vertex_median(obs: &Observations, score: &[f32], n_vertices: usize) -> Vec<f32> {
    let mut lists: Vec<Vec<f64>> = vec![Vec::new(); n_vertices];
    for p in 0..obs.len() {
        let x = obs.vertex[p] as usize;
        if obs.weight[p] > 0.0 && x < n_vertices {
            lists[x].push(score[p] as f64);
        }
    }
    let med: Vec<f64> = lists.iter_mut().map(|l| median(l).unwrap_or(0.0)).collect();
    (0..obs.len())
        .map(|p| {
            let x = obs.vertex[p] as usize;
            if obs.weight[p] > 0.0 && x < n_vertices {
                (score[p] as f64 - med[x]).max(0.0) as f32
            } else {
                0.0
            }
        })
        .collect()
}

/// The mask of one photo's observations (`vertex`, `score` of its range; module docs).
/// `slot` is scratch of one entry per vertex, all `u32::MAX`, and is left so.
fn photo_mask(
    vertex: &[u32],
    score: &[f32],
    adj: &Adjacency,
    opts: &OutlierOptions,
    slot: &mut [u32],
) -> Vec<bool> {
    for (q, &x) in vertex.iter().enumerate() {
        slot[x as usize] = q as u32;
    }
    let at = |x: u32, slot: &[u32]| -> Option<usize> {
        let q = slot[x as usize];
        (q != u32::MAX).then_some(q as usize)
    };
    let high: Vec<bool> = score.iter().map(|&s| s as f64 >= opts.seed).collect();
    let mut mask: Vec<bool> = (0..vertex.len())
        .map(|q| {
            high[q]
                && adj
                    .of(vertex[q] as usize)
                    .iter()
                    .filter(|&&n| at(n, slot).is_some_and(|j| high[j]))
                    .count()
                    >= opts.min_neighbours
        })
        .collect();
    for _ in 0..opts.rings {
        let join: Vec<usize> = (0..vertex.len())
            .filter(|&q| {
                !mask[q]
                    && score[q] as f64 >= opts.grow
                    && adj
                        .of(vertex[q] as usize)
                        .iter()
                        .any(|&n| at(n, slot).is_some_and(|j| mask[j]))
            })
            .collect();
        if join.is_empty() {
            break;
        }
        for q in join {
            mask[q] = true;
        }
    }
    for &x in vertex {
        slot[x as usize] = u32::MAX;
    }
    mask
}

/// The outlier mask of every observation (module docs), from its `score`s.
pub fn coherent_mask(
    obs: &Observations,
    score: &[f32],
    adj: &Adjacency,
    opts: &OutlierOptions,
) -> Vec<bool> {
    let n_vertices = adj.start.len().saturating_sub(1);
    let parts: Vec<Vec<bool>> = obs
        .photo_ranges
        .par_iter()
        .map_init(
            || vec![u32::MAX; n_vertices],
            |slot, r| {
                if obs.vertex[r.clone()]
                    .iter()
                    .any(|&x| x as usize >= n_vertices)
                {
                    return vec![false; r.len()];
                }
                photo_mask(&obs.vertex[r.clone()], &score[r.clone()], adj, opts, slot)
            },
        )
        .collect();
    let mut mask = vec![false; obs.len()];
    for (r, part) in obs.photo_ranges.iter().zip(parts) {
        mask[r.clone()].copy_from_slice(&part);
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A path graph 0 – 1 – … – 9 (faces of a strip) observed in one photo.
    fn strip(score: &[f32]) -> (Observations, Adjacency) {
        let n = score.len();
        let faces: Vec<[u32; 3]> = (0..n as u32 - 2).map(|i| [i, i + 1, i + 2]).collect();
        let adj = Adjacency::from_faces(&faces, n);
        let obs = Observations {
            vertex: (0..n as u32).collect(),
            photo: vec![0; n],
            rgb: vec![[0.5; 3]; n],
            weight: vec![1.0; n],
            dir: vec![[0.0, 0.0, 1.0]; n],
            photo_ranges: std::iter::once(0..n).collect(),
            clipped: Vec::new(),
            bound_weight: Vec::new(),
        };
        (obs, adj)
    }

    #[test]
    fn adjacency_of_a_strip() {
        let (_, adj) = strip(&[0.0; 5]);
        assert_eq!(adj.of(0), &[1, 2]);
        assert_eq!(adj.of(2), &[0, 1, 3, 4]);
        assert_eq!(adj.of(4), &[2, 3]);
    }

    #[test]
    fn seeds_need_neighbours_and_growth_follows_hysteresis() {
        // Vertex i's neighbours in the strip: i ± 1, i ± 2. A lone 9 at 1 (its neighbours
        // score 0) is no seed; 7, 8, 9 at 5..8 are seeds (each has ≥ 2 high neighbours);
        // 3.0 at 4 and 9 and 4.0 at 10 join in the first ring (≥ grow, next to a seed);
        // 2.0 at 3 stays out (below grow), and so does the lone 9 at 1.
        let score = [0.0, 9.0, 0.0, 2.0, 3.0, 7.0, 8.0, 9.0, 6.0, 3.0, 4.0, 0.0];
        let (obs, adj) = strip(&score);
        let o = OutlierOptions {
            seed: 5.0,
            grow: 2.5,
            ..OutlierOptions::with_floor(0.0)
        };
        let m = coherent_mask(&obs, &score, &adj, &o);
        let masked: Vec<usize> = (0..score.len()).filter(|&i| m[i]).collect();
        assert_eq!(masked, vec![4, 5, 6, 7, 8, 9, 10]);
        // Without growth only the seeds.
        let o = OutlierOptions { rings: 0, ..o };
        let m = coherent_mask(&obs, &score, &adj, &o);
        assert_eq!(
            (0..score.len()).filter(|&i| m[i]).collect::<Vec<_>>(),
            vec![5, 6, 7, 8]
        );
    }

    #[test]
    fn excess_is_over_the_vertex_median_across_photos() {
        // Vertex 0 in three photos scoring 1, 2, 9 → median 2: excess 0, 0, 7; vertex 1
        // once (score 8): excess 0; vertex 2's observation at α = 0: 0.
        let obs = Observations {
            vertex: vec![0, 1, 0, 0, 2],
            photo: vec![0, 0, 1, 2, 2],
            rgb: vec![[0.0; 3]; 5],
            weight: vec![1.0, 1.0, 1.0, 1.0, 0.0],
            dir: vec![[0.0, 0.0, 1.0]; 5],
            photo_ranges: vec![0..2, 2..3, 3..5],
            clipped: Vec::new(),
            bound_weight: Vec::new(),
        };
        let e = excess_over_vertex_median(&obs, &[1.0, 8.0, 2.0, 9.0, 5.0], 3);
        assert_eq!(e, vec![0.0, 0.0, 0.0, 7.0, 0.0]);
    }

    #[test]
    fn scores_use_the_mad_or_the_floor() {
        // One photo, red residuals 0.01 × (1, −1, 1, −1, 1, −1, 1, 0.5 → the last is 0.5):
        // median |r| = 0.01, σ = 1.4826 · 0.01 (the floor 0.05 · rms(y) with y = 0.1 is
        // 0.005); green and blue predicted exactly: σ = the floor, residual 0.
        let n = 8;
        let mut obs = strip(&vec![0.0; n]).0;
        obs.rgb = vec![[0.1, 0.1, 0.1]; n];
        let mut pred = vec![[0.1, 0.1, 0.1]; n];
        for (p, pr) in pred.iter_mut().enumerate().take(7) {
            pr[0] = 0.1 + if p % 2 == 0 { 0.01 } else { -0.01 };
        }
        pred[7][0] = 0.6;
        let s = scores(&obs, &pred, 0.05);
        let sigma = 1.4826 * 0.01;
        for p in 0..7 {
            assert!((s[p] as f64 - 0.01 / sigma).abs() < 1e-4, "{p}: {}", s[p]);
        }
        assert!((s[7] as f64 - 0.5 / sigma).abs() < 1e-2, "{}", s[7]);
    }
}
