"""Independent, extended-precision solutions of one mode's condensed QP.

For the campaign checks the C solver is compared against a solution that shares none of
its code or data layout:

1. DAQP (a dual active-set solver, double) solves ``min 1/2 U'EU + f'U  s.t.  L U <= b``
   from the *unreduced* QP of :mod:`rollmpc_codegen.qp.condense` (E, F, Phi, L, W, c in double)
   and proposes an active set;
2. the KKT system on that active set is solved in long double (x87 80-bit, eps 1.1e-19)
   by LU in double plus iterative refinement with long-double residuals, after removing
   linearly dependent active rows (rank-revealing QR), so duplicated or dependent rows
   do not make it singular;
3. a primal-dual active-set loop in long double fixes any wrong row (negative multiplier
   leaves, violated row joins) until the KKT conditions hold to ~1e-13.

Infeasibility is decided by a phase-1 LP (HiGHS through scipy), with a margin: a QP is
called infeasible only if every U in the input box violates some output row by more than
``margin * max(1, |b_r|)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from ..features import soft_constraints
from .rows import INPUT

LD = np.longdouble


@dataclass(frozen=True)
class QPData:
    """``min 1/2 U'EU + f'U  s.t.  L U <= b`` (f and b in long double)."""

    E: np.ndarray
    f: np.ndarray
    L: np.ndarray
    b: np.ndarray
    box: np.ndarray  # (m,) True for input-bound rows
    n_u: int = -1  # the first n_u variables are U (the rest: slacks of soft rows); -1: all


@dataclass(frozen=True)
class ExactSolution:
    status: str  # "optimal" | "infeasible" | "failed"
    U: np.ndarray | None = None
    active: np.ndarray | None = None  # rows in the final (independent) working set
    n_active: int = 0  # rows with L U = b (to 1e-9 relative), dependent ones included
    kkt_error: float = float("nan")  # max of the scaled KKT residuals
    daqp_gap: float = float("nan")  # max |U - U_daqp|


def qp_data(qp, x: np.ndarray, r: np.ndarray) -> QPData:
    """The QP of one mode (a :class:`~rollmpc_codegen.qp.condense.CondensedQP`) at state x, preview r;
    with soft output rows, the QP with explicit slacks (soft_constraints.explicit_qp)."""
    n_u = qp.n
    qp = soft_constraints.explicit_qp(qp)
    f = qp.gradient(x, r, LD)  # with the input target and the Δu terms (CondensedQP.gradient)
    b = qp.gamma(x, r, LD)  # c + W x, and Wr R where rows follow the reference
    return QPData(E=qp.E, f=f, L=qp.L, b=b, box=np.asarray(qp.row_kind) == INPUT.code, n_u=n_u)


def _independent_rows(L: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """A maximal linearly independent subset of the rows (rank-revealing QR)."""
    if rows.size == 0:
        return rows
    _, R, piv = scipy.linalg.qr(L[rows].T, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    rank = int(np.count_nonzero(d > 1e-10 * max(d[0], 1e-300)))
    return np.sort(rows[piv[:rank]])


def _kkt_solve(E: np.ndarray, f: np.ndarray, A: np.ndarray, bw: np.ndarray,
               refinements: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """[E A'; A 0] [U; lam] = [-f; bw], refined to long-double accuracy."""
    n, k = E.shape[0], A.shape[0]
    K = np.zeros((n + k, n + k))
    K[:n, :n] = E
    K[:n, n:] = A.T
    K[n:, :n] = A
    rhs = np.concatenate([-f, bw]).astype(LD)
    lu = scipy.linalg.lu_factor(K)
    KL = K.astype(LD)
    sol = scipy.linalg.lu_solve(lu, rhs.astype(np.float64)).astype(LD)
    for _ in range(refinements):
        res = rhs - KL @ sol
        sol = sol + scipy.linalg.lu_solve(lu, res.astype(np.float64)).astype(LD)
    return sol[:n], sol[n:]


def _daqp(data: QPData):
    import daqp

    b = data.b.astype(np.float64)
    m = b.size
    U, _, flag, info = daqp.solve(data.E, data.f.astype(np.float64), data.L, b,
                                  np.full(m, -1e30), np.zeros(m, dtype=np.intc))
    return U, flag, np.asarray(info["lam"])


def solve_exact(data: QPData, max_changes: int = 200) -> ExactSolution:
    """Extended-precision solution (see the module docstring)."""
    U_d, flag, lam_d = _daqp(data)
    if flag == -1:
        return ExactSolution(status="infeasible")
    if flag != 1:
        return ExactSolution(status="failed")
    E, f, L, b = data.E, data.f, data.L, data.b
    LL = L.astype(LD)
    scale = np.maximum(1.0, np.abs(b))
    W = _independent_rows(L, np.flatnonzero(lam_d > 0))
    for _ in range(max_changes):
        U, lam = _kkt_solve(E, f, L[W], b[W])
        viol = (LL @ U - b) / scale
        viol[W] = -np.inf
        lam_tol = 1e-13 * max(1.0, float(np.abs(lam).max(initial=0.0)))
        if lam.size and lam.min() < -lam_tol:
            W = np.delete(W, int(np.argmin(lam)))
            continue
        worst = int(np.argmax(viol)) if viol.size else -1
        if worst >= 0 and viol[worst] > 1e-13:
            W = _independent_rows(L, np.union1d(W, [worst]))
            continue
        grad = E.astype(LD) @ U + f + (LL[W].T @ lam if W.size else 0)
        kkt = float(np.abs(grad).max() / max(1.0, float(np.abs(f).max())))
        slack = (LL @ U - b) / scale
        n_active = int(np.count_nonzero(np.abs(slack) <= 1e-9))
        n_u = data.n_u if data.n_u >= 0 else U.size
        return ExactSolution(status="optimal", U=U.astype(np.float64)[:n_u], active=W,
                             n_active=n_active, kkt_error=kkt,
                             daqp_gap=float(np.abs(U.astype(np.float64) - U_d).max()))
    return ExactSolution(status="failed")


def infeasibility_margin(data: QPData) -> float:
    """min over the input box of the worst scaled output-row violation (> 0: infeasible).

    Phase-1 LP: minimise t subject to ``L_r U - b_r <= t max(1, |b_r|)`` on the output
    rows and the input-bound rows as variable bounds.
    """
    out = ~data.box
    if not np.any(out):
        return -np.inf
    n = data.E.shape[0]
    Lb, bb = data.L[data.box], data.b[data.box].astype(np.float64)
    lo = np.full(n, -np.inf)
    hi = np.full(n, np.inf)
    for row, rhs in zip(Lb, bb):  # box rows are +-e_i
        i = int(np.flatnonzero(row)[0])
        if row[i] > 0:
            hi[i] = min(hi[i], rhs / row[i])
        else:
            lo[i] = max(lo[i], rhs / row[i])
    Lo, bo = data.L[out], data.b[out].astype(np.float64)
    s = np.maximum(1.0, np.abs(bo))
    c = np.zeros(n + 1)
    c[-1] = 1.0
    A_ub = np.hstack([Lo, -s[:, None]])
    res = scipy.optimize.linprog(c, A_ub=A_ub, b_ub=bo,
                                 bounds=list(zip(lo, hi)) + [(None, None)], method="highs")
    if res.status != 0:
        raise RuntimeError(f"phase-1 LP failed: {res.message}")
    return float(res.x[-1])


def relative_error(U: np.ndarray, U_star: np.ndarray) -> float:
    """The campaigns' error measure (issue 4): max|U - U*| / max(1, max|U*|), in double."""
    U_star = np.asarray(U_star, np.float64)
    return float(np.abs(np.asarray(U, np.float64) - U_star).max()
                 / max(1.0, np.abs(U_star).max()))
