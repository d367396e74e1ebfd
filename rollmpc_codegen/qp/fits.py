"""What fits, for a refusal: a design beyond its cycle budget or its work budget is told
which smaller design (or faster part) passes the same test (docs/checks.md, "Budget").

A refusal used to state the figure and the limit only ("210 work units ... must be at
least the 1353 of the unconstrained step"), leaving the user to guess which key moves
it.  The callers (footprint.py, budget.py) pass their own test as a predicate on a
config; this module searches the two keys whose figures grow with the QP's size: the
largest ``horizon`` (the QP's stages), and with it unchanged the largest
``control_horizon`` (move blocking: n = Nc nu), both on the sizes alone (sizes.py:
the prediction needs no maths).  The scalings (clock, share, budget) are the callers':
their figures are linear in them.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable

from ..config import ControllerConfig

Test = Callable[[ControllerConfig], bool]


def _with_horizon(cfg: ControllerConfig, horizon: int) -> ControllerConfig:
    return dataclasses.replace(cfg, horizon=horizon)


def _with_control_horizon(cfg: ControllerConfig, nc: int) -> ControllerConfig:
    blocks = (1,) * (nc - 1) + (cfg.horizon - nc + 1,)
    return dataclasses.replace(cfg, modes=tuple(dataclasses.replace(m, blocks=blocks)
                                                for m in cfg.modes))


def _largest(lo: int, hi: int, ok: Callable[[int], bool]) -> int | None:
    """The largest k in [lo, hi] with ok(k), for ok monotone (true up to some k)."""
    if hi < lo or not ok(lo):
        return None
    while lo < hi:
        mid = (lo + hi + 1) // 2
        lo, hi = (mid, hi) if ok(mid) else (lo, mid - 1)
    return lo


def largest_horizon(cfg: ControllerConfig, test: Test) -> int | None:
    """The largest horizon below the config's that passes ``test`` (None: none does, or
    a mode has its own move blocking, which fixes the horizon)."""
    if any(m.blocks is not None for m in cfg.modes):
        return None
    return _largest(1, cfg.horizon - 1, lambda n: test(_with_horizon(cfg, n)))


def largest_control_horizon(cfg: ControllerConfig, test: Test) -> int | None:
    """The largest control horizon (every mode, the horizon kept) that passes ``test``;
    None when none does or the modes already block their moves."""
    if any(m.blocks is not None for m in cfg.modes) or cfg.horizon < 2:
        return None
    return _largest(1, cfg.horizon - 1, lambda nc: test(_with_control_horizon(cfg, nc)))


def at_least(value: float) -> str:
    """``value`` rounded up to three significant digits: a bound that still holds (from
    1,000 up as a whole number with thousands separators, never in exponent form)."""
    if value <= 0:
        return "0"
    scale = 10.0 ** (math.floor(math.log10(value)) - 2)
    rounded = math.ceil(value / scale - 1e-9) * scale
    return f"{rounded:,.0f}" if rounded >= 1000 else f"{rounded:.3g}"


def what_fits(cfg: ControllerConfig, test: Test, scalings: list[str]) -> str:
    """``what fits: horizon <= 7; or control_horizon: 4; or ...`` for a refusal: the
    searched keys first, then the callers' ``scalings`` (e.g. ``target.cpu_mhz >= 815``)."""
    found = []
    horizon = largest_horizon(cfg, test)
    if horizon is not None:
        found.append(f"horizon <= {horizon}")
    nc = largest_control_horizon(cfg, test)
    if nc is not None:
        found.append(f"control_horizon: {nc}")
    found += scalings
    return "what fits: " + "; or ".join(found) if found else "no smaller horizon fits"
