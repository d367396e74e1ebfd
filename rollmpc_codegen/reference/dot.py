"""Mirror of ``templates/solver/dot.c.j2``: products with the packed symmetric S and
S^-1 of the primal polish.

The C forms (M x)_q as one sequential sum over j = 0..n-1, whether it reads the whole row,
only the support of x (the other terms are exact zeros) or every row at once
(``sym_product()``); the reference sums the dense row.
"""
from __future__ import annotations

import numpy as np

from .linalg import seqsum_rows


def s_row_dots(M: np.ndarray, rows, x: np.ndarray) -> np.ndarray:
    """Mirror of ``s_row_dot``, ``sparse_row_dot`` and ``sym_product`` for each q in
    ``rows``: sum_j M(q, j) x_j in increasing j, from 0."""
    return seqsum_rows(M[np.asarray(rows, np.int64)] * x[None, :])
