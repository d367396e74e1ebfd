"""NumPy mirror of ``templates/linalg.c.j2``, and the sequential sums of every mirror.

The C sums in a fixed order with no fused multiply-add (it is built with
``-ffp-contract=off``), so each mirror sums with :func:`seqsum`, never BLAS or numpy's
pairwise summation, in the storage dtype.  The packed factor is the lower triangle by
rows, element (i, j) at ``i (i + 1) / 2 + j`` (``P_TRI``).
"""
from __future__ import annotations

import numpy as np


def seqsum(products: np.ndarray, start=None) -> np.generic:
    """``acc = start (default 0); for p in products: acc += p`` in the products' dtype."""
    dt = products.dtype
    head = np.zeros(1, dt) if start is None else np.array([start], dt)
    return np.add.accumulate(np.concatenate((head, products)))[-1]


def seqsum_rows(P: np.ndarray) -> np.ndarray:
    """Row-wise :func:`seqsum` of a 2-D array of products (each row from 0)."""
    head = np.zeros((P.shape[0], 1), P.dtype)
    return np.add.accumulate(np.hstack((head, P)), axis=1)[:, -1]


def cholesky_from(a: np.ndarray, n: int, start: int = 0) -> bool:
    """Mirror of ``P_cholesky_from`` (in place on the packed array, rows ``start``..n-1);
    False on a bad pivot."""
    dt = a.dtype
    tri = _tri_offsets(n)
    for i in range(start, n):
        ri = a[tri[i]:tri[i] + i + 1]
        for j in range(i + 1):
            rj = a[tri[j]:tri[j] + j + 1]
            s = seqsum(-(ri[:j] * rj[:j]), start=ri[j]) if j else ri[j]
            if i == j:
                if not s > 0:
                    return False
                ri[i] = np.sqrt(dt.type(s))
            else:
                ri[j] = dt.type(s) / rj[j]
    return True


def cholesky(a: np.ndarray, n: int) -> bool:
    """Mirror of ``P_cholesky``: :func:`cholesky_from` row 0."""
    return cholesky_from(a, n)


def chol_lsolve_from(l: np.ndarray, n: int, b: np.ndarray, start: int = 0) -> None:
    """Mirror of ``P_chol_lsolve_from`` (L y = b, in place on b, rows ``start``..n-1; the
    rows above already hold y)."""
    tri = _tri_offsets(n)
    for i in range(start, n):
        s = seqsum(-(l[tri[i]:tri[i] + i] * b[:i]), start=b[i])
        b[i] = s / l[tri[i] + i]


def chol_lsolve(l: np.ndarray, n: int, b: np.ndarray) -> None:
    """Mirror of ``P_chol_lsolve``: :func:`chol_lsolve_from` row 0."""
    chol_lsolve_from(l, n, b)


def chol_ltsolve(l: np.ndarray, n: int, b: np.ndarray) -> None:
    """Mirror of ``P_chol_ltsolve`` (L' x = y, in place on b): each x_i's sum in decreasing
    k, however many rows the C solves in one trip."""
    tri = _tri_offsets(n)
    for i in range(n - 1, -1, -1):
        col = l[tri[i + 1:n] + i] if i + 1 < n else np.zeros(0, l.dtype)
        s = seqsum(-(col * b[i + 1:n])[::-1], start=b[i])
        b[i] = s / l[tri[i] + i]


def chol_solve(l: np.ndarray, n: int, b: np.ndarray) -> None:
    """Mirror of ``P_chol_solve`` (in place on b)."""
    chol_lsolve(l, n, b)
    chol_ltsolve(l, n, b)


def factor_and_solve(a: np.ndarray, n: int, *rhs: np.ndarray) -> bool:
    """``P_cholesky`` on a, then ``P_chol_solve`` for each right-hand side in turn (all in
    place); False on a bad pivot."""
    if not cholesky(a, n):
        return False
    for b in rhs:
        chol_solve(a, n, b)
    return True


def _tri_offsets(n: int) -> np.ndarray:
    i = np.arange(n + 1)
    return i * (i + 1) // 2
