//! The diffuse albedo per material against the truth (`report.json` `albedo_truth`): the
//! per-channel scale that best maps the recovered per-vertex diffuse albedo onto the true
//! one, each recovered material's colour and its pure vertices' mean and median against
//! its true material's, and the ratios between the materials' medians.

use super::TrueMaterials;
use crate::report::metrics::{upper_median, AlbedoTruth, AlbedoTruthEntry, PURE_OFF, PURE_WEIGHT};
use crate::run::Fitted;
use crate::transport::brdf::BasisBrdf;

/// The dominant material of each vertex with any weight (`None` elsewhere).
fn dominant(weights: &[f64], k: usize) -> Vec<Option<usize>> {
    weights
        .chunks(k.max(1))
        .map(|w| {
            let (i, &m) = w.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
            (m > 0.0).then_some(i)
        })
        .collect()
}

/// Diffuse albedo per material against the truth `t` (`report.json` `albedo_truth`);
/// `None` with a mesh of another vertex count or without a Lambertian lobe in the fit.
///
/// Per channel `s_c = Σ_x b_{x,c} β_{x,c} / Σ_x β_{x,c}²` over the vertices with weights in
/// both (`b`, `β` the true and recovered per-vertex diffuse albedo); each recovered
/// material `k` stands for the true material most vertices it dominates are dominated by;
/// its ratio error is `s_c λ_{k,lb,c} / λ^true_{j,lambert,c} − 1`; its pure-vertex error is
/// the mean of `s_c β_{x,c}` over the vertices it dominates whose true weight of `j` is at
/// least [`PURE_WEIGHT`], over `λ^true_{j,lambert,c}`, − 1; beside it their median ([`PureFigures`]).
pub(crate) fn albedo_truth(f: &Fitted, t: &TrueMaterials) -> Option<AlbedoTruth> {
    let nv = f.scene.mesh.positions.len();
    let (kk, jj) = (f.est.lambda.len(), t.names.len());
    let lb = f
        .basis
        .iter()
        .position(|b| matches!(b, BasisBrdf::Lambert))?;
    if jj == 0 || t.weights.len() != nv * jj || f.est.weights.len() != nv * kk {
        return None;
    }
    let dom = Dominant {
        fit: dominant(&f.est.weights, kk),
        truth: dominant(&t.weights, jj),
    };
    let (scale, vertices) = diffuse_scale(f, t, &dom, lb);
    let materials: Vec<AlbedoTruthEntry> = (0..kk)
        .filter_map(|k| material_albedo(f, t, &dom, lb, scale, k))
        .collect();
    Some(AlbedoTruth {
        scale,
        vertices,
        max_ratio_error: max_abs(materials.iter().flat_map(|m| m.ratio_error)),
        max_pure_ratio_error: max_abs(
            materials
                .iter()
                .flat_map(|m| m.pure_ratio_error)
                .filter(|e| e.is_finite()),
        ),
        max_median_ratio_error: crate::report::metrics::max_median_ratio_error(&materials),
        materials,
    })
}

/// The largest absolute value (0 for none).
fn max_abs(values: impl Iterator<Item = f64>) -> f64 {
    values.map(f64::abs).fold(0.0, f64::max)
}

/// Each vertex's dominant material in the fit and in the truth ([`dominant`]).
struct Dominant {
    fit: Vec<Option<usize>>,
    truth: Vec<Option<usize>>,
}

impl Dominant {
    /// Whether vertex `x` has weights in both.
    fn both(&self, x: usize) -> bool {
        self.fit[x].is_some() && self.truth[x].is_some()
    }
}

/// The per-channel scale `s_c = Σ_x b_{x,c} β_{x,c} / Σ_x β_{x,c}²` over the vertices with
/// weights in both ([`albedo_truth`]), and how many vertices that is.
fn diffuse_scale(f: &Fitted, t: &TrueMaterials, dom: &Dominant, lb: usize) -> ([f64; 3], usize) {
    let (nb, jj) = (f.basis.len(), t.names.len());
    let (mut num, mut den, mut n) = ([0.0_f64; 3], [0.0_f64; 3], 0);
    for x in (0..dom.fit.len()).filter(|&x| dom.both(x)) {
        n += 1;
        let beta = f.beta[x * nb + lb];
        for c in 0..3 {
            let b: f64 = (0..jj)
                .map(|j| t.weights[x * jj + j] * t.diffuse(j)[c])
                .sum();
            num[c] += b * beta[c];
            den[c] += beta[c] * beta[c];
        }
    }
    let scale = [0, 1, 2].map(|c| {
        if den[c] > 0.0 {
            num[c] / den[c]
        } else {
            f64::NAN
        }
    });
    (scale, n)
}

/// Recovered material `k` against the true material most of the vertices it dominates are
/// dominated by ([`albedo_truth`]); `None` when it dominates no vertex with true weights.
fn material_albedo(
    f: &Fitted,
    t: &TrueMaterials,
    dom: &Dominant,
    lb: usize,
    scale: [f64; 3],
    k: usize,
) -> Option<AlbedoTruthEntry> {
    let (nb, jj, nv) = (f.basis.len(), t.names.len(), dom.fit.len());
    let mut votes = vec![0usize; jj];
    for x in (0..nv).filter(|&x| dom.fit[x] == Some(k)) {
        if let Some(b) = dom.truth[x] {
            votes[b] += 1;
        }
    }
    let total: usize = votes.iter().sum();
    if total == 0 {
        return None;
    }
    let (j, &v) = votes.iter().enumerate().max_by_key(|e| *e.1)?;
    let recovered = f.est.lambda[k][lb];
    let recovered_scaled = [0, 1, 2].map(|c| scale[c] * recovered[c]);
    let ratio_error = [0, 1, 2].map(|c| recovered_scaled[c] / t.diffuse(j)[c] - 1.0);
    let pure: Vec<usize> = (0..nv)
        .filter(|&x| dom.fit[x] == Some(k) && t.weights[x * jj + j] >= PURE_WEIGHT)
        .collect();
    let truth = t.diffuse(j);
    let scaled: Vec<[f64; 3]> = pure
        .iter()
        .map(|&x| [0, 1, 2].map(|c| scale[c] * f.beta[x * nb + lb][c]))
        .collect();
    let figures = pure_figures(&scaled, truth);
    Some(AlbedoTruthEntry {
        material: k,
        true_material: t.names[j].clone(),
        agreement: v as f64 / total as f64,
        recovered,
        recovered_scaled,
        truth,
        ratio_error,
        pure_vertices: pure.len(),
        pure_ratio_error: figures.mean_error,
        pure_median_error: figures.median_error,
        pure_off_share: figures.off_share,
    })
}

/// One material's scaled per-vertex diffuse albedo over its pure vertices against the
/// truth ([`AlbedoTruthEntry`]'s last three fields).
#[derive(Debug, PartialEq)]
struct PureFigures {
    /// `mean_x a_{x,c} / t_c − 1`.
    mean_error: [f64; 3],
    /// `median_x a_{x,c} / t_c − 1` ([`upper_median`]).
    median_error: [f64; 3],
    /// The share of `x` with `|a_{x,c} / t_c − 1| > PURE_OFF` in some channel.
    off_share: f64,
}

/// [`PureFigures`] of the scaled albedos `a` against the true albedo `t` (NaN errors and a
/// share of 0 when `a` is empty).
fn pure_figures(a: &[[f64; 3]], t: [f64; 3]) -> PureFigures {
    let (mut mean_error, mut median_error) = ([0.0; 3], [0.0; 3]);
    for c in 0..3 {
        let values: Vec<f64> = a.iter().map(|v| v[c]).collect();
        mean_error[c] = values.iter().sum::<f64>() / a.len() as f64 / t[c] - 1.0;
        median_error[c] = upper_median(values) / t[c] - 1.0;
    }
    let off = a
        .iter()
        .filter(|v| (0..3).any(|c| (v[c] / t[c] - 1.0).abs() > PURE_OFF))
        .count();
    PureFigures {
        mean_error,
        median_error,
        off_share: if a.is_empty() {
            0.0
        } else {
            off as f64 / a.len() as f64
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Five vertices of a material whose true albedo is (0.5, 0.2, 0.1): the mean, the
    /// median and the share off by more than 10%, counted by hand.
    #[test]
    fn pure_figures_read_the_mean_the_median_and_the_share_off() {
        let t = [0.5, 0.2, 0.1];
        let a = [
            [0.50, 0.20, 0.10], // exact
            [0.52, 0.20, 0.10], // +4% in red: within 10%
            [0.50, 0.19, 0.10], // −5% in green
            [0.50, 0.20, 0.15], // +50% in blue: off
            [0.40, 0.20, 0.10], // −20% in red: off
        ];
        let f = pure_figures(&a, t);
        let close = |x: f64, y: f64| (x - y).abs() < 1e-12;
        // Means 2.42 / 5, 0.99 / 5, 0.55 / 5; medians 0.50, 0.20, 0.10.
        for (c, mean) in [2.42 / 5.0, 0.99 / 5.0, 0.55 / 5.0].iter().enumerate() {
            assert!(close(f.mean_error[c], mean / t[c] - 1.0), "{f:?}");
            assert!(close(f.median_error[c], 0.0), "{f:?}");
        }
        assert!(close(f.off_share, 2.0 / 5.0), "{f:?}");
        // An even count takes the upper of the two middle values.
        let even = pure_figures(&[[0.4, 0.2, 0.1], [0.6, 0.2, 0.1]], t);
        assert!(close(even.median_error[0], 0.6 / 0.5 - 1.0), "{even:?}");
        let none = pure_figures(&[], t);
        assert!(none.mean_error[0].is_nan() && none.median_error[0].is_nan());
        assert_eq!(none.off_share, 0.0);
    }
}
