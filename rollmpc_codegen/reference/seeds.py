"""Mirror of ``templates/solver/seeds.c.j2``: the polish's working-set seeds, from
multipliers, the previous active set shifted one stage (the guess), or the rows the
unconstrained solution violates.

:class:`SeedsMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``wcap`` and
``chol_holds`` and sets the soft rows' states (:mod:`.soft_rows`).
"""
from __future__ import annotations

import numpy as np

from ..qp.work import append_work, delete_work, factor_work
from ..solver_codes import CHOL_DUAL, CHOL_NONE, OUT_OF_WORK


class SeedsMixin:
    @staticmethod
    def violated_at_th0(K):
        """Mirror of violated_at_th0() for every row: K < 0 (the C skips the output rows
        whose K output_slacks() did not form: certified, none of them is violated)."""
        return K < 0
    def new_working_set(self):
        """Mirror of new_working_set(): a dual factor belongs to the old working set."""
        if self.chol_holds == CHOL_DUAL:
            self.chol_holds = CHOL_NONE

    def seed_from_multipliers(self, lam, S):
        """Mirror of seed_from_multipliers(): the rows of S with positive multipliers,
        slack where lam > l1."""
        self.new_working_set()
        self.work += S.size
        seed = S[lam[S] > 0]
        self.set_state(seed, lam[seed])
        return seed

    def seed_shifted(self, lam, keep_first=False):
        """Mirror of seed_shifted(): row r where its next-stage row was active, slack where
        that row's lam > l1 (with ``keep_first``, only the first wcap such rows); without it,
        in the order of the dual factor the last QP left when carry_factor() brings it to
        them, or OUT_OF_WORK when only part of their factor fits (lam is then the guess)."""
        self.work += self.md.m
        row_next = self.md.row_next
        W = np.flatnonzero(lam[row_next] > 0)
        carried = None if keep_first else self.carry_factor(W, lam[row_next])
        if carried is not None:
            return carried
        self.new_working_set()
        head = W[:self.wcap]  # the C sets the states of the rows it stores, then gives up
        self.set_state(head, lam[row_next[head]])
        return head if keep_first else W

    def carry_factor(self, W, carried):
        """Mirror of carry_factor(): the guess W (rows in order, ``carried`` the multiplier
        each row takes: lam one stage later) in the order of the dual factor ``chol_set`` that the last QP
        left: its rows that leave the guess or change state deleted from the last down, the
        guess's other rows appended in order, when that costs less than a new factor and the
        budget pays it. When neither that nor a new factor's dual solve fits, as much of it
        as the budget pays, the next QP going on from there: lam becomes the guess (a
        TIME_LIMIT) and the result OUT_OF_WORK; there a row whose pivot depends on the rows
        before it leaves the guess (lam 0). None (nothing changed) when W is empty, beyond wcap or
        input bounds only (the primal form's), or a new factor fits."""
        md = self.md
        if W.size == 0 or W.size > self.wcap or np.all(md.row_q[W] < md.n):
            return None
        guess = np.zeros(md.m, bool)
        guess[W] = True
        C = self.chol_set if self.chol_holds == CHOL_DUAL else self.chol_set[:0]
        stays = guess[C] & self.state_kept(C, carried[C])
        cost, size = 0, C.size
        for i in range(C.size - 1, -1, -1):
            if not stays[i]:
                cost += delete_work(i, size)
                size -= 1
        for size in range(size, W.size):
            cost += append_work(md, size, self.hq_factor)
        whole = cost < factor_work(md, W.size, self.hq_factor) and self.afford(cost)
        if not whole and self.afford(self.dual_solve_work(W.size, False)):
            return None
        if self.chol_holds != CHOL_DUAL:  # the factor of the empty set, to append to
            self.chol_holds, self.chol_set, C = CHOL_DUAL, C[:0], C[:0]
        z = np.zeros(C.size, md.Kx.dtype)
        for i in range(C.size - 1, -1, -1):
            if not stays[i]:
                if not (whole or self.afford(delete_work(i, C.size))):
                    break
                C, z = self.remove_row(C, z, i)
        kept = np.zeros(md.m, bool)
        kept[C] = True
        dependent = np.zeros(md.m, bool)  # rows that leave a cut guess (their pivot)
        for p in W[~kept[W]]:
            if not (whole or self.afford(append_work(md, C.size, self.hq_factor))):
                break
            joined = self.append_row(C, p, bool(self.slack_state(p, carried[p])))
            if whole or self.chol_holds == CHOL_DUAL:
                C = joined
            else:  # dependent on C: the factor of C stands, p leaves
                self.chol_holds, self.slack_on[p], dependent[p] = CHOL_DUAL, False, True
        if whole:  # (a whole carry never breaks off)
            return C
        self.lam[:] = np.where((carried > 0) & ~dependent, carried, self.zero)  # the next QP's
        return OUT_OF_WORK

    def seed_from_violated(self, K):
        """Mirror of seed_from_violated(): the rows th0 violates (K < 0), all tight."""
        self.new_working_set()
        self.work += self.md.m
        W = np.flatnonzero(self.violated_at_th0(K))
        self.slack_on[W] = False
        return W

    def violated_resume(self, K):
        """Mirror of violated_resume(): the rows th0 violates, seeded again as the dual
        active set's start (``stop``: them, none known); their count, or -1 (the budget,
        none, or more than wcap: a cold start)."""
        if not self.afford(self.md.m):
            return -1
        W = self.seed_from_violated(K)
        if W.size == 0 or W.size > self.wcap:
            return -1
        self.stop = (W.copy(), np.zeros(0, self.md.Kx.dtype), 0)
        return W.size
