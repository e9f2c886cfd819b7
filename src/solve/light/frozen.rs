//! The lighting step with the reflectance frozen on a schedule of IRLS passes (held-out
//! protocol (b), `run::half_fit`): the objective of [`super::photo`] (Eq. 10 with the
//! Laplacian, the light prior and the robust IRLS weights),
//! `min_x ½ xᵀ(Wᵀ Aᵀ D_k A W + μ ΔᵀΔ) x − (Wᵀ Aᵀ D_k y)ᵀ x`, `x ≥ 0`, solved once per IRLS
//! pass `k` (`D_k = α ω_k`, the weights of pass `k − 1`'s residuals, unit in the first),
//! each pass by the same scaled GPCG from the previous pass's light, with its own
//! iteration caps.
//!
//! [`super::photo::lighting_step_full`] gives every pass the same caps. The passes before
//! the last only set the weights of the next, and a pass's weights depend on its light only
//! through the residuals' Huber clipping and their median, so a schedule may spend fewer
//! products there than on the last pass. With equal caps the answer is the lighting
//! step's, bit for bit (test below). Measured on protocol (b) in
//! `bench-results/speed-evaluation-4.md`.

// Numerical kernels index several arrays in step; range loops read like the math.
#![allow(clippy::needless_range_loop)]

use crate::solve::light::irls::pass_weights;
use crate::solve::light::laplacian::Laplacian;
use crate::solve::light::photo::{
    jacobi_scaling, set_pass_weights, smoothness_weights, solve_pass, start_texels, take_pass,
    PassSystem, PhotoData, QpStats,
};
use crate::solve::light::sh_prior::ShProjection;
use crate::solve::light::system::{split3, texel_diag_vec, PhotoSystem};
use crate::solve::options::{EstimateOptions, Robust};
use crate::solve::problem::Problem;
use crate::Result;

/// The caps of one IRLS pass: GPCG iterations and CG steps per GPCG iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PassCaps {
    /// GPCG iterations.
    pub gpcg: usize,
    /// CG steps per GPCG iteration (each one Hessian product).
    pub cg: usize,
}

/// A scheduled fit's light and its cost.
#[derive(Debug, Clone)]
pub struct ScheduledLight {
    /// Texels per channel, `≥ 0`.
    pub light: [Vec<f64>; 3],
    /// Hessian products over every pass.
    pub matvecs: usize,
    /// Whether every pass met the KKT tolerance (`opts.qp_rel_tol`).
    pub converged: bool,
}

/// Photo `photo`'s light with `beta` frozen, from `start` (`None`: zero), one IRLS pass per
/// entry of `passes` (module docs); without a robust loss, one pass with the last entry's
/// caps. `opts.qp_rel_tol` is every pass's stopping rule, its iteration caps are unused.
pub fn fit_light_scheduled(
    problem: &Problem,
    beta: &[[f64; 3]],
    photo: usize,
    start: Option<&[Vec<f64>; 3]>,
    opts: &EstimateOptions,
    passes: &[PassCaps],
) -> Result<ScheduledLight> {
    let n = problem.transport.n_global;
    let n2 = n * n;
    let data = PhotoData::new(problem, photo, None);
    let dw0 = data.alpha.iter().map(|&a| [a; 3]).collect();
    let mut sys = PhotoSystem::new(problem, beta, data.rows(), n, dw0, opts.blend_tolerance);
    let tdiag = texel_diag_vec(problem, beta, data.rows(), &data.alpha);
    let mu = smoothness_weights(problem, beta, &data, &sys, Some(&tdiag), opts);
    let lap = Laplacian::new(n);
    let jacobi = jacobi_scaling(Some(&tdiag), &lap, mu, n2);
    let mut x = start_texels(start, n2)?;
    let mut omega = vec![[1.0_f64; 3]; data.range.len()];
    let prior_proj = opts.light_prior.as_ref().map(|_| ShProjection::new(n, 4));
    let y_ms = data.mean_square();
    let mut stats = QpStats::new();
    let passes = match (opts.robust, passes.last()) {
        (Robust::None, Some(last)) => std::slice::from_ref(last),
        _ => passes,
    };
    for (pass, caps) in passes.iter().enumerate() {
        pass_weights(problem, beta, &sys, &x, &data, opts, pass > 0, &mut omega);
        set_pass_weights(&mut sys, &data, &omega);
        let system = PassSystem::new(&sys, &lap, mu, jacobi.as_deref(), opts, &prior_proj, y_ms);
        let pass_opts = EstimateOptions {
            qp_max_iter: caps.gpcg,
            qp_max_cg: caps.cg,
            ..opts.clone()
        };
        let res = solve_pass(&system, &data, &x, &pass_opts, photo)?;
        take_pass(res, &mut x, &mut stats);
    }
    Ok(ScheduledLight {
        light: split3(&x, n2),
        matvecs: stats.matvecs,
        converged: stats.converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::light::photo::lighting_step_full;
    use crate::solve::light::tests::{one_photo, planted_photo};

    /// 2,000 observations over a 16² map, 1% noise, every 8th a gross outlier (× 4): the
    /// robust loss has work to do in every pass.
    fn outlier_photo() -> (crate::observe::Observations, crate::transport::Transport) {
        let (mut obs, t) = planted_photo(2000, 16, 0.01, 11);
        for rgb in obs.rgb.iter_mut().step_by(8) {
            *rgb = rgb.map(|v| 4.0 * v);
        }
        (obs, t)
    }

    fn max_rel_diff(a: &[Vec<f64>; 3], b: &[Vec<f64>; 3]) -> f64 {
        let scale = b.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()))
            / scale
    }

    #[test]
    fn equal_caps_give_the_lighting_step_bit_for_bit() {
        // Capped passes (not converged: the path matters), from a non-zero start: the
        // schedule of three equal entries must be the lighting step's own three passes.
        let (obs, t) = outlier_photo();
        let problem = one_photo(&obs, &t);
        let beta = vec![[1.0; 3]; obs.len()];
        let opts = EstimateOptions {
            smoothness: 1e-4,
            irls_iters: 3,
            qp_max_iter: 3,
            qp_max_cg: 4,
            ..EstimateOptions::default()
        };
        let start: [Vec<f64>; 3] = [0, 1, 2].map(|c| vec![0.5 + 0.1 * c as f64; 256]);
        let step = lighting_step_full(&problem, &beta, 0, Some(&start), None, &opts).unwrap();
        let caps = PassCaps { gpcg: 3, cg: 4 };
        let s = fit_light_scheduled(&problem, &beta, 0, Some(&start), &opts, &[caps; 3]).unwrap();
        assert!(
            !s.converged,
            "the caps must bind for the test to mean anything"
        );
        assert_eq!(s.matvecs, step.matvecs);
        assert_eq!(s.light, step.light);
    }

    #[test]
    fn short_early_passes_then_a_converged_last_reach_the_robust_minimiser() {
        // The reference: the lighting step's three IRLS passes, each to the KKT tolerance
        // 1e-10 (a long solve). A schedule of two 2-iteration passes and a converged third
        // is a shorter path to the third pass's weights; its last pass solves its QP
        // exactly, so the light differs from the reference only through the weights,
        // which depend on the light through the residuals' Huber clipping and median.
        // It must sit within 1% of the map's peak of the reference, and at least 4×
        // nearer to it than the least-squares fit (no robust loss), which the 12.5%
        // outliers pull off.
        let (obs, t) = outlier_photo();
        let problem = one_photo(&obs, &t);
        let beta = vec![[1.0; 3]; obs.len()];
        let long = EstimateOptions {
            smoothness: 1e-4,
            irls_iters: 3,
            qp_rel_tol: 1e-10,
            qp_max_iter: 500,
            qp_max_cg: 50,
            ..EstimateOptions::default()
        };
        let reference = lighting_step_full(&problem, &beta, 0, None, None, &long).unwrap();
        assert!(reference.converged);
        let (cheap, full) = (PassCaps { gpcg: 2, cg: 20 }, PassCaps { gpcg: 500, cg: 50 });
        let s =
            fit_light_scheduled(&problem, &beta, 0, None, &long, &[cheap, cheap, full]).unwrap();
        assert!(s.matvecs < reference.matvecs);
        let plain = EstimateOptions {
            robust: Robust::None,
            ..long.clone()
        };
        let ls = fit_light_scheduled(&problem, &beta, 0, None, &plain, &[full]).unwrap();
        assert!(ls.converged);
        let (d, d_ls) = (
            max_rel_diff(&s.light, &reference.light),
            max_rel_diff(&ls.light, &reference.light),
        );
        assert!(d < 0.01, "scheduled fit {d} from the reference");
        assert!(d_ls > 4.0 * d, "least squares {d_ls}, scheduled {d}");
    }
}
