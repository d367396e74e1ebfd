"""A minimal state-space realisation of a transfer-function matrix (numpy/scipy only).

python-control's MIMO ``tf2ss`` needs slycot (Fortran), which rollmpc does not require,
so the matrix form of ``modes[].plant.transfer_function`` is realised here:

1. **One controllable-canonical block per input column.**  Column j's common
   denominator d_j is the product of its *distinct* (monic-normalised) element
   denominators, each element is rewritten as n_ij'/d_j, and the single-input,
   multi-output block (companion matrix of d_j, B = e_k, one C row per output, D the
   biproper part) realises the column exactly.  The blocks are stacked block-diagonally.
2. **Minimal realisation.**  The stack is controllable by construction but usually not
   observable: a pole shared by two columns (or a common factor d_j introduces that some
   element also cancels) appears once per column.  After a diagonal balancing of A
   (LAPACK gebal), two orthogonal staircase reductions (Kalman decomposition, Varga's
   algorithm: SVD rank decisions, no powers of A) keep the controllable and then the
   observable part.  The result has the McMillan degree of the matrix (up to the rank
   tolerance ``RANK_TOL`` relative to the system's norm), so the observer and the MPC get
   a model without hidden modes; a pole that every element of its row and column cancels
   is removed too (it is not part of the input-output map).

The realisation's frequency response equals the matrix (tests/model/test_tf_matrix_kalman_disturbance.py).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

RANK_TOL = 1e-9  # singular values below RANK_TOL * norm count as zero in the staircase

Element = tuple[tuple[float, ...], tuple[float, ...]]  # (num, den), highest power first


def _monic(den) -> np.ndarray:
    den = np.asarray(den, dtype=float)
    return den / den[0]


def _column_block(column: list[Element]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(A, b, C, d) of one input column: companion form of the common denominator."""
    ny = len(column)
    factors: list[np.ndarray] = []
    for num, den in column:
        m = _monic(den)
        if np.any(np.asarray(num) != 0) and not any(
                f.size == m.size and np.allclose(f, m, rtol=1e-12, atol=0) for f in factors):
            factors.append(m)
    common = np.array([1.0])
    for f in factors:
        common = np.polymul(common, f)
    k = common.size - 1
    A = np.zeros((k, k))
    if k:
        A[:-1, 1:] = np.eye(k - 1)
        A[-1] = -common[1:][::-1]  # -[a_k, .., a_1] of s^k + a_1 s^(k-1) + .. + a_k
    b = np.zeros(k)
    if k:
        b[-1] = 1.0
    C = np.zeros((ny, k))
    d = np.zeros(ny)
    for i, (num, den) in enumerate(column):
        num = np.asarray(num, dtype=float)
        if not np.any(num != 0):
            continue
        m = _monic(den)
        cofactor = np.array([1.0])
        for f in factors:  # the factors of d_j other than this element's denominator
            if not (f.size == m.size and np.allclose(f, m, rtol=1e-12, atol=0)):
                cofactor = np.polymul(cofactor, f)
        n = np.polymul(num / float(den[0]), cofactor)
        n = np.concatenate([np.zeros(k + 1 - n.size), n])  # degree <= k (proper)
        d[i] = n[0]
        rest = n - d[i] * common  # strictly proper remainder, degree < k
        C[i] = rest[1:][::-1]  # lowest power first, matching the companion form
    return A, b, C, d


def column_realisation(matrix) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The block-diagonal stack of the column blocks (controllable, not yet minimal)."""
    ny, nu = len(matrix), len(matrix[0])
    blocks = [_column_block([matrix[i][j] for i in range(ny)]) for j in range(nu)]
    n = sum(blk[0].shape[0] for blk in blocks)
    A, B, C, D = np.zeros((n, n)), np.zeros((n, nu)), np.zeros((ny, n)), np.zeros((ny, nu))
    at = 0
    for j, (Aj, bj, Cj, dj) in enumerate(blocks):
        k = Aj.shape[0]
        A[at:at + k, at:at + k] = Aj
        B[at:at + k, j] = bj
        C[:, at:at + k] = Cj
        D[:, j] = dj
        at += k
    return A, B, C, D


def controllable_staircase(A: np.ndarray, B: np.ndarray, tol: float) -> tuple[np.ndarray, int]:
    """Orthogonal Q and nc with Q'AQ = [[Ac, *], [0, Au]], Q'B = [[Bc], [0]]."""
    n = A.shape[0]
    Q = np.eye(n)
    nc = 0
    block = B
    while nc < n and block.size:
        U, s, _ = np.linalg.svd(block)
        rank = int(np.count_nonzero(s > tol))
        if rank == 0:
            break
        Q[:, nc:] = Q[:, nc:] @ U
        At = Q.T @ A @ Q
        block = At[nc + rank:, nc:nc + rank]
        nc += rank
    return Q, nc


def minimal_realisation(A: np.ndarray, B: np.ndarray, C: np.ndarray):
    """The controllable and observable part of (A, B, C), after diagonal balancing."""
    if A.size == 0:
        return A, B, C
    _, (scale, _) = scipy.linalg.matrix_balance(A, permute=False, separate=True)
    A, B, C = A * scale[None, :] / scale[:, None], B / scale[:, None], C * scale[None, :]
    tol = RANK_TOL * max(np.linalg.norm(A, 2), np.linalg.norm(B, 2), np.linalg.norm(C, 2))
    Q, nc = controllable_staircase(A, B, tol)
    A, B, C = (Q.T @ A @ Q)[:nc, :nc], (Q.T @ B)[:nc], (C @ Q)[:, :nc]
    Q, no = controllable_staircase(A.T, C.T, tol)  # observability = dual controllability
    return (Q.T @ A @ Q)[:no, :no], (Q.T @ B)[:no], (C @ Q)[:, :no]


def realise(matrix) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Minimal (A, B, C, D) of a transfer-function matrix [[(num, den), ...], ...]."""
    A, B, C, D = column_realisation(matrix)
    A, B, C = minimal_realisation(A, B, C)
    return A, B, C, D


def frequency_response(A, B, C, D, s: complex) -> np.ndarray:
    """C (sI - A)^-1 B + D."""
    return C @ np.linalg.solve(s * np.eye(A.shape[0]) - A, B.astype(complex)) + D


def matrix_response(matrix, s: complex) -> np.ndarray:
    """The transfer-function matrix evaluated at s, element by element."""
    return np.array([[np.polyval(num, s) / np.polyval(den, s) for num, den in row]
                     for row in matrix])
