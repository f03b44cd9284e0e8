//! The backtracking line search of a Newton iteration.

use std::time::Instant;

use super::Newton;
use super::params::{
    EXPAND_BELOW, GRADIENT_STEP_RISE, NewtonParams, Objective, Problem, StepLimit,
};
use super::state::{LineSearch, SolveState};

impl Newton {
    /// Backtracking from the feasible fraction of the objective's step bound (or 1) until
    /// Armijo holds — or, while prescribed DOFs are still on their way, until the energy is
    /// finite; a projected Hessian's full step whose predicted decrease the energy resolves
    /// (`may_expand`) and that found the energy much flatter than the model may expand ([`NewtonParams::max_expansion`]). The accepted point
    /// is left in `trial`.
    pub(super) fn line_search(
        &mut self,
        state: &mut SolveState,
        obj: &mut impl Objective,
        x: &[f64],
        problem: &Problem,
        (pmax, gp): (f64, f64),
        may_expand: bool,
    ) -> LineSearch {
        let params = problem.params;
        let stats = &mut state.stats;
        let t = Instant::now();
        let bound = obj.max_step(x, &self.p);
        let mut alpha = if bound.limit.is_some() || bound.alpha < 1.0 {
            match bound.limit {
                Some(StepLimit::Ccd) => stats.limited_by_ccd += 1,
                Some(StepLimit::DetF) => stats.limited_by_det_f += 1,
                _ => stats.limited_by_other += 1,
            }
            (params.feasible_fraction * bound.alpha).min(1.0)
        } else {
            1.0
        };
        let full_step_feasible = alpha == 1.0;
        let at_targets = problem.at_targets(x);
        let mut accepted = None;
        while alpha * pmax >= params.min_step {
            self.step_to(x, alpha);
            let et = obj.energy(&self.trial);
            // While prescribed DOFs are still on their way, the energy may rise (the motion
            // does work on the system): accept any feasible, finite step then. Afterwards,
            // Armijo.
            let ok = !at_targets || et <= state.e + params.armijo * alpha * gp;
            if et.is_finite() && ok {
                accepted = Some(et);
                break;
            }
            alpha *= 0.5;
            stats.backtracks += 1;
        }
        if let Some(e1) = accepted
            && may_expand
            && alpha == 1.0
            && at_targets
            && params.max_expansion >= 2.0
            // A decrease of at least 3/4 of the first-order one.
            && e1 - state.e <= EXPAND_BELOW * gp
        {
            let (a, ea) = self.expand(obj, x, params, (state.e, e1, gp), stats);
            (alpha, accepted) = (a, Some(ea));
        }
        stats.line_search_s += t.elapsed().as_secs_f64();
        LineSearch {
            accepted,
            alpha,
            full_step_feasible,
            bound,
        }
    }

    /// `x + alpha p` into `trial`.
    fn step_to(&mut self, x: &[f64], alpha: f64) {
        for (t, (x, p)) in self.trial.iter_mut().zip(x.iter().zip(&self.p)) {
            *t = x + alpha * p;
        }
    }

    /// The expanding part of the line search, after the full step `x + p` (in `trial`) took the
    /// energy from `e` to `e1` with slope `gp` at 0: one feasibility bound along the longest
    /// step `max_expansion · p`, then steps 2, 4, 8, … within its feasible fraction while the
    /// energy keeps falling and Armijo holds. Returns the step length taken (1 if none beyond
    /// the full step) and its energy, the point left in `trial`.
    fn expand(
        &mut self,
        obj: &mut impl Objective,
        x: &[f64],
        params: &NewtonParams,
        (e, e1, gp): (f64, f64, f64),
        stats: &mut super::SolveStats,
    ) -> (f64, f64) {
        let cap = params.max_expansion;
        for (l, p) in self.long_p.iter_mut().zip(&self.p) {
            *l = cap * p;
        }
        let bound = obj.max_step(x, &self.long_p);
        let reach = if bound.limit.is_some() || bound.alpha < 1.0 {
            cap * params.feasible_fraction * bound.alpha
        } else {
            cap
        };
        let (mut best, mut e_best) = (1.0, e1);
        let mut alpha = 2.0;
        let mut trial_holds_best = true;
        while alpha <= reach {
            self.step_to(x, alpha);
            let et = obj.energy(&self.trial);
            stats.expansion_trials += 1;
            if !(et.is_finite() && et < e_best && et <= e + params.armijo * alpha * gp) {
                trial_holds_best = false;
                break;
            }
            (best, e_best) = (alpha, et);
            alpha *= 2.0;
        }
        if !trial_holds_best {
            self.step_to(x, best);
        }
        if best > 1.0 {
            stats.expanded_steps += 1;
        }
        (best, e_best)
    }

    /// The energy at the full step `x + p` (left in `trial`) if it may be taken although no
    /// step length decreased the energy: that energy is finite and above `e` by no more than
    /// [`GRADIENT_STEP_RISE`] times the predicted decrease `−gᵀp` (a change the energy's
    /// evaluation does not resolve: measured on a spinning FEM ring, the energy of a
    /// converging Newton step came out 0.25–2.3× the predicted decrease *above* `e`), and the
    /// free gradient's norm there is at most half the current one (Newton's local convergence,
    /// which the gradient resolves: 2·10⁵× smaller in that case). See
    /// [`SolveStats::gradient_steps`].
    pub(super) fn full_step_on_the_gradients_word<O: Objective>(
        &mut self,
        obj: &mut O,
        x: &[f64],
        e: f64,
        gp: f64,
    ) -> Option<f64> {
        self.step_to(x, 1.0);
        let et = obj.energy(&self.trial);
        if !(et.is_finite() && et - e <= -GRADIENT_STEP_RISE * gp) {
            return None;
        }
        self.g_trial.iter_mut().for_each(|v| *v = 0.0);
        obj.gradient(&self.trial, &mut self.g_trial);
        let norm2 = |g: &[f64]| self.free_dofs.iter().map(|&d| g[d] * g[d]).sum::<f64>();
        (norm2(&self.g_trial) <= 0.25 * norm2(&self.g)).then_some(et)
    }
}
