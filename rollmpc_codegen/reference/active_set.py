"""Mirror of ``templates/solver/active_set.c.j2``: the dual active-set solve
(Goldfarb-Idnani) from the unconstrained optimum, whose working set goes to the polish.

:class:`ActiveSetMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``H``,
``Hdiag``, ``wcap``, ``active_set_max``, ``dep_tol``, ``tol``, ``zero``, ``soft``,
``soft_l1``/``soft_w`` and ``slack_on``, and keeps the dual factor ``chol`` by updates
(:mod:`.polish_dual`).  The C's other working-set arrays are the state dict of
:meth:`dual_active_set` (W, z, steps, in_set, K).
"""
from __future__ import annotations

import numpy as np

from .linalg import chol_ltsolve_packed, seqsum
from .polish_dual import CHOL_DUAL


class ActiveSetMixin:
    def most_violated(self, th, gam, in_set):
        """Mirror of most_violated(): first row of largest relative violation, or -1."""
        viol, scale = self.row_excess(th, gam)
        cand = (~in_set) & (viol > self.tol * scale)
        if not np.any(cand):
            return -1
        rel = np.where(cand, viol / scale, self.zero)
        return int(np.argmax(rel))

    def add_to_set(self, p, st):
        """Mirror of add_to_set() on the state dict st (W, z, steps, in_set)."""
        dt = self.md.Kx.dtype
        hpp = self.Hdiag[p]
        lp = self.zero
        wp, l1p, p_on = self.soft_w[p], self.soft_l1[p], False
        hcol = self.H[st["W"], p].astype(dt)  # H_Wp, read once for every step
        while True:
            st["steps"] += 1
            if st["steps"] > self.active_set_max:
                return -1
            W, z = st["W"], st["z"]
            nw = len(W)
            viol = seqsum(-(hcol * z), start=-st["K"][p] - hpp * lp)
            y = hcol.copy()
            zeta = self.factor_pivot(y, hpp)
            d = y.copy()
            chol_ltsolve_packed(self.chol, nw, d)
            k, tblock, event = -1, self.zero, 0
            if self.soft:
                k, tblock, event = self._first_event(W, z, d)
                if p_on:
                    zeta = zeta + wp
                    viol = viol - (lp - l1p) * wp
                elif wp > 0:
                    tp = l1p - lp if l1p > lp else self.zero
                    if k < 0 or tp < tblock:
                        k, tblock, event = nw, tp, 2
            else:
                for i in range(nw):
                    if d[i] > 0:
                        ratio = z[i] / d[i]
                        if k < 0 or ratio < tblock:
                            k, tblock = i, ratio
            dependent = nw == self.wcap or not zeta > self.dep_tol * hpp
            if dependent and k < 0:
                return 1
            t = tblock if dependent else viol / zeta
            if not dependent:
                if k >= 0 and tblock < t:
                    t = tblock
                else:
                    k = -1
            z = z - t * d
            lp = lp + t
            st["z"] = z
            if k < 0:
                self.factor_append(y, zeta)
                st["W"] = np.append(W, p)
                st["z"] = np.concatenate((z, np.array([lp], dt)))
                st["in_set"][p] = True
                self.slack_on[p] = p_on
                return 0
            if event == 2:
                p_on = True
                continue
            if event == 1:  # row k's diagonal gains or loses w: update, else refactor
                self.switch_row(W, k)
                if self.chol_holds != CHOL_DUAL and not self.factor_working_set(W):
                    return -1
                continue
            st["in_set"][W[k]] = False
            st["W"], st["z"] = self.remove_row(W, z, k)
            hcol = np.delete(hcol, k)

    def _first_event(self, W, z, d):
        """The soft add_to_set()'s scan: (k, tblock, event) of the first multiplier to reach
        0 (event 0) or to cross l1 (event 1), ratios clamped at 0; k = -1 if none."""
        k, tblock, event = -1, self.zero, 0
        for i, r in enumerate(W):
            ev, ratio = 0, None
            if d[i] > 0:
                ev = int(self.slack_on[r])
                ratio = (z[i] - self.soft_l1[r] if ev else z[i]) / d[i]
            elif d[i] < 0 and self.soft_w[r] > 0 and not self.slack_on[r]:
                ev = 1
                ratio = (self.soft_l1[r] - z[i]) / -d[i]
            if ratio is not None:
                ratio = ratio if ratio > 0 else self.zero
                if k < 0 or ratio < tblock:
                    k, tblock, event = i, ratio, ev
        return k, tblock, event

    def dual_active_set(self, lam, th0, K, gam):
        """Mirror of dual_active_set(): (code 0/1/-1, th, active, steps + polish its)."""
        md = self.md
        st = {"W": np.zeros(0, np.int64), "z": np.zeros(0, md.Kx.dtype), "steps": 0, "K": K,
              "in_set": np.zeros(md.m, bool)}
        self.chol_holds = CHOL_DUAL  # the factor of the empty working set
        th = th0.copy()
        code = 0
        self.slack_on[:] = False
        while True:
            p = self.most_violated(th, gam, st["in_set"])
            if p < 0:
                break
            code = self.add_to_set(p, st)
            if code != 0:
                break
            th = self.correct(th0, st["W"], st["z"])
        if not st["W"].size:
            if code == 0:
                lam[:] = 0
            return code, th, 0, st["steps"]
        ok, th_p, act, its = self.polish(st["W"], lam, th0, K, gam)
        if ok:
            return 0, th_p, act, st["steps"] + its
        return (1 if code == 1 else -1), th0, 0, st["steps"] + its
