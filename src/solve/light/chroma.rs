//! The chroma smoothness prior (`--chroma-smoothness κ`, beyond the paper): the light's
//! colour varies slowly over directions.
//!
//! The Laplacian prior `μ_c ‖Δ x_c‖²` smooths each channel on its own, so a free map per
//! photo may give one channel a shape the others do not have. That moves brightness in
//! that channel alone between surfaces that face different ways, and so changes the
//! albedo *ratios* between materials in that channel (issue 25: the glossy Spot's worst
//! ratio is in blue). The prior here penalises the Laplacian of the map's chromaticity
//! instead of its brightness:
//!
//! `E(x) = ν Σ_c ‖Δ (P u)_c‖²`,  `u_c = x_c / g_c`,  `P = I − 𝟙𝟙ᵀ/3` (per texel, over
//! channels),
//!
//! with `g_c` the map's channel gains, `g_c = S_c / mean_c S_c`, `S_c = Σ_t x_{c,t}` at the
//! pass's start (1 where a channel has no light). `P u` is each texel's deviation from grey
//! after white balance, so a map whose channels are one shape times per-channel gains
//! (`x_c = g_c s`) costs nothing: white balance and exposure stay free, only colour that
//! changes with direction is penalised. `E` is a positive semi-definite quadratic
//! (`P` is an orthogonal projector, `PᵀP = P`), its normal matrix
//! `H v = ν Σ_c (1/g_c) e_c ⊗ ΔᵀΔ (P u(v))_c`, added to the lighting QP's Hessian beside
//! `μ ΔᵀΔ`; its diagonal `ν (2/3) / g_c² · diag(ΔᵀΔ)` joins the Jacobi scaling. The weight
//! is relative to the luminance Laplacian's, `ν = κ · mean_c μ_c`.
//!
//! A prior of this kind, colour smoother than brightness, is the assumption behind
//! intrinsic-image methods that separate reflectance from shading by chromaticity (Land
//! and McCann 1971, "Lightness and Retinex theory"; Grosse et al. 2009, "Ground truth
//! dataset and baseline evaluations for intrinsic image algorithms", colour Retinex);
//! here it is placed on the light, whose chromaticity over directions is smooth away from
//! the sun's edge.

use super::laplacian::Laplacian;

/// The prior for one lighting pass: `ν` and the channel gains.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ChromaPrior {
    /// `ν`, the weight of `E`.
    pub nu: f64,
    /// Channel gains `g_c` (module docs).
    pub gains: [f64; 3],
}

/// Channel gains `g_c = S_c / mean_c S_c` of channel-major texels `x` (3 × `n2`); all 1
/// when any channel sums to zero or less (no white balance to keep).
fn gains(x: &[f64], n2: usize) -> [f64; 3] {
    let s: [f64; 3] = [0, 1, 2].map(|c| x[c * n2..(c + 1) * n2].iter().sum());
    let mean = (s[0] + s[1] + s[2]) / 3.0;
    if s.iter().any(|&v| v <= 0.0 || !v.is_finite()) || mean <= 0.0 {
        return [1.0; 3];
    }
    s.map(|v| v / mean)
}

impl ChromaPrior {
    /// The prior at `κ` relative to the Laplacian weights `mu`, gains from `x`; `None` at
    /// `κ = 0` (off).
    pub(crate) fn for_pass(kappa: f64, mu: [f64; 3], x: &[f64], n2: usize) -> Option<Self> {
        (kappa > 0.0).then(|| ChromaPrior {
            nu: kappa * (mu[0] + mu[1] + mu[2]) / 3.0,
            gains: gains(x, n2),
        })
    }

    /// `P u(v)`, channel-major: each texel's white-balanced channels less their mean.
    fn deviation(&self, v: &[f64], n2: usize) -> Vec<f64> {
        let mut w = vec![0.0; 3 * n2];
        for t in 0..n2 {
            let u = [0, 1, 2].map(|c| v[c * n2 + t] / self.gains[c]);
            let m = (u[0] + u[1] + u[2]) / 3.0;
            for c in 0..3 {
                w[c * n2 + t] = u[c] - m;
            }
        }
        w
    }

    /// `out += H v` (module docs).
    pub(crate) fn add_normal(&self, lap: &Laplacian, v: &[f64], out: &mut [f64]) {
        let n2 = v.len() / 3;
        let w = self.deviation(v, n2);
        for c in 0..3 {
            let r = c * n2..(c + 1) * n2;
            lap.add_normal(&w[r.clone()], self.nu / self.gains[c], &mut out[r]);
        }
    }

    /// The diagonal of `H`, channel-major: `ν (2/3) / g_c² · diag(ΔᵀΔ)`.
    pub(crate) fn diagonal(&self, lap: &Laplacian) -> Vec<f64> {
        let ld = lap.normal_diag();
        (0..3)
            .flat_map(|c| {
                let f = self.nu * (2.0 / 3.0) / (self.gains[c] * self.gains[c]);
                ld.iter().map(move |d| f * d)
            })
            .collect()
    }

    /// `E(v) = ν Σ_c ‖Δ (P u)_c‖²` (module docs). The objective `F` the alternation
    /// reports leaves it out, as it does the light prior: both are linearised at each
    /// pass's start (here, the gains).
    #[cfg(test)]
    pub(crate) fn energy(&self, lap: &Laplacian, v: &[f64]) -> f64 {
        let n2 = v.len() / 3;
        let w = self.deviation(v, n2);
        (0..3)
            .map(|c| lap.energy(&w[c * n2..(c + 1) * n2]))
            .sum::<f64>()
            * self.nu
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prior() -> ChromaPrior {
        ChromaPrior {
            nu: 0.7,
            gains: [1.3, 1.0, 0.7],
        }
    }

    /// A deterministic, non-smooth test vector.
    fn vector(len: usize, k: f64) -> Vec<f64> {
        (0..len)
            .map(|i| ((i as f64 * k).sin() + 1.1) * (1.0 + (i % 7) as f64 * 0.1))
            .collect()
    }

    #[test]
    fn a_grey_shape_times_the_gains_costs_nothing() {
        let n = 8;
        let lap = Laplacian::new(n);
        let p = prior();
        let s = vector(n * n, 0.37);
        let x: Vec<f64> = (0..3)
            .flat_map(|c| s.iter().map(move |v| v * [1.3, 1.0, 0.7][c]))
            .collect();
        // Sums of exact products: zero to rounding (1e-20 relative to the energy of a
        // coloured map of this size, which is O(1)).
        assert!(p.energy(&lap, &x).abs() < 1e-20, "{}", p.energy(&lap, &x));
        let mut hx = vec![0.0; 3 * n * n];
        p.add_normal(&lap, &x, &mut hx);
        assert!(hx.iter().all(|v| v.abs() < 1e-12));
        // Coloured light that changes with direction does cost.
        let y = vector(3 * n * n, 0.91);
        assert!(p.energy(&lap, &y) > 1e-3);
    }

    #[test]
    fn the_normal_matrix_is_the_energys_hessian() {
        // E is quadratic, E(v) = ½ vᵀ (2H/2) v with the Laplacian's convention
        // `energy = ‖Δx‖²`, `add_normal = ΔᵀΔ x`: so vᵀ H v = E(v) and, by polarisation,
        // aᵀ H b = (E(a + b) − E(a − b)) / 4. Both sides are sums of a few hundred terms of
        // size O(10): 1e-9 relative covers rounding.
        let n = 8;
        let lap = Laplacian::new(n);
        let p = prior();
        let a = vector(3 * n * n, 0.53);
        let b = vector(3 * n * n, 1.77);
        let mut hb = vec![0.0; a.len()];
        p.add_normal(&lap, &b, &mut hb);
        let lhs: f64 = a.iter().zip(&hb).map(|(x, y)| x * y).sum();
        let plus: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + y).collect();
        let minus: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x - y).collect();
        let rhs = (p.energy(&lap, &plus) - p.energy(&lap, &minus)) / 4.0;
        assert!(
            (lhs - rhs).abs() < 1e-9 * rhs.abs().max(1.0),
            "{lhs} vs {rhs}"
        );
    }

    #[test]
    fn the_diagonal_matches_unit_vector_products() {
        // Brute force: H e_i at i for every texel of every channel; the same sums as the
        // closed form, so 1e-12 relative.
        let n = 4;
        let lap = Laplacian::new(n);
        let p = prior();
        let d = p.diagonal(&lap);
        for i in 0..3 * n * n {
            let mut e = vec![0.0; 3 * n * n];
            e[i] = 1.0;
            let mut he = vec![0.0; 3 * n * n];
            p.add_normal(&lap, &e, &mut he);
            assert!(
                (he[i] - d[i]).abs() < 1e-12 * d[i].max(1.0),
                "{i}: {} vs {}",
                he[i],
                d[i]
            );
        }
    }

    #[test]
    fn gains_are_channel_sums_over_their_mean_and_one_without_light() {
        let n2 = 2;
        let x = [1.0, 1.0, 2.0, 2.0, 3.0, 3.0];
        let g = gains(&x, n2);
        for (a, b) in g.iter().zip([0.5, 1.0, 1.5]) {
            assert!((a - b).abs() < 1e-15);
        }
        assert_eq!(gains(&[1.0, 1.0, 0.0, 0.0, 3.0, 3.0], n2), [1.0; 3]);
        assert!(ChromaPrior::for_pass(0.0, [1.0; 3], &x, n2).is_none());
        let p = ChromaPrior::for_pass(2.0, [1.0, 2.0, 3.0], &x, n2).unwrap();
        assert_eq!(p.nu, 4.0);
    }
}
