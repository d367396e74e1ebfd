"""Mirror of ``templates/solver/resume.c.j2``: the dual active set's warm start (the
working set where the guess stopped, or the shifted previous one, made dual feasible) and
the check that accepts its final working set without a polish.

:class:`ResumeMixin` is part of :class:`~.solver.SolverRef`, beside
:class:`~.active_set.ActiveSetMixin`, which calls it; it keeps the state dict of
:meth:`~.active_set.ActiveSetMixin.dual_active_set` (W, z, in_set) and the dual factor.
"""
from __future__ import annotations

from ..qp.work import correct_work, final_check_work, independent_work
from ..solver_codes import CHOL_DUAL, OUT_OF_WORK


class ResumeMixin:
    def resume_working_set(self, lam, th0, K, st, from_):
        """Mirror of resume_working_set(): the working set where the guess stopped (``stop``,
        ``from_`` >= 0 rows), else the shifted previous one (its first wcap rows), made dual
        feasible in st (W, z, in_set), its dependent rows leaving if its factor breaks
        down; returns (its size, 0 to start cold, or OUT_OF_WORK with ``stop``; th)."""
        W = self.stop[0] if from_ >= 0 else self.seed_shifted(lam, True)
        st["in_set"][W] = True
        for _ in range(self.polish_max):
            if not W.size:  # no seed, or independent_rows() emptied it: start cold
                break
            st["steps"] += 1
            code, z = self.dual_solve(W, K)
            if code == -1:  # dependent rows: keep the independent ones, in order
                if not self.afford(independent_work(self.md, W.size, self.hq_factor)):
                    break  # start cold, with the work that is left
                st["in_set"][W] = False
                W = self.independent_rows(W)
                st["in_set"][W] = True
                continue
            known = W.size if code == 0 else 0
            if code == 0 and self.soft:
                code = self.switch_states(W, z)
            if code == 0:
                W, z, code = self.drop_negative(W, z, False)
            if code == OUT_OF_WORK:
                return self.stopped(W, z, known, OUT_OF_WORK), th0
            if code == 0:
                if not self.afford(correct_work(self.md, W.size)):
                    return self.stopped(W, z, W.size, OUT_OF_WORK), th0
                st["W"], st["z"] = W, z
                st["in_set"][:] = False  # remove_row() unflagged the dropped rows
                st["in_set"][W] = True
                return W.size, self.correct(th0, W, z)
            if code < 0:
                break
        st["in_set"][:] = False  # start cold
        self.slack_on[W] = False
        self.chol_holds, self.chol_set = CHOL_DUAL, W[:0]
        return 0, th0

    def final_set_holds(self, W, z, th, gam, exact):
        """Mirror of final_set_holds(): is the final working set, with no row violated
        outside it, optimal at its point?  ``exact``: th is its exact dual solve (the
        resume), so its rows need only hold; else they must also be tight.  Dual form
        only."""
        return (W.size <= self.wcap and not self.box_only(W)
                and self.afford(final_check_work(self.md))
                and self.working_set_holds(W, z, th, gam, predicted=True, tight=not exact))
