"""Mirror of ``templates/solver/sweeps.c.j2``: the corrected point and Hildreth's sweeps.

:class:`SweepsMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``Sinv``,
``H``, ``Hdiag``, ``omega``, ``limit``, ``one``, ``zero`` and ``soft_l1``/``soft_w``.
"""
from __future__ import annotations

import numpy as np

from ..qp.work import correct_cost, sweep_work
from .linalg import seqsum


class SweepsMixin:
    def build_set(self, in_set):
        """Mirror of build_set(): the sorted rows of the sweep set."""
        self.work += self.md.m
        return np.flatnonzero(in_set)
    def correct(self, th0, rows, mult, step=False):
        """Mirror of correct(): th0 - E^-1 M' mult over the rows with mult > 0, the
        multipliers summed by quantity first (in row order), then E^-1 v column by column
        over the nonzero entries: S^-1 v_in, minus Ew' (Ew v_in), plus E^-1 G' v_out.
        ``step`` (CORRECT_STEP): th0 is the current point, every nonzero multiplier
        counts, and th0 + E^-1 M' mult is returned (refine_dual() passes -d)."""
        md = self.md
        n, nyq, dt = md.n, md.n_yq, md.Kx.dtype
        count = rows.size
        sel = (mult > 0) | ((mult < 0) if step else False)
        rows, mult = rows[sel], mult[sel]
        v = np.where(md.row_sign[rows] > 0, mult, -mult)
        q = md.row_q[rows]
        nzq, z0 = md.nzq, 2 * n + nyq
        # quantity index in [inputs, outputs, signals] and its term
        at, val = np.where(q >= z0, q - z0 + n + nyq, q), v.copy()
        if self.has_rate:  # a Δu row adds to U_d and, past the first stage, subtracts from U_(d-nu)
            d = np.where(q >= z0, -1, q - (n + nyq))
            at = np.where(d >= 0, d, at)
            prev = d >= md.nu
            order = np.argsort(np.concatenate((2 * np.arange(rows.size),
                                               2 * np.flatnonzero(prev) + 1)), kind="stable")
            at = np.concatenate((at, d[prev] - md.nu))[order]
            val = np.concatenate((val, -v[prev]))[order]
        qv = np.zeros(n + nyq + nzq, dt)
        np.add.at(qv, at, val)  # sequential, in the rows' order
        met = (qv < 0) | (qv > 0)  # the C's test: a NaN sum (inf - inf) is skipped, as there
        th = th0.copy() if step else np.zeros(n, dt)
        ew_v = np.zeros(md.nt, dt)
        for j in np.flatnonzero(met[:n]):
            th = th + self.Sinv[:, j] * qv[j]
            ew_v = ew_v + md.Ew[:, j] * qv[j]
        for o in range(md.nt):
            th = th - md.Ew[o] * ew_v[o]
        for k in np.flatnonzero(met[n:n + nyq]):
            th = th + md.EinvGt[:, k] * qv[n + k]
        for k in np.flatnonzero(met[n + nyq:]):  # + E^-1 Gz' v_sig
            th = th + md.EinvZt[:, k] * qv[n + nyq + k]
        self.work += correct_cost(md, count, int(np.count_nonzero(met[:n])),
                                  int(np.count_nonzero(met[n:])))
        return th if step else th0 - th

    def sweep(self, S, K, lam):
        """Mirror of sweep() over the sorted rows S, in place on lam: (e2, diverged)."""
        e2 = self.zero
        diverged = False
        om = self.omega
        self.work += sweep_work(self.md, S.size, self.hq_factor)
        for r in S:
            mask = (S != r) & (lam[S] > 0)
            others = S[mask]
            acc = seqsum(self.H[r, others] * lam[others])
            t = -(K[r] + acc) / self.Hdiag[r]
            if self.soft_w[r] > 0 and t > self.soft_l1[r]:  # piecewise maximum
                t = (self.soft_l1[r] * self.soft_w[r] - (K[r] + acc)) / (self.Hdiag[r] + self.soft_w[r])
            wv = (self.one - om) * lam[r] + om * t
            nl = wv if wv > 0 else self.zero
            d = nl - lam[r]
            e2 = e2 + d * d
            lam[r] = nl
            if not nl <= self.limit:
                diverged = True
        return e2, diverged
