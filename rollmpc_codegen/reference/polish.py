"""Mirror of ``templates/solver/polish.c.j2``: the working-set seeds and the polish, an
exact solve on a guessed working set, corrected until KKT holds.

:class:`PolishMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``wcap``,
``polish_max``, ``soft``, ``tol`` and ``slack_on``, and solves through the primal and
dual mixins (:mod:`.polish_primal`, :mod:`.polish_dual`); the dual one keeps its factor
``chol`` across the corrections.  Working sets are in joining order, as in the C.
"""
from __future__ import annotations

import numpy as np

from .linalg import chol_solve_packed
from .polish_dual import CHOL_NONE


class PolishMixin:
    def seed_from_multipliers(self, lam, S):
        """Mirror of seed_from_multipliers(): the rows of S with positive multipliers,
        slack where lam > l1."""
        self.chol_holds = CHOL_NONE
        seed = S[lam[S] > 0]
        self.set_state(seed, lam[seed])
        return seed

    def seed_shifted(self, lam):
        """Mirror of seed_shifted(): row r where its next-stage row was active, slack where
        that row's lam > l1."""
        self.chol_holds = CHOL_NONE
        row_next = self.md.row_next
        W = np.flatnonzero(lam[row_next] > 0)
        self.set_state(W, lam[row_next[W]])
        return W

    def seed_from_violated(self, K):
        """Mirror of seed_from_violated(): the rows th0 violates (K < 0), all tight."""
        self.chol_holds = CHOL_NONE
        W = np.flatnonzero(K < 0)
        self.slack_on[W] = False
        return W

    def drop_negative(self, W, z, guess):
        """Mirror of drop_negative(): (W, z, 0 none dropped / 1 dropped / -1 give up),
        the negative rows removed from the last position down (remove_row())."""
        keep = z >= 0
        kept = int(np.count_nonzero(keep))
        if kept == W.size:
            return W, z, 0
        if kept == 0 or (guess and 2 * kept < W.size):
            return W, z, -1
        for k in np.flatnonzero(~keep)[::-1]:
            W, z = self.remove_row(W, z, k)
        return W, z, 1

    def working_set_holds(self, W, z, viol, scale):
        """Mirror of working_set_holds() (violated_in_set() with soft rows), from the
        rows' excess and tolerance scale at th (:meth:`row_excess`)."""
        if self.soft:
            return not np.any(viol[W] - self.slack_in_set(W, z) > self.tol * scale[W])
        return not np.any((viol > self.tol * scale)[W])

    def refine_dual(self, W, z, th0, K, gam, th):
        """Mirror of refine_dual(): (ok, th, z) after up to two refinement rounds."""
        nw = W.size
        chol = self.chol  # the factor dual_solve() used
        for _ in range(2):
            e = self.row_excess(th, gam)[0][W]
            if self.soft:
                e = e - self.slack_in_set(W, z)
            chol_solve_packed(chol, nw, e)
            z = z + e
            if np.any(z < 0) or (self.soft and self.switch_states(W, z)):
                return False, th, z
            th = self.correct(th0, W, z)
            exc, scale = self.row_excess(th, gam)
            if self.working_set_holds(W, z, exc, scale):
                viol = exc > self.tol * scale
                viol[W] = False  # violated_outside(): the rows outside W
                return (not np.any(viol)), th, z
        return False, th, z

    @staticmethod
    def accept(lam, W, z):
        """Mirror of accept(): W's multipliers become the warm start; returns |W|."""
        lam[:] = 0
        lam[W] = z
        return W.size

    def polish(self, W, lam, th0, K, gam, guess=False):
        """Mirror of polish() from working set W (taking the dual factor ``chol`` when
        ``chol_holds`` says it is W's); returns (ok, th, active, iterations)."""
        md = self.md
        n = md.n
        its = 0
        if W.size == 0 or W.size > self.wcap:
            return False, None, 0, its
        for _ in range(self.polish_max):
            its += 1
            box_only = bool(np.all(md.row_q[W] < n))
            if box_only:
                ok, th, z = self.primal_solve(th0, W)
                if not ok:
                    return False, None, 0, its
                add = self.violated_outside(th, gam, W)
                if add.size == 0:
                    if z is None:
                        z = self.free_multipliers(W)
                    W, z, dropped = self.drop_negative(W, z, guess)
                    if dropped < 0:
                        return False, None, 0, its
                    if dropped:
                        continue
                    return True, th, self.accept(lam, W, z), its
            else:
                ok, z = self.dual_solve(W, K)
                if not ok:
                    return False, None, 0, its
                if self.soft and self.switch_states(W, z):
                    continue
                W, z, dropped = self.drop_negative(W, z, guess)
                if dropped < 0:
                    return False, None, 0, its
                if dropped:
                    continue
                th = self.correct(th0, W, z)
                add = self.violated_outside(th, gam, W)
                if add.size == 0:
                    if not self.working_set_holds(W, z, *self.row_excess(th, gam)):
                        ok, th, z = self.refine_dual(W, z, th0, K, gam, th)
                        if not ok:
                            return False, None, 0, its
                    return True, th, self.accept(lam, W, z), its
            if add.size > self.wcap - W.size:
                return False, None, 0, its
            for p in add:
                W = self.append_row(W, p)
        return False, None, 0, its
