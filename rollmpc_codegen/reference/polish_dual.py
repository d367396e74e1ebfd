"""Mirror of ``templates/solver/polish_dual.c.j2``: the working set's dual factor
L = chol(H_WW) (plus w on the diagonal of slack soft rows), built from scratch, extended
by a joining row, shrunk by a leaving one, and the polish's dual solve with it.

:class:`DualPolishMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``H``,
``Hdiag``, ``dep_tol``, ``slack_on`` and ``soft_l1``/``soft_w``, keeps the C's ``ws->chol``
and ``ws->chol_holds`` as ``chol`` and ``chol_holds``, and charges ``work`` as the C.  A
working set W is an integer array in its C order (joining order).
"""
from __future__ import annotations

import numpy as np

from ..qp.work import delete_work, factor_work, hq_work, predict_work, tri_work
from ..solver_codes import CHOL_DUAL, CHOL_NONE, OUT_OF_WORK
from .factor_update import chol_delete, pivot_independent
from .linalg import cholesky_from, chol_lsolve_from, chol_solve, seqsum


class DualPolishMixin:
    def factor_working_set(self, W):
        """Mirror of factor_working_set(): chol(H_WW + w of the slack rows) from scratch
        into ``chol``; sets ``chol_holds``; False on a bad pivot: not positive, or its
        square not above ``dep_tol`` times its diagonal entry (a dependent row)."""
        chol = self.chol
        self.work += factor_work(self.md, len(W), self.hq_factor)
        for i in range(len(W)):
            tri = i * (i + 1) // 2
            chol[tri:tri + i + 1] = self.H[W[i], W[:i + 1]]
            if self.slack_on[W[i]]:
                chol[tri + i] = chol[tri + i] + self.soft_w[W[i]]
        on_diagonal = [i * (i + 3) // 2 for i in range(len(W))]  # packed (i, i)
        diag = chol[on_diagonal].copy()
        self.chol_rows = 0
        ok = cholesky_from(chol, len(W))
        if ok:  # rows above a dependent one do not read it: they stand (chol_rows)
            pivots = chol[on_diagonal]
            weak = np.flatnonzero(~pivot_independent(pivots * pivots, diag, self.dep_tol))
            ok = weak.size == 0
            self.chol_rows = 0 if ok else int(weak[0])
        if ok:
            self.chol_set = np.asarray(W).copy()
        self.chol_holds = CHOL_DUAL if ok else CHOL_NONE
        return ok

    def factor_pivot(self, y, hpp, start=0):
        """Mirror of factor_pivot(): y = L^-1 H_Wp in place (y[:start] solved already),
        returns hpp - y'y; charged as a whole solve."""
        self.work += tri_work(y.size) + y.size
        chol_lsolve_from(self.chol, y.size, y, start)
        return seqsum(-(y * y), start=hpp)

    def factor_append(self, y, zeta, p):
        """Mirror of factor_append(): row len(y) of the factor is (y, sqrt(zeta)), row p's
        (``chol_set``: the rows the factor holds, the C's wset[0..chol_n))."""
        nw = y.size
        self.chol_set = np.append(self.chol_set[:nw], p)
        tri = nw * (nw + 1) // 2
        self.chol[tri:tri + nw] = y
        self.chol[tri + nw] = np.sqrt(zeta)

    def append_row(self, W, p, slack=False):
        """Mirror of append_row(): W + [p], p tight (or slack); the kept factor gains p's
        row unless its pivot is below the dependence tolerance (then no factor is kept)."""
        self.slack_on[p] = slack
        if self.chol_holds == CHOL_DUAL:
            self.work += (len(W) + 1) * hq_work(self.md, self.hq_factor)
            hpp = self.Hdiag[p] + self.soft_w[p] if slack else self.Hdiag[p]
            y = self.H[W, p].astype(self.chol.dtype)
            zeta = self.factor_pivot(y, hpp)
            if pivot_independent(zeta, hpp, self.dep_tol):
                self.factor_append(y, zeta, p)
            else:
                self.chol_holds = CHOL_NONE
        return np.append(W, p)

    def independent_rows(self, W):
        """Mirror of independent_rows(): W's rows in order, each kept when its pivot on the
        rows kept before it exceeds the dependence tolerance times its diagonal (plus w for
        a slack row), the others leaving; their factor into ``chol``. The first
        ``chol_rows``, factored before a breakdown, are kept as they are."""
        kept = list(W[:self.chol_rows])
        self.chol_holds, self.chol_set = CHOL_DUAL, W[:self.chol_rows].copy()
        for p in W[self.chol_rows:]:
            hpp = self.Hdiag[p] + (self.soft_w[p] if self.slack_on[p] else 0)
            self.work += (len(kept) + 1) * hq_work(self.md, self.hq_factor)
            y = self.H[kept, p].astype(self.chol.dtype)
            zeta = self.factor_pivot(y, hpp)
            if pivot_independent(zeta, hpp, self.dep_tol):
                self.factor_append(y, zeta, p)
                kept.append(p)
            else:
                self.slack_on[p] = False
        return np.array(kept, dtype=W.dtype)

    def remove_row(self, W, z, k):
        """Mirror of remove_row(): position k leaves W and z (and the kept factor)."""
        self.slack_on[W[k]] = False
        if self.chol_holds == CHOL_DUAL:
            self.work += delete_work(k, len(W))
            chol_delete(self.chol, k, len(W), np.zeros(len(W), self.chol.dtype))
            self.chol_set = np.delete(W, k)
        return np.delete(W, k), np.delete(z, k)

    def dual_solve_work(self, nw, factored):
        """Mirror of dual_solve_work(): what dual_solve() on nw rows may spend, its factor
        ``factored`` or not."""
        md = self.md
        return ((0 if self.out_slacks_ok else md.m + predict_work(md))
                + (0 if factored else factor_work(md, nw, self.hq_factor)) + 2 * tri_work(nw))

    def dual_solve(self, W, K):
        """Mirror of dual_solve(): (0, z), or (-1 on a breakdown / OUT_OF_WORK, None)."""
        md, nw = self.md, W.size
        if not self.afford(self.dual_solve_work(nw, self.chol_holds == CHOL_DUAL)):
            return OUT_OF_WORK, None
        self.output_slacks()
        z = -K[W]
        on = self.slack_on[W]
        z[on] = z[on] + self.soft_l1[W][on] * self.soft_w[W][on]
        if self.chol_holds != CHOL_DUAL and not self.factor_working_set(W):
            return -1, None
        self.work += 2 * tri_work(nw)
        chol_solve(self.chol, nw, z)
        return 0, z
