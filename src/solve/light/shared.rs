//! Shared light (issue 25, not in the paper): photos taken under one sky share one
//! non-negative octahedral map, each photo seeing it through its own exposure and
//! white-balance gains.
//!
//! Photo `I` of group `g(I)` sees, per channel `c`, the map `x_{I,c} = a_{I,c} m_{g(I),c}`
//! with `m_{g,c} ≥ 0` (`n_global²` texels) and `a_{I,c} ≥ 0`. The lighting step minimises
//!
//! `Σ_I Σ_{p∈I} α_p ω_{p,c} (y_{p,c} − a_{I,c} ⟨e_{p,c}, W m_{g(I),c}⟩)² + Σ_g μ_{g,c} ‖Δ m_{g,c}‖²`
//!
//! (`e_{p,c} = Σ_b β_{x,b,c} g_{p,b}`, Eq. 8; the Laplacian prior of the paper's Eq. 10 on
//! each shared map) by block coordinate descent, [`INNER_ROUNDS`] rounds per IRLS pass:
//! 1. **map**, gains fixed: one bound-constrained QP per group, the paper's Eq. 10 over the
//!    group's photos with photo `I`'s rows weighted by `a_{I,c}²` and its right-hand side by
//!    `a_{I,c}`: `H = Σ_I a_I² Wᵀ A_Iᵀ D_I A_I W + μ ΔᵀΔ`, `b = Σ_I a_I Wᵀ A_Iᵀ D_I y_I`,
//!    solved matrix-free from the previous map ([`crate::solve::qp::bound_qp_scaled`]);
//! 2. **gains**, map fixed: per photo and channel the closed form of a one-variable
//!    non-negative least squares, `a_{I,c} = max(0, Σ_p d_p y_p s_p / Σ_p d_p s_p²)` with
//!    `s_p = ⟨e_{p,c}, W m_{g,c}⟩` and `d_p = α_p ω_{p,c}`;
//! 3. **gauge**: `a m` is invariant under `a → a t`, `m → m / t`; per group and channel the
//!    mean gain is set to 1, the map taking the factor (the data term is unchanged).
//!
//! Each step lowers (or keeps) the data term for the other's value, so the step is monotone
//! in it. A group of one photo is the paper's model with a gain fixed at 1. IRLS (Huber or
//! Tukey, [`crate::solve::light::photo`]) reweighs each photo from its own residuals under
//! `a_I m_g`, restarting from unit weights at every call as the paper's step does, and
//! clipped channels read as lower bounds leave each pass where its start meets them
//! ([`crate::solve::light::bounds`], as in the paper's step); the
//! lighting sample ([`crate::solve::EstimateOptions::lighting_sample`]) applies per photo.
//! `μ_{g,c}` = `smoothness` × the largest texel-basis diagonal entry of the group's
//! system at its first lighting step, decayed as the paper's
//! (`smoothness_decay`, `smoothness_min`). The statistical prior of
//! [`crate::solve::light::sh_prior`] is not applied here.
//!
//! **Backgrounds** ([`EstimateOptions::background`], [`crate::solve::light::background`]):
//! photo `I`'s background texels add `γ n_t (a_{I,c} m_{g,t,c} − ȳ_{I,t,c})²`. The map step
//! gains `a_{I,c}² γ n_t` on its diagonal and `a_{I,c} γ n_t ȳ` in `b`, the gain step
//! `Σ_t γ n_t ȳ m` and `Σ_t γ n_t m²` in its sums, and the gauge leaves `a m`, so the
//! term, unchanged. Under one map, a photo's background is the light on the side of the
//! object that the group's photos from the other side see.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use std::borrow::Cow;

use rayon::prelude::*;

use crate::solve::light::background::PhotoBackground;
use crate::solve::light::irls::pass_weights;
use crate::solve::light::laplacian::{
    combine_maps, extrapolate_maps, smoothness_factor, WeightedMaps,
};
use crate::solve::light::map_fit::MapFitState;
use crate::solve::light::photo::PhotoData;
use crate::solve::light::system::{split3, texel_diag_vec, unhaar3, PhotoSystem};
use crate::solve::light::{LightModel, LightingInput, LightingOutput};
pub use crate::solve::options::LightGroups;
use crate::solve::options::{EstimateOptions, Robust};
use crate::solve::problem::{haar3, par_largest_first, Problem};
use crate::solve::qp::{bound_qp_scaled, QpOptions, QpResult};
use crate::solve::result::{Conditioning, Materials0};
use crate::solve::subsample::{SampleCheck, Subsample};
use crate::{Error, Result};

/// Map / gains rounds per IRLS pass of one lighting step. Two: the first round's map
/// is fitted with the previous gains, the second's with gains matched to it.
pub const INNER_ROUNDS: usize = 2;

/// The shared model's parameters: a map per group and gains per photo.
#[derive(Clone, Debug)]
pub struct SharedParams {
    /// `m_{g,c}`: texels per group and channel.
    pub maps: Vec<[Vec<f64>; 3]>,
    /// `a_{I,c}` per photo.
    pub gains: Vec<[f64; 3]>,
}

/// One photo's data inside a lighting step.
struct PhotoWork {
    data: PhotoData,
    sys: PhotoSystem,
    /// Texel-basis diagonal of the photo's data term (α, no IRLS, no gain).
    tdiag: Vec<[f64; 3]>,
    /// IRLS weights of every observation of the photo (range order).
    omega: Vec<[f64; 3]>,
}

/// A group's normal equations before the smoothness term ([`SharedLight::group_normal`]).
struct GroupNormal {
    /// Diagonal of the data term, per texel and channel.
    diag: Vec<[f64; 3]>,
    /// Right-hand side in Haar coefficients.
    hb: Vec<[f64; 3]>,
}

/// One group's QP answer.
struct GroupSolve {
    map: [Vec<f64>; 3],
    mu: [f64; 3],
    res: Option<QpResult>,
}

/// The shared-sky light model (module docs).
pub struct SharedLight {
    params: SharedParams,
    groups: LightGroups,
    members: Vec<Vec<usize>>,
    /// The Laplacian prior's weights `μ_{g,c}` per group, the options and the lighting
    /// sample.
    state: MapFitState,
}

impl SharedLight {
    /// Each photo's system and data for this lighting step (the lighting sample drawn once
    /// per fit, on the first call).
    fn photo_work(&mut self, problem: &Problem, beta: &[[f64; 3]]) -> Vec<PhotoWork> {
        let sizes: Vec<usize> = problem.obs.photo_ranges.iter().map(|r| r.len()).collect();
        self.state.draw_samples(problem);
        let samples = self.state.samples();
        par_largest_first(&sizes, |i| {
            PhotoWork::new(
                problem,
                beta,
                i,
                samples[i].as_ref(),
                self.state.opts.blend_tolerance,
            )
        })
    }

    /// One map step for every group ([`Self::map_step`], largest groups first), with the
    /// solver's record in `cond`.
    fn maps_round(
        &mut self,
        problem: &Problem,
        work: &[PhotoWork],
        mu_factor: f64,
        cond: &mut Conditioning,
    ) -> Result<()> {
        let capped = self.state.capped();
        let group_sizes: Vec<usize> = self
            .members
            .iter()
            .map(|m| m.iter().map(|&i| problem.obs.photo_ranges[i].len()).sum())
            .collect();
        let solved: Vec<Result<GroupSolve>> =
            par_largest_first(&group_sizes, |g| self.map_step(work, g, mu_factor));
        for (g, s) in solved.into_iter().enumerate() {
            let s = s?;
            self.params.maps[g] = s.map;
            self.state.record_mu(g, s.mu);
            if let Some(r) = s.res {
                cond.qp_unconverged += usize::from(!r.converged);
                cond.qp_alternation_capped += usize::from(capped && !r.converged);
                cond.lighting_matvecs += r.matvecs;
                cond.lighting_qps += 1;
                cond.lighting_matvecs_max = cond.lighting_matvecs_max.max(r.matvecs);
                for &i in &self.members[g] {
                    if r.cond_lower_bound.is_finite() {
                        cond.lighting[i] = r.cond_lower_bound;
                    }
                }
            }
        }
        Ok(())
    }

    /// Zero maps, unit gains; `groups` must give one group per photo of `problem`.
    pub fn new(
        problem: &Problem,
        opts: &EstimateOptions,
        init: &Materials0,
        groups: &LightGroups,
    ) -> Result<Self> {
        if groups.group.len() != problem.n_photos {
            return Err(Error::Internal(format!(
                "shared light: {} photo groups for {} photos",
                groups.group.len(),
                problem.n_photos
            )));
        }
        let n2 = problem.transport.n_global.pow(2);
        let n_groups = groups.n_groups();
        Ok(SharedLight {
            params: SharedParams {
                maps: vec![[vec![0.0; n2], vec![0.0; n2], vec![0.0; n2]]; n_groups],
                gains: vec![[1.0; 3]; problem.n_photos],
            },
            members: groups.members(),
            groups: groups.clone(),
            state: MapFitState::new(n_groups, problem.transport.n_global, opts, init),
        })
    }

    /// Photo `i`'s background term on an `n²` map, when on.
    fn background(&self, i: usize, n: usize) -> Option<PhotoBackground<'_>> {
        self.state.opts.background.as_ref()?.photo(i, n)
    }

    /// The background term of `F` per channel at `params`, each photo seeing its group's
    /// map through its gains ([`MapFitState::background_penalty`]).
    fn background_penalty(&self, params: &SharedParams) -> [f64; 3] {
        let photo_maps = (self.groups.group.iter().enumerate())
            .map(|(i, &g)| (&params.maps[g], params.gains[i]));
        self.state.background_penalty(photo_maps)
    }

    fn photo_texels(params: &SharedParams, g: usize, i: usize) -> Vec<f64> {
        let (m, a) = (&params.maps[g], params.gains[i]);
        (0..3)
            .flat_map(|c| m[c].iter().map(move |v| a[c] * v))
            .collect()
    }

    /// Sets each photo's QP weights `d_p a_{I,c}²` from its IRLS weights and gain.
    fn set_row_weights(&self, work: &mut [PhotoWork]) {
        let gains = &self.params.gains;
        work.par_iter_mut().enumerate().for_each(|(i, w)| {
            let a = gains[i];
            for (r, &q) in w.data.pos.iter().enumerate() {
                for c in 0..3 {
                    w.sys.dw[r][c] = w.data.alpha[r] * w.omega[q][c] * a[c] * a[c];
                }
            }
        });
    }

    /// Step 1 for group `g` (module docs).
    fn map_step(&self, work: &[PhotoWork], g: usize, mu_factor: f64) -> Result<GroupSolve> {
        let n = self.lap_n(work);
        let n2 = n * n;
        let members = &self.members[g];
        let GroupNormal { diag, hb } = self.group_normal(work, g, n2);
        let mu = self.group_mu(g, &diag, mu_factor);
        let mut b = unhaar3(&hb, n);
        // The members' backgrounds, each through its photo's gains
        // ([`crate::solve::light::background`]).
        let backgrounds: Vec<_> = members
            .iter()
            .filter_map(|&i| Some((self.background(i, n)?, self.params.gains[i])))
            .collect();
        for (bg, a) in &backgrounds {
            bg.add_rhs(&mut b, *a);
        }
        let start: Vec<f64> = self.params.maps[g].iter().flatten().copied().collect();
        let bmax = b.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        if bmax == 0.0 {
            // No light reaches a weighted observation: the minimiser is 0.
            let zero = [vec![0.0; n2], vec![0.0; n2], vec![0.0; n2]];
            return Ok(GroupSolve {
                map: zero,
                mu,
                res: None,
            });
        }
        let ld = self.state.lap.normal_diag();
        let mut jacobi: Vec<f64> = (0..3)
            .flat_map(|c| (0..n2).map(move |t| (c, t)))
            .map(|(c, t)| diag[t][c] + mu[c] * ld[t])
            .collect();
        for (bg, a) in &backgrounds {
            bg.add_diagonal(&mut jacobi, *a);
        }
        let hess = |v: &[f64], out: &mut [f64]| {
            let h = haar3(&split3(v, n2), n);
            let mut acc = vec![[0.0; 3]; n2];
            for &i in members {
                work[i].sys.normal_rows(&h, &mut acc);
            }
            out.copy_from_slice(&unhaar3(&acc, n));
            for c in 0..3 {
                let r = c * n2..(c + 1) * n2;
                self.state.lap.add_normal(&v[r.clone()], mu[c], &mut out[r]);
            }
            for (bg, a) in &backgrounds {
                bg.add_normal(v, out, *a);
            }
        };
        let qp = QpOptions {
            tol: self.state.opts.qp_rel_tol * bmax,
            max_iter: self.state.light_opts.qp_max_iter,
            max_cg: self.state.light_opts.qp_max_cg.max(1),
        };
        let res =
            bound_qp_scaled(hess, &b, &start, &qp, Some(&jacobi)).map_err(|e| Error::Numeric {
                stage: format!("shared lighting step, group {g}"),
                message: e.to_string(),
            })?;
        Ok(GroupSolve {
            map: split3(&res.x, n2),
            mu,
            res: Some(res),
        })
    }

    /// The group's normal equations in the pixel basis: the diagonal of `Σ_i a_i² TᵀWT`
    /// and the right-hand side `Σ_i Tᵀ W (a_i ∘ y_i)` (still in Haar coefficients), summed
    /// over the group's photos `i` with their gains `a_i`.
    fn group_normal(&self, work: &[PhotoWork], g: usize, n2: usize) -> GroupNormal {
        let gains = &self.params.gains;
        let mut diag = vec![[0.0_f64; 3]; n2];
        let mut hb = vec![[0.0_f64; 3]; n2];
        for &i in &self.members[g] {
            let (w, a) = (&work[i], gains[i]);
            for (d, t) in diag.iter_mut().zip(&w.tdiag) {
                for c in 0..3 {
                    d[c] += a[c] * a[c] * t[c];
                }
            }
            let u: Vec<[f64; 3]> = (0..w.data.pos.len())
                .map(|r| {
                    let q = w.data.pos[r];
                    [0, 1, 2].map(|c| w.data.alpha[r] * w.omega[q][c] * a[c] * w.data.y[r][c])
                })
                .collect();
            w.sys.adjoint_rows(&u, &mut hb);
        }
        GroupNormal { diag, hb }
    }

    /// The smoothness weight `μ` per channel: the group's first one times `mu_factor`, or
    /// at the first step `smoothness` times the largest diagonal entry.
    fn group_mu(&self, g: usize, diag: &[[f64; 3]], mu_factor: f64) -> [f64; 3] {
        match self.state.mu_first[g] {
            Some(m) => m.map(|v| v * mu_factor),
            None => diag.iter().fold([0.0_f64; 3], |mut m, v| {
                for c in 0..3 {
                    m[c] = m[c].max(self.state.opts.smoothness * v[c]);
                }
                m
            }),
        }
    }

    fn lap_n(&self, work: &[PhotoWork]) -> usize {
        work.first().map_or(1, |w| w.sys.n)
    }

    /// Step 2 (module docs): every photo's gains in closed form.
    fn gain_step(&mut self, work: &[PhotoWork]) {
        let n = self.lap_n(work);
        let hmaps: Vec<Vec<[f64; 3]>> = self.params.maps.iter().map(|m| haar3(m, n)).collect();
        let groups = &self.groups.group;
        let old = &self.params.gains;
        let gains: Vec<[f64; 3]> = work
            .par_iter()
            .enumerate()
            .map(|(i, w)| {
                let mut s = vec![[0.0; 3]; w.data.pos.len()];
                w.sys.forward_rows(&hmaps[groups[i]], &mut s);
                let (mut num, mut den) = self.background(i, n).map_or(([0.0; 3], [0.0; 3]), |bg| {
                    bg.gain_sums(&self.params.maps[groups[i]])
                });
                for (r, &q) in w.data.pos.iter().enumerate() {
                    for c in 0..3 {
                        let d = w.data.alpha[r] * w.omega[q][c];
                        num[c] += d * w.data.y[r][c] * s[r][c];
                        den[c] += d * s[r][c] * s[r][c];
                    }
                }
                [0, 1, 2].map(|c| {
                    if den[c] > 0.0 {
                        (num[c] / den[c]).max(0.0)
                    } else {
                        old[i][c]
                    }
                })
            })
            .collect();
        self.params.gains = gains;
    }

    /// Step 3 (module docs): the mean gain of every group and channel becomes 1.
    fn balance_gains(&mut self) {
        balance(&mut self.params, &self.members);
    }
}

/// The gauge of step 3 on `params` (module docs).
fn balance(params: &mut SharedParams, members: &[Vec<usize>]) {
    for (g, m) in members.iter().enumerate() {
        for c in 0..3 {
            let t = m.iter().map(|&i| params.gains[i][c]).sum::<f64>() / m.len().max(1) as f64;
            if t > 0.0 && t.is_finite() {
                m.iter().for_each(|&i| params.gains[i][c] /= t);
                params.maps[g][c].iter_mut().for_each(|v| *v *= t);
            }
        }
    }
}

impl PhotoWork {
    fn new(
        problem: &Problem,
        beta: &[[f64; 3]],
        photo: usize,
        sample: Option<&Subsample>,
        blend_tolerance: f64,
    ) -> Self {
        let n = problem.transport.n_global;
        let data = PhotoData::new(problem, photo, sample);
        let dw = data.alpha.iter().map(|&a| [a; 3]).collect();
        let sys = PhotoSystem::new(problem, beta, data.rows(), n, dw, blend_tolerance);
        let tdiag = texel_diag_vec(problem, beta, data.rows(), &data.alpha);
        let omega = vec![[1.0; 3]; data.range.len()];
        PhotoWork {
            data,
            sys,
            tdiag,
            omega,
        }
    }
}

impl LightModel for SharedLight {
    type Params = SharedParams;

    fn name(&self) -> &'static str {
        "shared: one free wavelet map per group of photos, per-photo exposure and white-balance gains"
    }

    fn parameter_count(&self) -> usize {
        let n2 = self.params.maps.first().map_or(0, |m| m[0].len());
        self.params.maps.len() * 3 * n2 + 3 * self.params.gains.len()
    }

    fn fit(&mut self, input: &LightingInput, out: &mut LightingOutput) -> Result<()> {
        let problem = input.problem;
        let beta = input.beta;
        let mu_factor = smoothness_factor(&self.state.opts, input.outer_iteration);
        let mut work = self.photo_work(problem, beta);
        let passes = if self.state.opts.robust == Robust::None {
            1
        } else {
            self.state.opts.irls_iters.max(1)
        };
        let cond = &mut *out.conditioning;
        cond.lighting = vec![0.0; problem.n_photos];
        cond.qp_unconverged = 0;
        cond.qp_alternation_capped = 0;
        for pass in 0..passes {
            let (params, groups) = (&self.params, &self.groups.group);
            let opts = &self.state.opts;
            work.par_iter_mut().enumerate().for_each(|(i, w)| {
                let reweigh = pass > 0;
                if reweigh || w.data.has_bounds() {
                    let x = SharedLight::photo_texels(params, groups[i], i);
                    pass_weights(
                        problem,
                        beta,
                        &w.sys,
                        &x,
                        &w.data,
                        opts,
                        reweigh,
                        &mut w.omega,
                    );
                }
            });
            for _ in 0..INNER_ROUNDS {
                self.set_row_weights(&mut work);
                self.maps_round(problem, &work, mu_factor, cond)?;
                self.gain_step(&work);
                self.balance_gains();
            }
        }
        let n2 = problem.transport.n_global.pow(2);
        debug_assert!(self.params.maps.iter().all(|m| m[0].len() == n2));
        for (i, w) in work.iter().enumerate() {
            let range = problem.obs.photo_ranges[i].clone();
            for (o, v) in out.irls_weights[range].iter_mut().zip(&w.omega) {
                *o = v.map(|x| x as f32);
            }
        }
        Ok(())
    }

    fn params(&self) -> &SharedParams {
        &self.params
    }

    fn set_params(&mut self, params: SharedParams) {
        self.params = params;
    }

    fn maps<'a>(&'a self, params: &'a SharedParams) -> Cow<'a, [[Vec<f64>; 3]]> {
        Cow::Owned(photo_maps(params, &self.groups.group))
    }

    fn penalty(&self, params: &SharedParams) -> f64 {
        self.state.penalty(&params.maps) + self.background_penalty(params).iter().sum::<f64>()
    }

    fn channel_penalty(&self, params: &SharedParams) -> Option<[f64; 3]> {
        let (lap, bg) = (
            self.state.channel_penalty(&params.maps),
            self.background_penalty(params),
        );
        Some([0, 1, 2].map(|c| lap[c] + bg[c]))
    }

    /// The groups' maps and the photos' gains each mixed per channel with the weights,
    /// projected on `≥ 0`. `a m` is not linear in `(a, m)`, so this is the ratio step's
    /// interpolation of each factor, not of the photos' maps; the step keeps the result
    /// only where `F` drops. The ratio step's weights sum to one, so a group's mean gain
    /// stays 1.
    fn combine(&self, parts: &[(&SharedParams, [f64; 3])]) -> Option<SharedParams> {
        let maps: Vec<WeightedMaps> = parts.iter().map(|(p, w)| (p.maps.as_slice(), *w)).collect();
        let gains = (0..parts.first()?.0.gains.len())
            .map(|i| {
                [0, 1, 2].map(|c| {
                    let a: f64 = parts.iter().map(|(p, w)| w[c] * p.gains[i][c]).sum();
                    a.max(0.0)
                })
            })
            .collect();
        Some(SharedParams {
            maps: combine_maps(&maps)?,
            gains,
        })
    }

    fn extrapolate(&self, params: &SharedParams, prev: &SharedParams, sigma: f64) -> SharedParams {
        let ext = |a: f64, b: f64| (a + sigma * (a - b)).max(0.0);
        SharedParams {
            maps: extrapolate_maps(&params.maps, &prev.maps, sigma),
            gains: params
                .gains
                .iter()
                .zip(&prev.gains)
                .map(|(a, b)| [0, 1, 2].map(|c| ext(a[c], b[c])))
                .collect(),
        }
    }

    fn divide_channel(&mut self, c: usize, f: f64) {
        for m in self.params.maps.iter_mut() {
            m[c].iter_mut().for_each(|v| *v /= f);
        }
    }

    fn normalise(&mut self, s: f64) {
        for v in self.params.maps.iter_mut().flatten().flatten() {
            *v /= s;
        }
        self.state.normalise(s);
    }

    fn prior_weights(&self) -> Vec<[f64; 3]> {
        self.groups
            .group
            .iter()
            .map(|&g| self.state.mu[g].unwrap_or([0.0; 3]))
            .collect()
    }

    fn into_maps(self) -> Vec<[Vec<f64>; 3]> {
        photo_maps(&self.params, &self.groups.group)
    }

    fn sample_check(
        &self,
        problem: &Problem,
        lambda: &[Vec<[f64; 3]>],
        weights: &[f64],
    ) -> Option<SampleCheck> {
        self.state.sample_check(problem, lambda, weights, || {
            Cow::Owned(photo_maps(&self.params, &self.groups.group))
        })
    }
}

/// Per photo, `a_{I,c} m_{g(I),c}`.
pub fn photo_maps(params: &SharedParams, group: &[usize]) -> Vec<[Vec<f64>; 3]> {
    group
        .iter()
        .enumerate()
        .map(|(i, &g)| {
            let a = params.gains[i];
            [0, 1, 2].map(|c| params.maps[g][c].iter().map(|v| a[c] * v).collect())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_number_by_first_appearance_and_list_their_members() {
        let g = LightGroups::from_labels(&["b", "a", "b", "c", "a"], "test".into());
        assert_eq!(g.group, vec![0, 1, 0, 2, 1]);
        assert_eq!(g.n_groups(), 3);
        assert_eq!(g.members(), vec![vec![0, 2], vec![1, 4], vec![3]]);
        assert!(g.any_shared());
        let single = LightGroups::from_labels(&[1, 2, 3], "test".into());
        assert!(!single.any_shared());
    }

    #[test]
    fn the_gauge_keeps_every_photos_map_and_sets_mean_gains_to_one() {
        // Two groups, gains with means (2, 0.5, 1) in group 0: a m per photo must be
        // unchanged to rounding (1e-12 relative) and the means exactly 1.
        let mut p = SharedParams {
            maps: vec![
                [vec![1.0, 2.0], vec![3.0, 4.0], vec![5.0, 6.0]],
                [vec![0.5, 0.5], vec![0.0, 1.0], vec![2.0, 0.0]],
            ],
            gains: vec![[1.0, 0.25, 0.5], [3.0, 0.75, 1.5], [0.3, 0.0, 7.0]],
        };
        let group = vec![0, 0, 1];
        let before = photo_maps(&p, &group);
        balance(&mut p, &[vec![0, 1], vec![2]]);
        let after = photo_maps(&p, &group);
        for (a, b) in before
            .iter()
            .flatten()
            .flatten()
            .zip(after.iter().flatten().flatten())
        {
            assert!((a - b).abs() <= 1e-12 * a.abs().max(1.0), "{a} vs {b}");
        }
        for c in 0..3 {
            assert!(((p.gains[0][c] + p.gains[1][c]) / 2.0 - 1.0).abs() < 1e-12);
        }
        // A zero-mean channel (all gains 0) is left alone, never divided by 0.
        assert_eq!(p.gains[2][1], 0.0);
        assert!(p.maps[1][1].iter().all(|v| v.is_finite()));
    }
}
