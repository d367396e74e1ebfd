"""Stage 4: one Luenberger observer per mode, by pole placement (paper, section 3.1).

The observer is the paper's predictor form
``xhat(k+1) = A xhat(k) + B u(k) + L (y(k) - C xhat(k))``.
Default poles (when the config gives none): real, distinct, evenly spaced in
[0.80, 0.90]. The slowest, 0.9, decays to 1.3 % in 41 samples, the convergence time the
paper reports (0.41 s at Ts = 10 ms).
"""
from __future__ import annotations

import control
import numpy as np

from .config import ConfigError, ModeConfig
from .plant import DiscretePlant

DEFAULT_POLE_RANGE = (0.80, 0.90)


def default_poles(nx: int) -> tuple[complex, ...]:
    if nx == 1:
        return (complex(sum(DEFAULT_POLE_RANGE) / 2),)
    return tuple(complex(p) for p in np.linspace(*DEFAULT_POLE_RANGE, nx))


def observer_gain(plant: DiscretePlant, mode: ModeConfig, key: str) -> tuple[np.ndarray, tuple]:
    """L such that eig(A - L C) are the configured (or default) poles."""
    poles = mode.observer_poles or default_poles(plant.nx)
    pkey = f"{key}.observer.poles"
    if len(poles) != plant.nx:
        raise ConfigError(pkey, f"needs {plant.nx} poles (the mode has {plant.nx} states), "
                          f"got {len(poles)}")
    for p in poles:
        if p.imag != 0 and p.conjugate() not in poles:
            raise ConfigError(pkey, f"complex pole {p} needs its conjugate")
    try:
        K = control.place(plant.A.T, plant.C.T, list(poles))
    except Exception as exc:  # scipy raises ValueError for e.g. repeated poles
        raise ConfigError(pkey, f"pole placement failed: {exc}") from None
    L = np.asarray(K).T
    achieved = np.linalg.eigvals(plant.A - L @ plant.C)
    if np.max(np.abs(achieved)) >= 1.0:
        raise ConfigError(pkey, "placement produced an unstable observer")
    return L, poles
