"""What a mode's inputs can do to its outputs: the range each output reaches from rest
with every input within its bounds.

Two checks read it (docs/checks.md): the default of ``observer.innovation_limit`` for an
output that nothing else gives a range (no finite bound, a zero reference: fw_lateral's
sideslip), and the units check, which warns when the inputs move an output by decades
less (or more) than its bounds and references ask for (a buck with B off by 1e6 settled
with an error equal to its reference, silently).

The range is the hull of 0, of y_k for k = 1..N from rest (y_k = sum_i C A^i B u_{k-1-i},
each input anywhere in its bounds: per Markov parameter the larger of M u_min and
M u_max) and, for a plant whose modes all decay, of its steady state (G(1) u): a
stable plant's output keeps moving past the horizon, an integrator's is bounded by it.
Δu bounds are left out (they only slow the inputs), so the range is an outer one.
"""
from __future__ import annotations

import numpy as np

from ..config import ConfigError, ModeConfig
from ..config.schema import INNOVATION_LIMIT_SPANS
from .plant import DiscretePlant

STABLE_BELOW = 1.0 - 1e-9  # spectral radius of a plant whose steady state is taken


def _box(M: np.ndarray, u_min: np.ndarray, u_max: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lowest, highest) of M u over the box u_min <= u <= u_max, per row of M."""
    lo, hi = M * u_min, M * u_max
    return np.minimum(lo, hi).sum(axis=-1), np.maximum(lo, hi).sum(axis=-1)


def output_reach(plant: DiscretePlant, u_min: np.ndarray, u_max: np.ndarray,
                 horizon: int, steady: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) per output: the hull of 0 and every value the outputs reach from rest
    within ``horizon`` steps and, for a stable plant when ``steady``, at steady state
    (module docstring)."""
    A, B, C = plant.A, plant.B, plant.C
    low, high = np.zeros(plant.ny), np.zeros(plant.ny)
    reach_lo, reach_hi = np.zeros(plant.ny), np.zeros(plant.ny)
    AkB = B.copy()
    with np.errstate(all="ignore"):  # an unstable plant may overflow: the pipeline says so
        for _ in range(horizon):
            lo, hi = _box(C @ AkB, u_min, u_max)
            reach_lo, reach_hi = reach_lo + lo, reach_hi + hi
            low, high = np.minimum(low, reach_lo), np.maximum(high, reach_hi)
            AkB = A @ AkB
        keep = plant.non_disturbance_states  # constant by construction: nothing feeds them
        A_p = A[np.ix_(keep, keep)]
        if steady and A_p.size and np.abs(np.linalg.eigvals(A_p)).max() < STABLE_BELOW:
            gain = C[:, keep] @ np.linalg.solve(np.eye(keep.size) - A_p, B[keep])
            lo, hi = _box(gain, u_min, u_max)
            low, high = np.minimum(low, lo), np.maximum(high, hi)
    finite = np.isfinite(low) & np.isfinite(high)
    return np.where(finite, low, -np.inf), np.where(finite, high, np.inf)


def innovation_limit(mode: ModeConfig, plant: DiscretePlant, horizon: int, key: str,
                     outputs: tuple[str, ...]) -> np.ndarray:
    """``mode.innovation_limit`` with its DERIVED_FROM_MODEL entries (NaN: the config gives
    that output no range) set to INNOVATION_LIMIT_SPANS times the span of the output's
    reach; a ConfigError naming ``key`` (``modes[j].observer.innovation_limit``) when the
    inputs do not move that output either."""
    limit = np.array(mode.innovation_limit, dtype=float)
    derive = np.isnan(limit)
    if not derive.any():
        return limit
    low, high = output_reach(plant, mode.u_min, mode.u_max, horizon)
    for a in np.flatnonzero(derive):
        span = high[a] - low[a]
        if not span > 0.0:
            raise ConfigError(key, f"has no default for output {outputs[a]!r}: no finite "
                              "bound, a scenario reference of 0 and no input that moves it "
                              "within the horizon give it no range; give one (.inf: never "
                              "clip)")
        limit[a] = INNOVATION_LIMIT_SPANS * span  # +inf when the reach is unbounded
    return limit
