"""Soft output bounds (issue 5, item 3): ``modes[].bounds.soft``.

A soft output row ``M_r U <= gamma_r`` becomes ``M_r U - s_r <= gamma_r`` with its own slack
``s_r >= 0`` (one per row, i.e. per output, side and stage) and the cost
``J += l1 s_r + l2 s_r^2`` (the scale of J: Q and R without a factor 1/2).  The L1 term
makes the penalty exact: when the hard QP is feasible and l1 exceeds the multiplier the
hard bound needs, the soft QP has the same solution; when it is not, the QP stays
feasible (the input box is the only hard constraint left) and the slack says by how much
the plan exceeds the bound.

The generated solver never stores the slacks as variables.  Eliminating s_r from the dual
(min over s >= 0 of l1 s + l2 s^2 - lam s) leaves the multiplier lam_r >= 0 with the
concave penalty -(lam_r - l1)_+^2 w / 2, w = 1 / (2 l2), and ``s_r = max(0, (lam_r - l1) w)``.
So a soft row in the working set is in one of two states:

* *tight* (0 <= lam_r <= l1): s_r = 0, the row is an equality like a hard row;
* *slack* (lam_r >= l1): ``M_r U - gamma_r = (lam_r - l1) w``, i.e. the dual system gains
  w on the row's diagonal and l1 w on its right-hand side.

The sweeps take the piecewise coordinate maximum, the polish and the dual active set
switch a row's state where its multiplier crosses l1 (templates/solver/).  A working
set can then hold more than n rows (slack rows do not compete for the n degrees of
freedom of U): its capacity is n plus the soft (output, stage) pairs, :func:`working_set_cap`.

:func:`explicit_qp` writes the same problem with the slacks as variables, for the
independent solvers (DAQP, the extended-precision KKT reference, the bench peers).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..qp.rows import INPUT, OUTPUT, ROW_KINDS


def row_penalties(l1: np.ndarray | None, l2: np.ndarray | None, row_kind, row_index,
                  row_sign, ny: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(l1, l2) of every constraint row (0 for hard rows); (None, None) without soft bounds.

    ``l1``/``l2`` are the config's (ny, 2) arrays (column 0 = y_min, 1 = y_max).
    """
    if l2 is None:
        return None, None
    kind, index, sign = map(np.asarray, (row_kind, row_index, row_sign))
    out = kind == OUTPUT.code
    j = np.where(out, index % ny, 0)
    side = (sign > 0).astype(int)
    return np.where(out, l1[j, side], 0.0), np.where(out, l2[j, side], 0.0)


def storage(l1: np.ndarray, l2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The C's per-bound arrays: soft_l1[2 j + side] = l1 and soft_w[..] = 1 / (2 l2)
    (0 for a hard bound), side 0 = y_min, 1 = y_max; in double (the caller casts)."""
    w = np.divide(1.0, 2.0 * l2, out=np.zeros_like(l2), where=l2 > 0.0)
    return l1.reshape(-1).copy(), w.reshape(-1)


def working_set_cap(n: int, row_kind, row_index, row_l2) -> int:
    """n plus the quantities with a soft row ((output, stage) and (signal, time) pairs): at
    most one side of a pair is active, and only tight soft rows and hard rows compete for
    U's n degrees of freedom."""
    kind, index = np.asarray(row_kind), np.asarray(row_index)
    soft = np.asarray(row_l2) > 0.0
    return n + sum(int(np.unique(index[soft & (kind == k.code)]).size)
                   for k in ROW_KINDS if k.soft)


def multiplier_slack(lam: np.ndarray, row_l1: np.ndarray, row_w: np.ndarray) -> np.ndarray:
    """s_r = (lam_r - l1_r) w_r where w_r > 0 and lam_r > l1_r, else 0 (w = 1/(2 l2), 0 for
    hard rows), in the arrays' dtype: the C's multiplier_slack() for every row."""
    on = (row_w > 0) & (lam > row_l1)
    return np.where(on, (lam - row_l1) * row_w, np.zeros_like(row_w))


def explicit_qp(qp):
    """The :class:`~rollmpc_codegen.qp.condense.CondensedQP` with one slack variable per soft row
    appended to U: E + blkdiag(2 l2), the gradient's constant part l1, soft rows
    ``M_r U - s_r <= gamma_r`` and ``-s_r <= 0`` as box rows (kind 0) on the slacks.
    Without soft rows, qp itself.  Its solution's first ``qp.n`` entries are U.  For
    solvers only: its Kx/Kr rows of the slacks are 0 (their unconstrained value
    -l1 / (2 l2) is in ``gradient()``, not in ``theta0()``)."""
    if qp.soft_l2 is None or not np.any(qp.soft_l2 > 0.0):
        return qp
    soft = np.flatnonzero(qp.soft_l2 > 0.0)
    n, m, ns = qp.n, qp.m, soft.size
    E = np.zeros((n + ns, n + ns))
    E[:n, :n] = qp.E
    E[n:, n:] = np.diag(2.0 * qp.soft_l2[soft])
    L = np.zeros((m + ns, n + ns))
    L[:m, :n] = qp.L
    L[soft, n + np.arange(ns)] = -1.0
    L[m + np.arange(ns), n + np.arange(ns)] = -1.0
    pad = np.zeros((ns, qp.nx))
    Gx = np.vstack((np.zeros((n, qp.nx)) if qp.Gx is None else qp.Gx, pad))
    return dataclasses.replace(
        qp, E=E, Einv=np.linalg.inv(E), F=np.vstack((qp.F, np.zeros((ns, qp.F.shape[1])))),
        Kx=np.vstack((qp.Kx, pad)), Kr=np.vstack((qp.Kr, np.zeros((ns, qp.Kr.shape[1])))),
        L=L, W=np.vstack((qp.W, pad)), c=np.concatenate((qp.c, np.zeros(ns))),
        Wr=None if qp.Wr is None else np.vstack((qp.Wr, np.zeros((ns, qp.Wr.shape[1])))),
        row_kind=np.concatenate((qp.row_kind, np.full(ns, INPUT.code, np.int32))),
        row_index=np.concatenate((qp.row_index, n + np.arange(ns, dtype=np.int32))),
        row_sign=np.concatenate((qp.row_sign, -np.ones(ns, np.int32))),
        Gx=Gx, f_const=np.concatenate((np.zeros(n), qp.soft_l1[soft])),
        soft_l1=None, soft_l2=None)
