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

from ..qp.work import (add_step_work, correct_work, factor_work, hq_work, predict_work,
                       scan_work, tri_work)
from .linalg import chol_ltsolve, seqsum
from .factor_update import pivot_independent
from ..solver_codes import (CHOL_DUAL, COLD_START, OUT_OF_WORK, OUT_OF_WORK_AT_TH0,
                            SET_HANDED_BACK)


class ActiveSetMixin:
    def most_violated(self, th, gam, in_set):
        """Mirror of most_violated(): the rows of largest relative violation, at most
        ``add_batch``, most violated first (the lower row among equals)."""
        self.outputs_to_check(th, gam)  # its work; the mirror checks every row
        self.work += 2 * self.md.m
        viol, scale = self.row_excess(th, gam)
        cand = np.flatnonzero((~in_set) & (viol > self.tol * scale))
        rel = viol[cand] / scale[cand]
        return cand[np.lexsort((cand, -rel))][:self.add_batch]

    def add_to_set(self, p, st, recheck=False):
        """Mirror of add_to_set() on the state dict st (W, z, steps, in_set)."""
        md = self.md
        dt = md.Kx.dtype
        hpp = self.Hdiag[p]
        lp = self.zero
        wp, l1p, p_on = self.soft_w[p], self.soft_l1[p], False
        if not self.afford((len(st["W"]) + 1) * hq_work(md, self.hq_factor)):
            return OUT_OF_WORK
        self.work += (len(st["W"]) + 1) * hq_work(md, self.hq_factor)
        hcol = self.H[st["W"], p].astype(dt)  # H_Wp, read once for every step
        if recheck:  # chosen at an earlier point: still violated at this one?
            viol = seqsum(-(hcol * st["z"]), start=-st["K"][p])
            scale = abs(st["gam"][p]) if abs(st["gam"][p]) > self.one else self.one
            if not viol > self.tol * scale:
                return 2
        y, start = hcol, 0  # y[:start]: L^-1 H_Wp of the step before, still valid
        while True:
            st["steps"] += 1
            if st["steps"] > self.active_set_max:
                return -1
            W, z = st["W"], st["z"]
            nw = len(W)
            if not self.afford(add_step_work(nw)):
                return OUT_OF_WORK
            self.work += tri_work(nw) + 4 * nw
            viol = seqsum(-(hcol * z), start=-st["K"][p] - hpp * lp)
            y = np.concatenate((y[:start], hcol[start:]))
            zeta = self.factor_pivot(y, hpp, start)
            d = y.copy()
            chol_ltsolve(self.chol, nw, d)
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
            dependent = nw == self.wcap or not pivot_independent(zeta, hpp, self.dep_tol)
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
                self.factor_append(y, zeta, p)
                st["W"] = np.append(W, p)
                st["z"] = np.concatenate((z, np.array([lp], dt)))
                st["in_set"][p] = True
                self.slack_on[p] = p_on
                return 0
            if event == 2:
                p_on = True
                start = nw  # neither L nor H_Wp changed
                continue
            if event == 1:  # row k's diagonal gains or loses w: update, else refactor
                self.switch_row(W, k)
                start = k  # the update leaves the rows above k as they were
                if self.chol_holds != CHOL_DUAL:
                    start = 0
                    if not self.afford(factor_work(md, nw, self.hq_factor)):
                        return OUT_OF_WORK
                    if not self.factor_working_set(W):
                        return -1
                continue
            st["in_set"][W[k]] = False
            st["W"], st["z"] = self.remove_row(W, z, k)
            hcol, start = np.delete(hcol, k), k  # the deletion works on rows k.. only

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

    def dual_active_set(self, lam, th0, K, gam, from_=-1):
        """Mirror of dual_active_set() (``from_``: the rows of ``stop``, where the guess
        stopped; -1: none; COLD_START: no warm start either): (code 0/1/-1/OUT_OF_WORK/
        OUT_OF_WORK_AT_TH0, th, active, steps + polish its)."""
        md = self.md
        st = {"W": np.zeros(0, np.int64), "z": np.zeros(0, md.Kx.dtype), "steps": 0, "K": K,
              "gam": gam, "in_set": np.zeros(md.m, bool)}
        th, moved = th0.copy(), False  # moved: th is a corrected point
        if not self.afford((0 if self.out_slacks_ok else md.m + predict_work(md)) + 2 * md.m):
            if from_ >= 0:
                self.keep_progress(lam)  # where the shifted guess stopped
            return OUT_OF_WORK_AT_TH0, th, 0, 0
        self.th_solved = None  # the C resets ws->th to th0 here
        self.output_slacks()
        self.work += md.m
        if from_ < 0:
            self.chol_holds, self.chol_set = CHOL_DUAL, st["W"]  # of the empty working set
            self.slack_on[:] = False
        if from_ >= 0 or (from_ != COLD_START and self.warm):
            nw, th = self.resume_working_set(lam, th0, K, st, from_)
            if nw == OUT_OF_WORK:  # lam: the warm start as far as it got
                self.keep_progress(lam)
                return OUT_OF_WORK_AT_TH0, th, 0, st["steps"]
            moved = nw > 0  # resumed: corrected at its working set
        resumed = moved  # th: the exact dual solve of W, what polish() would compute again
        polished = 0  # the polish's iterations
        for hand_back in (True, False):  # the polish may hand the set back once
            code, th, grown = self.add_violated_rows(th0, gam, st, th)
            moved, resumed = moved or grown, resumed and not grown
            W = st["W"]
            if not W.size and code != OUT_OF_WORK:
                if code == 0:
                    self.converged(lam, W, st["z"])
                return code, th, 0, st["steps"] + polished
            self.keep_working_set(lam, W, st["z"])  # the warm start, until the polish's
            if code == OUT_OF_WORK:
                return ((OUT_OF_WORK if moved else OUT_OF_WORK_AT_TH0), th, W.size,
                        st["steps"] + polished)
            if code == 0 and moved and self.final_set_holds(W, st["z"], th, gam, resumed):
                return 0, th, self.converged(lam, W, st["z"]), st["steps"] + polished
            code2, th_p, act, its = self.polish(W, lam, th0, K, gam, th=th,
                                                hand_back=hand_back and code == 0)
            polished += its
            if code2 != SET_HANDED_BACK:
                break
            W, st["z"], _ = self.stop  # dual feasible at th_p, with its factor
            st["W"], th, resumed = W, th_p, False
            st["in_set"][:] = False
            st["in_set"][W] = True
        if code2 == 0:
            return 0, th_p, act, st["steps"] + polished
        if code2 == OUT_OF_WORK:
            return OUT_OF_WORK, th_p, W.size, st["steps"] + polished
        return (1 if code == 1 else -1), th0, 0, st["steps"] + polished

    def add_violated_rows(self, th0, gam, st, th):
        """Mirror of add_violated_rows(): the most violated rows join st's working set, a
        batch per scan, until none is violated: (0 / 1 infeasible / -1 / OUT_OF_WORK, th,
        whether th moved)."""
        md, moved = self.md, False
        while True:
            if not self.afford(scan_work(md) + md.m):
                return OUT_OF_WORK, th, moved
            cands = self.most_violated(th, gam, st["in_set"])
            if not cands.size:
                return 0, th, moved
            for c, p in enumerate(cands):  # 2: no longer violated, skipped
                code = self.add_to_set(p, st, c > 0)
                code = 0 if code == 2 else code
                if code != 0:
                    return code, th, moved
            if not self.afford(correct_work(md, len(st["W"]))):
                return OUT_OF_WORK, th, moved
            th = self.correct(th0, st["W"], st["z"])
            moved = True
