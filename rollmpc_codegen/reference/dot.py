"""Mirror of ``templates/solver/dot.c.j2``: products with the packed symmetric S and
S^-1 of the primal polish.

The C forms (M x)_q as one sequential sum over j = 0..n-1, whether it reads the whole row,
only the support of x (the other terms are exact zeros; a run of it along each row, or a
column of it down all the rows) or every row at once (``sym_product()``); the reference
sums the dense row.
"""
from __future__ import annotations

import numpy as np

from .linalg import seqsum_rows


def s_row_dot(M: np.ndarray, rows, x: np.ndarray) -> np.ndarray:
    """Mirror of ``s_row_dot``, ``sparse_rows_dot`` (either walk: along the rows by
    ``packed_range_dot``/``packed_range_dot2``, or down them by ``packed_columns_axpy``),
    ``gather_dot4`` and ``gather_product`` (over a gathered support list) and
    ``sym_product`` for each q in ``rows``: sum_j M(q, j) x_j in increasing j, from 0."""
    return seqsum_rows(M[np.asarray(rows, np.int64)] * x[None, :])
