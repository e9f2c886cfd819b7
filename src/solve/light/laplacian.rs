//! The map's smoothness prior: the 4-neighbour graph Laplacian `Δ` of the full octahedral
//! grid across its folded seams ([`crate::sphere::SphereGrid::neighbors`]), the term
//! `μ ‖Δ x‖²` of the objective (Eq. 9) and its normal matrix `μ ΔᵀΔ`.

use crate::solve::options::EstimateOptions;
use crate::sphere::SphereGrid;

/// The map's graph Laplacian `Δ` on the full octahedral grid (4 neighbours across seams):
/// `(Δ x)_t = Σ_{s ∈ N(t)} (x_t − x_s)`, with `apply` and its transpose.
#[derive(Debug, Clone)]
pub(crate) struct Laplacian {
    nb: Vec<[usize; 4]>,
}

impl Laplacian {
    pub(crate) fn new(n: usize) -> Self {
        let g = SphereGrid::full(n);
        Laplacian {
            nb: (0..n * n).map(|t| g.neighbors(t)).collect(),
        }
    }
    pub(crate) fn apply(&self, x: &[f64], out: &mut [f64]) {
        for (t, nb) in self.nb.iter().enumerate() {
            out[t] = nb.iter().map(|&s| x[t] - x[s]).sum();
        }
    }
    /// `out += μ ΔᵀΔ x`.
    pub(crate) fn add_normal(&self, x: &[f64], mu: f64, out: &mut [f64]) {
        let mut lx = vec![0.0; x.len()];
        self.apply(x, &mut lx);
        for (t, nb) in self.nb.iter().enumerate() {
            let v = mu * lx[t];
            for &s in nb {
                out[t] += v;
                out[s] -= v;
            }
        }
    }
    /// The diagonal of `ΔᵀΔ`: `Σ_r Δ_{r,t}²` with row `r` of `Δ` = 4 at `r`, −1 at each
    /// neighbour (repeated neighbours add up).
    pub(crate) fn normal_diag(&self) -> Vec<f64> {
        let mut diag = vec![0.0; self.nb.len()];
        let mut cols: Vec<(usize, f64)> = Vec::with_capacity(5);
        for (r, nb) in self.nb.iter().enumerate() {
            cols.clear();
            cols.push((r, nb.len() as f64));
            for &s in nb {
                match cols.iter_mut().find(|(c, _)| *c == s) {
                    Some(e) => e.1 -= 1.0,
                    None => cols.push((s, -1.0)),
                }
            }
            for &(c, v) in &cols {
                diag[c] += v * v;
            }
        }
        diag
    }
    pub(crate) fn energy(&self, x: &[f64]) -> f64 {
        let mut lx = vec![0.0; x.len()];
        self.apply(x, &mut lx);
        lx.iter().map(|v| v * v).sum()
    }
}

/// The factor on `μ_1` at outer iteration `outer_it` (from 1): `smoothness_decay^(it−1)`,
/// floored at `smoothness_min / smoothness` and capped at 1; 1 when the decay is off.
pub(crate) fn smoothness_factor(opts: &EstimateOptions, outer_it: usize) -> f64 {
    if opts.smoothness_decay == 1.0 || opts.smoothness <= 0.0 {
        1.0
    } else {
        opts.smoothness_decay
            .powi(outer_it as i32 - 1)
            .max(opts.smoothness_min / opts.smoothness)
            .min(1.0)
    }
}

/// `Σ_maps Σ_c μ_c ‖Δ x_c‖²` over maps paired with their weights (`None`: not yet fitted,
/// no penalty): the smoothness term of `F` for any model made of free maps.
pub(crate) fn maps_penalty(
    lap: &Laplacian,
    maps: &[[Vec<f64>; 3]],
    mu: &[Option<[f64; 3]>],
) -> f64 {
    maps.iter()
        .zip(mu)
        .map(|(l, m)| {
            let m = m.unwrap_or([0.0; 3]);
            (0..3).map(|c| m[c] * lap.energy(&l[c])).sum::<f64>()
        })
        .sum()
}

/// [`maps_penalty`] per channel.
pub(crate) fn channel_maps_penalty(
    lap: &Laplacian,
    maps: &[[Vec<f64>; 3]],
    mu: &[Option<[f64; 3]>],
) -> [f64; 3] {
    let mut f = [0.0; 3];
    for (l, m) in maps.iter().zip(mu) {
        let m = m.unwrap_or([0.0; 3]);
        for c in 0..3 {
            f[c] += m[c] * lap.energy(&l[c]);
        }
    }
    f
}

/// Maps moved along their last step, `a + σ (a − b)`, projected on `a ≥ 0`.
pub(crate) fn extrapolate_maps(
    maps: &[[Vec<f64>; 3]],
    prev: &[[Vec<f64>; 3]],
    sigma: f64,
) -> Vec<[Vec<f64>; 3]> {
    maps.iter()
        .zip(prev)
        .map(|(l, q)| {
            [0, 1, 2].map(|c| {
                l[c].iter()
                    .zip(&q[c])
                    .map(|(&a, &b)| (a + sigma * (a - b)).max(0.0))
                    .collect()
            })
        })
        .collect()
}

/// One part of [`combine_maps`]: maps (per photo or group, per channel) and their weight
/// per channel.
pub(crate) type WeightedMaps<'a> = (&'a [[Vec<f64>; 3]], [f64; 3]);

/// `Σ_i w_{i,c} θ_i` per map, channel and texel, projected on `≥ 0`: the per-channel maps
/// `θ_i` of `parts` mixed with their weights (the ratio step's Lagrange interpolation
/// between its probes, [`crate::solve::ratio_step`]); `None` without parts.
pub(crate) fn combine_maps(parts: &[WeightedMaps]) -> Option<Vec<[Vec<f64>; 3]>> {
    let first = parts.first()?.0;
    let mixed = first
        .iter()
        .enumerate()
        .map(|(i, l)| {
            [0, 1, 2].map(|c| {
                (0..l[c].len())
                    .map(|t| {
                        parts
                            .iter()
                            .map(|(p, w)| w[c] * p[i][c][t])
                            .sum::<f64>()
                            .max(0.0)
                    })
                    .collect()
            })
        })
        .collect();
    Some(mixed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn combined_maps_mix_each_channel_with_its_weights_and_stay_non_negative() {
        // Two photos' maps, two parts: per channel c the result is w0_c a + w1_c b, computed
        // here by hand; the blue mix of part weights (2, −1.5) goes below 0 at texel 1 and
        // is clamped there.
        let a = vec![
            [vec![1.0, 2.0], vec![0.0, 4.0], vec![1.0, 1.0]],
            [vec![3.0, 0.0], vec![1.0, 1.0], vec![0.5, 0.0]],
        ];
        let b = vec![
            [vec![3.0, 2.0], vec![2.0, 0.0], vec![0.0, 2.0]],
            [vec![1.0, 4.0], vec![1.0, 3.0], vec![0.0, 1.0]],
        ];
        let w0 = [0.5, 0.25, 2.0];
        let w1 = [0.5, 0.75, -1.5];
        let mixed = combine_maps(&[(a.as_slice(), w0), (b.as_slice(), w1)]).unwrap();
        assert_eq!(mixed[0], [vec![2.0, 2.0], vec![1.5, 1.0], vec![2.0, 0.0]]);
        assert_eq!(mixed[1], [vec![2.0, 2.0], vec![1.0, 2.5], vec![1.0, 0.0]]);
        assert!(combine_maps(&[]).is_none());
    }
}
