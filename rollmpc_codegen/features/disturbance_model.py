"""Offset-free tracking: a mode's prediction model augmented with constant disturbances.

``modes[].observer.disturbance`` (docs/features.md, "Kalman observer and offset-free tracking"):

* ``input``: one disturbance per mode input, acting like the input,
  ``x+ = A x + B (u + d)``, ``y = C x``  (nd = nu);
* ``output``: one disturbance per output, ``x+ = A x + B u``, ``y = C x + d``  (nd = ny);

with ``d+ = d`` in both.  The augmented state ``[x; d]`` is all the rest of the pipeline
sees: the condensed QP predicts with it, the observer (pole placement on nx + nd poles, or
Kalman) estimates it, and the generated C, generic in nx, runs it unchanged.

The input weight R then weights ``u - u_s(d)``, where ``u_s = M_u d`` is the steady input
that cancels the disturbance at the origin: ``(A - I) x_s + B u_s + B_d d = 0``,
``C x_s + C_d d = 0`` (least squares when it has no exact solution).  ``u_s`` is linear in
the estimate, so it only changes the state gain Kx of the unconstrained solution (no new
data in the C).  With it a constant disturbance costs the controller nothing, and in
steady state the loop behaves as the undisturbed nominal loop: the disturbance adds no
offset.  (An offset that the nominal loop has -- absolute input weighting R on a plant
that needs u != 0 to hold r -- stays.)  Without ``u_s`` an input disturbance on the UAV
would be cancelled only as far as R lets the controller spend input on it.

Observability of the augmented pair is checked here, naming
``modes[j].observer.disturbance``: an output disturbance cannot be told apart from a
plant integrator (the UAV modes, roll angle = G(s)/s: use ``input``), and either model
needs no plant zero at z = 1 and at most ny disturbances.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..config.errors import ConfigError
from ..model.plant import DiscretePlant, discretise


def disturbance_matrices(plant: DiscretePlant, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """(B_d, C_d): how d enters the state update and the outputs."""
    nx, nu, ny = plant.nx, plant.nu, plant.ny
    if kind == "input":
        return plant.B.copy(), np.zeros((ny, nu))
    return np.zeros((nx, ny)), np.eye(ny)


def augment(plant: DiscretePlant, kind: str, key: str) -> DiscretePlant:
    """The prediction model with ``kind`` disturbances appended to the state (``none``:
    the plant itself).  ``key`` (``modes[j]``) names the mode in errors."""
    if kind == "none":
        return plant
    nx, nu, ny = plant.nx, plant.nu, plant.ny
    Bd, Cd = disturbance_matrices(plant, kind)
    nd = Bd.shape[1]
    dkey = f"{key}.observer.disturbance"
    # PBH at z = 1, the only new eigenvalue: the plant itself is observable (discretise)
    M = np.block([[plant.A - np.eye(nx), Bd], [plant.C, Cd]])
    s = np.linalg.svd(M, compute_uv=False)
    scale = max(1.0, np.abs(M).max())
    if nd > ny or s[-1] <= 1e-9 * scale:
        if nd > ny:
            why = f"{nd} input disturbances cannot be told apart with {ny} outputs"
        elif kind == "output" and np.any(np.abs(np.linalg.eigvals(plant.A) - 1.0) < 1e-9):
            why = ("an output disturbance cannot be told apart from the plant's integrator "
                   "(A has an eigenvalue at 1); use disturbance: input")
        else:
            why = "the plant has a zero at z = 1, which hides the disturbance"
        raise ConfigError(dkey, f"the augmented model [x; d] is not observable: {why}")
    # steady input that cancels d at the origin: [A-I B; C 0] [x_s; u_s] = -[B_d; C_d] d
    T = np.block([[plant.A - np.eye(nx), plant.B], [plant.C, np.zeros((ny, nu))]])
    sol = np.linalg.lstsq(T, -np.vstack([Bd, Cd]), rcond=None)[0]
    Mu = sol[nx:]  # (nu, nd)
    Cr = Dr = None
    if plant.Cr is not None:  # the rate output sees an input disturbance like the input
        Cr = np.hstack([plant.Cr, plant.Dr if kind == "input" else np.zeros((ny, nd))])
        Dr = plant.Dr
    return replace(
        plant,
        A=np.block([[plant.A, Bd], [np.zeros((nd, nx)), np.eye(nd)]]),
        B=np.vstack([plant.B, np.zeros((nd, nu))]),
        C=np.hstack([plant.C, Cd]),
        Cr=Cr, Dr=Dr, nd=nd,
        input_target=np.hstack([np.zeros((nu, nx)), Mu]))


def prediction_model(mode, Ts: float, key: str,
                     outputs: tuple[str, ...] | None = None) -> DiscretePlant:
    """The mode's discrete plant (plant.discretise, whose errors name ``outputs``),
    augmented by its disturbance model."""
    return augment(discretise(mode, Ts, key, outputs), mode.disturbance, key)
