"""Mirror of ``templates/solver/rows.c.j2`` and ``violated_rows.c.j2``: row values, the
slacks K = gamma - M th0, and the violation tests, each for every row at once.

:class:`RowsMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``row_c``,
``has_out``, ``has_pred``, ``has_rate``, ``one``, ``limit`` and ``tol``.  Where the C skips the output rows
because ``outputs_certified()`` proves none violated, the mirror evaluates them anyway; it
decides the certificate only to charge the work the C does (:mod:`rollmpc_codegen.qp.work`),
and keeps the C's ``out_slacks_ok`` as ``out_slacks_ok``.
"""
from __future__ import annotations

import numpy as np

from ..qp.rows import OUTPUT, RATE, SIGNAL
from ..qp.work import certificate_read_work, predict_work
from .signals import predicted_index


class RowsMixin:
    def row_value(self, th, pv):
        """Mirror of row_value() for every row (pv = the predicted vector [Gamma th; Gz th]
        of :func:`.signals.predicted_index`, or None without predicted rows)."""
        md = self.md
        q, n, kind = md.row_q, md.n, md.row_kinds
        value = th[np.clip(q, 0, n - 1)]
        if self.has_rate:  # Δu rows: U_d - U_(d-nu), or U_d in the first stage
            i = np.clip(q - RATE.base(n, md.n_yq), 0, n - 1)
            prev = th[np.maximum(i - md.nu, 0)]
            rate = np.where(i >= md.nu, th[i] - prev, th[i])
            value = np.where(kind == RATE.code, rate, value)
        if pv is not None:
            value = np.where((kind == OUTPUT.code) | (kind == SIGNAL.code),
                             pv[predicted_index(md, q)], value)
        return value

    def is_out(self):
        """Mirror of the is_out() macro for every row: is it an output row?"""
        return self.md.output_rows

    def is_predicted(self):
        """Mirror of the is_predicted() macro for every row: an output or a signal row?"""
        return self.md.predicted_rows

    def outputs_certified(self, th, gam):
        """Mirror of outputs_certified(): can no output (or signal) row be violated at th?"""
        md = self.md
        a = np.abs(th)
        thmax = a[~np.isnan(a)].max(initial=self.zero)
        if md.has_signal_rows:
            last = md.out_bound[md.n_yq - md.ny:] if self.has_out else md.out_bound[:0]
            bmax = max(last.max(initial=self.zero), md.z_bound.max(initial=self.zero))
        else:
            bmax = md.out_bound[md.n_yq - md.ny:].max(initial=self.zero)
        self.work += certificate_read_work(md)  # what it reads: th and the signal bounds
        if bmax * thmax <= self.gam_out_min:
            return True
        out, sig = self.is_out(), md.signal_rows
        fails = np.zeros(md.m, dtype=bool)  # the rows it cannot clear; it stops at the first
        fails[out] = ~(md.out_bound[md.row_q[out] - md.n] * thmax <= gam[out])
        if md.has_signal_rows:
            z = md.row_q[sig] - SIGNAL.base(md.n, md.n_yq)
            fails[sig] = ~(md.z_bound[z] * thmax <= gam[sig])
        fails = fails[md.predicted_rows]  # it reads the predicted rows only, ascending
        first = int(np.argmax(fails)) if fails.any() else fails.size
        self.work += min(first + 1, fails.size)
        return first == fails.size

    def outputs_uncertified(self, th, gam):
        """Mirror of outputs_uncertified(): are there predicted rows the certificate cannot
        clear at th?"""
        return self.has_pred and not self.outputs_certified(th, gam)

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

    def slacks(self, x, th0, pfree):
        """Mirror of slacks() with output_slacks(): (gamma = c + W x, K = gamma - M th0);
        pfree: the predicted rows' free response [Phi x; Zx x + Zr r], None without."""
        md = self.md
        self.work += 2 * md.m
        pv0 = self.predict_outputs(th0) if self.has_pred else None
        v = self.row_value(th0, pv0)
        q, sg, n = md.row_q, md.row_sign, md.n
        gam = self.row_c.copy()
        pred = self.is_predicted()
        if self.has_pred:
            p = pfree[predicted_index(md, q)]
            gam = np.where(pred, np.where(sg > 0, gam - p, gam + p), gam)
        if self.has_rate:  # first-stage Δu rows: gamma carries u_prev (last nu states)
            d = q - RATE.base(n, md.n_yq)
            first = (md.row_kinds == RATE.code) & (d < md.nu)
            up = x[md.nx - md.nu + np.clip(d, 0, md.nu - 1)]
            gam = np.where(first, np.where(sg > 0, gam + up, gam - up), gam)
        self.gam_out_min = gam[pred].min(initial=self.limit)
        self.out_slacks_ok = not self.has_pred
        if self.has_pred and not self.outputs_certified(th0, gam):
            self.output_slacks()
        return gam, np.where(sg > 0, gam - v, gam + v)

    def tol_scale(self, gam):
        """Mirror of tol_scale() for every row: max(1, |gamma|), the tolerance's scale."""
        ag = np.abs(gam)
        return np.where(ag > self.one, ag, self.one)

    def row_excess(self, th, gam):
        """Mirror of row_excess() for every row, with its tol_scale(): (M th - gamma,
        max(1, |gamma|))."""
        pv = self.predict_outputs(th) if self.has_pred else None
        v = self.row_value(th, pv)
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
        box = ~self.is_predicted()
        first = np.flatnonzero(viol & box)
        self.work += self.md.m
        if first.size:
            return first
        if self.outputs_to_check(th, gam):
            self.work += self.md.m
        return np.flatnonzero(viol)  # all, certified or not: an unsound certificate shows
