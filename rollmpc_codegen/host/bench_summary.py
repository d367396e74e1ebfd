"""Step 4 of ``rollmpc bench`` (:mod:`rollmpc_codegen.host.bench`): the figures of one row
(:func:`row_summary`: average / median / max solve time, max < Ts, average / max
|u(k) - u_quadprog(k)| on the applied first move, status counts, per-mode medians) and
the check of the paper's reduced set (:func:`reduced_set_check`).

The paper's Hildreth+' restricts the dual to the rows with K = gamma - M theta0 < sigma
and never re-checks the others.  Solving that reduced QP *exactly* (quadprog on those
rows) shows what the reduced set alone returns, whatever the sweeps: rows outside it end
up violated, inputs beyond their limits.
"""
from __future__ import annotations

import numpy as np

from .bench_record import QpSequence
from .bench_replay import Replay, first_move_sizes
from ..model.controller import ControllerModel
from ..qp.peers import qp_vectors


def _stats(v: np.ndarray) -> tuple[float | None, float | None, float | None]:
    if v.size == 0:
        return None, None, None
    return float(v.mean()), float(np.median(v)), float(v.max())


def row_summary(key: str, label: str, timer: str, rep: Replay, ref: Replay,
                seq: QpSequence, idx: np.ndarray, model: ControllerModel) -> dict:
    ts = model.config.sample_time
    # the largest error per QP ignoring NaN (a QP quadprog found infeasible: all NaN, no warning)
    err = np.fmax.reduce(np.abs(rep.u0 - ref.u0), axis=1) if len(idx) else np.zeros(0)
    compared = np.isfinite(err)
    avg_s, med_s, max_s = _stats(rep.solver_s)
    call_avg, call_med, call_max = _stats(rep.call_s)
    names, counts = np.unique(np.array(rep.status, dtype=object).astype(str), return_counts=True)
    modes = seq.mode[idx]
    by_mode = {}
    for j, mm in enumerate(model.config.modes):
        sel = modes == j
        if sel.any():
            by_mode[mm.name] = sel
    optimal = int(sum(s == "optimal" for s in rep.status))
    return {
        "solver": label,
        "key": key,
        "timer": timer,
        "avg_s": avg_s,
        "max_s": max_s,
        "max_lt_ts": bool(max_s is not None and max_s < ts),
        "avg_abs_err": float(err[compared].mean()) if compared.any() else None,
        "max_abs_err": float(err[compared].max()) if compared.any() else None,
        "median_s": med_s,
        "call_avg_s": call_avg,
        "call_median_s": call_med,
        "call_max_s": call_max,
        "qps": int(len(idx)),
        "optimal": optimal,
        "not_optimal": int(len(idx)) - optimal,
        "status_counts": {str(n): int(c) for n, c in zip(names, counts)},
        "compared_qps": int(compared.sum()),
        "max_iterations": int(rep.iterations.max()) if len(idx) else 0,
        "median_iterations": float(np.median(rep.iterations)) if len(idx) else 0.0,
        "qps_by_mode": {m: int(sel.sum()) for m, sel in by_mode.items()},
        "median_s_by_mode": {m: float(np.median(rep.solver_s[sel])) for m, sel in by_mode.items()},
        "max_s_by_mode": {m: float(rep.solver_s[sel].max()) for m, sel in by_mode.items()},
        "call_median_s_by_mode": {m: float(np.median(rep.call_s[sel]))
                                  for m, sel in by_mode.items()},
        "not_optimal_by_mode": {m: int(sum(rep.status[q] != "optimal"
                                           for q in np.flatnonzero(sel)))
                                for m, sel in by_mode.items()},
    }


def reduced_set_check(model: ControllerModel, seq: QpSequence, idx: np.ndarray,
                      reference: Replay) -> dict:
    """The paper's reduced set {K < sigma} alone, solved exactly, on the constrained QPs."""
    import quadprog

    sigma = model.config.solver.sigma
    nus, _ = first_move_sizes(model)
    constrained = violating = infeasible = 0
    worst_row = worst_u = worst_beyond = worst_U_beyond = worst_err = 0.0
    for q, i in enumerate(idx):
        mode = int(seq.mode[i])
        qp = model.modes[mode].qp
        x, r = seq.x[i], seq.r[i]
        theta0 = qp.theta0(x, r)
        gamma = qp.gamma(x)
        K = gamma - qp.L @ theta0
        if K.min() >= 0:  # unconstrained: nothing to reduce
            continue
        constrained += 1
        rows = np.flatnonzero(K < sigma)
        f, _ = qp_vectors(qp, x, r)
        try:
            theta = quadprog.solve_qp(qp.E, -f, -qp.L[rows].T, -gamma[rows], 0)[0]
        except ValueError:  # "constraints are inconsistent": the QP itself is infeasible
            infeasible += 1
            continue
        viol = float((qp.L @ theta - gamma).max())
        scale = max(1.0, float(np.abs(gamma).max()))
        if viol > 1e-9 * scale:
            violating += 1
        mode_cfg = model.config.modes[mode]
        u0 = theta[:nus[mode]]
        beyond = float(max(0.0, (u0 - mode_cfg.u_max).max(), (mode_cfg.u_min - u0).max()))
        moves = qp.n // qp.nu  # stages, or blocks with move blocking
        U_beyond = max(0.0, float((theta - np.tile(mode_cfg.u_max, moves)).max()),
                       float((np.tile(mode_cfg.u_min, moves) - theta).max()))
        worst_U_beyond = max(worst_U_beyond, U_beyond)
        worst_row = max(worst_row, viol)
        worst_u = max(worst_u, float(np.abs(u0).max()))
        worst_beyond = max(worst_beyond, beyond)
        ref_u0 = reference.u0[q, :nus[mode]]
        if np.isfinite(ref_u0).any():  # quadprog solved the full QP
            worst_err = max(worst_err, float(np.nanmax(np.abs(u0 - ref_u0))))
    return {"sigma": sigma, "constrained_qps": constrained, "violating_qps": violating,
            "infeasible_qps": infeasible,
            "max_row_violation": worst_row, "max_abs_u0": worst_u,
            "max_u0_beyond_limit": worst_beyond, "max_U_beyond_limit": worst_U_beyond,
            "max_abs_err_u0_vs_quadprog": worst_err}
