"""Mirror of ``templates/solver/seeds.c.j2``: the polish's working-set seeds, from
multipliers, the previous active set shifted one stage (the guess), or the rows the
unconstrained solution violates.

:class:`SeedsMixin` is part of :class:`~.solver.SolverRef`; it reads ``md``, ``wcap`` and
``chol_holds`` and sets the soft rows' states (:mod:`.soft_rows`).
"""
from __future__ import annotations

import numpy as np

from ..solver_codes import CHOL_DUAL, CHOL_NONE


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
        that row's lam > l1 (with ``keep_first``, only the first wcap such rows)."""
        self.new_working_set()
        self.work += self.md.m
        row_next = self.md.row_next
        W = np.flatnonzero(lam[row_next] > 0)
        head = W[:self.wcap]  # the C sets the states of the rows it stores, then gives up
        self.set_state(head, lam[row_next[head]])
        return head if keep_first else W

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
