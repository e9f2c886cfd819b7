//! The ratio step inside the alternation ([`crate::solve::ratio_step`]: its math), right
//! after a round's lighting step, and the two tests every move along the valley passes
//! (the variable-projection step's too): `F` per channel drops, and early stopping's
//! held-back observations are predicted no worse.

use super::{Alternation, BestIterate, Snapshot};
use crate::solve::light::LightModel;
use crate::solve::objective::channel_data_fit;
use crate::solve::problem::{basis_responses, beta_per_vertex, predict_from};
use crate::solve::ratio_step;
use crate::solve::validation::EarlyStop;
use crate::Result;

impl<M: LightModel> Alternation<'_, M> {
    /// `F` per channel at the current state (data, the light model's prior, ridge), when
    /// the light model's channels are separable.
    pub(super) fn channel_objective(&self) -> Option<[f64; 3]> {
        let params = self.light.params();
        let prior = self.light.channel_penalty(params)?;
        let maps = self.light.maps(params);
        let s = basis_responses(self.problem, &maps);
        let beta = beta_per_vertex(&self.lambda, &self.weights, self.problem.n_vertices);
        let pred = predict_from(self.problem, &beta, &s);
        let data = channel_data_fit(self.problem, &pred, &self.omega);
        let r = self.ridge.unwrap_or([0.0; 3]);
        Some([0, 1, 2].map(|c| {
            let rid: f64 = self
                .lambda
                .iter()
                .flatten()
                .map(|v| r[c] * v[c] * v[c])
                .sum();
            data[c] + prior[c] + rid
        }))
    }

    /// The ratio step ([`crate::solve::ratio_step`]) in the first
    /// [`EstimateOptions::ratio_steps`] rounds, right after the round's lighting step.
    pub(super) fn ratio_step(
        &mut self,
        outer_it: usize,
        stop: &EarlyStop<BestIterate<M::Params>>,
    ) -> Result<()> {
        let kk = self.lambda.len();
        if outer_it > self.opts.ratio_steps
            || ratio_step::directions(kk) == 0
            || self.ratio_moves.stopped_after.is_some()
        {
            return Ok(());
        }
        let Some(mut f0) = self.channel_objective() else {
            self.ratio_moves.unsupported += 1;
            return Ok(());
        };
        let kept_before = self.ratio_moves.kept;
        for j in 0..ratio_step::directions(kk) {
            let Some(f) = self.ratio_move(outer_it, j, f0, stop)? else {
                self.ratio_moves.unsupported += 1;
                return Ok(());
            };
            self.ratio_moves.tried += 1;
            f0 = f;
        }
        self.ratio_idle = if self.ratio_moves.kept > kept_before {
            0
        } else {
            self.ratio_idle + 1
        };
        if self.ratio_idle >= ratio_step::PATIENCE {
            self.ratio_moves.stopped_after = Some(outer_it);
        }
        Ok(())
    }

    /// One direction of the ratio step from the state whose per-channel `F` is `f0`; the
    /// per-channel `F` of the state it leaves, or `None` when the light model cannot mix
    /// its parameters.
    fn ratio_move(
        &mut self,
        outer_it: usize,
        j: usize,
        f0: [f64; 3],
        stop: &EarlyStop<BestIterate<M::Params>>,
    ) -> Result<Option<[f64; 3]>> {
        let delta = ratio_step::PROBE_STEP;
        let u = ratio_step::direction(self.lambda.len(), j);
        let (base, omega0) = (self.snapshot(), self.omega.clone());
        self.light.hold_shape(true);
        let mut probe = |t: f64| -> Result<([f64; 3], M::Params)> {
            self.restore(base.clone());
            self.omega.clone_from(&omega0);
            self.lambda = ratio_step::scaled(&base.lambda, &u, [t; 3]);
            self.lighting(outer_it)?;
            let f = self.channel_objective().unwrap_or([f64::INFINITY; 3]);
            Ok((f, self.light.params().clone()))
        };
        let probes = probe(-delta).and_then(|m| Ok((m, probe(delta)?)));
        self.light.hold_shape(false);
        let ((fm, lights_m), (fp, lights_p)) = probes?;
        let t = [0, 1, 2].map(|c| ratio_step::parabola_step(fm[c], f0[c], fp[c], delta));
        let w = t.map(|tc| ratio_step::lagrange_weights(tc, delta));
        let weights_of = |i: usize| [w[0][i], w[1][i], w[2][i]];
        let mixed = self.light.combine(&[
            (&lights_m, weights_of(0)),
            (&base.light, weights_of(1)),
            (&lights_p, weights_of(2)),
        ]);
        self.restore(base.clone());
        self.omega.clone_from(&omega0);
        let Some(mixed) = mixed else {
            return Ok(None);
        };
        self.light.set_params(mixed);
        self.lambda = ratio_step::scaled(&base.lambda, &u, t);
        let ft = self.channel_objective().unwrap_or([f64::INFINITY; 3]);
        // The held-back observations of early stopping must not get worse either: a lower
        // `F` along the valley need not be nearer the truth's ratios (the built-in example).
        // The held-back score only where `F` dropped: two predictions saved on every
        // rejected move.
        if ft.iter().sum::<f64>() < f0.iter().sum::<f64>() && self.held_no_worse(stop, &base) {
            self.ratio_moves.kept += 1;
            return Ok(Some(ft));
        }
        self.restore(base);
        Ok(Some(f0))
    }

    /// Whether early stopping's held-back observations are predicted no worse by the current
    /// state than by `base` (the same weights; true when early stopping is off).
    pub(crate) fn held_no_worse(
        &self,
        stop: &EarlyStop<BestIterate<M::Params>>,
        base: &Snapshot<M::Params>,
    ) -> bool {
        let score = |lights: &M::Params, lambda: &[Vec<[f64; 3]>]| {
            let beta = beta_per_vertex(lambda, &self.weights, self.problem.n_vertices);
            stop.peek(self.problem, &self.light.maps(lights), &beta)
        };
        let now = score(self.light.params(), &self.lambda);
        now.zip(score(&base.light, &base.lambda))
            .is_none_or(|(a, b)| a <= b)
    }
}
