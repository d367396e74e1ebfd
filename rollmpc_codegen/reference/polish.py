"""Mirror of ``templates/solver/polish.c.j2``: the polish, an exact solve on a seeded
working set (:mod:`.seeds`), corrected until KKT holds.

:class:`PolishMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``wcap``,
``polish_max``, ``soft``, ``tol`` and ``slack_on``, and solves through the primal and
dual mixins (:mod:`.polish_primal`, :mod:`.polish_dual`); the dual one keeps its factor
``chol`` across the corrections.  Working sets are in joining order, as in the C.
"""
from __future__ import annotations

import numpy as np

from ..qp.work import append_work, correct_work, delete_work, primal_reserve, scan_work
from ..solver_codes import (CHOL_DUAL, GUESS_CAPPED, GUESS_HANDED_OVER, OUT_OF_WORK,
                            SET_HANDED_BACK)


class PolishMixin:
    @staticmethod
    def kept_rows(z):
        """Mirror of kept_rows(): the working-set rows whose multiplier is not negative."""
        return int(np.count_nonzero(z >= 0))

    @staticmethod
    def given_up(kept, size, guess):
        """Mirror of given_up(): emptied, or a guess losing more than half of its rows."""
        return kept == 0 or (guess and 2 * kept < size)

    def drop_negative(self, W, z, guess):
        """Mirror of drop_negative(): (W, z, 0 none dropped / 1 dropped / -1 give up /
        OUT_OF_WORK), the negative rows removed from the last position down (remove_row())."""
        keep = z >= 0
        kept = self.kept_rows(z)
        if kept == W.size:
            return W, z, 0
        if self.given_up(kept, W.size, guess):
            return W, z, -1
        if self.chol_holds == CHOL_DUAL and not self.afford((W.size - kept)
                                                            * delete_work(0, W.size)):
            return W, z, OUT_OF_WORK
        for k in np.flatnonzero(~keep)[::-1]:
            W, z = self.remove_row(W, z, k)
        return W, z, 1

    def drop_negative_tracked(self, W, z, guess):
        """Mirror of drop_negative_tracked(): drop_negative()'s (W, z, code), keeping
        ``guess_left`` (W[:guess_left] are the guess's rows still in W); code 2 instead of 1
        when a row that joined in this polish is among those dropped."""
        neg = np.flatnonzero(~(z >= 0))
        W, z, code = self.drop_negative(W, z, guess)
        if code == 1:
            code += bool(np.any(neg >= self.guess_left))
            self.guess_left -= int(np.count_nonzero(neg < self.guess_left))
        return W, z, code

    @staticmethod
    def keep_working_set(lam, W, z):
        """Mirror of keep_working_set(): lam = W's multipliers, 0 elsewhere."""
        lam[:] = 0
        lam[W] = z

    def converged(self, lam, W, z):
        """Mirror of converged(): W's multipliers become the warm start; returns |W|."""
        self.work += self.md.m
        self.keep_working_set(lam, W, z)
        return W.size

    def stopped(self, W, z, known, code):
        """Mirror of stopped(): where polish() ran out of work, or the working set a guess
        hands over (W, z, known); returns code."""
        if code in (OUT_OF_WORK, GUESS_HANDED_OVER, SET_HANDED_BACK):
            self.stop = (W.copy(), np.zeros(0, self.md.Kx.dtype) if z is None else z.copy(),
                         known)
        return code

    def keep_progress(self, lam):
        """Mirror of keep_progress(): lam = the stopped working set, its first ``known``
        rows with their positive multipliers, the others with a token one."""
        W, z, known = self.stop
        zk = np.full(W.size, self.dt(1.0e-30), self.md.Kx.dtype)
        zk[:known] = np.where(z[:known] > 0, z[:known], self.zero)
        self.keep_working_set(lam, W, zk)

    def polish(self, W, lam, th0, K, gam, guess=False, th=None, hand_back=False):
        """Mirror of polish() from working set W (taking the dual factor ``chol`` when
        ``chol_holds`` says it is W's); returns (0 / -1 / GUESS_CAPPED / GUESS_HANDED_OVER /
        SET_HANDED_BACK / OUT_OF_WORK, th, active, iterations), th after OUT_OF_WORK being
        the C's ws->th then (``th`` on entry) and ``stop`` where it stopped (after
        GUESS_HANDED_OVER: a guess' rows, dual feasible or after a drop, with their factor;
        after SET_HANDED_BACK, ``hand_back`` being set: the dual active set's rows, dual
        feasible, with their factor, th their point)."""
        md = self.md
        its, known, z = 0, 0, None
        repeatable = guess  # every round so far a dual solve that switched or dropped
        if W.size == 0 or W.size > self.wcap:
            return -1, None, 0, its
        if not self.afford(md.m):
            return self.stopped(W, z, 0, OUT_OF_WORK), th, 0, its
        self.work += md.m
        self.guess_left = W.size
        for _ in range(self.polish_max):
            its += 1
            if self.box_only(W):
                repeatable = False
                ok, th_p, zp = self.primal_solve(th0, W, primal_reserve(md))
                if ok == OUT_OF_WORK:
                    return self.stopped(W, z, known, OUT_OF_WORK), th, 0, its
                if not ok:
                    return -1, None, 0, its
                th = th_p
                if zp is not None:
                    z = zp
                known = W.size if zp is not None else 0
                add = self.violated_outside(th, gam, W)
                if zp is None and guess and its == 1 and self.guess_reversed(W):
                    W = self.trim_guess(W, lam, K)  # before free_multipliers()
                    if W is None:
                        return -1, None, 0, its
                    self.guess_left = W.size
                    continue
                if add.size and guess and its == 1:  # the C's early test of a guess
                    zc = zp if zp is not None else self.free_multipliers(W)
                    if self.given_up(self.kept_rows(zc), W.size, True):
                        return -1, None, 0, its
                if add.size and zp is not None:  # the C's primal-dual round (all negative: kept)
                    W, z, _ = self.drop_negative_tracked(W, zp, False)
                    known = W.size
                if add.size == 0:
                    if zp is None:
                        z = self.free_multipliers(W)
                    known = W.size
                    W, z, code = self.drop_negative_tracked(W, z, guess)
                    if code < 0:
                        return self.stopped(W, z, known, code), th, 0, its
                    if code:
                        known = W.size
                        continue
                    return 0, th, self.converged(lam, W, z), its
            else:
                code, zd = self.dual_solve(W, K)
                if code:
                    return self.stopped(W, z, known, code), th, 0, its
                z, known = zd, W.size
                if self.soft:
                    code = self.switch_states(W, z)
                    if code < 0:
                        return self.stopped(W, z, known, code), th, 0, its
                    if code:
                        continue
                W, z, code = self.drop_negative_tracked(W, z, guess)
                if code < 0:
                    return self.stopped(W, z, known, code), th, 0, its
                if code:
                    known = W.size
                    if code == 2 and guess and self.active_set and self.chol_holds == CHOL_DUAL:
                        # a row the guess added leaves again: the dual active set ends the cycle
                        return self.stopped(W, z, known, GUESS_HANDED_OVER), th, 0, its
                    continue
                repeatable = False  # dual feasible: the resume would stop here
                if not self.afford(correct_work(md, W.size) + 2 * scan_work(md) + md.m):
                    return self.stopped(W, z, known, OUT_OF_WORK), th, 0, its
                th = self.correct(th0, W, z)
                add = self.violated_outside(th, gam, W)
                if add.size == 0:
                    code = 0
                    if not self.working_set_holds(W, z, th, gam, predicted=True):
                        code, th, z = self.refine_dual(W, z, gam, th)
                        if code == 1:  # a row outside: the dual active set makes room
                            code = SET_HANDED_BACK if hand_back else -1
                    if code:
                        return self.stopped(W, z, known, code), th, 0, its
                    return 0, th, self.converged(lam, W, z), its
            dual = (W.size if (guess or hand_back) and self.active_set
                    and self.chol_holds == CHOL_DUAL else -1)  # dual feasible, factored
            handed = GUESS_HANDED_OVER if guess else SET_HANDED_BACK
            if add.size > self.wcap - W.size:
                code = self.stopped(W, z, dual, handed) if dual >= 0 else -1
                return code, th, 0, its
            if self.chol_holds == CHOL_DUAL and not self.afford(
                    add.size * append_work(md, W.size + add.size, self.hq_factor)):
                return self.stopped(W, z, known, OUT_OF_WORK), th, 0, its
            for p in add:
                W = self.append_row(W, p)
            if dual >= 0 and self.chol_holds != CHOL_DUAL:
                # of W[:dual], which the appends kept
                self.chol_holds, self.chol_set = CHOL_DUAL, W[:dual].copy()
                return self.stopped(W[:dual], z, dual, handed), th, 0, its
        return (GUESS_CAPPED if repeatable else -1), th, 0, its
