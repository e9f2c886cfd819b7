//! What the ratio step ([`crate::solve::ratio_step`]) needs of the sun-and-sky model: the
//! residual prior's term per channel, and the probes' lights mixed. The probes hold every
//! photo's `θ` ([`crate::solve::light::LightModel::hold_shape`]), and at fixed `θ` a photo's map
//! `Σ_j w_{j,c} B_{j,c} + r_c` is linear in its colour weights `w` and residual `r`, so
//! mixing those per channel mixes the maps.

use super::{residual_penalty, SkyLight, SkyPhoto, N_BASIS};
use crate::sphere::haar;

impl SkyLight {
    /// The residuals' prior term per channel at `params`, with the current scales.
    pub(super) fn residual_penalties(&self, params: &[SkyPhoto]) -> [f64; 3] {
        let n = self.params.first().map_or(0, |p| p.basis.n);
        let mut out = [0.0; 3];
        for (p, s) in params.iter().zip(&self.scale) {
            let Some(s) = s else { continue };
            for (c, o) in out.iter_mut().enumerate() {
                let mut h = p.residual[c].clone();
                haar::forward(&mut h, n);
                *o += residual_penalty(&h, s.h0[c], &self.b, s.sigma2);
            }
        }
        out
    }
}

/// Photo `i` of the ratio step's mix ([`SkyLight::combine`](crate::solve::light::LightModel::combine)).
pub(in crate::solve::light::sky) fn combine_photo(
    parts: &[(&Vec<SkyPhoto>, [f64; 3])],
    i: usize,
) -> SkyPhoto {
    let weight = |k: usize| parts[k].1.iter().sum::<f64>();
    let heaviest = (0..parts.len())
        .max_by(|&a, &b| weight(a).total_cmp(&weight(b)))
        .unwrap_or(0);
    let mut out = parts[heaviest].0[i].clone();
    if parts.iter().any(|(p, _)| p[i].theta != out.theta) {
        return out;
    }
    for c in 0..3 {
        for j in 0..N_BASIS {
            let w: f64 = parts.iter().map(|(p, w)| w[c] * p[i].weights[j][c]).sum();
            out.weights[j][c] = w.max(0.0);
        }
        for (t, v) in out.residual[c].iter_mut().enumerate() {
            let r: f64 = parts.iter().map(|(p, w)| w[c] * p[i].residual[c][t]).sum();
            *v = r.max(0.0);
        }
    }
    out
}
