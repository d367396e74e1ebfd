"""Mirror of ``templates/solver/factor_update.c.j2``: updates of a packed Cholesky factor
(rank one, row deletion) in place of a refactorisation.

The packed factor is the lower triangle by rows (:mod:`.linalg`).  Each column's rotation
is applied to the entries below the diagonal at once: elementwise, in the storage dtype,
so every entry rounds as in the C loop.
"""
from __future__ import annotations

import numpy as np

from .linalg import _tri_offsets


def pivot_independent(square, diagonal, dep_tol):
    """Mirror of ``pivot_independent()``: a pivot's square keeps more than ``dep_tol`` of
    the row's diagonal entry (elementwise on arrays)."""
    return square > dep_tol * diagonal


def chol_rank_one(l: np.ndarray, start: int, n: int, v: np.ndarray, downdate: bool,
                  dep_tol, carry: np.ndarray | None = None) -> bool:
    """Mirror of ``chol_rank_one()``: L L' +- v v' on the trailing block from ``start``
    (in place on l and v); False when a downdated pivot keeps no more than ``dep_tol`` of
    its square. ``carry``: rows of solves L^-1 b that the rotations carry along, entry n
    of each holding the extra one (chol_delete())."""
    tri = _tri_offsets(n)
    for j in range(start, n):
        ljj, vj = l[tri[j] + j], v[j]
        r2 = (ljj - vj) * (ljj + vj) if downdate else ljj * ljj + vj * vj
        if downdate and not pivot_independent(r2, ljj * ljj, dep_tol):
            return False
        r = np.sqrt(r2)
        c, s, ic = r / ljj, vj / ljj, ljj / r
        l[tri[j] + j] = r
        below = tri[j + 1:n] + j  # column j below the diagonal
        col = ((l[below] - s * v[j + 1:n]) if downdate else (l[below] + s * v[j + 1:n])) * ic
        l[below] = col
        v[j + 1:n] = c * v[j + 1:n] - s * col
        for y in () if carry is None else carry:  # entry j of the solve, as column j's
            yj = ((y[j] - s * y[n]) if downdate else (y[j] + s * y[n])) * ic
            y[j] = yj
            y[n] = c * y[n] - s * yj
    return True


def chol_delete(l: np.ndarray, k: int, n: int, v: np.ndarray,
                carry: np.ndarray | None = None) -> None:
    """Mirror of ``chol_delete()``: row and column k leave the factor of order n (in place
    on l; v is scratch of n entries); the solves ``carry`` (rows) become those of their
    right-hand sides without entry k."""
    tri = _tri_offsets(n)
    rows = [l[tri[i]:tri[i] + i + 1].copy() for i in range(k + 1, n)]
    for i, row in zip(range(k + 1, n), rows):
        v[i - 1] = row[k]
        l[tri[i - 1]:tri[i - 1] + i] = np.delete(row, k)
    for y in () if carry is None else carry:  # entry k to the end, where the rotations read it
        y[k:n] = np.concatenate((y[k + 1:n], y[k:k + 1]))
    chol_rank_one(l, k, n - 1, v, False, None, carry)
