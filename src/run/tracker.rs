//! Held-out error as the estimator goes: the `timeline`'s `holdout_rmse` of the report,
//! one figure per outer iteration, from the held-out photos' observations and their own
//! transport rows ([`HoldoutTracker`]).

use super::truth::Truth;
use crate::import::photo::Photo;
use crate::observe::{self, Observations, ObserveOptions};
use crate::solve;
use crate::transport::{self, TransportOptions};
use crate::{Result, Vec3};
use nalgebra::Matrix3;

/// Held-out error as the estimator goes (the `timeline`'s `holdout_rmse`): the held-out
/// photos' observations predicted with the current reflectance under their true light
/// (protocol (a)) when the workspace has `truth/`, else under the mean of the current
/// training maps (protocol (c)); RMSE over observations with `α > 0`, after the best
/// global scale (the state before the final normalisation has an arbitrary scale).
/// At most [`TRACKER_MAX_OBSERVATIONS`] observations are tracked (every `k`-th, in photo
/// order, when there are more): their transport rows would otherwise cost a third of the
/// training rows' memory (3 of 13 photos held out) for a figure that 20,000 observations
/// already give to about 1% (the relative standard error of a mean square over `n`
/// roughly independent residuals is `√(2/n)`).
pub(crate) struct HoldoutTracker {
    obs: Observations,
    transport: crate::transport::Transport,
    /// Haar coefficients of each held-out view's true light, when known (by view order).
    truth: Option<Vec<[Vec<f64>; 3]>>,
    n_global: usize,
}

impl HoldoutTracker {
    /// Observations and transport of the held-out views; `None` when there are none.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        scene: &crate::import::scene::Scene,
        photos: &[Photo],
        held: &[usize],
        bvh: &crate::observe::trace::SceneBvh,
        normals_env: &[Vec3],
        env_from_world: &Matrix3<f64>,
        vis: &crate::transport::visibility::Visibility,
        basis: &[crate::transport::brdf::BasisBrdf],
        rot: &crate::sphere::rotation::Rotation,
        topts: &TransportOptions,
        truth: Option<&Truth>,
    ) -> Result<Option<Self>> {
        if held.is_empty() {
            return Ok(None);
        }
        let views: Vec<_> = held.iter().map(|&i| scene.views[i].clone()).collect();
        let ph: Vec<&Photo> = held.iter().map(|&i| &photos[i]).collect();
        let obs = observe::extract(&scene.mesh, bvh, &views, &ph, &ObserveOptions::default());
        let obs = every_kth(obs, TRACKER_MAX_OBSERVATIONS);
        if obs.weight.iter().all(|&w| w <= 0.0) {
            return Ok(None);
        }
        let transport =
            transport::build(normals_env, &obs, env_from_world, vis, basis, rot, topts)?;
        let truth = match truth {
            Some(t) => {
                let mut lights = Vec::new();
                for v in &views {
                    match t.light(&v.image.name, topts.n_global, env_from_world)? {
                        Some(env) => lights.push(transport::light_haar(&env)),
                        None => {
                            return Ok(Some(Self {
                                obs,
                                transport,
                                truth: None,
                                n_global: topts.n_global,
                            }))
                        }
                    }
                }
                Some(lights)
            }
            None => None,
        };
        Ok(Some(HoldoutTracker {
            obs,
            transport,
            truth,
            n_global: topts.n_global,
        }))
    }

    /// The scaled RMSE for the estimator's current state.
    pub(crate) fn rmse(&self, state: &solve::IterState, n_vertices: usize) -> f64 {
        let beta = solve::beta_per_vertex(state.lambda, state.weights, n_vertices);
        let mean_haar = || {
            let n2 = self.n_global * self.n_global;
            let k = state.lights.len().max(1) as f64;
            [0, 1, 2].map(|c| {
                let mut m = vec![0.0; n2];
                for l in state.lights {
                    for (a, b) in m.iter_mut().zip(&l[c]) {
                        *a += b / k;
                    }
                }
                crate::sphere::haar::forward(&mut m, self.n_global);
                m
            })
        };
        let mean = if self.truth.is_none() {
            Some(mean_haar())
        } else {
            None
        };
        let nb = self.transport.n_basis;
        let (mut syy, mut syp, mut spp, mut n) = (0.0, 0.0, 0.0, 0usize);
        for p in 0..self.obs.len() {
            if self.obs.weight[p] <= 0.0 {
                continue;
            }
            let light = match (&self.truth, &mean) {
                (Some(t), _) => &t[self.obs.photo[p] as usize],
                (None, Some(m)) => m,
                (None, None) => return f64::NAN,
            };
            let x = self.obs.vertex[p] as usize;
            for c in 0..3 {
                let pred: f64 = (0..nb)
                    .map(|b| beta[x * nb + b][c] * self.transport.response(p, b, &light[c]))
                    .sum();
                let y = self.obs.rgb[p][c] as f64;
                syy += y * y;
                syp += y * pred;
                spp += pred * pred;
            }
            n += 3;
        }
        if n == 0 {
            return f64::NAN;
        }
        let s = if spp > 0.0 { syp / spp } else { 0.0 };
        ((syy - 2.0 * s * syp + s * s * spp).max(0.0) / n as f64).sqrt()
    }
}

/// Observations the held-out tracker keeps at most ([`HoldoutTracker`]).
pub(crate) const TRACKER_MAX_OBSERVATIONS: usize =
    crate::solve::budget::HELD_OUT_TRACKED_MAX as usize;

/// Every `⌈len / max⌉`-th observation of `obs` (all of them when `len ≤ max`), photo
/// ranges recomputed.
fn every_kth(obs: Observations, max: usize) -> Observations {
    let n = obs.len();
    if n <= max || max == 0 {
        return obs;
    }
    let k = n.div_ceil(max);
    let kept: Vec<usize> = obs
        .photo_ranges
        .iter()
        .flat_map(|r| r.clone().filter(|p| p % k == 0))
        .collect();
    obs.gather(&kept)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kth_keeps_a_stride_and_its_photo_ranges() {
        // 10 observations, photos 0..6 and 6..10; at most 4 → every 3rd: 0, 3, | 6, 9.
        let mut obs = Observations::default();
        for p in 0..10u32 {
            obs.vertex.push(100 + p);
            obs.photo.push(u32::from(p >= 6));
            obs.rgb.push([p as f32; 3]);
            obs.weight.push(1.0);
            obs.dir.push([0.0, 0.0, 1.0]);
        }
        obs.photo_ranges = vec![0..6, 6..10];
        let small = every_kth(obs.clone(), 4);
        assert_eq!(small.vertex, vec![100, 103, 106, 109]);
        assert_eq!(small.photo, vec![0, 0, 1, 1]);
        assert_eq!(small.photo_ranges, vec![0..2, 2..4]);
        // At or under the cap nothing changes.
        assert_eq!(every_kth(obs.clone(), 10).vertex, obs.vertex);
    }
}
