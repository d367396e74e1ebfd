"""The references of a random flight that presses the envelope (an ``envelope`` flight of
sim/flight_plan.py): what users command, beyond the design's own scenario, past its soft
output bounds and up to its hard ones.

An *inside* flight draws each level uniformly within the range its scenario spans, inside
the output bounds (scenario.reference_range): the envelope the design was written for,
which never asks for more than the scenario.  An envelope flight draws per output from
two ranges:

* the inside range [lo, hi] (scenario.reference_range);
* the *envelope* [lo_e, hi_e] around it, side by side: a hard finite bound is its edge
  (a level up to the bound itself), a soft bound is passed by :data:`SOFT_REACH` of its
  distance from the middle of the inside range (a reference the soft bound is there to
  give way to), an open side keeps the inside range's edge (nothing to press).

Each level (per segment and output) is, with probability :data:`PRESS`, drawn uniformly
from the bands the envelope adds, [lo_e, lo) and (hi, hi_e] (their union, by length),
else uniformly from the inside range; an output whose envelope adds nothing draws inside.
The bounds a side has in common are the modes' tightest (the largest y_min, the smallest
y_max); a side is soft when every mode softens it.
"""
from __future__ import annotations

import numpy as np

from ..config import ControllerConfig
from .scenario import reference_range

SOFT_REACH = 0.25  # past a soft bound, as a share of its distance from the inside middle
PRESS = 0.5  # the share of levels drawn beyond the inside range


def _soft_sides(cfg: ControllerConfig) -> np.ndarray:
    """(ny, 2) bool: the lower and upper output bound soft in every mode."""
    soft = np.ones((cfg.n_outputs, 2), bool)
    for m in cfg.modes:
        soft &= (m.soft_l2 > 0) if m.soft_l2 is not None else False
    return soft


def envelope_range(cfg: ControllerConfig) -> tuple[np.ndarray, np.ndarray]:
    """(lo_e, hi_e) per output: the edges an envelope flight's levels reach (see the
    module docstring)."""
    lo, hi = reference_range(cfg)
    y_min = np.max([m.y_min for m in cfg.modes], axis=0)
    y_max = np.min([m.y_max for m in cfg.modes], axis=0)
    soft, middle = _soft_sides(cfg), (lo + hi) / 2
    with np.errstate(invalid="ignore"):  # an open side: inf - inf never reaches a result
        lo_e = np.where(np.isfinite(y_min), y_min - soft[:, 0] * SOFT_REACH * (middle - y_min), lo)
        hi_e = np.where(np.isfinite(y_max), y_max + soft[:, 1] * SOFT_REACH * (y_max - middle), hi)
    return np.minimum(lo_e, lo), np.maximum(hi_e, hi)


def envelope_levels(cfg: ControllerConfig, rng: np.random.Generator, count: int) -> np.ndarray:
    """``count`` levels (count, n_outputs) of an envelope flight, from ``rng``."""
    lo, hi = reference_range(cfg)
    lo_e, hi_e = envelope_range(cfg)
    below, above = lo - lo_e, hi_e - hi
    shape = (count, cfg.n_outputs)
    inside = rng.uniform(lo, hi, size=shape)
    press = rng.uniform(size=shape) < PRESS
    t = rng.uniform(size=shape) * (below + above)  # a point of the two bands, by length
    beyond = np.where(t < below, lo - t, hi + (t - below))
    return np.where(press & (below + above > 0), beyond, inside)
