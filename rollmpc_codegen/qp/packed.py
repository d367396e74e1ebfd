"""Packed lower-triangular storage of symmetric matrices (the C's P_TRI layout)."""
from __future__ import annotations

import numpy as np


def packed_lower(S: np.ndarray) -> np.ndarray:
    """Row-major packed lower triangle: element (i, j), j <= i, at i(i+1)/2 + j."""
    n = S.shape[0]
    return np.concatenate([S[i, :i + 1] for i in range(n)]) if n else np.zeros(0)


def unpack_lower(p: np.ndarray, n: int) -> np.ndarray:
    """Symmetric matrix from its packed lower triangle (same dtype)."""
    S = np.zeros((n, n), dtype=p.dtype)
    idx = 0
    for i in range(n):
        S[i, :i + 1] = p[idx:idx + i + 1]
        S[:i + 1, i] = p[idx:idx + i + 1]
        idx += i + 1
    return S
