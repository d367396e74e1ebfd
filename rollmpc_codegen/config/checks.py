"""Checks across sections, run once the sections they relate are parsed.

Each names the key to change.  Some run before the heavy maths on purpose: a typo like
``horizon: 100000`` must fail here, not after hours of condensing.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .constraints import signal_row_count
from .errors import ConfigError
from .schema import (BOUND_KEYS, MAX_ROWS, WEIGHT_KEYS, ModeConfig, SchedulerConfig,
                     SimulationConfig, SolverConfig, storage_range)


def _finite(bound) -> int:
    return 0 if bound is None else int(np.isfinite(bound).sum())


def output_rows(horizon: int, mode: ModeConfig) -> int:
    """The output-bound rows among :func:`qp_rows`: one per finite output bound on stages
    1..N."""
    return horizon * (_finite(mode.y_min) + _finite(mode.y_max))


def qp_rows(horizon: int, mode: ModeConfig) -> int:
    """The constraint rows of the mode's QP (condense._constraints): 2 nu per move (stage
    or block), the :func:`output_rows`, one per finite Δu bound on stages 0..N-1, and the
    constrained signals' (a terminal set's rows are known only once it is computed:
    qp/sizes.py)."""
    moves = horizon if mode.blocks is None else len(mode.blocks)
    return (moves * 2 * len(mode.actuators) + output_rows(horizon, mode)
            + horizon * (_finite(mode.du_min) + _finite(mode.du_max))
            + signal_row_count(mode.signals))


def check_horizon(horizon: int, modes: tuple[ModeConfig, ...]) -> None:
    """Reject a horizon whose QP overflows the C's int16 row tables *before* building it.

    Checking after condensing is too late: a typo like ``horizon: 100000`` would first
    allocate and fill N^2-sized matrices for hours.  qp/sizes.py bounds the stored data.
    """
    for i, m in enumerate(modes):
        rows = qp_rows(horizon, m)
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


def check_literal(precision: str, key: str, value: Any) -> None:
    """A number the C is compiled with as a literal must be a normal number of the storage
    precision (``sample_time`` is checked so before the sections that divide by it)."""
    lo, hi = storage_range(precision)
    for v in _nonzero(value):
        if not lo <= abs(v) <= hi:
            raise ConfigError(key, _out_of_range(float(v), "literal", precision, lo, hi))


def check_representable(precision: str, modes: tuple[ModeConfig, ...],
                        scheduler: SchedulerConfig | None, solver: SolverConfig) -> None:
    """Every number the C is compiled with must survive the cast to the storage precision.

    A value written as a literal must not overflow to inf, round to 0 or lose digits as a
    subnormal (``delta: 1e-50`` became ``0.0f``).  A weight w is stored as 2w (Omega2, S)
    and as 1/(2w) ((2P)^-1), so both must be normal numbers.  Checked here, the key is
    named; later the failure is a non-finite literal, or a silently wrong constant.
    """
    tiny, huge = storage_range(precision)
    ranges = {"literal": (tiny, huge),
              "weight": (max(tiny / 2, 0.5 / huge), min(huge / 2, 0.5 / tiny))}
    checked: list[tuple[str, str, Any]] = []
    for i, m in enumerate(modes):
        k = f"modes[{i}]"
        checked += [("weight", f"{k}.weights.{name}", getattr(m, name)) for name in WEIGHT_KEYS]
        checked += [("literal", f"{k}.bounds.{name}", getattr(m, name)) for name in BOUND_KEYS
                    if name != "soft"]
        checked += [("literal", f"{k}.bounds.soft", m.soft_l1),
                    ("literal", f"{k}.bounds.soft", m.soft_l2),
                    ("literal", f"{k}.observer.innovation_limit", m.innovation_limit)]
    if scheduler is not None:  # the C stores every threshold -/+ its epsilon
        checked += [("literal", "scheduler", scheduler.below),
                    ("literal", "scheduler", scheduler.above)]
    checked += [("literal", f"solver.{name}", getattr(solver, name)) for name in
                ("omega", "sigma", "delta", "feasibility_tol", "dependence_tol")]
    for kind, key, value in checked:
        lo, hi = ranges[kind]
        for v in _nonzero(value):
            if not lo <= abs(v) <= hi:
                raise ConfigError(key, _out_of_range(float(v), kind, precision, lo, hi))
    if scheduler is not None and precision == "float":
        # rounded to float, every middle band must keep a region where its mode is chosen
        below, above = np.float32(scheduler.below), np.float32(scheduler.above)
        if not np.all(above[:-1] < below[1:]):
            raise ConfigError("scheduler", "in float precision the thresholds -/+ epsilon "
                              "leave a band with no region where its mode is chosen")


def _nonzero(value: Any) -> np.ndarray:
    """The finite nonzero entries of a config value (None: none; +-inf means unbounded)."""
    if value is None:
        return np.zeros(0)
    arr = np.asarray(value, dtype=float).ravel()
    return arr[np.isfinite(arr) & (arr != 0.0)]


def _out_of_range(value: float, kind: str, precision: str, lo: float, hi: float) -> str:
    """The problem of a literal or a weight outside [lo, hi] (nonzero magnitudes)."""
    if kind == "weight":
        return (f"{value!r} is out of range in {precision} precision: a nonzero weight w "
                f"needs {lo:.3g} <= |w| <= {hi:.3g} (2w and 1/(2w) are stored)")
    with np.errstate(over="ignore", under="ignore"):  # what the value becomes in C
        cast = float(np.float32(value) if precision == "float" else np.float64(value))
    becomes = f"{cast:g}" if cast in (0.0, math.inf, -math.inf) else f"the subnormal {cast:.3g}"
    return (f"{value!r} is not representable in {precision} precision: it would be "
            f"{becomes} (nonzero magnitudes from {lo:.3g} to {hi:.3g})")


def check_schedule_source(simulation: SimulationConfig, scheduler: SchedulerConfig | None,
                          modes: tuple[ModeConfig, ...]) -> None:
    """The pre-integrator output (the roll rate) exists only with integrator: true."""
    if simulation.schedule_source == "output_rate" and scheduler is not None:
        for i, m in enumerate(modes):
            if not m.plant.integrator:
                raise ConfigError(f"modes[{i}].plant.integrator",
                                  "simulation.schedule_source output_rate needs integrator: true")
