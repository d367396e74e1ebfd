"""How far the float build's *stored numbers* alone put a QP's solution from the exact one.

A float build stores every matrix of :mod:`rollmpc_codegen.qp.storage` rounded to float.  Even a
solver doing its arithmetic exactly would then solve a slightly different QP; the
*stored-data floor* of a QP is the error that causes:

    floor = max|U_s - U*| / max(1, max|U*|)

with U* the extended-precision solution of the design's QP (:mod:`..qp.exact`) and U_s what
our own solver returns, in *double* arithmetic, on the float build's stored numbers (every
float array widened exactly to double).  Double arithmetic adds ~1e-16 cond(E), far below
the float rounding it measures.  No float solver can be expected to beat the floor; when it
exceeds the issue's float bound (1e-3), only more precise data (the double build) helps.

Why it can be large: E^-1 stored in float is E^-1 of a Hessian perturbed by about
eps_float * cond(E) relative (measured ||E fl(E^-1) - I|| up to 0.65 at cond 7e6), so the
allocation between weakly weighted directions (e.g. redundant inputs with a small R)
moves.  docs/reliability.md ("Float: what it achieves") has the measured figures.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..qp.exact import relative_error
from ..qp.storage import ModeData
from ..reference.solver import SolverRef
from ..status import OPTIMAL

FLOOR_CLASSES = ("above_1e-3", "1e-4_to_1e-3", "below_1e-4", "not_optimal")


def widened(md: ModeData) -> ModeData:
    """The same mode data with every float array widened (exactly) to double."""
    def wide(a):
        return (a.astype(np.float64) if isinstance(a, np.ndarray) and a.dtype == np.float32
                else a)
    return dataclasses.replace(md, **{f.name: wide(getattr(md, f.name))
                                      for f in dataclasses.fields(md)})


def stored_data_floor(md_float: ModeData, double_solver_ctx: dict, x, r,
                      U_exact: np.ndarray) -> tuple[int, float]:
    """(status, floor) of one QP, solved cold; floor is NaN unless the status is OPTIMAL."""
    status, U, *_ = SolverRef(widened(md_float), double_solver_ctx).solve_mode(
        np.asarray(x, np.float64), np.asarray(r, np.float64))
    if status != OPTIMAL:
        return int(status), float("nan")
    return int(status), relative_error(U, U_exact)


def floor_class(status: int, floor: float) -> str:
    """One of FLOOR_CLASSES."""
    if status != OPTIMAL:
        return "not_optimal"
    return "above_1e-3" if floor > 1e-3 else ("1e-4_to_1e-3" if floor > 1e-4 else "below_1e-4")
