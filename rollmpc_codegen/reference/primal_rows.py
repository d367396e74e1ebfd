"""Mirror of ``templates/solver/primal_rows.c.j2``: the rows of the primal polish's
factor, in order (the head, then the tail by generation), the choice between updating the
previous factor and a new one, and the previous rows deleted by updates.

:class:`PrimalRowsMixin` is part of :class:`~.solver.SolverRef` (through
:class:`~.polish_primal.PrimalPolishMixin`); it reads ``md`` and keeps
:attr:`factor_rows` (reset by ``forget_factor()``), the C's ws->primal_form and roles.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..qp.work import primal_delete_work

FREE, BOUND = 1, 2  # FORM_FREE, FORM_BOUND


def factor_order(nw: int, n: int) -> int:
    """Mirror of factor_order(): a new primal factor's order on nw bound inputs of n (the
    bound form's when fewer are bound than free)."""
    return nw if nw < n - nw else n - nw


# The C keeps a tail row's generation in the high bits of ws->input_role (ROLE_GEN_*):
# 1 for the inputs of the first update, one more for each update that appends inputs.
GEN_MAX = 31


class FactorRows(NamedTuple):
    """The C's ws->primal_form and its rows: the head (the last full factorisation's), in
    descending inputs in the free form and ascending in the bound form, then the tail
    (inputs that joined since) in joining order: by generation (``gens``, one per tail
    row), each generation in the head's order."""
    form: int
    head: list
    tail: list
    gens: list


def primal_cost(n: int, nt: int, k: int, p: int) -> int:
    """Mirror of primal_cost(): six times the multiply-adds of a solve of order k, rows
    p.. factored."""
    factor = (k ** 3 - k - p ** 3 + p) + 3 * (k * (k + 1) - p * (p + 1))
    solves = 3 * nt * (k * k - k - p * p + p) + 6 * (k * k - k)
    return factor + solves + 6 * k * (n - k)


class PrimalRowsMixin:
    factor_rows: FactorRows | None = None

    def box_only(self, W):
        """Mirror of box_only(): does the seed W hold only input bounds (the primal form's
        working set)?  A seed beyond wcap is the C's -1, no rows: True."""
        return W.size > self.wcap or bool(np.all(self.md.row_q[W] < self.md.n))

    def primal_order(self, bound, form):
        """Mirror of primal_diff() and primal_order(): the rows of the factor in order, the
        factor_rows they make, the first row that changes and, for an update, the previous
        factor's rows in order (else None)."""
        n, nw = self.md.n, int(np.count_nonzero(bound))
        prev = self.factor_rows
        if prev is not None and (nw > 0 if prev.form == FREE else nw < n):
            member = bound if prev.form == BOUND else ~bound
            kept = [(g, q) for g, q in zip(prev.gens, prev.tail) if member[q]]
            newest = max((g for g, _ in kept), default=0)
            head = [q for q in prev.head if member[q]]
            joined = sorted([int(q) for q in np.flatnonzero(member)
                             if q not in prev.head and q not in prev.tail],
                            reverse=prev.form == FREE)  # appended: the rows above stay
            tail = [q for _, q in kept] + joined
            gens = [g for g, _ in kept] + [newest + 1] * len(joined)
            old, new = prev.head + prev.tail, head + tail
            start = next((i for i, (a, b) in enumerate(zip(old, new)) if a != b),
                         min(len(old), len(new)))
            k_new = factor_order(nw, n)
            nt = self.md.nt
            if newest < GEN_MAX and (prev.form == form or (primal_cost(n, nt, len(new), start)
                                                           <= primal_cost(n, nt, k_new, 0))):
                return new, FactorRows(prev.form, head, tail, gens), start, old
        member = bound if form == BOUND else ~bound
        head = [int(q) for q in np.flatnonzero(member)]
        if form == FREE:
            head.reverse()
        return head, FactorRows(form, head, [], []), 0, None

    def primal_deletes(self, old, member):
        """Mirror of primal_deletes(): the work of deleting the rows of the previous factor
        (order ``old``, the C's ws->primal_rows) whose inputs are not in ``member``, and
        their (position, order) from the last up."""
        k, work, deletes = len(old), 0, []
        for pos in range(len(old) - 1, -1, -1):
            if old[pos] not in member:
                work += primal_delete_work(pos, k, self.md.nt)
                deletes.append((pos, k))
                k -= 1
        return work, deletes
