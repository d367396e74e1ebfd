"""Mirror of ``templates/solver/polish_primal.c.j2``: the polish's primal solve on a
working set of input bounds only, in free-variable form (Cholesky of S_FF) or bound form
(Cholesky of (S^-1)_BB), the factor of the previous solve of the QP updated when cheaper.

:class:`PrimalPolishMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``,
``row_c``, ``S`` and ``Sinv``.  Like the C it keeps the factor and Y between the solves of
a mode's QPs (``_chol``, ``_Y``, valid while ``chol_holds`` is CHOL_PRIMAL) and factors again
only the rows that change, after deleting by updates the rows that left
(:mod:`.primal_rows` chooses which).  A free-form solve leaves (d, nu) in ``_free_state``
for :meth:`free_multipliers`, as the C leaves them in ``ws->dv`` and ``ws->nu``.
"""
from __future__ import annotations

import numpy as np

from .dot import s_row_dot
from .linalg import (chol_lsolve_from, chol_ltsolve, cholesky_from,
                     factor_and_solve, seqsum)
from ..qp.work import multipliers_work, primal_work
from ..solver_codes import CHOL_NONE, CHOL_PRIMAL, OUT_OF_WORK
from .factor_update import chol_delete
from .primal_rows import BOUND, FREE, PrimalRowsMixin


class PrimalPolishMixin(PrimalRowsMixin):
    def primal_solve(self, th0, W, reserve):
        """Mirror of primal_solve(): bounds, the updated or new factor, its work charged
        once afford() grants it and ``reserve`` more; (ok, th, z or None), or
        (OUT_OF_WORK, None, None) with the factor's rows unchanged."""
        md = self.md
        n, nw, dt = md.n, W.size, md.Kx.dtype
        th = np.zeros(n, dt)
        dv = np.zeros(n, dt)
        qW = md.row_q[W]
        if np.unique(qW).size != qW.size:
            return False, None, None
        th[qW] = np.where(md.row_sign[W] > 0, self.row_c[W], -self.row_c[W])
        dv[qW] = th[qW] - th0[qW]
        bound = np.zeros(n, bool)
        bound[qW] = True
        form = BOUND if nw < n - nw else FREE
        order, rows, first, old = self.primal_order(bound, form)
        intact = self.chol_holds == CHOL_PRIMAL
        start = first if intact else 0
        runs = int(np.count_nonzero(bound & ~np.concatenate(([False], bound[:-1]))))
        bound_form = rows.form == BOUND
        cost = primal_work(md, len(order), start, bound_form, runs)
        later = 0 if bound_form else multipliers_work(md, nw)  # free_multipliers()
        deletes = []
        kept = len(old) - len(set(old) - set(order)) if old is not None else 0
        if intact and old is not None and first < kept:  # rows leave from inside the factor
            by_update, deletes = self.primal_deletes(old, set(order))
            by_update += primal_work(md, len(order), kept, bound_form, runs)
            if by_update < cost:  # the rows below them kept, when that costs less
                cost, start = by_update, kept
            else:
                deletes = []
        if not self.afford(cost + later + reserve):
            return OUT_OF_WORK, None, None
        self.work += cost
        self.factor_rows = rows
        self.th_solved = None  # the C's th is partly written until the solve succeeds
        ok = self.primal_factor(order, start, deletes)
        if not ok:
            return False, None, None
        out = (self.primal_solve_bound(th0, W, qW, th, dv, bound)
               if self.factor_rows.form == BOUND else self.primal_solve_free(th0, th, dv, bound))
        if out[0] is True:
            self.th_solved = out[1].copy()
        return out

    def primal_factor(self, order, start=0, deletes=()):
        """Mirror of primal_factor() after primal_deletes(): L of S_FF or (S^-1)_BB and
        Y = L^-1 V_F' or L^-1 Uv_B' (rows by ``order``), rows from ``start`` factored on the
        kept ones (those of the previous factor, ``deletes`` (position, order) deleted from
        it); False (factor forgotten) on a bad pivot."""
        md = self.md
        dt = md.Kx.dtype
        bound = self.factor_rows.form == BOUND
        A, cols = (self.Sinv, md.Uv) if bound else (self.S, md.V)
        k = len(order)
        idx = np.array(order, np.int64)
        kept_l, kept_y = (self._chol.copy(), self._Y.copy()) if start else (None, None)
        for pos, kk in deletes:
            chol_delete(kept_l, pos, kk, np.zeros(kk, dt), kept_y)
        tri_start = start * (start + 1) // 2
        chol = np.concatenate([kept_l[:tri_start] if start else np.zeros(0, dt)]
                              + [A[idx[a], idx[:a + 1]] for a in range(start, k)])
        ok = cholesky_from(chol, k, start)
        self.chol_holds = CHOL_PRIMAL if ok else CHOL_NONE  # the C's ws->chol now
        if not ok:
            self.factor_rows = None
            return False
        Y = np.array(cols[:, idx], dt) if md.nt else np.zeros((0, k), dt)
        if start:
            Y[:, :start] = kept_y[:, :start]
        for y in Y:
            chol_lsolve_from(chol, k, y, start)
        self._chol, self._Y, self._idx = chol, Y, idx
        return True

    def terminal_step(self, y0, extra):
        """Mirror of terminal_step(): nu, and w = y0 -/+ Y nu in place on y0; None on a bad
        pivot.  ``extra(o)`` is the free form's V_B d_B term of row o (None: bound form)."""
        md = self.md
        nt, dt, Y = md.nt, md.Kx.dtype, self._Y
        nu = np.zeros(nt, dt)
        if nt == 0:
            return nu
        free = extra is not None
        small = np.empty(nt * (nt + 1) // 2, dt)
        for o in range(nt):
            for p in range(o + 1):
                acc = seqsum(Y[o] * Y[p])
                small[o * (o + 1) // 2 + p] = acc + md.P2inv[o, p] if free else md.T[o, p] - acc
            nu[o] = seqsum(np.concatenate((Y[o] * y0, extra(o))) if free else Y[o] * y0)
        if not factor_and_solve(small, nt, nu):
            return None
        for a in range(y0.size):
            t = Y[:, a] * nu
            y0[a] = seqsum(-t if free else t, start=y0[a])
        return nu

    def primal_solve_free(self, th0, th, dv, bound):
        """Mirror of primal_solve_free()."""
        md = self.md
        idx, chol, k = self._idx, self._chol, self._idx.size
        B = np.flatnonzero(bound)
        rhs = -s_row_dot(self.S, idx, dv)  # dv is 0 on the free inputs here
        chol_lsolve_from(chol, k, rhs)
        nu = self.terminal_step(rhs, lambda o: md.V[o, B] * dv[B])
        if nu is None:
            return False, None, None
        chol_ltsolve(chol, k, rhs)
        dv[idx] = rhs
        th[idx] = th0[idx] + rhs
        self._free_state = (dv, nu)
        return True, th, None

    def free_multipliers(self, W):
        """Mirror of free_multipliers() for the last free-form solve."""
        self.work += multipliers_work(self.md, W.size)
        return self.signed_multiplier(W)

    def signed_multiplier(self, W):
        """Mirror of signed_multiplier() on each row of W: z = -/+ (S d + V' nu)_q."""
        md = self.md
        dv, nu = self._free_state
        qW = md.row_q[W]
        g = s_row_dot(self.S, qW, dv)
        g = np.add.accumulate(np.hstack((g[:, None], md.V[:, qW].T * nu[None, :])), axis=1)[:, -1]
        return np.where(md.row_sign[W] > 0, -g, g)

    def primal_solve_bound(self, th0, W, qW, th, dv, bound):
        """Mirror of primal_solve_bound() (through S^-1; few bound inputs)."""
        md = self.md
        idx, chol, k = self._idx, self._chol, self._idx.size
        beta = dv[idx].copy()
        chol_lsolve_from(chol, k, beta)
        nu = self.terminal_step(beta, None)
        if nu is None:
            return False, None, None
        chol_ltsolve(chol, k, beta)
        by_input = np.zeros(md.n, md.Kx.dtype)
        by_input[idx] = beta
        z = np.where(md.row_sign[W] > 0, -by_input[qW], by_input[qW])
        F = np.flatnonzero(~bound)
        for f, d in zip(F, s_row_dot(self.Sinv, F, by_input)):
            th[f] = th0[f] + seqsum(-(md.Uv[:, f] * nu), start=d)
        return True, th, z
