"""The delay margin of the generated controller on its own model: how many samples of
measurement delay the model does not know of the loop tolerates.

With no bound active the MPC law is linear (qp/nominal_loop.py): u_k = K x̂_k, K the
first nu rows of Kx (the reference terms do not change stability), and the observer is
x̂+ = A x̂ + B u + L (y_meas - C x̂).  The true plant is the model's plant part (without
the disturbance states, which stand for what the plant does not have, nor the previous
input of Δu weighting, which is the controller's own memory), and the measurement it
gives the observer is d samples old: y_meas,k = C x_{k-d}.  The joint state [x, the d
delayed outputs, x̂] evolves linearly; the delay margin is the largest d up to which its
spectral radius stays below 1.  Exact for the linear loop; a loop at its margin rings
(its slowest pole near the unit circle), and once the actuator saturates it limit-cycles
(the c172p example at 5 samples on its 110 kts mode, whose margin is 4: docs/flight.md).
"""
from __future__ import annotations

import numpy as np

from .controller import ControllerModel

MAX_DELAY = 30  # samples searched
STABLE_BELOW = 1.0 - 1e-9  # spectral radius: inside the unit circle beyond roundoff


def loop_radius(model: ControllerModel, j: int, delay: int) -> float:
    """Spectral radius of mode ``j``'s unconstrained loop with ``delay`` samples of
    measurement delay the model does not have (module docstring)."""
    plant, qp, L = model.modes[j].plant, model.modes[j].qp, model.modes[j].observer_gain
    A, B, C = plant.A, plant.B, plant.C
    K = qp.Kx[:qp.nu]
    n_p = plant.nx - plant.nd - plant.n_prev  # the plant's own states come first
    ny, n = C.shape[0], plant.nx
    Ap, Bp, Cp = A[:n_p, :n_p], B[:n_p], C[:, :n_p]
    size = n_p + delay * ny + n
    M = np.zeros((size, size))
    obs = slice(n_p + delay * ny, size)
    M[:n_p, :n_p] = Ap
    M[:n_p, obs] = Bp @ K
    if delay:
        M[n_p:n_p + ny, :n_p] = Cp
        for i in range(1, delay):
            M[n_p + i * ny:n_p + (i + 1) * ny, n_p + (i - 1) * ny:n_p + i * ny] = np.eye(ny)
        M[obs, n_p + (delay - 1) * ny:n_p + delay * ny] = L
    else:
        M[obs, :n_p] = L @ Cp
    M[obs, obs] = A + B @ K - L @ C
    return float(np.abs(np.linalg.eigvals(M)).max())


def delay_margin(model: ControllerModel, j: int) -> int | None:
    """The largest unmodelled measurement delay (samples) under which mode ``j``'s loop
    is stable (module docstring); -1 if it is not even without delay, None if it is up
    to MAX_DELAY."""
    for d in range(MAX_DELAY + 1):
        if loop_radius(model, j, d) >= STABLE_BELOW:
            return d - 1
    return None


def delay_margins(model: ControllerModel) -> list[int | None]:
    """Per mode, :func:`delay_margin`."""
    return [delay_margin(model, j) for j in range(len(model.modes))]
