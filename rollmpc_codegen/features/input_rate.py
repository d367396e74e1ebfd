"""Δu weighting: a mode's prediction model augmented with the previous input.

``modes[].weights.R_delta`` (docs/features.md, "Δu weighting") adds

    sum_{k=0}^{N-1} (u_k - u_{k-1})' R_delta (u_k - u_{k-1}),   u_{-1} = the previous command,

to the cost of eq. (5).  As for offset-free tracking (:mod:`.disturbance_model`) this is
done at the model level, so the generated C is unchanged:

* the prediction state gets the previous input appended, ``x_a = [x; d; u_prev]`` with
  ``u_prev+ = u`` (the "velocity form"): ``A_a = diag(A, 0)``, ``B_a = [B; I]``,
  ``C_a = [C, 0]``.  The outputs do not depend on u_prev, so Phi gets zero columns and
  Gamma (the Markov parameters) is unchanged;
* in the condensed QP (:func:`.mpc.condense`) ``Delta U = D U - e_0 u_prev`` with D the
  block bidiagonal difference matrix: the Hessian gains ``2 D' R_delta D`` (Psi becomes
  block tridiagonal, so E and the terminal split S = 2(Psi + ...) keep it) and the
  gradient gains ``-2 R_delta u_prev`` on the first stage, a linear function of the
  augmented state that only changes the state gain Kx;
* the observer's rows of u_prev are ``u_prev+ = u`` exactly (zero rows of L): the C's
  observer update, which feeds every mode's observer its own actuators' commands every
  sample (0 while the mode is inactive, the held command when the measurement is not
  finite), then *is* the previous command, deadbeat (nu observer poles at 0) and exact in
  both precisions (a sum of zero products plus 1 * u).  The gain of the other states is
  designed on the model without u_prev (pole placement or Kalman, with its disturbances),
  which u_prev does not influence.

Δu *constraints* (``bounds.du_min``/``du_max``, rate limits) use the same augmented state:
they are rows of a third kind in the condensed QP (:func:`.mpc.condense`, row kind 2) on
u_k - u_{k-1}, whose stage-0 rows u_0 - u_prev carry u_prev in their right-hand side
c + W x.  Δu bounds without ``R_delta`` add the u_prev states but no cost term.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..config import ModeConfig
from ..model.observer import observer_gain as base_observer_gain
from ..model.plant import DiscretePlant


def augment(plant: DiscretePlant, mode: ModeConfig) -> DiscretePlant:
    """The prediction model with the previous input appended to the state, when the mode
    weights or bounds Δu (else the plant itself)."""
    if mode.R_delta is None and not mode.has_rate_bounds:
        return plant
    nx, nu, ny = plant.nx, plant.nu, plant.ny
    zeros = np.zeros((ny, nu))
    return replace(
        plant,
        A=np.block([[plant.A, np.zeros((nx, nu))], [np.zeros((nu, nx + nu))]]),
        B=np.vstack([plant.B, np.eye(nu)]),
        C=np.hstack([plant.C, zeros]),
        Cr=None if plant.Cr is None else np.hstack([plant.Cr, zeros]),
        input_target=(None if plant.input_target is None
                      else np.hstack([plant.input_target, np.zeros((nu, nu))])),
        n_prev=nu)


def without_previous_input(plant: DiscretePlant) -> DiscretePlant:
    """The model :func:`augment` started from."""
    if plant.n_prev == 0:
        return plant
    k = plant.nx - plant.n_prev
    return replace(
        plant, A=plant.A[:k, :k], B=plant.B[:k], C=plant.C[:, :k],
        Cr=None if plant.Cr is None else plant.Cr[:, :k],
        input_target=None if plant.input_target is None else plant.input_target[:, :k],
        n_prev=0)


def delta_hessian(R_delta: np.ndarray, N: int) -> np.ndarray:
    """D' blkdiag(R_delta) D (N nu x N nu, block tridiagonal): the Δu part of Psi."""
    nu = R_delta.shape[0]
    D = np.eye(N * nu) - np.eye(N * nu, k=-nu)
    return D.T @ np.kron(np.eye(N), R_delta) @ D


def delta_gradient(R_delta: np.ndarray, N: int, nx: int) -> np.ndarray:
    """G (N nu x nx) with the Δu part of the QP gradient = G x_a: -2 R_delta u_prev on the
    first stage (u_prev = the last nu states of x_a)."""
    nu = R_delta.shape[0]
    G = np.zeros((N * nu, nx))
    G[:nu, nx - nu:] = -2.0 * R_delta
    return G


def observer_gain(plant: DiscretePlant, mode: ModeConfig, key: str) -> tuple[np.ndarray, tuple]:
    """The mode's observer gain (:func:`.observer.observer_gain`) with zero rows for the
    previous-input states, and its poles with their nu deadbeat poles at 0."""
    L, poles = base_observer_gain(without_previous_input(plant), mode, key)
    if plant.n_prev == 0:
        return L, poles
    L = np.vstack([L, np.zeros((plant.n_prev, L.shape[1]))])
    return L, tuple(poles) + (0j,) * plant.n_prev
