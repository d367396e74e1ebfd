"""Mirror of ``templates/solver/polish_primal.c.j2``: the polish's primal solve on a
working set of input bounds only, in free-variable form (Cholesky of S_FF) or bound form
(Cholesky of (S^-1)_BB), the factor of the previous solve of the QP updated when cheaper.

:class:`PrimalPolishMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``,
``row_c``, ``S`` and ``Sinv``.  The C keeps its factor and refactors only the rows that
change; each row is bit for bit the full factorisation's in the same row order, so the
reference keeps only that order (:attr:`factor_rows`, reset by ``unconstrained()``) and
factors in full.  A free-form solve leaves (d, nu) in ``_free_state`` for
:meth:`free_multipliers`, as the C leaves them in ``ws->dv`` and ``ws->nu``.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .dot import s_row_dots
from .linalg import (chol_lsolve_packed, chol_ltsolve_packed, cholesky_packed,
                     factor_and_solve_packed, seqsum)
from ..qp.work import multipliers_work, primal_work
from .polish_dual import CHOL_NONE, CHOL_PRIMAL, OUT_OF_WORK

FREE, BOUND = 1, 2  # FORM_FREE, FORM_BOUND


# The C keeps a tail row's generation in the high bits of ws->input_role (ROLE_GEN_*):
# 1 for the inputs of the first update, one more for each update that appends inputs.
GEN_MAX = 31


class FactorRows(NamedTuple):
    """The C's ws->primal_form and its rows: the head (the last full factorisation's), in
    descending inputs in the free form and ascending in the bound form, then the tail
    (inputs that joined since) in joining order: by generation (``gens``, one per tail
    row), each generation in the head's order."""
    form: int
    head: list
    tail: list
    gens: list


def primal_cost(n: int, nt: int, k: int, p: int) -> int:
    """Mirror of primal_cost(): six times the multiply-adds of a solve of order k, rows
    p.. factored."""
    factor = (k ** 3 - k - p ** 3 + p) + 3 * (k * (k + 1) - p * (p + 1))
    solves = 3 * nt * (k * k - k - p * p + p) + 6 * (k * k - k)
    return factor + solves + 6 * k * (n - k)


class PrimalPolishMixin:
    factor_rows: FactorRows | None = None

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
        order, rows, first = self.primal_order(bound, form)
        start = first if self.chol_holds == CHOL_PRIMAL else 0
        runs = int(np.count_nonzero(bound & ~np.concatenate(([False], bound[:-1]))))
        cost = primal_work(md, nw, len(order), start, rows.form == BOUND, runs)
        later = 0 if rows.form == BOUND else multipliers_work(md, nw)  # free_multipliers()
        if not self.afford(cost + later + reserve):
            return OUT_OF_WORK, None, None
        self.work += cost
        self.factor_rows = rows
        ok = self.primal_factor(order)
        if not ok:
            return False, None, None
        if self.factor_rows.form == BOUND:
            return self.primal_solve_bound(th0, W, qW, th, dv, bound)
        return self.primal_solve_free(th0, th, dv, bound)

    def primal_order(self, bound, form):
        """Mirror of primal_diff() and primal_order(): the rows of the factor in order, the
        factor_rows they make and the first row factored again."""
        n, nw = self.md.n, int(np.count_nonzero(bound))
        prev = self.factor_rows
        if prev is not None and (nw > 0 if prev.form == FREE else nw < n):
            member = bound if prev.form == BOUND else ~bound
            kept = [(g, q) for g, q in zip(prev.gens, prev.tail) if member[q]]
            newest = max((g for g, _ in kept), default=0)
            head = [q for q in prev.head if member[q]]
            joined = sorted([int(q) for q in np.flatnonzero(member)
                             if q not in prev.head and q not in prev.tail],
                            reverse=prev.form == FREE)  # appended: the rows above stay
            tail = [q for _, q in kept] + joined
            gens = [g for g, _ in kept] + [newest + 1] * len(joined)
            old, new = prev.head + prev.tail, head + tail
            start = next((i for i, (a, b) in enumerate(zip(old, new)) if a != b),
                         min(len(old), len(new)))
            k_new = nw if form == BOUND else n - nw
            nt = self.md.nt
            if newest < GEN_MAX and (prev.form == form or (primal_cost(n, nt, len(new), start)
                                                           <= primal_cost(n, nt, k_new, 0))):
                return new, FactorRows(prev.form, head, tail, gens), start
        member = bound if form == BOUND else ~bound
        head = [int(q) for q in np.flatnonzero(member)]
        if form == FREE:
            head.reverse()
        return head, FactorRows(form, head, [], []), 0

    def primal_factor(self, order):
        """Mirror of primal_factor(): L of S_FF or (S^-1)_BB and Y = L^-1 V_F' or
        L^-1 Uv_B' (rows by ``order``), in full; False (factor forgotten) on a bad pivot."""
        md = self.md
        bound = self.factor_rows.form == BOUND
        A, cols = (self.Sinv, md.Uv) if bound else (self.S, md.V)
        k = len(order)
        idx = np.array(order, np.int64)
        chol = (np.concatenate([A[idx[a], idx[:a + 1]] for a in range(k)]) if k
                else np.zeros(0, md.Kx.dtype))
        ok = cholesky_packed(chol, k)
        self.chol_holds = CHOL_PRIMAL if ok else CHOL_NONE  # the C's ws->chol now
        if not ok:
            self.factor_rows = None
            return False
        Y = np.array(cols[:, idx], md.Kx.dtype) if md.nt else np.zeros((0, k), md.Kx.dtype)
        for y in Y:
            chol_lsolve_packed(chol, k, y)
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
        if not factor_and_solve_packed(small, nt, nu):
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
        rhs = -s_row_dots(self.S, idx, dv)  # dv is 0 on the free inputs here
        chol_lsolve_packed(chol, k, rhs)
        nu = self.terminal_step(rhs, lambda o: md.V[o, B] * dv[B])
        if nu is None:
            return False, None, None
        chol_ltsolve_packed(chol, k, rhs)
        dv[idx] = rhs
        th[idx] = th0[idx] + rhs
        self._free_state = (dv, nu)
        return True, th, None

    def free_multipliers(self, W):
        """Mirror of free_multipliers() for the last free-form solve."""
        md = self.md
        self.work += multipliers_work(md, W.size)
        dv, nu = self._free_state
        qW = md.row_q[W]
        g = s_row_dots(self.S, qW, dv)
        g = np.add.accumulate(np.hstack((g[:, None], md.V[:, qW].T * nu[None, :])), axis=1)[:, -1]
        return np.where(md.row_sign[W] > 0, -g, g)

    def primal_solve_bound(self, th0, W, qW, th, dv, bound):
        """Mirror of primal_solve_bound() (through S^-1; few bound inputs)."""
        md = self.md
        idx, chol, k = self._idx, self._chol, self._idx.size
        beta = dv[idx].copy()
        chol_lsolve_packed(chol, k, beta)
        nu = self.terminal_step(beta, None)
        if nu is None:
            return False, None, None
        chol_ltsolve_packed(chol, k, beta)
        by_input = np.zeros(md.n, md.Kx.dtype)
        by_input[idx] = beta
        z = np.where(md.row_sign[W] > 0, -by_input[qW], by_input[qW])
        F = np.flatnonzero(~bound)
        for f, d in zip(F, s_row_dots(self.Sinv, F, by_input)):
            th[f] = th0[f] + seqsum(-(md.Uv[:, f] * nu), start=d)
        return True, th, z
