//! Stratified subsample of one photo's observations for the lighting step.
//!
//! The lighting step of a photo (Eq. 10) has `3 n²` unknowns (12,288 at 64²) against every
//! observation of the photo (25,000 at 100K vertices, 13 photos); its data term is a sum
//! over observations, `Σ_p α_p ω_p (y_p − ⟨e_p, W x⟩)²`, whose normal equations
//! `Σ_p α_p ω_p Wᵀ e_p e_pᵀ W` are the same sum. A stratified sample estimates that sum
//! without bias (Horvitz–Thompson, Cochran, "Sampling Techniques", 3rd ed., §5.1–5.3):
//! with the eligible observations of stratum `h` numbering `N_h`, draw `n_h` of them
//! uniformly without replacement and give each the weight `N_h / n_h`; then
//! `E[Σ_{p ∈ sample} (N_h / n_h) f_p] = Σ_p f_p` for any per-observation term `f`. With
//! proportional allocation (`n_h ∝ N_h`, largest remainders, at least one per non-empty
//! stratum while the budget allows) the variance is at most that of a simple random sample
//! of the same size, and zero for every term that is constant within strata.
//!
//! Strata are what the transport rows depend on: the vertex normal (which part of the map
//! a row sees, [`vertex_strata`] bins it on an octahedral grid), how much of the vertex's
//! hemisphere is open (shadowed rows see less of the map) and the vertex's dominant
//! material (which lobes blend into its row). Draws are seeded (PCG) and the result is
//! sorted, so the sample depends only on its inputs.

use rand::{Rng, SeedableRng};

/// A subsample of `0..len`: the chosen positions (ascending) and their Horvitz–Thompson
/// weights `N_h / n_h`.
#[derive(Debug, Clone, PartialEq)]
pub struct Subsample {
    /// Chosen positions, ascending.
    pub index: Vec<usize>,
    /// Weight of each chosen position (`N_h / n_h` of its stratum), `≥ 1`.
    pub weight: Vec<f64>,
}

impl Subsample {
    /// Every eligible position with weight 1.
    pub fn all(eligible: &[bool]) -> Self {
        let index: Vec<usize> = (0..eligible.len()).filter(|&i| eligible[i]).collect();
        let weight = vec![1.0; index.len()];
        Subsample { index, weight }
    }
}

/// Per-stratum sample sizes for `budget` draws from strata of `sizes` (proportional,
/// largest remainders; every non-empty stratum gets one first while the budget allows).
/// Returns `sizes` itself when `budget ≥ Σ sizes`.
pub fn allocate(sizes: &[usize], budget: usize) -> Vec<usize> {
    let total: usize = sizes.iter().sum();
    if budget >= total {
        return sizes.to_vec();
    }
    let nonempty = sizes.iter().filter(|&&s| s > 0).count();
    let mut out = vec![0usize; sizes.len()];
    // One per non-empty stratum first (largest strata first when even that is too many).
    let mut rest = budget;
    if nonempty <= budget {
        for (o, &s) in out.iter_mut().zip(sizes) {
            if s > 0 {
                *o = 1;
            }
        }
        rest -= nonempty;
    }
    // The remainder proportionally to what each stratum has left, largest remainders.
    let left: Vec<usize> = sizes.iter().zip(&out).map(|(s, o)| s - o).collect();
    let left_total: usize = left.iter().sum();
    if left_total == 0 || rest == 0 {
        if nonempty > budget {
            let mut order: Vec<usize> = (0..sizes.len()).collect();
            order.sort_by_key(|&h| (std::cmp::Reverse(sizes[h]), h));
            for &h in order.iter().take(budget) {
                out[h] = 1;
            }
        }
        return out;
    }
    let mut rems: Vec<(u128, usize)> = Vec::with_capacity(sizes.len());
    let mut given = 0usize;
    for (h, &l) in left.iter().enumerate() {
        let exact = l as u128 * rest as u128;
        let q = (exact / left_total as u128) as usize;
        out[h] += q;
        given += q;
        rems.push((exact % left_total as u128, h));
    }
    rems.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    for &(_, h) in rems.iter().take(rest - given) {
        out[h] += 1;
    }
    out
}

/// A stratified sample of at most `budget` of the positions `i` with `eligible[i]`,
/// `stratum[i]` naming each position's stratum (module docs). All eligible positions with
/// weight 1 when there are at most `budget`.
pub fn stratified(stratum: &[u32], eligible: &[bool], budget: usize, seed: u64) -> Subsample {
    assert_eq!(stratum.len(), eligible.len(), "one stratum per position");
    let n_eligible = eligible.iter().filter(|&&e| e).count();
    if n_eligible <= budget {
        return Subsample::all(eligible);
    }
    // Members of each stratum, in position order.
    let n_strata = stratum.iter().map(|&s| s as usize + 1).max().unwrap_or(0);
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); n_strata];
    for (i, (&s, &e)) in stratum.iter().zip(eligible).enumerate() {
        if e {
            members[s as usize].push(i);
        }
    }
    let sizes: Vec<usize> = members.iter().map(Vec::len).collect();
    let take = allocate(&sizes, budget);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut chosen: Vec<(usize, f64)> = Vec::with_capacity(budget);
    for (m, &k) in members.iter_mut().zip(&take) {
        if k == 0 {
            continue;
        }
        // Partial Fisher–Yates: the first `k` of a uniform random permutation.
        for j in 0..k {
            let r = rng.random_range(j..m.len());
            m.swap(j, r);
        }
        let w = m.len() as f64 / k as f64;
        chosen.extend(m[..k].iter().map(|&i| (i, w)));
    }
    chosen.sort_unstable_by_key(|c| c.0);
    Subsample {
        index: chosen.iter().map(|c| c.0).collect(),
        weight: chosen.iter().map(|c| c.1).collect(),
    }
}

/// Octahedral normal bins per side of the lighting step's strata ([`lighting_strata`]).
pub const LIGHTING_NORMAL_BINS: usize = 8;
/// Levels of the mean visible fraction of the lighting step's strata ([`lighting_strata`]).
pub const LIGHTING_OPEN_LEVELS: usize = 3;

/// The strata `run` gives the lighting step's sample
/// ([`crate::solve::EstimateOptions::lighting_strata`]): the env-frame normal in
/// [`LIGHTING_NORMAL_BINS`]² octahedral bins × the vertex's open fraction of the hemisphere
/// (`open_fraction`, from the visibility) in [`LIGHTING_OPEN_LEVELS`] levels.
pub fn lighting_strata(normals_env: &[crate::Vec3], open_fraction: &[f64]) -> Vec<u32> {
    vertex_strata(
        normals_env,
        Some(open_fraction),
        LIGHTING_NORMAL_BINS,
        LIGHTING_OPEN_LEVELS,
    )
}

/// Per-vertex stratum from the vertex normal (environment frame) binned on a
/// `normal_bins × normal_bins` octahedral grid ([`crate::sphere::oct_encode`]) and, when
/// given, its open fraction of the hemisphere (`0..=1`) in `open_levels` equal bins:
/// `normal_bin · open_levels + open_bin`.
pub fn vertex_strata(
    normals: &[crate::Vec3],
    open_fraction: Option<&[f64]>,
    normal_bins: usize,
    open_levels: usize,
) -> Vec<u32> {
    let nb = normal_bins.max(1);
    let levels = if open_fraction.is_some() {
        open_levels.max(1)
    } else {
        1
    };
    normals
        .iter()
        .enumerate()
        .map(|(v, n)| {
            let norm = n.norm();
            let bin = if norm > 0.0 && norm.is_finite() {
                let uv = crate::sphere::oct_encode(&(n / norm));
                let iu = ((uv[0] * nb as f64) as usize).min(nb - 1);
                let iv = ((uv[1] * nb as f64) as usize).min(nb - 1);
                iv * nb + iu
            } else {
                0
            };
            let open = open_fraction.map_or(0, |f| {
                ((f[v].clamp(0.0, 1.0) * levels as f64) as usize).min(levels - 1)
            });
            (bin * levels + open) as u32
        })
        .collect()
}

/// Each vertex's material with the largest blending weight (`weights` row-major `V × K`,
/// the first on ties).
pub fn dominant_material(weights: &[f64], kk: usize) -> Vec<u32> {
    weights
        .chunks(kk.max(1))
        .map(|row| {
            let mut best = 0;
            for (k, &w) in row.iter().enumerate() {
                if w > row[best] {
                    best = k;
                }
            }
            best as u32
        })
        .collect()
}

/// Does the answer move when the lighting step sees a sample? The fit's error on the
/// sampled photos' fitted observations inside their lighting samples against outside them
/// (`sqrt(Σ α (y − ŷ)²) / sqrt(Σ α y²)` each; the material step fitted both). A lighting
/// fit that over-fits its sample predicts the rest worse: `ratio = out / in` well above 1.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SampleCheck {
    /// Observations per photo asked for.
    pub budget: usize,
    /// Photos with more fitted observations than that, which were sampled.
    pub photos_sampled: usize,
    /// Fitted observations of those photos in their samples.
    pub in_sample: usize,
    /// Fitted observations of those photos outside their samples.
    pub out_of_sample: usize,
    /// Relative RMSE inside the samples.
    pub rel_rmse_in: f64,
    /// Relative RMSE outside the samples.
    pub rel_rmse_out: f64,
    /// `rel_rmse_out / rel_rmse_in`.
    pub ratio: f64,
}

/// [`SampleCheck`] from the predictions `pred` of observations with colours `rgb` and
/// weights `alpha` (`α`; 0 = not fitted), photo `i` spanning `photo_ranges[i]` and sampled
/// by `samples[i]` (positions in its range; `None`: not sampled, left out of the check).
pub fn sample_check(
    pred: &[[f64; 3]],
    rgb: &[[f32; 3]],
    alpha: &[f32],
    photo_ranges: &[std::ops::Range<usize>],
    samples: &[Option<Subsample>],
    budget: usize,
) -> SampleCheck {
    // [in, out] × (Σ α r², Σ α y², count)
    let mut acc = [[0.0_f64; 3]; 2];
    let mut photos = 0;
    for (range, sample) in photo_ranges.iter().zip(samples) {
        let Some(sample) = sample else { continue };
        photos += 1;
        let mut inside = vec![false; range.len()];
        for &q in &sample.index {
            inside[q] = true;
        }
        for (q, p) in range.clone().enumerate() {
            let a = alpha[p] as f64;
            if a <= 0.0 {
                continue;
            }
            let slot = &mut acc[usize::from(!inside[q])];
            for c in 0..3 {
                let y = rgb[p][c] as f64;
                slot[0] += a * (y - pred[p][c]).powi(2);
                slot[1] += a * y * y;
            }
            slot[2] += 1.0;
        }
    }
    let rel = |a: &[f64; 3]| {
        if a[1] > 0.0 {
            (a[0] / a[1]).sqrt()
        } else {
            0.0
        }
    };
    let (rel_in, rel_out) = (rel(&acc[0]), rel(&acc[1]));
    SampleCheck {
        budget,
        photos_sampled: photos,
        in_sample: acc[0][2] as usize,
        out_of_sample: acc[1][2] as usize,
        rel_rmse_in: rel_in,
        rel_rmse_out: rel_out,
        ratio: if rel_in > 0.0 { rel_out / rel_in } else { 1.0 },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;

    #[test]
    fn allocation_is_proportional_and_spends_the_budget() {
        // Brute force: the proportional share of each stratum, within one draw of it
        // (largest remainders), after the one-per-stratum floor.
        let sizes = [1000, 10, 0, 3, 500, 1];
        let a = allocate(&sizes, 100);
        assert_eq!(a.iter().sum::<usize>(), 100);
        assert_eq!(a[2], 0, "an empty stratum gets nothing");
        for (h, (&s, &k)) in sizes.iter().zip(&a).enumerate() {
            assert!(k <= s);
            if s > 0 {
                assert!(k >= 1, "stratum {h} has members but no draw");
                let share = (s - 1) as f64 * 95.0 / 1509.0 + 1.0;
                assert!(
                    (k as f64 - share).abs() < 1.0,
                    "stratum {h}: {k} vs {share}"
                );
            }
        }
        // Budget at or above the total: everything.
        assert_eq!(allocate(&sizes, 2000), sizes.to_vec());
        // Fewer draws than non-empty strata: the largest strata get one each.
        assert_eq!(allocate(&sizes, 2), vec![1, 0, 0, 0, 1, 0]);
    }

    #[test]
    fn the_sample_respects_budget_eligibility_and_strata() {
        let mut rng = StdRng::seed_from_u64(5);
        let n = 5000;
        let stratum: Vec<u32> = (0..n).map(|_| rng.random_range(0..7)).collect();
        let eligible: Vec<bool> = (0..n).map(|_| rng.random_bool(0.9)).collect();
        let s = stratified(&stratum, &eligible, 800, 3);
        assert_eq!(s.index.len(), 800);
        assert!(
            s.index.windows(2).all(|w| w[0] < w[1]),
            "ascending, no repeats"
        );
        assert!(s.index.iter().all(|&i| eligible[i]));
        // The weights of each stratum add up to its eligible count exactly (N_h/n_h · n_h).
        for h in 0..7u32 {
            let n_h = (0..n).filter(|&i| eligible[i] && stratum[i] == h).count() as f64;
            let w: f64 = s
                .index
                .iter()
                .zip(&s.weight)
                .filter(|(&i, _)| stratum[i] == h)
                .map(|(_, w)| w)
                .sum();
            // Floating-point sum of ~115 equal terms: 1e-9 relative.
            assert!((w - n_h).abs() <= 1e-9 * n_h, "stratum {h}: {w} vs {n_h}");
        }
        // Deterministic for a seed, different for another.
        assert_eq!(s, stratified(&stratum, &eligible, 800, 3));
        assert_ne!(s.index, stratified(&stratum, &eligible, 800, 4).index);
        // Under budget: every eligible position, weight 1.
        let all = stratified(&stratum, &eligible, n, 3);
        assert_eq!(all, Subsample::all(&eligible));
    }

    #[test]
    fn the_weighted_sample_sum_is_unbiased() {
        // Monte Carlo over seeds against the brute-force total of a per-position term
        // that varies within and across strata. 400 draws of a 10% sample: the mean's
        // relative standard error is ~0.3% here (measured spread), so 1.5% is ~5 σ.
        let mut rng = StdRng::seed_from_u64(9);
        let n = 3000;
        let stratum: Vec<u32> = (0..n).map(|i| (i % 5) as u32).collect();
        let f: Vec<f64> = (0..n)
            .map(|i| (i % 5) as f64 * 3.0 + rng.random_range(0.0..2.0))
            .collect();
        let eligible = vec![true; n];
        let total: f64 = f.iter().sum();
        let runs = 400;
        let mean: f64 = (0..runs)
            .map(|seed| {
                let s = stratified(&stratum, &eligible, 300, seed);
                s.index
                    .iter()
                    .zip(&s.weight)
                    .map(|(&i, w)| w * f[i])
                    .sum::<f64>()
            })
            .sum::<f64>()
            / runs as f64;
        assert!((mean - total).abs() < 0.015 * total, "{mean} vs {total}");
        // A term constant within strata is estimated exactly by every sample.
        let g: Vec<f64> = (0..n).map(|i| (i % 5) as f64 + 1.0).collect();
        let s = stratified(&stratum, &eligible, 300, 1);
        let est: f64 = s.index.iter().zip(&s.weight).map(|(&i, w)| w * g[i]).sum();
        let exact: f64 = g.iter().sum();
        assert!((est - exact).abs() <= 1e-9 * exact);
    }

    #[test]
    fn dominant_material_and_sample_check_by_hand() {
        assert_eq!(
            dominant_material(&[0.1, 0.7, 0.2, 0.5, 0.5, 0.0], 3),
            vec![1, 0],
            "largest weight; the first on a tie"
        );
        // Photo 0: 4 observations, positions 0 and 2 sampled; photo 1 not sampled (left
        // out). Residuals 0.1 inside (y = 1), 0.2 outside (y = 1), one unfitted (α = 0).
        let rgb = vec![[1.0_f32; 3]; 6];
        let pred = vec![[0.9; 3], [0.8; 3], [0.9; 3], [0.8; 3], [0.0; 3], [0.0; 3]];
        let alpha = [1.0, 1.0, 1.0, 0.0, 1.0, 1.0];
        let s = Subsample {
            index: vec![0, 2],
            weight: vec![2.0, 2.0],
        };
        let c = sample_check(&pred, &rgb, &alpha, &[0..4, 4..6], &[Some(s), None], 2);
        assert_eq!((c.photos_sampled, c.in_sample, c.out_of_sample), (1, 2, 1));
        // f32 colours against f64 predictions: 1e-6 absolute.
        assert!((c.rel_rmse_in - 0.1).abs() < 1e-6, "{c:?}");
        assert!((c.rel_rmse_out - 0.2).abs() < 1e-6, "{c:?}");
        assert!((c.ratio - 2.0).abs() < 1e-5, "{c:?}");
    }

    #[test]
    fn vertex_strata_bin_normals_and_openness() {
        use crate::Vec3;
        let normals = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
        ];
        let s = vertex_strata(&normals, None, 4, 3);
        assert_eq!(s[0], s[1], "the length of a normal does not matter");
        assert_ne!(s[0], s[2]);
        assert_ne!(s[0], s[3]);
        assert!(s.iter().all(|&v| v < 16));
        let open = [0.0, 1.0, 0.5, 0.2, 0.9];
        let t = vertex_strata(&normals, Some(&open), 4, 3);
        assert_eq!(t[0], s[0] * 3, "closed: level 0");
        assert_eq!(t[1], s[1] * 3 + 2, "fully open: the top level");
        assert_eq!(t[2], s[2] * 3 + 1);
    }
}
