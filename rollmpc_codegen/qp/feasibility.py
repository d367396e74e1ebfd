"""Design warnings at generation: hard output bounds that no input can meet from rest.

Roll kept in [10, 30] deg was accepted silently, and at run time 199 of 1000 samples
were INFEASIBLE (issue 18): from rest the roll is 0, and no aileron lifts it to 10 deg by
the first constrained step.  ``rollmpc generate`` now warns, one line per mode, naming
the mode, the output and the bound.

The start is the origin: the plant at rest, which is also where the scenario of
``rollmpc simulate``/``report`` starts (plant, observers and held command at zero; any
disturbance and previous-input states too).  There U = 0 meets every input and Δu bound
(they contain 0, config/checks.py) and gives y = 0 at every step, so the QP can only be
infeasible when a hard output bound excludes 0; otherwise nothing is solved.  Then the
mode's own rows ``L U <= c + W x`` at x = 0 (output rows on y_1..y_N: y_0 carries no
decision variable and has none; soft rows are left out, their slack keeps the QP
feasible) are tested with scipy.optimize.linprog (HiGHS):

1. infeasible at all?  If not, no warning (the inputs can fix it in time);
2. the first prediction step k whose output rows, with those before it, are infeasible
   (bisection on k);
3. at step k, the output bound outside the range the inputs reach there (two LPs per
   bounded output, over the inputs that meet every earlier row).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from ..config.diagnostics import DesignWarning
from ..model.controller import ControllerModel

FEASIBLE, INFEASIBLE = 0, 2  # linprog's statuses
UNREACHABLE = "bound_unreachable_from_rest"  # the warnings' code


def _solve(objective: np.ndarray, L: np.ndarray, rhs: np.ndarray):
    return linprog(objective, A_ub=L, b_ub=rhs, bounds=(None, None), method="highs")


def _rows_through(qp, hard: np.ndarray, stage: int) -> np.ndarray:
    """The hard rows of the input, Δu and output rows of steps 1..``stage``."""
    output = qp.row_kind == 1
    return hard & (~output | (qp.row_index // qp.ny < stage))


def _first_infeasible_step(qp, hard: np.ndarray) -> int:
    lo, hi = 0, qp.N  # rows through lo are feasible, through hi not
    while hi - lo > 1:
        mid = (lo + hi) // 2
        rows = _rows_through(qp, hard, mid)
        if _solve(np.zeros(qp.L.shape[1]), qp.L[rows], qp.c[rows]).status == INFEASIBLE:
            hi = mid
        else:
            lo = mid
    return hi


def rest_warning(model: ControllerModel, j: int) -> DesignWarning | None:
    """The warning of mode ``j``, or None when its QP is feasible from rest."""
    cfg, mode, qp = model.config, model.config.modes[j], model.modes[j].qp
    hard = np.ones(len(qp.c), bool) if qp.soft_l2 is None else ~(qp.soft_l2 > 0)
    output = hard & (qp.row_kind == 1)
    # at x = 0 a row holds y = 0 unless its right-hand side c is negative
    if not np.any(output & (qp.c < 0)):
        return None
    if _solve(np.zeros(qp.L.shape[1]), qp.L[hard], qp.c[hard]).status != INFEASIBLE:
        return None
    k = _first_infeasible_step(qp, hard)
    earlier = _rows_through(qp, hard, k - 1)
    names, units = cfg.outputs, cfg.units.outputs
    for r in np.flatnonzero(output & (qp.row_index // qp.ny == k - 1)):
        o, lower = qp.row_index[r] % qp.ny, qp.row_sign[r] < 0
        gamma = qp.Gamma[qp.row_index[r]]  # y_k = Gamma_k U at x = 0
        reach = [_solve(sign * gamma, qp.L[earlier], qp.c[earlier]) for sign in (1, -1)]
        if any(res.status != FEASIBLE for res in reach):
            continue
        low, high = reach[0].fun, -reach[1].fun
        bound = qp.row_sign[r] * qp.c[r]
        if (bound > high) if lower else (bound < low):
            unit = f" {units[o]}" if units and units[o] else ""
            verb, side, most, got = ((">=", "y_min", "at most", high) if lower
                                     else ("<=", "y_max", "at least", low))
            return DesignWarning(
                UNREACHABLE, f"modes[{j}].bounds.{side}",
                f"modes[{j}] ({mode.name}): {names[o]} {verb} {bound:g}{unit} (bounds.{side}) "
                f"cannot be met from rest: at prediction step {k} the inputs within their "
                f"bounds reach {names[o]} = {got:.4g}{unit} {most}, so the QP near rest is "
                "INFEASIBLE; widen the bound or make it soft (bounds.soft)")
    return DesignWarning(
        UNREACHABLE, f"modes[{j}].bounds",
        f"modes[{j}] ({mode.name}): the output bounds cannot all be met from rest: at "
        f"prediction step {k} no input within its bounds meets them together, so the QP near "
        "rest is INFEASIBLE; widen them or make them soft (bounds.soft)")


def rest_warnings(model: ControllerModel) -> list[DesignWarning]:
    """One warning per mode whose hard output bounds no input can meet from rest."""
    found = (rest_warning(model, j) for j in range(len(model.modes)))
    return [w for w in found if w is not None]
