"""Mirror of ``templates/solver/rows.c.j2`` and ``violated_rows.c.j2``: row values, the
slacks K = gamma - M th0, and the violation tests, each for every row at once.

:class:`RowsMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``row_c``,
``has_out``, ``has_rate``, ``one``, ``limit`` and ``tol``.  Where the C skips the output rows
because ``outputs_certified()`` proves none violated, the mirror evaluates them anyway; it
decides the certificate only to charge the work the C does (:mod:`rollmpc_codegen.qp.work`),
and keeps the C's ``out_slacks_ok`` as ``out_slacks_ok``.
"""
from __future__ import annotations

import numpy as np

from ..qp.work import predict_work


class RowsMixin:
    def row_value(self, th, yv):
        """Mirror of row_value() for every row (yv = Gamma th, or None without output
        rows)."""
        q, n = self.md.row_q, self.md.n
        if self.has_rate:  # Δu rows: U_d - U_(d-nu), or U_d in the first stage
            d = q - (n + self.md.n_yq)
            i = np.clip(d, 0, n - 1)
            prev = th[np.maximum(i - self.md.nu, 0)]
            rate = np.where(d >= self.md.nu, th[i] - prev, th[i])
            plain = th[np.minimum(q, n - 1)] if yv is None else np.where(
                q < n, th[np.minimum(q, n - 1)], yv[np.clip(q - n, 0, self.md.n_yq - 1)])
            return np.where(d >= 0, rate, plain)
        if yv is None:
            return th[q]
        return np.where(q < n, th[np.minimum(q, n - 1)], yv[np.maximum(q - n, 0)])

    def is_out(self):
        """Mirror of the is_out() macro for every row: is it an output row?"""
        q, n = self.md.row_q, self.md.n
        return (q >= n) & (q < n + self.md.n_yq)

    def outputs_certified(self, th, gam):
        """Mirror of outputs_certified(): can no output row be violated at th?"""
        md = self.md
        self.work += md.n + md.m
        a = np.abs(th)
        thmax = a[~np.isnan(a)].max(initial=self.zero)
        bmax = md.out_bound[md.n_yq - md.ny:].max(initial=self.zero)
        out = self.is_out()
        if bmax * thmax <= self.gam_out_min:
            return True
        q = md.row_q[out] - md.n
        return bool(np.all(md.out_bound[q] * thmax <= gam[out]))

    def outputs_uncertified(self, th, gam):
        """Mirror of outputs_uncertified(): are there output rows the certificate cannot
        clear at th?"""
        return self.has_out and not self.outputs_certified(th, gam)

    def outputs_to_check(self, th, gam):
        """Mirror of outputs_to_check()'s decision and work: must the output rows be
        checked at th (then the C predicts them)?"""
        if not self.outputs_uncertified(th, gam):
            return False
        self.work += predict_work(self.md)
        return True

    def output_slacks(self):
        """The work of output_slacks() (the K of the output rows: slacks() has them)."""
        if not self.out_slacks_ok:
            self.work += self.md.m + predict_work(self.md)
            self.out_slacks_ok = True

    def slacks(self, x, th0, px):
        """Mirror of slacks() with output_slacks(): (gamma = c + W x, K = gamma - M th0)."""
        md = self.md
        self.work += 2 * md.m
        yv0 = self.predict_outputs(th0) if self.has_out else None
        v = self.row_value(th0, yv0)
        q, sg, n = md.row_q, md.row_sign, md.n
        gam = self.row_c.copy()
        if self.has_out:
            pxr = px[np.clip(q - n, 0, md.n_yq - 1)]
            gam = np.where(self.is_out(), np.where(sg > 0, gam - pxr, gam + pxr), gam)
        if self.has_rate:  # first-stage Δu rows: gamma carries u_prev (last nu states)
            d = q - (n + md.n_yq)
            first = (d >= 0) & (d < md.nu)
            up = x[md.nx - md.nu + np.clip(d, 0, md.nu - 1)]
            gam = np.where(first, np.where(sg > 0, gam + up, gam - up), gam)
        self.gam_out_min = gam[self.is_out()].min(initial=self.limit)
        self.out_slacks_ok = not self.has_out
        if self.has_out and not self.outputs_certified(th0, gam):
            self.output_slacks()
        return gam, np.where(sg > 0, gam - v, gam + v)

    def tol_scale(self, gam):
        """Mirror of tol_scale() for every row: max(1, |gamma|), the tolerance's scale."""
        ag = np.abs(gam)
        return np.where(ag > self.one, ag, self.one)

    def row_excess(self, th, gam):
        """Mirror of row_excess() for every row, with its tol_scale(): (M th - gamma,
        max(1, |gamma|))."""
        yv = self.predict_outputs(th) if self.has_out else None
        v = self.row_value(th, yv)
        sg = self.md.row_sign
        return np.where(sg > 0, v - gam, -v - gam), self.tol_scale(gam)

    def row_violated(self, th, gam):
        """Mirror of row_violated() for every row."""
        viol, scale = self.row_excess(th, gam)
        return viol > self.tol * scale

    def violated_outside(self, th, gam, W):
        """Mirror of violated_outside(): violated input rows first, output rows only if none
        (the C skips them when certified: only its work differs)."""
        viol = self.row_violated(th, gam)
        viol[W] = False
        box = ~self.is_out()
        first = np.flatnonzero(viol & box)
        self.work += self.md.m
        if first.size:
            return first
        if self.outputs_to_check(th, gam):
            self.work += self.md.m
        return np.flatnonzero(viol)  # all, certified or not: an unsound certificate shows
