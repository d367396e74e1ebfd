"""Hard bounds on constrained signals read on the simulated plant (``modes[].constraints``:
``signals`` and ``mixed`` rows, config/constraints.py).

A signal z = C x + D u is a bound on the plant's states (a motor's q current, a rate no
output measures), so the outputs the loop logs never show it: :func:`plant_signals`
picks each mode's hard signals once, :func:`read_signals` evaluates them on the simulated
plant every sample (x_k and the command u_k), and :func:`signal_violations` counts the
samples of the active mode past a bound, as ``metrics.constraint_violations`` does for
the outputs.

Which signals are read: hard sides only (a soft side's excursion is a penalty, not a
violation), and only signals held from the first stages on (``first <= 1``: a bound of the
trajectory; a signal declared for late stages only, e.g. ``stages: [N, N]``, constrains
the plan's end, not the plant).  A signal of a mode whose states the plant does not carry
(an operating point of a shared-actuator plant with a different state count) is skipped.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import ControllerConfig
from .scenario import plant_modes


@dataclass(frozen=True)
class PlantSignal:
    """One hard signal of mode ``mode``, read on the plant channel ``channel``:
    z = C x + D u[actuators] within [lo, hi] (-inf/+inf: that side is free or soft)."""

    name: str
    mode: int
    channel: int
    C: np.ndarray
    D: np.ndarray
    actuators: np.ndarray
    lo: float
    hi: float


def plant_signals(cfg: ControllerConfig, channel_states: list[int]) -> list[PlantSignal]:
    """The hard signals the plant can read; ``channel_states``: the state count of each of
    the plant's channels (SimulatedPlant.channels, in plant_modes order)."""
    channels = plant_modes(cfg)
    out = []
    for j, mode in enumerate(cfg.modes):
        ch = channels.index(j) if j in channels else (0 if len(channels) == 1 else None)
        if ch is None:
            continue
        nx = channel_states[ch]
        acts = np.array([cfg.actuators.index(a) for a in mode.actuators])
        for s in mode.signals:
            lo = -np.inf if s.soft_l2[0] > 0 else s.lo
            hi = np.inf if s.soft_l2[1] > 0 else s.hi
            if s.first > 1 or s.C.size > nx or not (np.isfinite(lo) or np.isfinite(hi)):
                continue
            out.append(PlantSignal(s.name, j, ch, np.r_[s.C, np.zeros(nx - s.C.size)],
                                   np.r_[s.D, np.zeros(acts.size - s.D.size)], acts, lo, hi))
    return out


def read_signals(signals: list[PlantSignal], states: list[np.ndarray],
                 u: np.ndarray) -> np.ndarray:
    """Each signal's value at the plant's ``states`` (one per channel) under command ``u``
    (every actuator)."""
    u = np.asarray(u, float)
    return np.array([s.C @ states[s.channel] + s.D @ u[s.actuators] for s in signals])


def signal_violations(signals: list[PlantSignal], z: np.ndarray, modes: np.ndarray,
                      tol: float) -> tuple[int, dict]:
    """(samples where a signal of the active mode is past a hard bound by more than
    ``tol * max(1, |bound|)``, {signal name: the farthest it passed one})."""
    bad = np.zeros(len(modes), bool)
    far: dict[str, float] = {}
    for i, s in enumerate(signals):
        active = np.asarray(modes) == s.mode
        v = z[active, i] if z.size else np.zeros(0)
        excess = np.zeros_like(v)
        for bound, sign in ((s.lo, -1.0), (s.hi, 1.0)):
            if np.isfinite(bound):
                past = sign * (v - bound)
                excess = np.maximum(excess, np.where(past > tol * max(1.0, abs(bound)),
                                                     past, 0.0))
        bad[np.flatnonzero(active)[excess > 0]] = True
        if excess.size and excess.max() > 0:
            far[s.name] = max(far.get(s.name, 0.0), float(excess.max()))
    return int(bad.sum()), far
