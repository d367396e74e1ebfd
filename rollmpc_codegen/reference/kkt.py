"""Mirror of ``templates/solver/kkt.c.j2``: whether a working set's rows hold at its point
(the KKT check of the polish and of the dual active set's final set), and the iterative
refinement of a dual solve's point that misses them.

:class:`KktMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``tol``,
``soft``, ``has_pred`` and the dual factor ``chol`` that dual_solve() left.
"""
from __future__ import annotations

import numpy as np

from ..qp.work import correct_work, predict_work, scan_work, tri_work
from ..solver_codes import OUT_OF_WORK
from .linalg import chol_solve


class KktMixin:
    def working_set_holds(self, W, z, th, gam, predicted=False, tight=False):
        """Mirror of working_set_holds() (violated_in_set() with soft rows) at th;
        ``predicted``: violated_outside() has just predicted the outputs at th; ``tight``:
        the rows must also be tight within the tolerance and no multiplier negative."""
        if predicted:
            outputs = self.outputs_uncertified(th, gam)  # its work: the prediction stands
        else:
            outputs = self.outputs_to_check(th, gam)  # its work; the mirror checks every row
        viol, scale = self.row_excess(th, gam)
        e = viol[W] - self.slack_in_set(W, z) if self.soft else viol[W]
        tol = self.tol * scale[W]
        if np.any(e > tol):
            return False
        if tight:  # a row the certificate cleared is inside its bound: not tight
            return not (np.any(e < -tol) or np.any(z < 0)
                        or (not outputs and np.any(self.is_predicted()[W])))
        return True

    def refine_dual(self, W, z, gam, th):
        """Mirror of refine_dual(): (0 / 1 / -1 / OUT_OF_WORK, th, z) after up to two rounds,
        each z += d and th -= E^-1 M_W' d for d = H_WW^-1 e; 1: the set holds at th, a row
        outside it does not."""
        md, nw = self.md, W.size
        if not self.afford(2 * (2 * tri_work(nw) + correct_work(md, nw) + 2 * scan_work(md))
                           + md.m):
            return OUT_OF_WORK, th, z
        chol = self.chol  # the factor dual_solve() used
        for _ in range(2):
            if self.has_pred:
                self.work += predict_work(md)
            e = self.row_excess(th, gam)[0][W]
            if self.soft:
                e = e - self.slack_in_set(W, z)
            self.work += 2 * tri_work(nw)
            chol_solve(chol, nw, e)
            z = z + e
            if np.any(z < 0):
                return -1, th, z
            if self.soft:
                code = self.switch_states(W, z)
                if code:
                    return (OUT_OF_WORK if code == OUT_OF_WORK else -1), th, z
            th = self.correct(th, W, -e, step=True)  # th - E^-1 M' d, not th0 - E^-1 M' z
            if self.working_set_holds(W, z, th, gam):
                return (0 if self.violated_outside(th, gam, W).size == 0 else 1), th, z
        return -1, th, z
