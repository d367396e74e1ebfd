"""Stage 6: everything the templates see, as one plain dict (also written as JSON).

``build_context`` turns the model of :func:`rollmpc_codegen.pipeline.build_model` into the
render context.  The context JSON is the
contract between the maths and the C: the numbers in it are exactly the numbers the C
is compiled with (already rounded to the storage precision).
"""
from __future__ import annotations

import json
import numpy as np

from .. import __version__
from ..config.schema import default_dependence_tol, default_feasibility_tol
from ..features.runtime_bounds import context_bounds
from ..model.controller import ControllerModel


def _solver_flags(method: str) -> dict:
    """The paper's three variants as compile-time switches of one solver."""
    return {
        "hildreth": {"reduced": False, "warm": False, "sor": False},
        "hildreth_plus": {"reduced": False, "warm": True, "sor": True},
        "hildreth_plus_prime": {"reduced": True, "warm": True, "sor": True},
    }[method]


def _arr(a) -> list:
    return np.asarray(a).tolist()


def build_context(model: ControllerModel) -> dict:
    cfg = model.config
    s = cfg.solver
    flags = _solver_flags(s.method)
    modes = []
    for mm in model.modes:
        d = mm.data
        modes.append({
            "name": d.name, "nx": d.nx, "nu": d.nu, "ny": d.ny, "n": d.n, "m": d.m,
            "nyq": d.n_yq, "has_output_rows": d.has_output_rows,
            "actuator_index": _arr(d.actuator_index),
            "observer_poles": [[p.real, p.imag] for p in mm.observer_poles],
            "A": _arr(d.A), "B": _arr(d.B), "C": _arr(d.C), "L": _arr(d.L),
            "Kx": _arr(d.Kx), "EinvGt": _arr(d.EinvGt), "Sinv_p": _arr(d.Sinv_p), "Ew": _arr(d.Ew), "Uv": _arr(d.Uv), "T": _arr(d.T),
            "S_p": _arr(d.S_p), "V": _arr(d.V), "P2inv": _arr(d.P2inv), "nt": d.nt,
            "GEinvGt_p": _arr(d.GEinvGt_p), "Omega2": _arr(d.Omega2),
            "Phi": _arr(d.Phi), "markov": _arr(d.markov), "row_q": _arr(d.row_q),
            "row_sign": _arr(d.row_sign), "row_c": _arr(d.row_c),
            "row_next": _arr(d.row_next), "colsum": _arr(d.colsum),
            "out_bound": _arr(d.out_bound),
            "u_min": _arr(d.u_min), "u_max": _arr(d.u_max),
            "cond_E": float(np.linalg.cond(mm.qp.E)),
        })
    blocking = any(mm.qp.blocks is not None for mm in model.modes)
    if blocking:  # every mode's block lengths and stage -> block map (identity: unblocked)
        for entry, mm in zip(modes, model.modes):
            sb = mm.data.stage_block
            entry.update({"blocks": list(mm.qp.blocks or (1,) * cfg.horizon),
                          "stage_block": _arr(np.arange(cfg.horizon) if sb is None else sb)})
    if cfg.runtime_bounds:  # the output bounds P_init gives the instance (None: unbounded)
        for entry, mode_cfg in zip(modes, cfg.modes):
            entry.update(context_bounds(mode_cfg))
    sched = None
    if cfg.scheduler is not None:
        sc = cfg.scheduler
        # below/above: each threshold -/+ its margin, computed once in double; the C
        # stores them rounded to the precision (the reference rounds the same numbers)
        sched = {"signal": sc.signal, "thresholds": list(sc.thresholds),
                 "epsilons": list(sc.epsilons), "below": list(sc.below),
                 "above": list(sc.above), "band_modes": list(sc.band_modes),
                 "n_bands": len(sc.band_modes), "initial": sc.initial}
    soft = any(mm.data.has_soft_rows for mm in model.modes)
    if soft:  # per-bound penalties and the working-set capacity (soft_constraints.py)
        for entry, mm in zip(modes, model.modes):
            d = mm.data
            zeros = np.zeros(2 * d.ny)
            entry.update({"soft_l1": _arr(zeros if d.soft_l1 is None else d.soft_l1),
                          "soft_w": _arr(zeros if d.soft_w is None else d.soft_w),
                          "w_cap": d.w_cap})
    n_max = max(m["n"] for m in modes)
    w_max = max(mm.data.w_cap for mm in model.modes) if soft else n_max
    return {
        "generator": {"name": "rollmpc-codegen", "version": __version__},
        "config_hash": cfg.config_hash,
        "prefix": cfg.prefix,
        "PREFIX": cfg.prefix.upper(),
        "precision": cfg.precision,
        "real": "double" if cfg.precision == "double" else "float",
        "sample_time": cfg.sample_time,
        "horizon": cfg.horizon,
        "outputs": list(cfg.outputs),
        "actuators": list(cfg.actuators),
        "n_outputs": cfg.n_outputs,
        "n_actuators": len(cfg.actuators),
        "n_schedule": cfg.n_schedule,
        "n_modes": len(modes),
        "initial_mode": 0 if sched is None else sched["initial"],
        "scheduler": sched,
        "runtime_bounds": cfg.runtime_bounds,
        # Δu rows in some mode: the solver's third row kind (else the C is unchanged)
        "has_rate_rows": any(mm.data.has_rate_rows for mm in model.modes),
        # some mode holds its input over blocks of stages (move_blocking.py): the C then
        # stores each mode's stage -> block map; without blocking its text is unchanged
        "move_blocking": blocking,
        # soft output rows in some mode (soft_constraints.py): slack states in the solver,
        # the slack in the info struct, working sets beyond n rows (else the C is unchanged)
        "has_soft_rows": soft,
        "solver": {
            "method": s.method, "reduced": flags["reduced"], "warm_start": flags["warm"]
            and s.warm_start, "omega": s.omega if flags["sor"] else 1.0, "sigma": s.sigma,
            "delta": s.delta, "max_iterations": s.max_iterations, "polish": s.polish,
            "polish_first": s.polish and s.polish_first, "polish_every": s.polish_every, "polish_max": s.polish_max,
            "feasibility_tol": s.feasibility_tol if s.feasibility_tol is not None
            else default_feasibility_tol(cfg.precision),
            "active_set": s.polish and s.active_set, "active_set_max": s.active_set_max,
            "dependence_tol": s.dependence_tol if s.dependence_tol is not None
            else default_dependence_tol(cfg.precision),
        },
        "sizes": {
            "nx_max": max(m["nx"] for m in modes), "nu_max": max(m["nu"] for m in modes),
            "n_max": n_max, "m_max": max(m["m"] for m in modes),
            "nyq_max": max(m["nyq"] for m in modes),
            "nt_max": max(m["nt"] for m in modes),
            "w_max": w_max, "chol_max": w_max * (w_max + 1) // 2,
        },
        "modes": modes,
    }


def context_json(ctx: dict) -> str:
    """Deterministic JSON (sorted keys; floats by repr, so they round-trip exactly)."""
    return json.dumps(ctx, sort_keys=True, indent=1, allow_nan=False) + "\n"
