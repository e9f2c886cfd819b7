//! The variable-projection step inside the alternation ([`crate::solve::varpro_step`]: its
//! math), right after a round's lighting step and ratio step.

use super::{Alternation, BestIterate, Snapshot};
use crate::solve::light::LightModel;
use crate::solve::objective::weighted_residuals;
use crate::solve::problem::{basis_responses, beta_per_vertex, predict_from};
use crate::solve::validation::EarlyStop;
use crate::solve::varpro_step::{self as vp, Jacobian, Parameter};
use crate::Result;

/// The reduced residual at the current `λ` (the lights re-solved) and its Jacobian.
struct Linearised {
    r0: Vec<[f64; 3]>,
    jac: Jacobian,
}

/// What one try of `λ + t Δ` saw: whether a channel kept it, the move it made (before
/// the channels that refused it went back) and, for Broyden's update
/// ([`crate::solve::EstimateOptions::varpro_broyden`]), the residual there.
struct Tried {
    kept: bool,
    s: Vec<[f64; 3]>,
    r: Option<Vec<[f64; 3]>>,
}

impl Tried {
    /// Broyden's update of `jac` by this try's move and the residual change it made
    /// from `r0` ([`vp::broyden_update`]); nothing when the try kept no residual.
    fn secant_update(&self, jac: &mut Jacobian, r0: &[[f64; 3]]) {
        let Some(r) = &self.r else {
            return;
        };
        let dr: Vec<[f64; 3]> = r
            .iter()
            .zip(r0)
            .map(|(a, b)| [0, 1, 2].map(|c| a[c] - b[c]))
            .collect();
        vp::broyden_update(jac, &self.s, &dr);
    }
}

impl<M: LightModel> Alternation<'_, M> {
    /// The step in the first [`crate::solve::EstimateOptions::varpro_steps`] rounds: the
    /// materials' `λ` moved per channel where `F` drops and the held-back observations of
    /// early stopping are predicted no worse.
    pub(super) fn varpro_step(
        &mut self,
        outer_it: usize,
        stop: &EarlyStop<BestIterate<M::Params>>,
    ) -> Result<()> {
        if outer_it > self.opts.varpro_steps {
            return Ok(());
        }
        let Some(f0) = self.channel_objective() else {
            self.varpro_moves.unsupported += 1;
            return Ok(());
        };
        let (base, omega0) = (self.snapshot(), self.omega.clone());
        let params = self.varpro_parameters(&base.lambda);
        self.light.hold_shape(true);
        let lin = self.linearise(outer_it, &base, &omega0, &params);
        self.light.hold_shape(false);
        let Linearised { r0, mut jac } = lin?;
        let delta = vp::steps(&vp::normal_equations(&jac, &r0), vp::DAMPING);
        self.varpro_moves.tried += 1;
        for scale in [1.0, 0.25] {
            let t = [scale; 3];
            let tried =
                self.varpro_try(outer_it, (&base, &omega0), (&params, &delta), t, f0, stop)?;
            tried.secant_update(&mut jac, &r0);
            if tried.kept {
                self.varpro_moves.kept += 1;
                self.varpro_jacobian = self.opts.varpro_broyden.then_some(jac);
                return Ok(());
            }
        }
        self.varpro_jacobian = None;
        self.restore(base);
        self.omega = omega0;
        Ok(())
    }

    /// Every `(k, b)` of `lambda` but the pruned lobes ([`crate::solve::lobe_prune`]).
    fn varpro_parameters(&self, lambda: &[Vec<[f64; 3]>]) -> Vec<Parameter> {
        let nb = lambda.first().map_or(0, Vec::len);
        vp::parameters(lambda)
            .into_iter()
            .filter(|p| {
                !self
                    .pruned
                    .get(p.material * nb + p.lobe)
                    .copied()
                    .unwrap_or(false)
            })
            .collect()
    }

    /// The residual at `base.lambda`, the lights re-solved from `base.light`, and its
    /// Jacobian: Broyden's from the last kept step when
    /// [`crate::solve::EstimateOptions::varpro_broyden`] carried one over (and this is no
    /// refresh round), else by forward differences (one more lighting step per parameter).
    fn linearise(
        &mut self,
        outer_it: usize,
        base: &Snapshot<M::Params>,
        omega0: &[[f32; 3]],
        params: &[Parameter],
    ) -> Result<Linearised> {
        let at = |alt: &mut Self, lambda: Vec<Vec<[f64; 3]>>| -> Result<Vec<[f64; 3]>> {
            alt.restore(base.clone());
            alt.omega.copy_from_slice(omega0);
            alt.lambda = lambda;
            alt.lighting(outer_it)?;
            Ok(alt.residuals(omega0))
        };
        let refresh = self.opts.varpro_refresh;
        let carried = self
            .varpro_jacobian
            .take()
            .filter(|_| refresh == 0 || !(outer_it - 1).is_multiple_of(refresh));
        let r0 = at(self, base.lambda.clone())?;
        if let Some(jac) = carried {
            return Ok(Linearised { r0, jac });
        }
        let probes = params
            .iter()
            .map(|p| at(self, vp::probed(&base.lambda, p)))
            .collect::<Result<Vec<_>>>()?;
        let jac = vp::forward_differences(&probes, &r0, params);
        Ok(Linearised { r0, jac })
    }

    /// `√(α ω) r` at the current state with the IRLS weights `omega`.
    fn residuals(&self, omega: &[[f32; 3]]) -> Vec<[f64; 3]> {
        let maps = self.light.maps(self.light.params());
        let s = basis_responses(self.problem, &maps);
        let beta = beta_per_vertex(&self.lambda, &self.weights, self.problem.n_vertices);
        weighted_residuals(self.problem, &predict_from(self.problem, &beta, &s), omega)
    }

    /// `λ + t Δ` with the lights re-solved from `base`'s, kept per channel where `F_c`
    /// drops below `f0`'s and then only when the held-back observations are predicted no
    /// worse (otherwise the state is `base` again); what the try saw, for Broyden's update.
    fn varpro_try(
        &mut self,
        outer_it: usize,
        (base, omega0): (&Snapshot<M::Params>, &[[f32; 3]]),
        (params, delta): (&[Parameter], &[[f64; 3]]),
        t: [f64; 3],
        f0: [f64; 3],
        stop: &EarlyStop<BestIterate<M::Params>>,
    ) -> Result<Tried> {
        self.restore(base.clone());
        self.omega.copy_from_slice(omega0);
        self.lambda = vp::moved(&base.lambda, params, delta, t);
        let s: Vec<[f64; 3]> = params
            .iter()
            .map(|p| {
                let (a, b) = (
                    self.lambda[p.material][p.lobe],
                    base.lambda[p.material][p.lobe],
                );
                [0, 1, 2].map(|c| a[c] - b[c])
            })
            .collect();
        self.lighting(outer_it)?;
        let r = self.opts.varpro_broyden.then(|| self.residuals(omega0));
        self.omega.copy_from_slice(omega0);
        let ft = self.channel_objective().unwrap_or([f64::INFINITY; 3]);
        let keep = [0, 1, 2].map(|c| ft[c] < f0[c]);
        let mut tried = Tried { kept: false, s, r };
        if !keep.iter().any(|&k| k) {
            self.restore(base.clone());
            return Ok(tried);
        }
        let on = keep.map(|k| f64::from(u8::from(k)));
        let mixed = self.light.combine(&[
            (self.light.params(), on),
            (&base.light, on.map(|v| 1.0 - v)),
        ]);
        let Some(mixed) = mixed else {
            self.restore(base.clone());
            return Ok(tried);
        };
        self.light.set_params(mixed);
        self.lambda = vp::moved(&base.lambda, params, delta, [0, 1, 2].map(|c| t[c] * on[c]));
        tried.kept = self.held_no_worse(stop, base);
        if !tried.kept {
            self.restore(base.clone());
        }
        Ok(tried)
    }
}
