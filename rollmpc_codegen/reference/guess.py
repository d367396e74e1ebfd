"""Mirror of ``templates/solver/guess.c.j2``: the shifted guess's first point, reversed
(:meth:`GuessMixin.guess_reversed`) or run past its edge and trimmed
(:meth:`GuessMixin.trim_guess`).

:class:`GuessMixin` is part of :class:`~.solver.SolverRef`; it reads ``md`` and the free
form's multipliers (:meth:`~.polish_primal.PrimalPolishMixin.signed_multiplier`).
"""
from __future__ import annotations

import numpy as np

from ..qp.work import (GUESS_SAMPLE_MIN, guess_sample_work, multipliers_work, primal_reserve,
                       trim_work)
from .primal_rows import factor_order


class GuessMixin:
    def guess_reversed(self, W):
        """Mirror of guess_reversed(): a free-form guess of GUESS_SAMPLE_MIN rows or more
        whose middle, first and last rows (in that order) all have negative multipliers."""
        md, nw = self.md, W.size
        if nw < GUESS_SAMPLE_MIN or not self.afford(
                guess_sample_work(md, 3) + multipliers_work(md, nw) + primal_reserve(md)):
            return False  # the budget keeps what primal_solve() granted polish()
        for a in (nw // 2, 0, nw - 1):
            self.work += guess_sample_work(self.md, 1)
            if not self.signed_multiplier(W[a:a + 1])[0] < 0:
                return False
        return True

    def trim_guess(self, W, lam, K):
        """Mirror of trim_guess(): a reversed guess W trimmed to its rows carrying at least
        half of the largest multiplier carried from the previous sample, or None (give it
        up) unless that keeps 3/4 of W and a lower factor order than K's violated rows."""
        md = self.md
        if not self.afford(trim_work(md, W.size)):
            return None
        self.work += 2 * W.size  # the guess's scans
        carried = lam[md.row_next[W]]
        keep = carried >= carried.max() * self.dt(0.5)
        kept = int(np.count_nonzero(keep))
        if 4 * kept < 3 * W.size:
            return None
        self.work += md.m  # the rows' scan
        violated = int(np.count_nonzero(self.violated_at_th0(K)))
        if factor_order(kept, md.n) >= factor_order(violated, md.n):
            return None
        return W[keep]
