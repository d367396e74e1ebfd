"""Mirror of ``templates/solver/polish_dual.c.j2``: the polish's dual solve on a general
working set, by Cholesky of H_WW (plus w on the diagonal of slack soft rows).

:class:`DualPolishMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``H``,
``slack_on`` and ``soft_l1``/``soft_w``.
"""
from __future__ import annotations

import numpy as np

from .linalg import cholesky_packed, chol_solve_packed


class DualPolishMixin:
    def factor_working_set(self, W, start=0, chol=None):
        """Mirror of factor_working_set(): rows start.. of chol(H_WW + w of the slack rows);
        (ok, packed factor)."""
        nw = len(W)
        if chol is None:
            chol = np.zeros(nw * (nw + 1) // 2 + nw + 1, self.md.Kx.dtype)
        for i in range(start, nw):
            tri = i * (i + 1) // 2
            chol[tri:tri + i + 1] = self.H[W[i], W[:i + 1]]
            if self.slack_on[W[i]]:
                chol[tri + i] = chol[tri + i] + self.soft_w[W[i]]
        return cholesky_packed(chol, nw, start=start), chol

    def dual_solve(self, W, K):
        """Mirror of dual_solve(): returns (ok, z)."""
        nw = W.size
        ok, chol = self.factor_working_set(W)
        if not ok:
            return False, None
        z = -K[W]
        on = self.slack_on[W]
        z[on] = z[on] + self.soft_l1[W][on] * self.soft_w[W][on]
        chol_solve_packed(chol, nw, z)
        return True, z
