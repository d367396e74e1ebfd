"""Mirror of ``templates/solver/sweeps.c.j2``: the corrected point and Hildreth's sweeps.

``build_set()`` is ``np.flatnonzero(in_set)`` in :meth:`~.solver.SolverRef.solve`.
:class:`SweepsMixin` is part of :class:`~.solver.SolverRef`; it reads ``EM``, ``H``,
``Hdiag``, ``omega``, ``limit``, ``one``, ``zero`` and ``soft_l1``/``soft_w``.
"""
from __future__ import annotations

from .linalg import seqsum, seqsum_rows


class SweepsMixin:
    def correct(self, th0, rows, mult):
        """Mirror of correct(): th0 - sum_j (E^-1 M_{rows_j}') mult_j over mult_j > 0."""
        sel = mult > 0
        rows, mult = rows[sel], mult[sel]
        return th0 - seqsum_rows(self.EM[:, rows] * mult[None, :])

    def sweep(self, S, K, lam):
        """Mirror of sweep() over the sorted rows S, in place on lam: (e2, diverged)."""
        e2 = self.zero
        diverged = False
        om = self.omega
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
