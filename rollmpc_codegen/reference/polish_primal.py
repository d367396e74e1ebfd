"""Mirror of ``templates/solver/polish_primal.c.j2``: the polish's primal solve on a
working set of input bounds only, in free-variable form (Cholesky of S_FF) or, with few
bound inputs, through S^-1.

:class:`PrimalPolishMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``,
``row_c``, ``S`` and ``Sinv``.  A free-form solve leaves (d, nu) in ``_free_state`` for
:meth:`free_multipliers`, as the C leaves them in ``ws->dv`` and ``ws->nu``.
"""
from __future__ import annotations

import numpy as np

from .dot import s_row_dots
from .linalg import factor_and_solve_packed, seqsum, seqsum_rows
from .polish_dual import CHOL_NONE


class PrimalPolishMixin:
    def primal_solve(self, th0, W):
        """Mirror of primal_solve(): bounds, then the cheaper form; (ok, th, z or None)."""
        md = self.md
        n, dt = md.n, md.Kx.dtype
        self.chol_holds = CHOL_NONE  # ws->chol is about to hold a primal factor
        th = np.zeros(n, dt)
        dv = np.zeros(n, dt)
        qW = md.row_q[W]
        if np.unique(qW).size != qW.size:
            return False, None, None
        th[qW] = np.where(md.row_sign[W] > 0, self.row_c[W], -self.row_c[W])
        dv[qW] = th[qW] - th0[qW]
        bound = np.zeros(n, bool)
        bound[qW] = True
        if W.size < n - W.size:
            return self.primal_solve_bound(th0, W, qW, th, dv, bound)
        return self.primal_solve_free(th0, W, th, dv, bound)

    def primal_solve_free(self, th0, W, th, dv, bound):
        """Mirror of primal_solve_free()."""
        md = self.md
        nt, dt = md.nt, md.Kx.dtype
        F = np.flatnonzero(~bound)
        B = np.flatnonzero(bound)
        nf = F.size
        rhs = np.empty(nf, dt)
        for a, f in enumerate(F):
            rhs[a] = -s_row_dots(self.S, [f], dv)[0]  # dv is 0 on the free inputs here
        Y = np.ascontiguousarray(md.V[:, F]) if nt else np.zeros((0, nf), dt)
        if nf:
            chol = np.concatenate([self.S[F[a], F[:a + 1]] for a in range(nf)])
            if not factor_and_solve_packed(chol, nf, rhs, *Y):
                return False, None, None
        nu = _schur_solve(nt, dt, lambda o, p: seqsum(md.V[o, F] * Y[p]) + md.P2inv[o, p],
                          lambda o: seqsum(np.concatenate((md.V[o, F] * rhs, md.V[o, B] * dv[B]))))
        if nu is None:
            return False, None, None
        for a, f in enumerate(F):
            dv[f] = seqsum(-(Y[:, a] * nu), start=rhs[a])
            th[f] = th0[f] + dv[f]
        self._free_state = (dv, nu)
        return True, th, None

    def free_multipliers(self, W):
        """Mirror of free_multipliers() for the last free-form solve."""
        md = self.md
        dv, nu = self._free_state
        qW = md.row_q[W]
        g = s_row_dots(self.S, qW, dv)
        g = np.add.accumulate(np.hstack((g[:, None], md.V[:, qW].T * nu[None, :])), axis=1)[:, -1]
        return np.where(md.row_sign[W] > 0, -g, g)

    def primal_solve_bound(self, th0, W, qW, th, dv, bound):
        """Mirror of primal_solve_bound() (through S^-1; few bound inputs)."""
        md = self.md
        nt, dt, nb = md.nt, md.Kx.dtype, W.size
        chol = np.concatenate([self.Sinv[qW[a], qW[:a + 1]] for a in range(nb)])
        x1 = dv[qW].copy()
        Y = np.ascontiguousarray(md.Uv[:, qW]) if nt else np.zeros((0, nb), dt)
        if not factor_and_solve_packed(chol, nb, x1, *Y):
            return False, None, None
        nu = _schur_solve(nt, dt, lambda o, p: md.T[o, p] - seqsum(md.Uv[o, qW] * Y[p]),
                          lambda o: seqsum(md.Uv[o, qW] * x1))
        if nu is None:
            return False, None, None
        beta = np.array([seqsum(Y[:, a] * nu, start=x1[a]) for a in range(nb)], dt)
        z = np.where(md.row_sign[W] > 0, -beta, beta)
        F = np.flatnonzero(~bound)
        d = seqsum_rows(np.hstack((self.Sinv[np.ix_(F, qW)] * beta[None, :],
                                   -(md.Uv[:, F].T * nu[None, :]))))
        th[F] = th0[F] + d
        return True, th, z


def _schur_solve(nt, dt, entry, rhs):
    """The terminal multiplier step nu of both forms: the nt x nt system with packed lower
    entries entry(o, p) and right-hand side rhs(o), filled row by row as the C fills
    ws->tsmall and ws->nu; None on a bad pivot."""
    nu = np.zeros(nt, dt)
    if nt:
        small = np.empty(nt * (nt + 1) // 2, dt)
        for o in range(nt):
            for p in range(o + 1):
                small[o * (o + 1) // 2 + p] = entry(o, p)
            nu[o] = rhs(o)
        if not factor_and_solve_packed(small, nt, nu):
            return None
    return nu
