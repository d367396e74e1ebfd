"""Checks across sections, run once the sections they relate are parsed.

Each names the key to change.  Some run before the heavy maths on purpose: a typo like
``horizon: 100000`` must fail here, not after hours of condensing.
"""
from __future__ import annotations

import sys
from typing import Any

import numpy as np

from .errors import ConfigError
from .schema import (FLOAT_MAX, MAX_ROWS, ModeConfig, SchedulerConfig, SimulationConfig,
                     SolverConfig)


def check_horizon(horizon: int, modes: tuple[ModeConfig, ...]) -> None:
    """Reject a horizon whose QP overflows the C's int16 row tables *before* building it.

    The row count is that of mpc._constraints: 2 nu box rows per stage and one row per
    finite output bound on stages 1..N.  Checking after condensing is too late: a typo
    like ``horizon: 100000`` would first allocate and fill N^2-sized matrices for hours.
    """
    for i, m in enumerate(modes):
        moves = horizon if m.blocks is None else len(m.blocks)  # input rows: per block
        rows = (moves * 2 * len(m.actuators) + horizon * (int(np.isfinite(m.y_min).sum())
                                                          + int(np.isfinite(m.y_max).sum())))
        if rows > MAX_ROWS:
            raise ConfigError("horizon", f"too long: modes[{i}] would have {rows} QP rows; "
                              f"at most {MAX_ROWS} supported")


def check_unique_names(modes: tuple[ModeConfig, ...]) -> None:
    names = [m.name for m in modes]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise ConfigError(f"modes[{i}].name", f"duplicate mode name {n!r}")


def check_rate_bounds(runtime_bounds: bool, modes: tuple[ModeConfig, ...]) -> None:
    """Δu bounds exclude run-time bounds and move blocking (their rows are per stage)."""
    rate = [i for i, m in enumerate(modes) if m.has_rate_bounds]
    if runtime_bounds and rate:
        raise ConfigError("runtime_bounds", f"is not supported with Δu bounds (modes[{rate[0]}]"
                          ".bounds.du_min/du_max): their rows are not updatable at run time")
    for i, m in enumerate(modes):
        if m.has_rate_bounds and m.blocks is not None:
            raise ConfigError(f"modes[{i}].bounds.du_min", "Δu bounds are not supported with "
                              "move blocking / a control horizon (rate rows are built per "
                              "stage); remove one of them")


def check_range(precision: str, modes: tuple[ModeConfig, ...],
                scheduler: SchedulerConfig | None, solver: SolverConfig) -> None:
    """Every number the C stores as a literal must be finite in the storage precision.

    Otherwise the failure surfaces much later, as a non-finite literal while rendering.
    """
    limit = FLOAT_MAX if precision == "float" else sys.float_info.max
    values: list[tuple[str, Any]] = []
    for i, m in enumerate(modes):
        k = f"modes[{i}]"
        values += [(f"{k}.weights.Q", m.Q), (f"{k}.weights.R", m.R), (f"{k}.weights.P", m.P),
                   (f"{k}.bounds.u_min", m.u_min), (f"{k}.bounds.u_max", m.u_max),
                   # infinite output bounds mean "unbounded" and are never written
                   (f"{k}.bounds.y_min", m.y_min[np.isfinite(m.y_min)]),
                   (f"{k}.bounds.y_max", m.y_max[np.isfinite(m.y_max)])]
        if m.du_min is not None:
            values += [(f"{k}.bounds.du_min", m.du_min[np.isfinite(m.du_min)]),
                       (f"{k}.bounds.du_max", m.du_max[np.isfinite(m.du_max)])]
    if scheduler is not None:  # the C stores every threshold -/+ its epsilon
        values += [("scheduler", scheduler.below), ("scheduler", scheduler.above)]
    values += [("solver.sigma", solver.sigma), ("solver.delta", solver.delta),
               ("solver.feasibility_tol", solver.feasibility_tol or 0.0)]
    for key, value in values:
        arr = np.abs(np.asarray(value, dtype=float))
        if arr.size and not arr.max() <= limit:
            raise ConfigError(key, f"a value of magnitude {arr.max():.3g} does not fit in "
                              f"{precision} precision (max {limit:.3g})")
    if scheduler is not None and precision == "float":
        # rounded to float, every middle band must keep a region where its mode is chosen
        below, above = np.float32(scheduler.below), np.float32(scheduler.above)
        if not np.all(above[:-1] < below[1:]):
            raise ConfigError("scheduler", "in float precision the thresholds -/+ epsilon "
                              "leave a band with no region where its mode is chosen")


def check_schedule_source(simulation: SimulationConfig, scheduler: SchedulerConfig | None,
                          modes: tuple[ModeConfig, ...]) -> None:
    """The pre-integrator output (the roll rate) exists only with integrator: true."""
    if simulation.schedule_source == "output_rate" and scheduler is not None:
        for i, m in enumerate(modes):
            if not m.plant.integrator:
                raise ConfigError(f"modes[{i}].plant.integrator",
                                  "simulation.schedule_source output_rate needs integrator: true")
