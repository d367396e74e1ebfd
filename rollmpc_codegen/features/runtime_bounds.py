"""Run-time bounds (``runtime_bounds: true``): the input and output bounds of every mode
live in the controller instance and change between samples through ``P_set_bounds()``.

What can change on line and what is baked in (docs/features.md, "Run-time bounds"):
the bounds enter the QP only through the constant right-hand side ``c`` of
``M U <= c + W x`` (eq. 6), and the clamp of the command.  Nothing the solver
precomputes offline -- E and its factorisations, E^-1 Gamma', Gamma E^-1 Gamma', the
gains Kx, the Markov parameters, the output certificate ``out_bound`` -- depends on ``c``,
so a new bound needs no regeneration.  What a bound change cannot do is add or remove
rows: a bound the config leaves infinite has no rows, and a configured bound stays finite.

The C keeps, per mode, only the bound vectors (2 (nu + ny) reals) and derives each row's
constant on line from ``row_q``/``row_sign`` (``row_const()`` in solver/bounds.c.j2): the per-row
copy would cost m reals per mode (200 for the chain of masses, 4 x 200 B in float).

This module is the reference of the C's bound handling: :func:`check_bounds` mirrors the
validation of ``P_set_bounds()``, :func:`row_const` the constants the C derives (bit
for bit: -cast(u_min) == cast(-u_min)), and :func:`config_bounds` the values ``P_init``
restores.
"""
from __future__ import annotations

import math

import numpy as np

from ..status import BAD_ARGUMENT, BAD_BOUNDS, BOUND_NOT_CONFIGURED, OPTIMAL

__all__ = ["check_bounds", "check_signal_bounds", "config_bounds", "context_bounds", "row_const"]


def context_bounds(mode_cfg, signals: bool = False) -> dict:
    """The output bounds of one mode for the render context (JSON: None = unbounded);
    with ``signals`` (a build with signal rows) also its constrained signals' (z_min,
    z_max: constraints.signals and .mixed, in order; a terminal set's are baked in)."""
    def finite_or_none(v):
        return [float(x) if math.isfinite(x) else None for x in v]

    out = {"y_min": finite_or_none(mode_cfg.y_min), "y_max": finite_or_none(mode_cfg.y_max)}
    if signals:
        out |= {"z_min": finite_or_none([s.lo for s in mode_cfg.signals]),
                "z_max": finite_or_none([s.hi for s in mode_cfg.signals])}
    return out


def config_bounds(mode_ctx: dict, dtype) -> dict:
    """The bounds ``P_init`` gives a mode, in the storage dtype (+-inf where unbounded)."""
    def vec(values, unbounded):
        return np.array([unbounded if v is None else v for v in values], dtype=dtype)

    out = {"u_min": np.asarray(mode_ctx["u_min"], dtype),
           "u_max": np.asarray(mode_ctx["u_max"], dtype),
           "y_min": vec(mode_ctx["y_min"], -np.inf), "y_max": vec(mode_ctx["y_max"], np.inf)}
    if "z_min" in mode_ctx:  # a build with signal rows
        out |= {"z_min": vec(mode_ctx["z_min"], -np.inf), "z_max": vec(mode_ctx["z_max"], np.inf)}
    return out


def output_bound_status(configured, value, upper: bool) -> int:
    """Mirror of output_bound_status() in controller.c.j2 for one output bound."""
    if math.isnan(value):
        return BAD_BOUNDS
    if math.isfinite(configured):
        return OPTIMAL if math.isfinite(value) else BAD_BOUNDS
    if math.isfinite(value):
        return BOUND_NOT_CONFIGURED
    return OPTIMAL if (value > 0) == upper else BAD_BOUNDS


def check_bounds(configured: dict, u_min, u_max, y_min, y_max) -> int:
    """Status of ``P_set_bounds()`` for new bounds (already in the storage dtype), checked
    in the C's order: the inputs, then each output (lower, upper, lower < upper).
    ``configured`` is :func:`config_bounds` of the mode; None stands for a NULL pointer."""
    if any(v is None for v in (u_min, u_max, y_min, y_max)):
        return BAD_ARGUMENT
    for lo, hi in zip(u_min, u_max):
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi and lo <= 0 <= hi):
            return BAD_BOUNDS
    for a, (lo, hi) in enumerate(zip(y_min, y_max)):
        status = output_bound_status(configured["y_min"][a], lo, False)
        if status == OPTIMAL:
            status = output_bound_status(configured["y_max"][a], hi, True)
        if status == OPTIMAL and not lo < hi:
            status = BAD_BOUNDS
        if status != OPTIMAL:
            return status
    return OPTIMAL


def check_signal_bounds(configured: dict, z_min, z_max) -> int:
    """Status of ``P_set_signal_bounds()``: each signal as an output bound is checked
    (lower, upper, lower <= upper: a signal may be held at a value)."""
    if z_min is None or z_max is None:
        return BAD_ARGUMENT
    for a, (lo, hi) in enumerate(zip(z_min, z_max)):
        status = output_bound_status(configured["z_min"][a], lo, False)
        if status == OPTIMAL:
            status = output_bound_status(configured["z_max"][a], hi, True)
        if status == OPTIMAL and not lo <= hi:
            status = BAD_BOUNDS
        if status != OPTIMAL:
            return status
    return OPTIMAL


def row_const(row_q, row_sign, n: int, nu: int, ny: int, u_min, u_max, y_min, y_max,
                  dtype=np.float64) -> np.ndarray:
    """c of eq. (6) for the given bounds: u_max / -u_min of input U_q (bound q mod nu),
    y_max / -y_min of output (Gamma U)_k (bound k mod ny), as ``row_const()`` derives it."""
    row_q, row_sign = np.asarray(row_q), np.asarray(row_sign)
    lo = np.concatenate((np.asarray(u_min, dtype), np.asarray(y_min, dtype)))
    hi = np.concatenate((np.asarray(u_max, dtype), np.asarray(y_max, dtype)))
    idx = np.where(row_q < n, row_q % nu, nu + (row_q - n) % ny)
    return np.where(row_sign > 0, hi[idx], -lo[idx]).astype(dtype)


def signal_row_const(md, z_min, z_max) -> np.ndarray:
    """c of every row as ``row_const()`` derives a signal row's: z_max / -z_min of the
    quantity's signal when it takes run-time bounds (the first nsig_live), else the baked
    c (a terminal facet); the other rows' baked c (row_const() gives theirs)."""
    c = md.row_c.copy()
    sig = np.flatnonzero(md.signal_rows)
    if sig.size == 0:
        return c
    j = md.z_sig[md.row_q[sig] - (2 * md.n + md.n_yq)]
    live = j < md.nsig_live
    lo = np.asarray(z_min, c.dtype)
    hi = np.asarray(z_max, c.dtype)
    jj = np.minimum(j, max(md.nsig_live - 1, 0))
    value = np.where(md.row_sign[sig] > 0, hi[jj] if hi.size else c[sig],
                     -lo[jj] if lo.size else c[sig])
    c[sig] = np.where(live, value, c[sig])
    return c

