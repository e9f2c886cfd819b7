//! The variable-projection step inside the alternation ([`crate::solve::varpro_step`]: its
//! math), right after a round's lighting step and ratio step.

use super::{Alternation, BestIterate, Snapshot};
use crate::solve::light::LightModel;
use crate::solve::objective::weighted_residuals;
use crate::solve::problem::{basis_responses, beta_per_vertex, predict_from};
use crate::solve::validation::EarlyStop;
use crate::solve::varpro_step::{self as vp, Parameter};
use crate::Result;

/// The probes of one step: the residual at the current `λ` and at each probed entry,
/// all with the lights re-solved.
struct Probes {
    r0: Vec<[f64; 3]>,
    columns: Vec<Vec<[f64; 3]>>,
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
        let params = vp::parameters(&base.lambda);
        self.light.hold_shape(true);
        let probes = self.probe_all(outer_it, &base, &omega0, &params);
        self.light.hold_shape(false);
        let probes = probes?;
        let system = vp::normal_equations(&probes.columns, &probes.r0, &params);
        let delta = vp::steps(&system, vp::DAMPING);
        self.varpro_moves.tried += 1;
        for scale in [1.0, 0.25] {
            let t = [scale; 3];
            if self.varpro_try(outer_it, (&base, &omega0), (&params, &delta), t, f0, stop)? {
                self.varpro_moves.kept += 1;
                return Ok(());
            }
        }
        self.restore(base);
        self.omega = omega0;
        Ok(())
    }

    /// The residual at `base.lambda` and at each probe, the lights re-solved from
    /// `base.light` every time, all weighted by `omega0`.
    fn probe_all(
        &mut self,
        outer_it: usize,
        base: &Snapshot<M::Params>,
        omega0: &[[f32; 3]],
        params: &[Parameter],
    ) -> Result<Probes> {
        let at = |alt: &mut Self, lambda: Vec<Vec<[f64; 3]>>| -> Result<Vec<[f64; 3]>> {
            alt.restore(base.clone());
            alt.omega.copy_from_slice(omega0);
            alt.lambda = lambda;
            alt.lighting(outer_it)?;
            Ok(alt.residuals(omega0))
        };
        let r0 = at(self, base.lambda.clone())?;
        let columns = params
            .iter()
            .map(|p| at(self, vp::probed(&base.lambda, p)))
            .collect::<Result<Vec<_>>>()?;
        Ok(Probes { r0, columns })
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
    /// worse; whether any channel moved (otherwise the state is `base` again).
    fn varpro_try(
        &mut self,
        outer_it: usize,
        (base, omega0): (&Snapshot<M::Params>, &[[f32; 3]]),
        (params, delta): (&[Parameter], &[[f64; 3]]),
        t: [f64; 3],
        f0: [f64; 3],
        stop: &EarlyStop<BestIterate<M::Params>>,
    ) -> Result<bool> {
        self.restore(base.clone());
        self.omega.copy_from_slice(omega0);
        self.lambda = vp::moved(&base.lambda, params, delta, t);
        self.lighting(outer_it)?;
        self.omega.copy_from_slice(omega0);
        let ft = self.channel_objective().unwrap_or([f64::INFINITY; 3]);
        let keep = [0, 1, 2].map(|c| ft[c] < f0[c]);
        if !keep.iter().any(|&k| k) {
            self.restore(base.clone());
            return Ok(false);
        }
        let on = keep.map(|k| f64::from(u8::from(k)));
        let mixed = self.light.combine(&[
            (self.light.params(), on),
            (&base.light, on.map(|v| 1.0 - v)),
        ]);
        let Some(mixed) = mixed else {
            self.restore(base.clone());
            return Ok(false);
        };
        self.light.set_params(mixed);
        self.lambda = vp::moved(&base.lambda, params, delta, [0, 1, 2].map(|c| t[c] * on[c]));
        let held_ok = self.held_no_worse(stop, base);
        if !held_ok {
            self.restore(base.clone());
        }
        Ok(held_ok)
    }
}
