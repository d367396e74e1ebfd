"""The PyPI QP solvers ``rollmpc bench`` compares against: quadprog, DAQP, OSQP.

Each peer solves the condensed QP of one mode (eq. 5-6, from ``model.modes[j].qp``, in
double):  min 1/2 U'E U + U'f  s.t.  L U <= b,  with f = F (Phi x - R), b = c + W x.
Every peer returns ``PeerResult(status, U, solver_s, iterations)``: status "optimal" or
the peer's own word for what went wrong; ``solver_s`` is the solver's own timer where it
has one, else None (the caller times the Python call).

* **quadprog** (Goldfarb-Idnani, dense, no warm start, no timer): called as in the
  tests, ``solve_qp(E, -f, -L', -b)``.  Its solution is the reference of the table.
* **DAQP** at its best: one ``daqp.Model`` per mode, set up on the mode's first QP and
  fed through ``update(f, bupper, blower)`` afterwards, so it warm-starts from the
  previous working set of that mode; the input boxes are simple bounds, every output
  row is one two-sided constraint.  Time: ``info['solve_time']`` (in C).
* **OSQP**: one solver per mode, set up on the mode's first QP, then ``update(q, l, u)``
  (warm-started ADMM), in the same two-sided form with the simple bounds as identity
  rows.  Time: ``info.solve_time + info.polish_time`` (in C; excludes the update, as
  for DAQP).  Default settings, or any settings passed (the "tight" row).
"""
from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass

import numpy as np

from .condense import CondensedQP
from .rows import INPUT
from ..features.soft_constraints import explicit_qp

DAQP_INF = 1e30


def qp_vectors(qp: CondensedQP, x: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(f, b) of one QP: f = F (Phi x - R) (eq. 5; minus 2 Psi Ut x with an offset-free
    input target, CondensedQP.gradient) and b = c + W x (eq. 6; + Wr R where rows follow
    the reference)."""
    return qp.gradient(x, r), qp.gamma(x, r)


@dataclass
class PeerResult:
    status: str
    U: np.ndarray
    solver_s: float | None
    iterations: int


def peer_problems(qps: list[CondensedQP]) -> tuple[list[CondensedQP], list[int]]:
    """The QPs the peers solve -- with soft output rows, the explicit-slack form
    (soft_constraints.explicit_qp) -- and each mode's n (their U is its first n entries)."""
    return [explicit_qp(qp) for qp in qps], [qp.n for qp in qps]


@contextlib.contextmanager
def c_stdout_silenced():
    """Redirect file descriptor 1 to /dev/null (OSQP's C prints "Polishing not needed"
    even with ``verbose=False``); Python's own stdout is flushed first."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


class TwoSidedForm:
    """``L U <= b`` regrouped as simple bounds on U and two-sided general rows.

    Rows come in +/- pairs on the same quantity (an input or a predicted output, see
    ``row_kind/row_index/row_sign`` of the condensed QP); a pair becomes one two-sided
    row, an unpaired row a one-sided one.  Rows on a single input become simple bounds.
    """

    def __init__(self, qp: CondensedQP):
        self.qp = qp
        n = qp.n
        self.bound_upper = np.full(n, -1)
        self.bound_lower = np.full(n, -1)
        groups: dict[tuple[int, int], dict[int, int]] = {}
        for row in range(qp.m):
            key = (int(qp.row_kind[row]), int(qp.row_index[row]))
            groups.setdefault(key, {})[int(qp.row_sign[row])] = row
        general = []
        for (kind, _), sides in groups.items():
            up, lo = sides.get(1, -1), sides.get(-1, -1)
            if up >= 0 and lo >= 0 and not np.array_equal(qp.L[up], -qp.L[lo]):
                general += [(qp.L[up], up, -1), (qp.L[lo], lo, -1)]  # not a +/- pair
                continue
            direction = qp.L[up] if up >= 0 else -qp.L[lo]
            nz = np.flatnonzero(direction)
            if (kind == INPUT.code and nz.size == 1 and direction[nz[0]] == 1.0
                    and self.bound_upper[nz[0]] < 0 and self.bound_lower[nz[0]] < 0):
                self.bound_upper[nz[0]], self.bound_lower[nz[0]] = up, lo
            else:
                general.append((direction, up, lo))
        self.A = np.array([g[0] for g in general]).reshape(len(general), n)
        self.general_upper = np.array([g[1] for g in general], int)
        self.general_lower = np.array([g[2] for g in general], int)

    def data(self, x: np.ndarray, r: np.ndarray, inf: float = np.inf):
        """(f, lower, upper) for [simple bounds on U; A U] at state x and preview r."""
        f, b = qp_vectors(self.qp, x, r)
        up = np.concatenate((self.bound_upper, self.general_upper))
        lo = np.concatenate((self.bound_lower, self.general_lower))
        upper = np.where(up >= 0, b[np.maximum(up, 0)], inf)
        lower = np.where(lo >= 0, -b[np.maximum(lo, 0)], -inf)
        return f, lower, upper


class QuadprogPeer:
    name = "quadprog"

    def __init__(self, qps: list[CondensedQP]):
        import quadprog

        self._solve = quadprog.solve_qp
        self.qps, self.n_u = peer_problems(qps)

    def solve(self, mode: int, x: np.ndarray, r: np.ndarray) -> PeerResult:
        qp = self.qps[mode]
        f, b = qp_vectors(qp, x, r)
        try:
            U = self._solve(qp.E, -f, -qp.L.T, -b, 0)[0]
        except ValueError:  # "constraints are inconsistent, no solution"
            return PeerResult("infeasible", np.full(self.n_u[mode], np.nan), None, 0)
        return PeerResult("optimal", U[:self.n_u[mode]], None, 0)


class DaqpPeer:
    name = "daqp"

    def __init__(self, qps: list[CondensedQP]):
        import daqp

        self._daqp = daqp
        problems, self.n_u = peer_problems(qps)
        self.forms = [TwoSidedForm(qp) for qp in problems]
        self.models: list = [None] * len(qps)

    def solve(self, mode: int, x: np.ndarray, r: np.ndarray) -> PeerResult:
        form = self.forms[mode]
        f, lower, upper = form.data(x, r, DAQP_INF)
        model = self.models[mode]
        if model is None:
            model = self.models[mode] = self._daqp.Model()
            flag, _ = model.setup(form.qp.E, f, form.A, upper, lower,
                                  np.zeros(upper.size, dtype=np.intc))
            if flag < 0:
                raise RuntimeError(f"daqp setup failed with exit flag {flag}")
        else:
            model.update(f=f, bupper=upper, blower=lower)
        U, _, exitflag, info = model.solve()
        status = "optimal" if exitflag == 1 else f"exitflag {exitflag}"
        return PeerResult(status, np.asarray(U, float)[:self.n_u[mode]], float(info["solve_time"]),
                          int(info["iterations"]))


class OsqpPeer:
    name = "osqp"

    def __init__(self, qps: list[CondensedQP], **settings):
        import osqp
        import scipy.sparse as sp

        self._osqp = osqp
        self._sp = sp
        self.settings = {"verbose": False, **settings}
        problems, self.n_u = peer_problems(qps)
        self.forms = [TwoSidedForm(qp) for qp in problems]
        self.solvers: list = [None] * len(qps)

    def solve(self, mode: int, x: np.ndarray, r: np.ndarray) -> PeerResult:
        form = self.forms[mode]
        f, lower, upper = form.data(x, r)
        solver = self.solvers[mode]
        if solver is None:
            sp = self._sp
            n = form.qp.n
            A = sp.vstack([sp.eye(n, format="csc"), sp.csc_matrix(form.A)]).tocsc()
            solver = self.solvers[mode] = self._osqp.OSQP()
            solver.setup(sp.triu(sp.csc_matrix(form.qp.E)).tocsc(), f, A, lower, upper,
                         **self.settings)
        else:
            solver.update(q=f, l=lower, u=upper)
        res = solver.solve(raise_error=False)  # a failure is a status, not an error
        # status_val 1 is "solved"; "solved inaccurate" or "maximum iterations reached"
        # are reported by name (the iterate is still what a controller would apply)
        status = "optimal" if res.info.status_val == 1 else str(res.info.status)
        U = np.asarray(res.x, float) if res.x is not None else np.full(form.qp.n, np.nan)
        return PeerResult(status, U[:self.n_u[mode]], float(res.info.solve_time + res.info.polish_time),
                          int(res.info.iter))
