//! The scale normalisation after the alternation.
//!
//! `F` is invariant under `x → s x`, `λ → λ / s` (and `w_k → t w_k`, `λ_k → λ_k / t`) up to
//! the tiny regularisers. The result is normalised once: every material's median blending
//! weight over the observed vertices (read by an observation of positive weight,
//! [`crate::observe::Observations::seen_vertices`]) pure in it becomes 1, so that a pure vertex has
//! weight ≈ 1 and `λ_k` is the material's own colour. A vertex is pure in `k` when `w_k`
//! carries at least [`PURE_SHARE`] of its weights' sum, a test the gauge `w_k → t w_k`
//! barely moves where the other weights are near 0; with fewer than [`MIN_PURE`] such
//! vertices, every observed vertex where `k` is the largest counts. Two rules it replaces:
//! - every vertex where `k` is the largest: vertices no photo observes keep the start's
//!   uniform weights `1/K`, which tie for every material, and pulled one material's median
//!   toward `1/K` when they outnumbered the observed vertices it dominates (on the
//!   ablation's three-material scene its pure vertices came out at weight 2.9 and its blends
//!   were read as the wrong material);
//! - every observed vertex where `k` is the largest: the blends it leads sit below 1 and
//!   pulled the median under the pure vertices' weight, by a different factor for each
//!   material (on `spot-three` through `run`, the fitted `λ` 26% and 35% darker than two
//!   materials' pure vertices, against under 1% for the third).
//!
//! Then the mean Lambertian weight
//! (basis `lambert_basis`) over materials and channels equals that of the start (the
//! initial materials' median colours; the mean of all `λ` when either is 0), the lights
//! taking the inverse scale. With `fixed_materials` (Sec. 6.1) nothing is rescaled.
//!
//! **The per-channel scale anchor** ([`ScaleAnchor`]). `F` is also invariant under a
//! per-channel `λ_{·,·,c} → t_c λ_{·,·,c}`, `x_{I,c} → x_{I,c} / t_c`: photos can never
//! tell a reddish object under white light from a white one under reddish light. Some
//! anchor fixes `t_c`, and the report names it (`scale_anchor`):
//! - `start` (default): the per-channel balance is where the alternation left it from the
//!   start (the initial materials' median colours, the gauge of
//!   [`EstimateOptions::fix_gauge`] when on); only the overall scale above is anchored;
//! - `grey-world`: per channel, the mean diffuse albedo over the surface,
//!   `(1/|X|) Σ_{x∈X} β_{x,lb,c}` (`X` the vertices with any blending weight), is
//!   [`GREY_WORLD_ALBEDO`] = 0.5, the lights taking `1 / t_c` (applied after the rule
//!   above, so it replaces that rule's overall scale).

use crate::solve::light::LightModel;
use crate::solve::options::EstimateOptions;
pub use crate::solve::options::ScaleAnchor;
use crate::solve::result::Materials0;

/// The mean diffuse albedo per channel under [`ScaleAnchor::GreyWorld`].
pub const GREY_WORLD_ALBEDO: f64 = 0.5;

/// Normalises `lambda`, `weights` and the light (module docs); the rule applied, in words
/// ([`crate::solve::Estimate::normalisation`]).
pub(crate) fn normalise<M: LightModel>(
    light: &mut M,
    lambda: &mut [Vec<[f64; 3]>],
    weights: &mut [f64],
    init: &Materials0,
    opts: &EstimateOptions,
    observed: &[bool],
) -> String {
    if opts.fixed_materials {
        return "none: the reflectance is given, so the lights carry the absolute scale"
            .to_string();
    }
    median_weights_to_one(lambda, weights, observed);
    let nb = lambda.first().map_or(0, |l| l.len());
    let lb = opts.lambert_basis.min(nb - 1);
    let scale = InitialScale::of(&init.lambda, lambda, lb);
    if scale.target > 0.0 && scale.now > 0.0 {
        let s = scale.target / scale.now;
        for v in lambda.iter_mut().flatten().flatten() {
            *v *= s;
        }
        light.normalise(s);
    }
    let rule = format!(
        "every material's median blending weight over the observed vertices pure in it (its weight at least {PURE_SHARE} of their sum) is 1; then {} equals its initial value {:.6e}; maps scaled inversely",
        scale.what, scale.target
    );
    match opts.scale_anchor {
        ScaleAnchor::Start => {
            format!("{rule}; per-channel balance: the start's (scale anchor `start`)")
        }
        ScaleAnchor::GreyWorld => {
            let t = grey_world_scales(lambda, weights, lb);
            for (c, &tc) in t.iter().enumerate() {
                if tc > 0.0 && tc.is_finite() {
                    lambda.iter_mut().flatten().for_each(|v| v[c] *= tc);
                    light.divide_channel(c, tc);
                }
            }
            format!(
                "every material's median blending weight over the observed vertices pure in it (its weight at least {PURE_SHARE} of their sum) is 1; then per channel the mean diffuse albedo over the surface is {GREY_WORLD_ALBEDO} (scale anchor `grey-world`, factors {:.4} / {:.4} / {:.4}); maps scaled inversely",
                t[0], t[1], t[2]
            )
        }
    }
}

/// Per channel, the factor `t_c` that brings the surface's mean diffuse albedo
/// `(1/|X|) Σ_x Σ_k w_{x,k} λ_{k,lb,c}` to [`GREY_WORLD_ALBEDO`] (`X`: vertices with any
/// blending weight); 1 where that mean is 0.
pub fn grey_world_scales(lambda: &[Vec<[f64; 3]>], weights: &[f64], lb: usize) -> [f64; 3] {
    let kk = lambda.len();
    let nv = weights.len() / kk.max(1);
    let (mut sum, mut n) = ([0.0_f64; 3], 0usize);
    for x in 0..nv {
        let w = &weights[x * kk..(x + 1) * kk];
        if w.iter().all(|&v| v <= 0.0) {
            continue;
        }
        n += 1;
        for (k, &wk) in w.iter().enumerate() {
            for c in 0..3 {
                sum[c] += wk * lambda[k][lb][c];
            }
        }
    }
    sum.map(|s| {
        let mean = s / n.max(1) as f64;
        if mean > 0.0 {
            GREY_WORLD_ALBEDO / mean
        } else {
            1.0
        }
    })
}

/// A vertex counts as pure material `k` in the normalisation when `w_k` carries at least
/// this share of its weights' sum (module docs).
pub const PURE_SHARE: f64 = 0.9;

/// The fewest pure vertices a material's scale is read from; below it, from every
/// observed vertex it dominates.
pub const MIN_PURE: usize = 10;

/// Per material, the median weight over the `observed` vertices pure in it (share
/// [`PURE_SHARE`]; those it dominates when fewer than [`MIN_PURE`]) becomes 1, its `λ`
/// taking the inverse factor (module docs).
fn median_weights_to_one(lambda: &mut [Vec<[f64; 3]>], weights: &mut [f64], observed: &[bool]) {
    let kk = lambda.len();
    let nv = weights.len() / kk.max(1);
    for k in 0..kk {
        let dominated = |share: f64| -> Vec<f64> {
            (0..nv)
                .filter(|&x| observed.get(x).copied().unwrap_or(false))
                .filter(|&x| {
                    let row = &weights[x * kk..(x + 1) * kk];
                    let sum: f64 = row.iter().sum();
                    row[k] > 0.0 && row.iter().all(|&v| v <= row[k]) && row[k] >= share * sum
                })
                .map(|x| weights[x * kk + k])
                .collect()
        };
        let mut dom = dominated(PURE_SHARE);
        if dom.len() < MIN_PURE {
            dom = dominated(0.0);
        }
        if dom.is_empty() {
            continue;
        }
        let mid = dom.len() / 2;
        let (_, med, _) = dom.select_nth_unstable_by(mid, f64::total_cmp);
        let scale = *med;
        if scale > 0.0 {
            for x in 0..nv {
                weights[x * kk + k] /= scale;
            }
            for v in lambda[k].iter_mut().flatten() {
                *v *= scale;
            }
        }
    }
}

/// The figure the final scale matches: its start value, its value now, and its name.
struct InitialScale {
    target: f64,
    now: f64,
    what: String,
}

impl InitialScale {
    fn of(init: &[Vec<[f64; 3]>], lambda: &[Vec<[f64; 3]>], lb: usize) -> Self {
        let kk = lambda.len();
        let nb = lambda.first().map_or(0, |l| l.len());
        let mean_l = |l: &[Vec<[f64; 3]>]| {
            l.iter().map(|r| r[lb].iter().sum::<f64>()).sum::<f64>() / (3 * kk) as f64
        };
        let mean_all =
            |l: &[Vec<[f64; 3]>]| l.iter().flatten().flatten().sum::<f64>() / (3 * kk * nb) as f64;
        if mean_l(init) > 0.0 && mean_l(lambda) > 0.0 {
            InitialScale {
                target: mean_l(init),
                now: mean_l(lambda),
                what: format!("the mean Lambertian weight λ_k,{lb},c over materials and channels"),
            }
        } else {
            InitialScale {
                target: mean_all(init),
                now: mean_all(lambda),
                what: "the mean of all λ_k,b,c".to_string(),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three materials; 100 observed pure vertices of each at weight `g_k` (one material's
    /// fitted gauge 3× off), 200 observed blends led by material 0 at `(0.6 g_0, 0.4 g_1,
    /// 0)`, and 500 vertices no photo observes at the start's uniform `1/3`. Every observed
    /// pure vertex must come out at weight 1 exactly (the median of a constant set), the
    /// product `w λ` unchanged to rounding. Counting the unobserved vertices puts material
    /// 2's median at 1/3; counting the blends material 0 leads puts its median at 0.6.
    #[test]
    fn the_median_weight_is_one_over_observed_vertices_whatever_the_unobserved_ones_hold() {
        let gauge = [1.0, 1.0, 3.0];
        let mut lambda: Vec<Vec<[f64; 3]>> = gauge.iter().map(|g| vec![[0.6 / g; 3]]).collect();
        let (pure, unseen) = (100, 500);
        let mut weights = Vec::new();
        for (k, g) in gauge.iter().enumerate() {
            for _ in 0..pure {
                let mut row = [0.0; 3];
                row[k] = *g;
                weights.extend(row);
            }
        }
        let blends = 200;
        for _ in 0..blends {
            weights.extend([0.6 * gauge[0], 0.4 * gauge[1], 0.0]);
        }
        for _ in 0..unseen {
            weights.extend([1.0 / 3.0; 3]);
        }
        let mut observed = vec![true; 3 * pure + blends];
        observed.resize(3 * pure + blends + unseen, false);
        let before: Vec<f64> = (0..3 * pure)
            .map(|x| (0..3).map(|k| weights[x * 3 + k] * lambda[k][0][0]).sum())
            .collect();
        median_weights_to_one(&mut lambda, &mut weights, &observed);
        for x in 0..3 * pure {
            let k = x / pure;
            assert!(
                (weights[x * 3 + k] - 1.0).abs() < 1e-12,
                "vertex {x}: {}",
                weights[x * 3 + k]
            );
            let now: f64 = (0..3).map(|j| weights[x * 3 + j] * lambda[j][0][0]).sum();
            assert!((now - before[x]).abs() < 1e-12);
        }
    }
}
