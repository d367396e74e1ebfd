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
from ..config.schema import default_dependence_tol
from ..features.runtime_bounds import context_bounds
from ..model.controller import ControllerModel
from ..parts import DEFAULT_PART, PARTS
from ..qp.arrays import REAL, declared_for
from ..qp.sizes import working_set_lengths
from ..qp.budget import check_work_budget
from ..qp.work import cycles_per_work_unit
from ..qp.work import (ADD_BATCH, CHOL_UNITS_PER_OP, GUESS_SAMPLE_MIN, PREDICT_UNITS_PER_OP,
                       PRIMAL_CALL_OPS, PRIMAL_CALL_UNITS, PRIMAL_SIXTHS_PER_OP,
                       TRI_UNITS_PER_OP, UNIT_CALL_WORK)
from ..info_struct import context_info_fields
from ..solver_codes import context_codes
from ..status import UNKNOWN_MESSAGE, context_statuses
from .templates import generation_stamp


# Flags of features added after designs were generated, all False there: the context
# (and its JSON) carries them only where a design uses one, so every other design's files
# keep their bytes; the templates and the context's readers see these defaults
# (:func:`rendering_context`).
LATER_FEATURES = {"has_signal_rows": False, "has_signal_reference": False,
                  "has_soft_signal_rows": False}


def later_features(flags: dict) -> dict:
    """``flags`` (keys of LATER_FEATURES), or none of them when all are False."""
    return flags if any(flags.values()) else {}


def rendering_context(ctx: dict) -> dict:
    """The context with LATER_FEATURES' defaults: what the templates render."""
    return {**LATER_FEATURES, **ctx}


def _solver_flags(method: str) -> dict:
    """The paper's three variants as compile-time switches of one solver."""
    return {
        "hildreth": {"reduced": False, "warm": False, "sor": False},
        "hildreth_plus": {"reduced": False, "warm": True, "sor": True},
        "hildreth_plus_prime": {"reduced": True, "warm": True, "sor": True},
    }[method]


def _arr(a) -> list:
    return np.asarray(a).tolist()


def actuator_range(modes: list[dict], n_actuators: int) -> tuple[list, list]:
    """Per actuator, the lowest u_min and highest u_max of the modes that drive it (the
    stored bounds, so already in the precision; 0 for an actuator no mode drives): the
    range an applied command can have, which P_observe() clips ``u_applied`` to."""
    lo, hi = np.zeros(n_actuators), np.zeros(n_actuators)
    for m in modes:
        act = np.asarray(m["actuator_index"])
        lo[act] = np.minimum(lo[act], m["u_min"])
        hi[act] = np.maximum(hi[act], m["u_max"])
    return lo.tolist(), hi.tolist()


def build_context(model: ControllerModel) -> dict:
    cfg = model.config
    s = cfg.solver
    flags = _solver_flags(s.method)
    features = {
        # some mode holds its input over blocks of stages (move_blocking.py): the C then
        # stores each mode's stage -> block map; without blocking its text is unchanged
        "move_blocking": any(mm.qp.blocks is not None for mm in model.modes),
        # soft output rows in some mode (soft_constraints.py): slack states in the solver,
        # the slack in the info struct, working sets beyond n rows (else the C is unchanged)
        "has_soft_rows": any(mm.data.has_soft_rows for mm in model.modes),
        # general constraints (features/signals.py): the signal row kind (qp/rows.py),
        # its reference term (terminal sets) and its soft bounds; else the C is unchanged
        **later_features({
            "has_signal_rows": any(mm.data.has_signal_rows for mm in model.modes),
            "has_signal_reference": any(mm.data.has_signal_reference for mm in model.modes),
            "has_soft_signal_rows": any(mm.data.has_soft_signal_rows for mm in model.modes),
        }),
    }
    modes = []
    for mm in model.modes:
        d = mm.data
        modes.append({
            "name": d.name, "has_output_rows": d.has_output_rows,
            "observer_poles": [[p.real, p.imag] for p in mm.observer_poles],
            "cond_E": float(np.linalg.cond(mm.qp.E)),
            **stored_values(d, features),
        })
    if features["move_blocking"]:  # every mode's block lengths (stage_block is stored)
        for entry, mm in zip(modes, model.modes):
            entry["blocks"] = list(mm.qp.blocks or (1,) * cfg.horizon)
    if cfg.runtime_bounds:  # the output bounds P_init gives the instance (None: unbounded)
        for entry, mode_cfg in zip(modes, cfg.modes):
            entry.update(context_bounds(mode_cfg, features.get("has_signal_rows", False)))
    sched = None
    if cfg.scheduler is not None:
        sc = cfg.scheduler
        # below/above: each threshold -/+ its margin, computed once in double; the C
        # stores them rounded to the precision (the reference rounds the same numbers)
        sched = {"signal": sc.signal, "thresholds": list(sc.thresholds),
                 "epsilons": list(sc.epsilons), "below": list(sc.below),
                 "above": list(sc.above), "band_modes": list(sc.band_modes),
                 "n_bands": len(sc.band_modes), "initial": sc.initial}
    has_rate_rows = any(mm.data.has_rate_rows for mm in model.modes)
    hq_work_factor = 2 if has_rate_rows else 1  # a Δu read is a difference of reads
    n_max = max(m["n"] for m in modes)
    w_max = max(m["w_cap"] for m in modes) if features["has_soft_rows"] else n_max
    lengths = working_set_lengths(w_max)
    return {
        "generator": {"name": "rollmpc-codegen", "version": __version__},
        "config_hash": cfg.config_hash,
        "generation": generation_stamp(cfg.config_hash),  # templates/generation_check.j2
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
        # P_observe's plausibility check of u_applied (templates/controller.c.j2)
        **dict(zip(("actuator_min", "actuator_max"), actuator_range(modes, len(cfg.actuators)))),
        "n_schedule": cfg.n_schedule,
        "n_modes": len(modes),
        "initial_mode": 0 if sched is None else sched["initial"],
        "scheduler": sched,
        "runtime_bounds": cfg.runtime_bounds,
        "target": target_context(cfg.target),
        "statuses": context_statuses(cfg.prefix, cfg.runtime_bounds),
        "unknown_status_message": UNKNOWN_MESSAGE,
        "info_fields": context_info_fields(cfg.prefix, features["has_soft_rows"]),
        # the solver's internal return codes, what chol holds, P_LAMBDA_LIMIT (solver_codes.py)
        **context_codes(),
        # Δu rows in some mode: the solver's third row kind (else the C is unchanged)
        "has_rate_rows": has_rate_rows,
        **features,
        "solver": {
            "method": s.method, "reduced": flags["reduced"], "warm_start": flags["warm"]
            and s.warm_start, "omega": s.omega if flags["sor"] else 1.0, "sigma": s.sigma,
            "delta": s.delta, "max_iterations": s.max_iterations, "polish": s.polish,
            "polish_first": s.polish and s.polish_first, "polish_every": s.polish_every, "polish_max": s.polish_max,
            "feasibility_tol": cfg.feasibility_tol,
            "active_set": s.polish and s.active_set, "active_set_max": s.active_set_max,
            "dependence_tol": s.dependence_tol if s.dependence_tol is not None
            else default_dependence_tol(cfg.precision),
            # work units a solve may spend (qp/work.py), and the unit cost of an H read
            "work_budget": check_work_budget(cfg, [mm.data for mm in model.modes], hq_work_factor),
            "cycles_per_work_unit": cycles_per_work_unit(cfg),  # the target core's
            "hq_work_factor": hq_work_factor, "add_batch": ADD_BATCH,
            "work_units": {"chol": CHOL_UNITS_PER_OP, "tri": TRI_UNITS_PER_OP,
                           "primal": PRIMAL_SIXTHS_PER_OP, "primal_call": PRIMAL_CALL_UNITS,
                           "primal_call_ops": PRIMAL_CALL_OPS,
                           "guess_sample_min": GUESS_SAMPLE_MIN,
                           "predict": PREDICT_UNITS_PER_OP, "unit_call": UNIT_CALL_WORK},
        },
        "sizes": {
            "nx_max": max(m["nx"] for m in modes), "nu_max": max(m["nu"] for m in modes),
            "n_max": n_max, "m_max": max(m["m"] for m in modes),
            "nyq_max": max(m["nyq"] for m in modes),
            "nt_max": max(m["nt"] for m in modes),
            **({"nzq_max": max(m["nzq"] for m in modes),
                "nsig_live_max": max(max(m["nsig_live"] for m in modes), 1)}
               if features.get("has_signal_rows") else {}),
            "w_max": w_max, "chol_max": lengths["chol"],
            "wset_max": lengths["wset"], "tmp_max": lengths["tmp"],
            # ws->ycol: the primal polish's Y (nt columns of n), or the dual's H_Wp (w)
            "ycol_max": max(max(max(m["nt"] for m in modes), 1) * n_max, w_max),
        },
        # the members of P_mode_data (qp/arrays.py); each mode lists the arrays it defines
        "mode_struct": stored_members(features, cfg.prefix),
        "modes": modes,
    }


def target_context(target) -> dict:
    """The target the design was generated for (config/target.py, parts.py): its core's
    flags for the target build and P_target.mk, and a memory map for the firmware stub's
    linker script (a core without a named part: the default part's)."""
    core, part = target.core_decl, PARTS[target.part or DEFAULT_PART]
    return {"part": target.part, "label": target.label, "core": core.name,
            "core_short": core.short, "cflags": list(core.cflags),
            "fpu_double": core.fpu_double, "cpu_mhz": target.cpu_mhz,
            # what the firmware build checks the linked image against (firmware.mk); null
            # where the target: section is silent
            "flash_kib": target.flash_kib, "ram_kib": target.ram_kib,
            "regions": [{"name": r.name, "origin": r.origin, "kib": r.kib}
                        for r in (part.flash, part.ram)]}


def stored_members(features: dict, prefix: str) -> dict:
    """The sizes and arrays of P_mode_data that exist with these features."""
    sizes, arrays = declared_for(features)
    return {
        "sizes": [{"name": s.name, "doc": s.doc} for s in sizes],
        "arrays": [{"name": a.name, "real": a.ctype == REAL, "doc": a.describe(),
                    "ctype": f"{prefix}_real" if a.ctype == REAL else a.ctype}
                   for a in arrays],
    }


def stored_values(d, features: dict) -> dict:
    """One mode's sizes and stored arrays (JSON lists), and the names of those it defines."""
    sizes, arrays = declared_for(features)
    return ({s.name: s.of(d) for s in sizes} | {a.name: _arr(a.stored(d)) for a in arrays}
            | {"defined": [a.name for a in arrays if a.exists_in(d)]})


def context_json(ctx: dict) -> str:
    """Deterministic JSON (sorted keys; floats by repr, so they round-trip exactly)."""
    return json.dumps(ctx, sort_keys=True, indent=1, allow_nan=False) + "\n"
