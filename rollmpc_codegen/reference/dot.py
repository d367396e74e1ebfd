"""Mirror of ``templates/solver/dot.c.j2``: the four-lane sums over S of the primal polish.

``s_at()`` has no function here: the reference reads the unpacked S (:mod:`.hq`).
"""
from __future__ import annotations

import numpy as np

from .linalg import seqsum_rows


def dot4_rows(P: np.ndarray) -> np.ndarray:
    """Row-wise mirror of the C ``dot4``: lanes i mod 4, the tail into lane 0,
    combined as (s0 + s1) + (s2 + s3)."""
    rows, length = P.shape
    main = length - length % 4
    lanes = [seqsum_rows(P[:, j:main:4]) for j in range(4)]
    s0 = np.add.accumulate(np.hstack((lanes[0][:, None], P[:, main:])), axis=1)[:, -1]
    return (s0 + lanes[1]) + (lanes[2] + lanes[3])


def s_row_dots(S: np.ndarray, rows, v: np.ndarray) -> np.ndarray:
    """Mirror of ``s_row_dot`` for each q in ``rows``: dot4 up to the diagonal, dot4 below."""
    out = np.empty(len(rows), S.dtype)
    for j, q in enumerate(rows):
        head = dot4_rows((S[q, :q + 1] * v[:q + 1])[None, :])[0]
        tail = dot4_rows((S[q, q + 1:] * v[q + 1:])[None, :])[0]
        out[j] = head + tail
    return out
