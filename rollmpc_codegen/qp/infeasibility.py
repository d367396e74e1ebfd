"""Which constraints make a QP infeasible, named by their config keys: the diagnosis of
``simulate``'s INFEASIBLE warning (sim/run_checks.py).

The hard rows of eq. (6), ``L U <= c + W x + Wr R``, are relaxed by one slack each and the
total slack minimised (an elastic LP, scipy's HiGHS): the rows left with a positive slack
are a least violation the plan cannot avoid.  Each is named by what wrote it: an output
bound (``modes[j].bounds.y_min``/``y_max``), a Δu bound, a constrained signal or mixed
row (its ``modes[j].constraints...`` key), or the terminal set.  Input bounds hold by
construction (the slacks relax the others against them).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from .condense import CondensedQP
from .rows import INPUT, OUTPUT, RATE, SIGNAL


def row_keys(qp: CondensedQP, j: int) -> list[str]:
    """The config key of every row of mode ``j``'s QP."""
    key = f"modes[{j}]"
    out = []
    for kind, index, sign in zip(qp.row_kind, qp.row_index, qp.row_sign):
        side = "min" if sign < 0 else "max"
        if kind == SIGNAL.code:
            out.append(qp.signals.signals[qp.signals.sig[index]].key)
        elif kind == OUTPUT.code:
            out.append(f"{key}.bounds.y_{side}")
        elif kind == RATE.code:
            out.append(f"{key}.bounds.du_{side}")
        else:
            out.append(f"{key}.bounds.u_{side}")
    return out


def violated_keys(qp: CondensedQP, j: int, x: np.ndarray, r: np.ndarray) -> list[str]:
    """The keys of the hard rows a least-violation plan still violates at (x, r); [] when
    the QP is feasible there (or the LP fails)."""
    hard = np.ones(qp.m, bool) if qp.soft_l2 is None else ~(qp.soft_l2 > 0)
    box = hard & (qp.row_kind == INPUT.code)
    relaxed = np.flatnonzero(hard & ~box)
    b = qp.gamma(x, r)
    n, k = qp.n, relaxed.size
    if k == 0:
        return []
    # variables (U, s): min sum s, L_box U <= b_box, L_rel U - s <= b_rel, s >= 0
    A = np.block([[qp.L[box], np.zeros((int(box.sum()), k))],
                  [qp.L[relaxed], -np.eye(k)]])
    rhs = np.concatenate((b[box], b[relaxed]))
    cost = np.concatenate((np.zeros(n), np.ones(k)))
    res = linprog(cost, A_ub=A, b_ub=rhs, bounds=[(None, None)] * n + [(0, None)] * k,
                  method="highs")
    if res.status != 0:
        return []
    scale = np.maximum(1.0, np.abs(b[relaxed]))
    violated = relaxed[res.x[n:] > 1e-7 * scale]
    keys = row_keys(qp, j)
    return sorted({keys[i] for i in violated})
