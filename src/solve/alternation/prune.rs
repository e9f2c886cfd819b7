//! The pruning round inside the alternation ([`crate::solve::lobe_prune`]: the rule).

use super::Alternation;
use crate::solve::accel::AndersonHistory;
use crate::solve::light::LightModel;
use crate::solve::lobe_prune;

impl<M: LightModel> Alternation<'_, M> {
    /// At round [`EstimateOptions::prune_round`], each material's shiny lobes but its
    /// strongest held at zero from here on ([`lobe_prune::one_shiny_lobe`]); the
    /// extrapolation's and Anderson's histories restart, so that no combination of
    /// earlier iterates brings a pruned lobe back, and the variable-projection step probes
    /// its Jacobian afresh over the entries left.
    pub(super) fn prune_lobes(&mut self, outer_it: usize) {
        if self.opts.fixed_materials || outer_it != self.opts.prune_round {
            return;
        }
        let nb = self.problem.transport.n_basis;
        if nb < 3 {
            return;
        }
        self.pruned = lobe_prune::one_shiny_lobe(&self.lambda, self.opts.lambert_basis);
        lobe_prune::zero_pruned(&mut self.lambda, &self.pruned);
        self.varpro_jacobian = None;
        self.prev = None;
        if let Some(hist) = self.anderson.as_mut() {
            *hist = AndersonHistory::new(self.opts.anderson_depth);
        }
    }
}
