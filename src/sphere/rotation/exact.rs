//! A reference rotation without normal blending, `R_n = W_l S_n W_gᵀ` with `S_n` the
//! nearest-texel average over `s × s` sub-texels of each local texel: slow, for tests and
//! for checking the blended rotation.

use super::LocalRotation;
use crate::sphere::haar;
use crate::sphere::{from_local, local_frame, SphereGrid};
use crate::Vec3;

/// A reference rotation without normal blending: `R_n = W_l S_n W_gᵀ`, where `S_n` averages
/// the global texels under `s × s` sub-texels of each local texel (nearest global texel per
/// sub-texel, weights = exact sub-texel solid angles). Slow (`n_local² s²` lookups per
/// call): for tests and for checking the blended rotation.
#[derive(Debug, Clone)]
pub struct ExactRotation {
    global: SphereGrid,
    local: SphereGrid,
    /// Sub-texels per local texel: local direction and weight `w / Δω_t`.
    subs: Vec<Vec<(Vec3, f64)>>,
}

impl ExactRotation {
    /// Sub-sampling `s × s` per local texel.
    pub fn new(n_global: usize, n_local: usize, s: usize) -> Self {
        let local = SphereGrid::hemi(n_local);
        let subs = (0..local.len())
            .map(|t| {
                let pts: Vec<(Vec3, f64)> = local.sample_points(t, s).collect();
                let total: f64 = pts.iter().map(|p| p.1).sum();
                pts.into_iter().map(|(d, w)| (d, w / total)).collect()
            })
            .collect();
        ExactRotation {
            global: SphereGrid::full(n_global),
            local,
            subs,
        }
    }
}

impl LocalRotation for ExactRotation {
    fn n_global(&self) -> usize {
        self.global.n
    }
    fn n_local(&self) -> usize {
        self.local.n
    }
    fn apply(&self, normal_env: &Vec3, global: &[f64], local: &mut [f64]) {
        let mut texels = global.to_vec();
        haar::inverse(&mut texels, self.global.n);
        let frame = local_frame(normal_env);
        for (t, o) in local.iter_mut().enumerate() {
            *o = self.subs[t]
                .iter()
                .map(|(d, w)| w * texels[self.global.texel_of(&from_local(&frame, d))])
                .sum();
        }
        haar::forward(local, self.local.n);
    }
    fn apply_transpose_add(&self, normal_env: &Vec3, local: &[f64], global: &mut [f64]) {
        let mut lt = local.to_vec();
        haar::inverse(&mut lt, self.local.n);
        let frame = local_frame(normal_env);
        let mut acc = vec![0.0; self.global.len()];
        for (t, &x) in lt.iter().enumerate() {
            if x == 0.0 {
                continue;
            }
            for (d, w) in &self.subs[t] {
                acc[self.global.texel_of(&from_local(&frame, d))] += w * x;
            }
        }
        haar::forward(&mut acc, self.global.n);
        for (g, a) in global.iter_mut().zip(&acc) {
            *g += a;
        }
    }
}
