"""Mirror of ``templates/solver/soft_rows.c.j2``: the slack states of soft output rows.

``soft_of()`` is the per-row table ``soft_l1``/``soft_w`` (``ModeData.soft_rows()``, w = 0
on hard rows) and ``multiplier_slack()`` is
:func:`rollmpc_codegen.features.soft_constraints.slacks`.  :class:`SoftRowsMixin` is part of
:class:`~.solver.SolverRef`; it reads ``soft_l1``, ``soft_w``, ``tol`` and ``zero``, keeps the
working-set rows' states in ``slack_on`` (``ws->slack_on``) and updates the dual factor
``chol`` (:mod:`.polish_dual`) when a state switches.
"""
from __future__ import annotations

import numpy as np

from ..features.soft_constraints import multiplier_slack
from ..qp.work import rank_one_work
from .factor_update import chol_rank_one
from ..solver_codes import CHOL_DUAL, CHOL_NONE, OUT_OF_WORK


class SoftRowsMixin:
    def slack_in_set(self, W, z):
        """Mirror of slack_in_set() for the working set: (z - l1) w where slack, else 0."""
        sl = (z - self.soft_l1[W]) * self.soft_w[W]
        return np.where(self.slack_on[W], sl, self.zero)

    def violated_in_set(self, W, z, excess, scale):
        """Mirror of violated_in_set() for the working set W (multipliers z), from the rows'
        excess and tolerance scale at th (:meth:`row_excess`)."""
        return excess[W] - self.slack_in_set(W, z) > self.tol * scale[W]

    def slack_state(self, W, lam_of_W):
        """Mirror of slack_state() for rows W joining with these multipliers."""
        return (self.soft_w[W] > 0) & (lam_of_W > self.soft_l1[W])

    def set_state(self, W, lam_of_W):
        """Mirror of set_state() for rows joining with these multipliers."""
        self.slack_on[W] = self.slack_state(W, lam_of_W)

    def state_kept(self, W, lam_of_W):
        """Mirror of state_kept(): are rows W in the states they would join with?"""
        return self.slack_on[W] == self.slack_state(W, lam_of_W)

    def switch_row(self, W, k):
        """Mirror of switch_row(): flip position k's state; the kept factor takes the
        rank-one update (slack) or downdate (tight) of sqrt(w) e_k, or is dropped when
        the downdate breaks down."""
        r = W[k]
        self.slack_on[r] = not self.slack_on[r]
        if self.chol_holds == CHOL_DUAL:
            self.work += rank_one_work(len(W) - k)
            v = np.zeros(len(W), self.chol.dtype)
            v[k] = np.sqrt(self.soft_w[r])
            if not chol_rank_one(self.chol, k, len(W), v, not self.slack_on[r], self.dep_tol):
                self.chol_holds = CHOL_NONE

    def switch_states(self, W, z):
        """Mirror of switch_states(): flip the rows whose multiplier crossed l1; count, or
        OUT_OF_WORK before a switch the budget cannot afford."""
        l1, on = self.soft_l1[W], self.slack_on[W]
        flip = (self.soft_w[W] > 0) & np.where(on, z < l1, z > l1)
        for k in np.flatnonzero(flip):
            if not self.afford(rank_one_work(len(W) - k)):
                return OUT_OF_WORK
            self.switch_row(W, k)
        return int(np.count_nonzero(flip))

    def violated_beyond_slack(self, excess, scale, lam):
        """Mirror of violated_beyond_slack() from the rows' excess and tolerance scale at th
        (:meth:`row_excess`): how many exceed the slack of their multiplier."""
        sl = multiplier_slack(lam, self.soft_l1, self.soft_w)
        return int(np.count_nonzero(excess - sl > self.tol * scale))
