"""Stage 4: one observer per mode: pole placement (paper, section 3.1) or steady-state Kalman.

Both run in the paper's predictor form
``xhat(k+1) = A xhat(k) + B u(k) + L (y(k) - C xhat(k))``, on the mode's prediction model
(with its disturbance states when ``observer.disturbance`` is set, disturbance_model).

* ``kind: poles`` (default): ``eig(A - L C)`` are the configured poles, one per state
  (nx + nd with a disturbance model).  Default poles (when the config gives none): real,
  distinct, evenly spaced in [0.80, 0.90]; the slowest, 0.9, decays to 1.3 % in 41
  samples, the convergence time the paper reports (0.41 s at Ts = 10 ms).
* ``kind: kalman``: the steady-state Kalman predictor of
  ``x+ = A x + B (u + w)``, ``d+ = d + w_d``, ``y = C x (+ d) + v`` with
  ``cov(w) = Qn`` (process noise *on the inputs*, nu x nu: meaningful for transfer-function
  and state-space plants alike, since the generator's state realisation is not the
  user's), ``cov(w_d) = Qd`` (the disturbance random walk, nd x nd) and ``cov(v) = Rn``.
  ``L = A P C' (C P C' + Rn)^-1`` with P the stabilising solution of the filter DARE
  (control.dlqe, which returns exactly this predictor-form gain).
"""
from __future__ import annotations

import warnings

import control
import numpy as np
from scipy.optimize import linear_sum_assignment

from ..config import ConfigError, ModeConfig
from .pbh import defect_text, more_text, pbh_defects, state_names
from .plant import DiscretePlant

DEFAULT_POLE_RANGE = (0.80, 0.90)
# how far a placed pole may land from the one asked for: placement rounds to ~1e-14 on
# distinct poles; clustered ones can land far off (0.06 at 1e-7 apart), a different observer
PLACEMENT_TOL = 1e-4


def default_poles(nx: int) -> tuple[complex, ...]:
    if nx == 1:
        return (complex(sum(DEFAULT_POLE_RANGE) / 2),)
    return tuple(complex(p) for p in np.linspace(*DEFAULT_POLE_RANGE, nx))


def _states_text(plant: DiscretePlant) -> str:
    n = plant.nx
    if plant.nd == 0:
        return f"{n} states"
    return f"{n} states: {n - plant.nd} of the plant + {plant.nd} disturbance states"


def _placement_gain(plant: DiscretePlant, mode: ModeConfig, key: str):
    poles = mode.observer_poles or default_poles(plant.nx)
    pkey = f"{key}.observer.poles"
    if len(poles) != plant.nx:
        raise ConfigError(pkey, f"needs {plant.nx} poles (the mode has "
                          f"{_states_text(plant)}), got {len(poles)}")
    for p in poles:
        if p.imag != 0 and p.conjugate() not in poles:
            raise ConfigError(pkey, f"complex pole {p} needs its conjugate")
    try:
        with warnings.catch_warnings():
            # with several outputs scipy's YT method iterates for the most robust gain and
            # warns when that iteration stops short; the poles are placed all the same
            # (checked below), so its warning would only confuse
            warnings.filterwarnings("ignore", "Convergence was not reached", UserWarning)
            K = control.place(plant.A.T, plant.C.T, list(poles))
    except Exception as exc:  # scipy raises ValueError for e.g. repeated poles
        why = str(exc)
        if "repeated more than rank(B)" in why:  # scipy's B is C' here: say it in our terms
            why = (f"a pole is repeated more often than the mode has outputs "
                   f"({plant.ny}); make the poles distinct")
        raise ConfigError(pkey, f"pole placement failed: {why}") from None
    L = np.asarray(K).T
    achieved = np.linalg.eigvals(plant.A - L @ plant.C)
    if np.max(np.abs(achieved)) >= 1.0:
        raise ConfigError(pkey, "placement produced an unstable observer")
    # each pole asked for against the achieved one it pairs with (the closest assignment)
    dist = np.abs(achieved[:, None] - np.array(poles, complex)[None, :])
    off = dist[linear_sum_assignment(dist)]
    if np.max(off) > PLACEMENT_TOL:
        raise ConfigError(pkey, f"placement missed a pole by {np.max(off):.2g} (poles "
                          f"{', '.join(f'{p:.4g}' for p in achieved)}): ill-conditioned; "
                          "choose poles further apart or use kind: kalman")
    return L, poles


def process_noise(plant: DiscretePlant, mode: ModeConfig) -> np.ndarray:
    """State covariance of the Kalman model: B Qn B' on the plant, Qd on the disturbances."""
    Qx = plant.B @ mode.observer_Qn @ plant.B.T
    if plant.nd:
        Qx[-plant.nd:, -plant.nd:] += mode.observer_Qd
    return 0.5 * (Qx + Qx.T)


def kalman_gain(plant: DiscretePlant, mode: ModeConfig, key: str):
    """Predictor-form steady-state Kalman gain and the observer poles eig(A - L C)."""
    okey = f"{key}.observer"
    # PBH on |z| >= 1 only: a stable mode no output sees needs no correction
    undetectable = pbh_defects(plant.A, plant.C, inputs=False, only_unstable=True)
    if undetectable:
        names = state_names(mode, plant.nx, plant.nd, plant.n_prev)
        raise ConfigError(okey, "(A, C) is not detectable: no Kalman filter converges: "
                          f"{defect_text(undetectable[0], names, None, False)} does not reach any "
                          f"output{more_text(undetectable)}")
    Qx = process_noise(plant, mode)
    try:
        L, _, poles = control.dlqe(plant.A, np.eye(plant.nx), plant.C, Qx, mode.observer_Rn)
    except Exception as exc:  # no stabilising DARE solution (control raises several types)
        raise ConfigError(f"{okey}.Qn", "the filter Riccati equation has no stabilising "
                          "solution: some marginal or unstable mode is not driven by the "
                          f"process noise ({' '.join(str(exc).split())})") from None
    L = np.asarray(L, dtype=float)
    achieved = np.linalg.eigvals(plant.A - L @ plant.C)
    if not np.all(np.isfinite(L)) or np.max(np.abs(achieved)) >= 1.0 - 1e-9:
        raise ConfigError(f"{okey}.Qn", "the Kalman predictor is not stable: some marginal "
                          "mode is not driven by the process noise (make Qn positive definite)")
    poles = tuple(sorted((complex(p) for p in achieved), key=lambda p: (abs(p), p.imag)))
    return L, poles


def observer_gain(plant: DiscretePlant, mode: ModeConfig, key: str) -> tuple[np.ndarray, tuple]:
    """L of the predictor observer and its poles eig(A - L C), by the configured method."""
    if mode.observer_kind == "kalman":
        return kalman_gain(plant, mode, key)
    return _placement_gain(plant, mode, key)

